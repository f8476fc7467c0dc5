"""
The wrench from a measured pose: a maximum-a-posteriori estimate with the exact compliance.

Deflection-based force sensing runs the forward model backwards: the load on a continuum
robot is the one whose equilibrium has the pose a tracker sees (Rucker & Webster,
"Deflection-based force sensing for continuum robots: a probabilistic approach", IROS
2011; Black, Till & Rucker, IEEE T-RO 34(1), 2018, for parallel continuum robots). A pose
does not see every wrench direction alike: a lateral force of 1 N moves the end disk about
6 mm, an axial force of 3 N about 0.6 um, so at a tracker's 0.1-0.5 mm the axial force is
not observed at all, and a force and a moment that bend the joints alike are hard to tell
apart. Rucker & Webster's answer is a prior on the load: the estimate minimizes

    |W (y(w) - y_m)|^2 + |L (w_f - mu)|^2,

the pose error y(w) - y_m (position difference and the rotation vector log(R R_m^T), both
in the base frame: the twist convention of the compliance C, cdr_translator/compliance.py)
whitened by the pose covariance (W^T W = Sigma^-1), plus the estimated components w_f
against a Gaussian prior N(mu, P) (L^T L = P^-1; with some components held, the prior's
conditional on the held values). Directions the pose cannot see come back at the prior
with the prior's spread; the posterior covariance (J^T J)^-1, J the whitened derivative
[W C_b; L], says which.

Each iterate is a forward solve with the compliance (implicit differentiation, exact to
rounding), so the Gauss-Newton step uses the exact derivative of the position and, at a
matched pose, of the rotation. Steps are Levenberg-Marquardt steps within a trust radius
in length-scaled units (moments as the force that makes them at the stack height H), the
radius growing after steps the linearization predicted well and shrinking after steps
that do not lower the cost (Nocedal & Wright, Numerical Optimization, 2006, Ch. 4 and
10.3). The estimate has converged when the Gauss-Newton step would lower the whitened
cost by less than CONVERGED_CHI2 (a tenth of a posterior standard deviation). Along a
stream each estimate starts from the last converged one (its solve and compliance reused:
the first step needs no solve), and one that cannot converge gives up after MAX_SOLVES
forward solves.

Without a pose covariance the pose is taken as exact (a standard deviation of
EXACT_POSE_SD_M): the estimate then matches the pose to the forward solve's rounding, and
its accuracy is not assessed (``accuracy_met`` None), since nothing says how far the
measurement may be off. With one, ``accuracy_met`` compares the posterior standard
deviations with their targets, and the estimate is flagged when its normalized pose
residual fails a chi-square test, when its spread exceeds both the load it reports and the
target, past buckling, near a bifurcation, or when another wrench matches as well.

Never an exception for a pose the model cannot match: a result flagged by ``converged``,
``accuracy_met`` and ``flags``, with a message. Bad input (non-finite, wrong shape, a
non-unit quaternion, a covariance that is not symmetric positive semidefinite, an unknown
component name) raises InputError, a ValueError naming it.
"""

from dataclasses import dataclass, replace
from functools import cached_property
import math
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, TYPE_CHECKING, Union
from weakref import WeakKeyDictionary

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from .branch import RECHECK_MARGIN
from .checks import check_covariance, check_number, check_unit_quaternion, check_vector
from .compliance import ComplianceAnalysis, frame_twist
from .errors import InputError
from .geometry import quaternion_xyzw
from .stability import load_scale
from .wrench_estimate import (COMPONENT_CHOICES, COMPONENT_NAMES, CONDITION_LIMIT,
                              observability, TRANSLATOR_WRENCH_LABELS, WrenchEstimate)

if TYPE_CHECKING:
    from .solver import TranslatorSolver

__all__ = ['Components', 'DEFAULT_PRIOR_FORCE_SD', 'DEFAULT_PRIOR_MOMENT_SD',
           'DEFAULT_TARGET_FORCE_SD', 'DEFAULT_TARGET_MOMENT_SD', 'diagonal_prior',
           'estimate_along', 'estimate_from', 'estimate_wrench', 'estimated_components',
           'Evaluation', 'LOAD_LIMIT', 'measured_target', 'search', 'Target']

#: What ``estimate=`` takes: a name of COMPONENT_CHOICES or a sequence of COMPONENT_NAMES.
Components = Union[str, Sequence[str]]

#: The default prior on the wrench: zero mean, these standard deviations (N; N m). A
#: quarter of the node's default ``max_force`` (100 N) and ``max_moment`` (10 N m): wide
#: enough that any load the node accepts is within four standard deviations, narrow
#: enough to keep an unobserved axial force near zero instead of at the 29 N buckling load.
DEFAULT_PRIOR_FORCE_SD = 25.0
DEFAULT_PRIOR_MOMENT_SD = 2.5

#: The default accuracy targets of an estimate: posterior standard deviations (N; N m).
DEFAULT_TARGET_FORCE_SD = 0.5
DEFAULT_TARGET_MOMENT_SD = 0.05

#: Standard deviation (m; rad times the stack height) of a pose given without a covariance:
#: exact, ten times the forward solve's rounding (about 1e-12 m).
EXACT_POSE_SD_M = 1e-11

#: Forward solves of one estimate at most (a warm one takes 1-3; a moment from a position
#: alone, which the pose sees poorly, can take 20).
MAX_SOLVES = 40

#: Converged when the Gauss-Newton step lowers the whitened cost by at most this: the step
#: is within a tenth of a posterior standard deviation, which adds a hundredth to the
#: estimate's variance (a warm estimate along a stream then takes one forward solve).
CONVERGED_CHI2 = 1e-2

#: A rejected step from a point whose Gauss-Newton decrease is below this has hit the
#: forward solve's rounding (1e-12 m against EXACT_POSE_SD_M): converged.
ROUNDING_CHI2 = 1.0

#: Flag an estimate whose normalized pose residual has a chi-square tail probability below
#: this (the pose is further from the model than its covariance allows).
CHI2_TAIL = 1e-3

#: Trust radius after an estimate's first (damped) step, at least, and at most: scaled
#: wrench norm (N).
TRUST_RADIUS_N = 1.0
MAX_TRUST_RADIUS_N = 400.0

#: A trust radius this small relative to the wrench (scaled norm, at least 1 N) means no
#: nearby wrench lowers the cost.
STEP_TOLERANCE = 1e-10

#: Two matches further apart than this (relative, scaled wrench norm, at least 1 N) are
#: different wrenches: the forward solves converge to 1e-10, the matches to about 1e-9.
MATCH_DISTANCE = 1e-6

#: Below this stability margin another equilibrium branch is close (branch.RECHECK_MARGIN):
#: a second wrench may match the pose, and the estimate is flagged.
AMBIGUOUS_MARGIN = RECHECK_MARGIN

#: Wrenches beyond this many times the translator's load scale w* (stability.load_scale:
#: 31.4 N for the shipped one, the axial buckling load 29.3 N) are not tried: a pose that
#: only such a load could match is reported as unmatched, not solved at kilonewtons.
LOAD_LIMIT = 20.0

#: No equilibrium puts the end-disk centre further from the base than this many stack
#: heights (the backbones would have to stretch by a percent: kilonewtons).
REACH = 1.01


@dataclass
class Evaluation:
    """The forward model at one wrench: the pose it gives and its derivative."""

    wrench: np.ndarray  # (6,) SI, in the base frame
    frame: np.ndarray  # 4x4 pose of the measured body in the base frame
    compliance: np.ndarray  # 6x6 d twist / d wrench (compliance.py's convention)
    stable: Optional[bool]
    margin: float  # stability margin, 1 unloaded (NaN: none)
    accuracy_met: Optional[bool]
    message: str
    analysis: Optional[ComplianceAnalysis]
    solution: Any  # the forward solve's result


@dataclass(frozen=True)
class Target:
    """What is measured, what is estimated, and what is known beforehand."""

    frame: np.ndarray  # 4x4 measured pose (identity rotation when not measured)
    rows: Tuple[int, ...]  # measured twist components: position, and rotation if measured
    free: Tuple[int, ...]  # estimated wrench components
    given: np.ndarray  # (6,) the components that are not estimated (the rest ignored)
    covariance: Optional[np.ndarray]  # of the measured components (None: exact)
    length: float  # the scaling length H
    labels: Tuple[str, ...]  # names of the six wrench components
    prior_mean: np.ndarray  # (6,) of the wrench, SI
    prior_covariance: np.ndarray  # (6, 6) of the wrench, SI
    target_sd: np.ndarray  # (6,) accuracy targets: posterior standard deviations, SI
    load_limit: float = math.inf  # largest scaled wrench norm tried (N)

    def error(self, evaluation: Evaluation) -> np.ndarray:
        """Model pose minus measured pose, the measured components (m, rad)."""
        return frame_twist(self.frame, evaluation.frame)[list(self.rows)]

    @cached_property
    def weights(self) -> 'Weights':
        """Return the whitening of the pose and the prior (made once per Target)."""
        return Weights.of(self)


@dataclass(frozen=True)
class Weights:
    """The whitening of a Target: the pose's W and the estimated components' prior."""

    pose: np.ndarray  # W, (m, m): W^T W = Sigma^-1 (Sigma the pose covariance, or exact)
    prior: np.ndarray  # L, (k, k): L^T L = P^-1, P the prior of w_f given the held values
    mean: np.ndarray  # (k,) the prior mean of w_f given the held values

    @classmethod
    def of(cls, target: Target) -> 'Weights':
        """Whiten ``target``'s pose covariance and condition its prior on the held values."""
        exact = np.repeat([EXACT_POSE_SD_M, EXACT_POSE_SD_M / target.length], 3)
        rows = list(target.rows)
        covariance = np.diag(exact[rows] ** 2)
        if target.covariance is not None:  # a zero or singular covariance: exact there
            covariance = covariance + target.covariance
        free = list(target.free)
        held = [index for index in range(6) if index not in target.free]
        prior = target.prior_covariance
        mean = target.prior_mean[free].copy()
        spread = prior[np.ix_(free, free)]
        if held:
            gain = prior[np.ix_(free, held)] @ np.linalg.pinv(prior[np.ix_(held, held)])
            mean = mean + gain @ (target.given[held] - target.prior_mean[held])
            spread = spread - gain @ prior[np.ix_(held, free)]
        return cls(_inverse_root(covariance), _inverse_root(0.5 * (spread + spread.T)), mean)


def _inverse_root(covariance: np.ndarray) -> np.ndarray:
    """Return W with W^T W = covariance^-1: the inverse of its lower Cholesky factor."""
    factor = np.linalg.cholesky(covariance)
    return np.linalg.solve(factor, np.eye(len(factor)))


@dataclass
class Search:
    """Where the iteration ended and why."""

    best: Optional[Evaluation]
    converged: bool
    message: str
    iterations: int = 0
    solves: int = 0
    #: another matching wrench, found by the second search (see estimate_along)
    alternative: Optional[np.ndarray] = None


def estimated_components(estimate: Optional[Components], oriented: bool,
                         force: Optional[ArrayLike], moment: Optional[ArrayLike]
                         ) -> Tuple[int, ...]:
    """
    Return the indices of the wrench components to estimate (InputError naming a bad one).

    ``estimate`` is a name of COMPONENT_CHOICES ('wrench', 'force', 'moment', 'lateral') or
    a sequence of COMPONENT_NAMES ('fx', 'fy', 'fz', 'mx', 'my', 'mz'). None: what the
    pose and the given components leave: with a measured orientation all six, the force
    when only ``moment`` is given, the moment when only ``force`` is; from a position the
    force (under ``moment``, default zero) or, when only ``force`` is given, the moment.
    """
    if estimate is None:
        if force is not None and moment is not None:
            raise InputError('force and moment both given: name the components to estimate '
                             'with estimate= (e.g. estimate=("fx", "fy")), not both')
        if force is not None:
            return COMPONENT_CHOICES['moment']
        if moment is not None or not oriented:
            return COMPONENT_CHOICES['force']
        return COMPONENT_CHOICES['wrench']
    if isinstance(estimate, str):
        if estimate in COMPONENT_CHOICES:
            return COMPONENT_CHOICES[estimate]
        names: Sequence[Any] = [part for part in estimate.replace(',', ' ').split() if part]
    else:
        names = list(estimate)
    unknown = [name for name in names if name not in COMPONENT_NAMES]
    if unknown or not names:
        raise InputError(f'estimate must be one of {sorted(COMPONENT_CHOICES)} or names from '
                         f'{list(COMPONENT_NAMES)}, got {estimate!r}')
    if len(set(names)) != len(names):
        raise InputError(f'estimate names a component twice: {estimate!r}')
    return tuple(sorted(COMPONENT_NAMES.index(name) for name in names))


def diagonal_prior(force_sd: float = DEFAULT_PRIOR_FORCE_SD,
                     moment_sd: float = DEFAULT_PRIOR_MOMENT_SD) -> np.ndarray:
    """Return the diagonal 6x6 prior covariance of standard deviations (N, N m) given."""
    force_sd = check_number('prior force standard deviation', force_sd, low=0.0,
                            low_open=True, error=InputError)
    moment_sd = check_number('prior moment standard deviation', moment_sd, low=0.0,
                             low_open=True, error=InputError)
    return np.diag(np.repeat([force_sd, moment_sd], 3) ** 2)


def measured_target(position: ArrayLike, quaternion_xyzw: Optional[ArrayLike],
                    covariance: Optional[ArrayLike], moment: Optional[ArrayLike],
                    force: Optional[ArrayLike], length: float,
                    labels: Tuple[str, ...] = TRANSLATOR_WRENCH_LABELS,
                    names: Tuple[str, str, str] = ('position', 'quaternion_xyzw',
                                                   'pose_covariance'), *,
                    estimate: Optional[Components] = None,
                    prior_mean: Optional[ArrayLike] = None,
                    prior_covariance: Optional[ArrayLike] = None,
                    target_force_sd: float = DEFAULT_TARGET_FORCE_SD,
                    target_moment_sd: float = DEFAULT_TARGET_MOMENT_SD) -> Target:
    """
    Check a measured pose, the components to estimate and the prior; return the Target.

    ``estimate`` (estimated_components) names the components solved for; the others are
    held at ``force`` and ``moment`` (default zero; their estimated components are
    ignored). ``covariance`` is 6x6 (position, then rotation about the base axes, as a ROS
    PoseWithCovariance) with the orientation; 3x3 or 6x6 (its position block used) without
    it. ``prior_mean`` (6, default zero) and ``prior_covariance`` (6x6, default
    diagonal_prior()) are the Gaussian prior on the wrench in the base frame.
    ``target_force_sd`` and ``target_moment_sd`` (N, N m) are the posterior standard
    deviations an estimate must reach to meet its accuracy target. InputError (a
    ValueError) names a bad value.
    """
    frame = np.eye(4)
    frame[:3, 3] = check_vector(names[0], position)
    oriented = quaternion_xyzw is not None
    if oriented:
        quaternion = check_unit_quaternion(names[1], quaternion_xyzw)
        frame[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
    free = estimated_components(estimate, oriented, force, moment)
    given = np.zeros(6)
    if force is not None:
        given[:3] = check_vector('force', force)
    if moment is not None:
        given[3:] = check_vector('moment', moment)
    rows = tuple(range(6)) if oriented else (0, 1, 2)
    checked = None
    if covariance is not None:
        size = 3 if len(rows) == 3 and np.shape(covariance) == (3, 3) else 6
        checked = check_covariance(names[2], covariance, size)[:len(rows), :len(rows)]
    mean = np.zeros(6) if prior_mean is None else check_vector('prior_mean', prior_mean, 6)
    spread = (diagonal_prior() if prior_covariance is None
              else check_covariance('prior_covariance', prior_covariance, 6))
    if np.linalg.eigvalsh(spread[np.ix_(free, free)])[0] <= 0.0:
        raise InputError('prior_covariance must be positive definite over the estimated '
                         f'components {[COMPONENT_NAMES[index] for index in free]}')
    targets = np.repeat([check_number('target_force_sd', target_force_sd, low=0.0,
                                      low_open=True, error=InputError),
                         check_number('target_moment_sd', target_moment_sd, low=0.0,
                                      low_open=True, error=InputError)], 3)
    return Target(frame, rows, free, given, checked, float(length), labels, mean, spread,
                  targets)


def _whitened(target: Target, weights: Weights, evaluation: Evaluation,
              scale: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return (r, J): the whitened residual [W e; L (w_f - mu)] and its derivative.

    J is by the estimated components in scaled units (N: moments over H).
    """
    free = list(target.free)
    block = evaluation.compliance[np.ix_(list(target.rows), free)] * scale[None, free]
    residual = np.concatenate([weights.pose @ target.error(evaluation),
                               weights.prior @ (evaluation.wrench[free] - weights.mean)])
    return residual, np.vstack([weights.pose @ block, weights.prior * scale[None, free]])


def search(evaluate: Callable[[np.ndarray], Optional[Evaluation]],
           start: Optional[Evaluation], target: Target, deadline: float,
           begin: Optional[np.ndarray] = None, solves: int = MAX_SOLVES) -> Search:
    """
    Minimize the whitened cost over the estimated components from ``start``.

    Without ``start`` (or one at other held values) from ``begin``, else from the prior
    mean. ``evaluate`` solves the forward model at a wrench (None when that solve fails);
    at most ``solves`` of them.
    """
    found = Search(None, False, '')
    weights = target.weights
    free = list(target.free)
    fixed = [index for index in range(6) if index not in target.free]
    warm = start is not None
    if start is None or np.any(start.wrench[fixed] != target.given[fixed]):
        wrench = target.given.copy()
        wrench[free] = weights.mean
        origin = start.wrench if start is not None else begin
        if origin is not None:
            wrench[free] = origin[free]
        start = evaluate(wrench)
        found.solves += 1
        if start is None:
            found.message = 'the forward solve at the starting wrench did not converge'
            return found
    current, radius = start, None
    found.best = current
    scale = np.repeat([1.0, target.length], 3)
    residual, jacobian = _whitened(target, weights, current, scale)
    while True:
        cost = float(residual @ residual)
        left, values, right = np.linalg.svd(jacobian, full_matrices=False)
        projected = left.T @ residual
        if float(projected @ projected) <= CONVERGED_CHI2:
            found.converged, found.message = True, 'converged'
            return found
        if radius is None:
            # the first radius from the damped step: the Gauss-Newton one is mostly the
            # poorly observed directions (the axial force), where the linearization from
            # far away is least trusted. A warm start takes the Gauss-Newton step when it
            # fits (along a stream it does: one forward solve per estimate); a cold one the
            # damped step.
            damped = _trust_region_step(values, right, projected, None)
            radius = max(2.0 * float(np.linalg.norm(damped)), TRUST_RADIUS_N)
            step = _trust_region_step(values, right, projected, radius) if warm else damped
        else:
            step = _trust_region_step(values, right, projected, radius)
        floor = STEP_TOLERANCE * max(float(np.linalg.norm(current.wrench / scale)), 1.0)
        if found.solves >= solves or time.perf_counter() > deadline:
            found.message = (f'no match after {found.solves} forward solves'
                             if found.solves >= solves else 'time limit reached')
            return found
        found.iterations += 1
        wrench = current.wrench.copy()
        wrench[free] += scale[free] * step
        beyond = float(np.linalg.norm(wrench / scale)) > target.load_limit
        trial = None if beyond else evaluate(wrench)
        found.solves += 0 if beyond else 1
        predicted = cost - float(np.sum((residual + jacobian @ step) ** 2))
        if trial is not None and not (trial.stable is False and current.stable is not False):
            # a stable iterate never steps past buckling: the structure rests on a stable
            # equilibrium, and the unstable side only leads the iteration to kilonewtons
            trial_residual, trial_jacobian = _whitened(target, weights, trial, scale)
            trial_cost = float(trial_residual @ trial_residual)
            if trial_cost < cost:
                gain = (cost - trial_cost) / predicted if predicted > 0.0 else 0.0
                if gain > 0.75 and float(np.linalg.norm(step)) >= 0.99 * radius:
                    radius = min(2.0 * radius, MAX_TRUST_RADIUS_N)
                elif gain < 0.25:
                    radius = 0.5 * float(np.linalg.norm(step))
                current, residual, jacobian = trial, trial_residual, trial_jacobian
                found.best = current
                continue
        if float(projected @ projected) <= ROUNDING_CHI2:
            found.converged = True
            found.message = 'converged (to the rounding of the forward solve)'
            return found
        radius = 0.25 * float(np.linalg.norm(step))
        if radius <= floor:
            found.message = 'no nearby wrench lowers the pose residual: no equilibrium ' \
                'matches the measured pose' + (
                    f' within the load limit ({target.load_limit:.4g} N, scaled)' if beyond
                    else '')
            return found


def _trust_region_step(values: np.ndarray, right: np.ndarray, projected: np.ndarray,
                       radius: Optional[float]) -> np.ndarray:
    """
    Return the Levenberg-Marquardt step within ``radius``.

    Minimizes |r + J step|^2 + lambda |step|^2 (scaled units; J = U diag(values) V^T and
    ``projected`` = U^T r) with the smallest lambda >= 0 that keeps the step within the
    radius (the Gauss-Newton step when it fits), picked on a logarithmic grid. Without a
    radius (an estimate's first step) lambda is (values_max / CONDITION_LIMIT)^2: the
    poorly observable directions (the axial force) barely move until the others fit,
    since there the pose error is mostly the others' second-order effect (the end disk
    drops as it swings sideways) that a first-order model reads as axial load.
    """
    weights = values * projected
    newton = -right.T @ (weights / values ** 2)
    size = float(np.linalg.norm(newton))
    if radius is None:
        return -right.T @ (weights / (values ** 2 + (values[0] / CONDITION_LIMIT) ** 2))
    if size <= radius or not math.isfinite(size):
        return newton
    top = float(np.linalg.norm(weights)) / radius  # |step| <= |J^T r| / lambda
    grid = np.geomspace(max(1e-6 * values[-1] ** 2, 1e-12 * top), top, 200)
    sizes = np.linalg.norm(weights[None, :] / (values[None, :] ** 2 + grid[:, None]), axis=1)
    damping = grid[int(np.argmax(sizes <= radius))]
    return -right.T @ (weights / (values ** 2 + damping))


def estimate_from(found: Search, target: Target, started: float) -> WrenchEstimate:
    """Build the WrenchEstimate of a search: posterior, conditioning, verdicts, message."""
    best = found.best
    components = tuple(COMPONENT_NAMES[index] for index in target.free)
    if best is None:
        return WrenchEstimate(np.full(3, np.nan), np.full(3, np.nan), None, False, None,
                              False, math.nan, math.nan, [], found.message,
                              estimated=_estimated(target), components=components,
                              iterations=found.iterations, solves=found.solves,
                              flags=[found.message],
                              estimate_time_s=time.perf_counter() - started)
    rows, free = list(target.rows), list(target.free)
    weights = target.weights
    pose_block = weights.pose @ best.compliance[np.ix_(rows, free)]
    information = pose_block.T @ pose_block + weights.prior.T @ weights.prior
    posterior = np.linalg.inv(information)
    sensitivity = np.zeros((6, len(rows)))
    sensitivity[free] = posterior @ pose_block.T @ weights.pose
    covariance = None
    if target.covariance is not None:
        covariance = np.zeros((6, 6))
        covariance[np.ix_(free, free)] = 0.5 * (posterior + posterior.T)
    condition, directions = observability(best.compliance, rows, free, target.length,
                                          target.labels, covariance, best.analysis)
    error = frame_twist(target.frame, best.frame)
    whitened = weights.pose @ error[rows]
    chi_square = float(whitened @ whitened)
    tail = float(chi2.sf(chi_square, len(rows))) if target.covariance is not None else math.nan
    deviation = np.zeros(6)
    deviation[free] = np.sqrt(np.maximum(np.diag(posterior), 0.0))
    flags = _flags(found, best, target, deviation, tail)
    messages = [found.message, *flags]
    if directions:
        messages.append('poorly observable: ' + ', '.join(
            f"{direction['label']} ({direction['ratio']:.3g} x)" for direction in directions))
    accuracy_met: Optional[bool] = False
    if not found.converged:
        flags.insert(0, found.message)
    elif target.covariance is None:
        accuracy_met = None  # an exact pose: nothing to compare a spread with
        messages.append('accuracy not assessed: no pose covariance')
    else:
        accuracy_met = not flags
    rotation = quaternion_xyzw(best.frame[:3, :3])
    return WrenchEstimate(
        force=best.wrench[:3].copy(), moment=best.wrench[3:].copy(), covariance=covariance,
        converged=found.converged, stable=best.stable, accuracy_met=accuracy_met,
        residual_m=float(np.linalg.norm(error[:3])),
        residual_deg=(math.degrees(float(np.linalg.norm(error[3:]))) if len(rows) == 6
                      else math.nan),
        conditioning=directions, message='; '.join(messages), estimated=_estimated(target),
        components=components, condition_number=condition,
        ill_conditioned=bool(directions), stability_margin=best.margin,
        iterations=found.iterations, solves=found.solves, alternative=found.alternative,
        estimate_time_s=time.perf_counter() - started, position=best.frame[:3, 3].copy(),
        quaternion_xyzw=rotation, sensitivity=sensitivity, solution=best.solution,
        standard_deviation=deviation if covariance is not None else np.full(6, np.nan),
        target_sd=np.where(np.isin(np.arange(6), free), target.target_sd, np.nan),
        chi_square=chi_square, chi_square_p=tail, flags=flags)


def _flags(found: Search, best: Evaluation, target: Target, deviation: np.ndarray,
           tail: float) -> List[str]:
    """Say why an estimate is not to be acted on (empty: nothing found wrong)."""
    flags = []
    if best.stable is False:
        flags.append('past buckling: the matching equilibrium is unstable')
    elif best.stable is None:
        flags.append('stability unknown')
    elif best.margin < AMBIGUOUS_MARGIN:
        flags.append(f'near a bifurcation (stability margin {best.margin:.3g}): another '
                     'wrench may match this pose')
    if best.accuracy_met is False:
        flags.append('the forward solve misses its accuracy target')
    if found.alternative is not None:
        flags.append('ambiguous: the moment ' + ', '.join(
            f'{value:.4g}' for value in found.alternative[3:]) + ' N m matches too')
    if target.covariance is None:
        return flags
    if tail < CHI2_TAIL:
        flags.append(f'the pose is further from the model than its covariance allows '
                     f'(chi-square {_chi_text(tail, len(target.rows))})')
    free = set(target.free)
    for name, part, unit in (('force', slice(0, 3), 'N'), ('moment', slice(3, 6), 'N m')):
        indices = [index for index in range(6)[part] if index in free]
        if not indices:
            continue
        spread = float(np.linalg.norm(deviation[indices]))
        load = float(np.linalg.norm(best.wrench[part]))
        if spread > load and spread > float(np.linalg.norm(target.target_sd[indices])):
            flags.append(f'uninformative: the {name} spread {spread:.3g} {unit} exceeds the '
                         f'{name} it reports ({load:.3g} {unit})')
    missed = [f'{COMPONENT_NAMES[index]} {deviation[index]:.3g} > {target.target_sd[index]:.3g}'
              for index in target.free if deviation[index] > target.target_sd[index]]
    if missed:
        flags.append('accuracy target missed (posterior standard deviation): '
                     + ', '.join(missed))
    return flags


def _chi_text(tail: float, dof: int) -> str:
    """Say a chi-square test's tail probability and degrees of freedom."""
    return f'tail probability {tail:.2g} at {dof} degrees of freedom'


def _estimated(target: Target) -> str:
    """Name what was estimated: a COMPONENT_CHOICES name, or the components joined."""
    for name, indices in COMPONENT_CHOICES.items():
        if target.free == indices:
            return name
    return ','.join(COMPONENT_NAMES[index] for index in target.free)


# the translator ------------------------------------------------------------------------------
#: Each solver's (or robot's) last converged iterate: the next estimate's first linearization.
_STARTS: 'WeakKeyDictionary[Any, Evaluation]' = WeakKeyDictionary()


def _translator_evaluation(solver: 'TranslatorSolver', wrench: np.ndarray,
                           deadline: float) -> Optional[Evaluation]:
    """Solve the translator at ``wrench`` with its compliance by ``deadline`` (None: failed)."""
    limit = solver.time_limit_s
    solver.time_limit_s = max(deadline - time.perf_counter(), 0.0)
    try:
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
    finally:
        solver.time_limit_s = limit
    if not result.converged or result.compliance is None:
        return None
    # the margin from the exact compliance here: the solve's may come from a factorization
    # made at another wrench (docs/stability.md), and near zero it decides the ambiguity
    compliance = result.compliance.matrix
    scale = np.repeat([1.0, solver.params.stack_height], 3)
    try:
        stiffness = np.linalg.inv(scale[:, None] * compliance * scale[None, :])
        margin = float(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0]
                       / solver._origin().smallest_stiffness)
    except np.linalg.LinAlgError:
        margin = -math.inf
    return Evaluation(wrench.copy(), result.frames['de'], compliance, result.stable, margin,
                      result.accuracy_met, result.message, result.compliance, result)


def estimate_wrench(solver: 'TranslatorSolver', position: ArrayLike,
                    quaternion_xyzw: Optional[ArrayLike] = None, *,
                    pose_covariance: Optional[ArrayLike] = None,
                    moment: Optional[ArrayLike] = None,
                    force: Optional[ArrayLike] = None,
                    estimate: Optional[Components] = None,
                    prior_mean: Optional[ArrayLike] = None,
                    prior_covariance: Optional[ArrayLike] = None,
                    target_force_sd: float = DEFAULT_TARGET_FORCE_SD,
                    target_moment_sd: float = DEFAULT_TARGET_MOMENT_SD) -> WrenchEstimate:
    """Return the end-disk wrench matching a measured pose (TranslatorSolver's method)."""
    started = time.perf_counter()
    length = solver.params.stack_height
    target = replace(measured_target(position, quaternion_xyzw, pose_covariance, moment, force,
                                     length, estimate=estimate, prior_mean=prior_mean,
                                     prior_covariance=prior_covariance,
                                     target_force_sd=target_force_sd,
                                     target_moment_sd=target_moment_sd),
                     load_limit=LOAD_LIMIT * load_scale(solver._origin()))
    reach = float(np.linalg.norm(target.frame[:3, 3]))
    if reach > REACH * length:
        return estimate_from(
            Search(None, False, f'unreachable: the end disk cannot be {reach:.4g} m from the '
                   f'base (stack height {length:.4g} m)'), target, started)
    deadline = started + solver.time_limit_s
    return estimate_along(solver, lambda wrench: _translator_evaluation(solver, wrench, deadline),
                          target, started, deadline, solver._previous is not None,
                          solver.reset)


def _other_match(evaluate: Callable[[np.ndarray], Optional[Evaluation]], found: Search,
                 target: Target, deadline: float) -> Optional[np.ndarray]:
    """Search from the other starts of a moment (estimate_along); return a second match."""
    assert found.best is not None and found.best.compliance is not None
    scale = np.repeat([1.0, target.length], 3)
    rows, free = list(target.rows), list(target.free)
    block = scale[rows, None] * found.best.compliance[np.ix_(rows, free)] * scale[None, free]
    least = np.zeros(6)
    least[free] = np.linalg.svd(block)[2][-1] * scale[free]
    reach = 0.1 * target.load_limit / LOAD_LIMIT  # a tenth of w* (scaled N)
    match = found.best.wrench
    for begin in (target.given, match + reach * least, match - reach * least):
        if time.perf_counter() > deadline:
            break
        other = search(evaluate, None, target, deadline, begin)
        found.iterations += other.iterations
        found.solves += other.solves
        if other.converged and other.best is not None and np.linalg.norm(
                (other.best.wrench - match) / scale) > MATCH_DISTANCE * max(
                float(np.linalg.norm(match / scale)), 1.0):
            return other.best.wrench.copy()
    return None


def estimate_along(owner: Any, evaluate: Callable[[np.ndarray], Optional[Evaluation]],
                   target: Target, started: float, deadline: float, warm: bool,
                   reset: Callable[[], None]) -> WrenchEstimate:
    """
    Search from ``owner``'s last estimate when ``warm`` (else cold), and build the estimate.

    A warm search that fails is repeated once from the prior mean after ``reset`` (the
    previous estimate may sit past buckling or far away), within ``deadline`` and the rest
    of MAX_SOLVES; a converged one is the next warm start. A moment from a position alone
    is searched again from no moment and from the match moved either way along its least
    observable direction (by a tenth of the load scale w*): a position sees the moment
    only through the couplings of the compliance, and several moments put the end disk at
    the same point; a second match found is ``alternative``.
    """
    start = _STARTS.get(owner) if warm else None
    found = search(evaluate, start, target, deadline)
    if (not found.converged and start is not None and time.perf_counter() < deadline
            and found.solves < MAX_SOLVES):
        reset()
        restart = search(evaluate, None, target, deadline, solves=MAX_SOLVES - found.solves)
        restart.iterations += found.iterations
        restart.solves += found.solves
        restart.message += ' (after a restart from the prior mean)'
        found = restart
    if (found.converged and found.best is not None and _estimated(target) == 'moment'
            and len(target.rows) == 3):
        found.alternative = _other_match(evaluate, found, target, deadline)
    if found.converged and found.best is not None:
        _STARTS[owner] = found.best
    else:
        _STARTS.pop(owner, None)
    return estimate_from(found, target, started)
