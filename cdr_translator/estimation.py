"""
The wrench from a measured pose: Newton on the wrench with the exact compliance.

Deflection-based force sensing runs the forward model backwards: the load on a continuum
robot is the one whose equilibrium has the pose a tracker sees (Rucker & Webster's
probabilistic deflection-based force sensing for continuum robots, 2011; Black, Till &
Rucker, IEEE T-RO 34(1), 2018, for parallel continuum robots). Here the unknowns are the
wrench components estimated (all six with a measured orientation, else the force or the
moment) and the residual is the model's pose minus the measured one: the position
difference and the rotation vector log(R R_m^T), both in the base frame, which is the
twist convention of the compliance C (cdr_translator/compliance.py). Each iterate is a
forward solve with the compliance (implicit differentiation, exact to rounding), so the
Newton step -C_b^-1 e uses the exact derivative of the position and, at the solution
(where log(R R_m^T) = 0), of the rotation; convergence is quadratic. Far from the solution
Newton's step trusts the linearization too much (from the unloaded state, the end disk's
drop under a lateral load reads as kilonewtons of axial compression): steps are
Levenberg-Marquardt steps within a trust radius, in length-scaled units (moments as the
force that makes them at the stack height, rotations as the displacement they cause
there), the radius growing after steps the linearization predicted well and shrinking
after steps that do not lower the scaled residual (Nocedal & Wright, Numerical
Optimization, 2006, Ch. 4 and 10.3). Along a stream each estimate starts from the last
accepted iterate of the previous one (its solve and compliance are reused: the first step
needs no solve), and the forward solves warm-start along the iterates.

Near the solution the estimate is a linear function of the measured pose, so the pose
covariance Sigma maps to the wrench covariance G Sigma G^T, G = C_b^-1 (the block of the
stiffness); observability and the conditioning flag: cdr_translator/wrench_estimate.py.

Never an exception for a pose the model cannot match: beyond the translator's reach, a
pose no wrench reaches (the trust radius collapses, or the iterations or the time run
out), an equilibrium past buckling (unstable) or one close to a bifurcation (another
wrench may match the same pose), or a second match found (a moment from a position:
``estimate_along``) give a result flagged by ``converged`` or ``accuracy_met`` and its
message. Bad input (non-finite, wrong shape, a non-unit quaternion, a covariance
that is not symmetric positive semidefinite) raises InputError, a ValueError.
"""

from dataclasses import dataclass, replace
import math
import time
from typing import Any, Callable, Optional, Tuple, TYPE_CHECKING
from weakref import WeakKeyDictionary

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from .branch import RECHECK_MARGIN
from .checks import check_covariance, check_unit_quaternion, check_vector
from .compliance import ComplianceAnalysis, frame_twist
from .errors import InputError
from .geometry import quaternion_xyzw
from .stability import load_scale
from .wrench_estimate import (CONDITION_LIMIT, observability, TRANSLATOR_WRENCH_LABELS,
                              WrenchEstimate)

if TYPE_CHECKING:
    from .solver import TranslatorSolver

__all__ = ['estimate', 'estimate_along', 'estimate_wrench', 'Evaluation', 'LOAD_LIMIT',
           'measured_target', 'search', 'Target']

#: Newton iterations (forward solves) of one estimate at most.
MAX_ITERATIONS = 40

#: Trust radius after an estimate's first (damped) step, at least, and at most: scaled
#: wrench norm (N).
TRUST_RADIUS_N = 1.0
MAX_TRUST_RADIUS_N = 400.0

#: The model's pose matches the measured one when the scaled residual (position, and the
#: rotation vector times the stack height) is within this (m): the forward solve's tolerance
#: (1e-10 of the disk spacing) leaves about 1e-12 m.
MATCH_M = 1e-11

#: A Newton step this small relative to the wrench (scaled norm, at least 1 N) ends the
#: iteration: the pose is matched to the rounding of the forward solve.
STEP_TOLERANCE = 1e-10

#: Two matches further apart than this (relative, scaled wrench norm, at least 1 N) are
#: different wrenches: the forward solves converge to 1e-10, the matches to about 1e-9.
MATCH_DISTANCE = 1e-6

#: A rejected step from a residual below this (m, scaled) ends the iteration as converged:
#: the forward solve's rounding, not the wrench, sets the residual there.
ROUNDING_M = 1e-9

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
    accuracy_met: bool
    message: str
    analysis: Optional[ComplianceAnalysis]
    solution: Any  # the forward solve's result


@dataclass(frozen=True)
class Target:
    """What is measured and what is estimated."""

    frame: np.ndarray  # 4x4 measured pose (identity rotation when not measured)
    rows: Tuple[int, ...]  # measured twist components: position, and rotation if measured
    free: Tuple[int, ...]  # estimated wrench components
    given: np.ndarray  # (6,) the components that are not estimated (the rest ignored)
    covariance: Optional[np.ndarray]  # of the measured components
    length: float  # the scaling length H
    labels: Tuple[str, ...]  # names of the six wrench components
    load_limit: float = math.inf  # largest scaled wrench norm tried (N)

    def error(self, evaluation: Evaluation) -> np.ndarray:
        """Model pose minus measured pose, the measured components (m, rad)."""
        return frame_twist(self.frame, evaluation.frame)[list(self.rows)]

    def merit(self, evaluation: Evaluation) -> float:
        """Scaled size of the error (m): rotations as the displacement they cause at H."""
        error = self.error(evaluation)
        if error.size == 6:
            error[3:] *= self.length
        return float(np.linalg.norm(error))


@dataclass
class Search:
    """Where the Newton iteration ended and why."""

    best: Optional[Evaluation]
    converged: bool
    message: str
    iterations: int = 0
    solves: int = 0
    #: another matching wrench, found by the second search (see estimate_along)
    alternative: Optional[np.ndarray] = None


def measured_target(position: ArrayLike, quaternion_xyzw: Optional[ArrayLike],
                    covariance: Optional[ArrayLike], moment: Optional[ArrayLike],
                    force: Optional[ArrayLike], length: float,
                    labels: Tuple[str, ...] = TRANSLATOR_WRENCH_LABELS,
                    names: Tuple[str, str, str] = ('position', 'quaternion_xyzw',
                                                   'pose_covariance')) -> Target:
    """
    Check a measured pose and the given wrench components; return the Target (InputError).

    With the orientation all six components are estimated (``moment`` and ``force`` must be
    None); without it the force (``moment`` given, default zero) or, when only ``force`` is
    given, the moment. ``covariance`` is 6x6 (position, then rotation about the base axes,
    as a ROS PoseWithCovariance) with the orientation; 3x3 or 6x6 (its position block used)
    without it.
    """
    frame = np.eye(4)
    frame[:3, 3] = check_vector(names[0], position)
    given = np.zeros(6)
    if quaternion_xyzw is not None:
        quaternion = check_unit_quaternion(names[1], quaternion_xyzw)
        frame[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
        if moment is not None or force is not None:
            raise InputError('with the orientation all six wrench components are estimated: '
                             'give neither moment nor force')
        rows, free = tuple(range(6)), tuple(range(6))
    elif force is not None:
        if moment is not None:
            raise InputError('a position observes three components: give moment or force, '
                             'not both')
        given[:3] = check_vector('force', force)
        rows, free = (0, 1, 2), (3, 4, 5)
    else:
        given[3:] = check_vector('moment', moment if moment is not None else np.zeros(3))
        rows, free = (0, 1, 2), (0, 1, 2)
    checked = None
    if covariance is not None:
        size = 3 if len(rows) == 3 and np.shape(covariance) == (3, 3) else 6
        checked = check_covariance(names[2], covariance, size)[:len(rows), :len(rows)]
    return Target(frame, rows, free, given, checked, float(length), labels)


def search(evaluate: Callable[[np.ndarray], Optional[Evaluation]],
           start: Optional[Evaluation], target: Target, deadline: float,
           begin: Optional[np.ndarray] = None) -> Search:
    """
    Newton on the estimated components from ``start`` (None: from ``begin``, else zero).

    ``evaluate`` solves the forward model at a wrench (None when that solve fails).
    """
    found = Search(None, False, '')
    fixed = [index for index in range(6) if index not in target.free]
    if start is None or np.any(start.wrench[fixed] != target.given[fixed]):
        wrench = target.given.copy()
        origin = start.wrench if start is not None else begin
        if origin is not None:
            wrench[list(target.free)] = origin[list(target.free)]
        start = evaluate(wrench)
        found.solves += 1
        if start is None:
            found.message = 'the forward solve at the starting wrench did not converge'
            return found
    current, radius = start, None
    found.best = current
    scale = np.repeat([1.0, target.length], 3)
    rows, free = list(target.rows), list(target.free)
    error = scale[rows] * target.error(current)
    while True:
        merit = float(np.linalg.norm(error))
        if merit <= MATCH_M:
            found.converged, found.message = True, 'converged'
            return found
        block = scale[rows, None] * current.compliance[np.ix_(rows, free)] * scale[None, free]
        step, newton = _trust_region_step(block, error, radius)
        size = float(np.linalg.norm(step))
        radius = max(2.0 * size, TRUST_RADIUS_N) if radius is None else radius
        floor = STEP_TOLERANCE * max(float(np.linalg.norm(current.wrench / scale)), 1.0)
        if newton <= floor:
            found.converged, found.message = True, 'converged'
            return found
        if not np.all(np.isfinite(step)):
            found.message = 'the compliance at the iterate is singular: the pose does not ' \
                'determine the wrench there'
            return found
        if found.iterations >= MAX_ITERATIONS or time.perf_counter() > deadline:
            found.message = (f'no match after {found.iterations} iterations'
                             if found.iterations >= MAX_ITERATIONS else 'time limit reached')
            return found
        found.iterations += 1
        wrench = current.wrench.copy()
        wrench[free] += scale[free] * step
        beyond = float(np.linalg.norm(wrench / scale)) > target.load_limit
        trial = None if beyond else evaluate(wrench)
        found.solves += 0 if beyond else 1
        predicted = merit ** 2 - float(np.linalg.norm(error + block @ step)) ** 2
        trial_error = None if trial is None else scale[rows] * target.error(trial)
        if trial is not None and trial_error is not None and np.linalg.norm(trial_error) < merit:
            gain = (merit ** 2 - float(np.linalg.norm(trial_error)) ** 2) / predicted
            if gain > 0.75 and size >= 0.99 * radius:
                radius = min(2.0 * radius, MAX_TRUST_RADIUS_N)
            elif gain < 0.25:
                radius = 0.5 * size
            current, error = trial, trial_error
            found.best = current
            continue
        if merit <= ROUNDING_M:
            found.converged = True
            found.message = 'converged (to the rounding of the forward solve)'
            return found
        radius = 0.25 * size
        if radius <= floor:
            found.message = 'no nearby wrench lowers the pose residual: no equilibrium ' \
                'matches the measured pose' + (
                    f' within the load limit ({target.load_limit:.4g} N, scaled)' if beyond
                    else '')
            return found


def _trust_region_step(block: np.ndarray, error: np.ndarray,
                       radius: Optional[float]) -> Tuple[np.ndarray, float]:
    """
    Return (step, Newton step's size): the Levenberg-Marquardt step of size at most ``radius``.

    Minimizes |error + block step|^2 + lambda |step|^2 (scaled units) with the smallest
    lambda >= 0 that keeps the step within the radius (Newton's step when it fits), picked
    on a logarithmic grid from the SVD of the block: the step bends from Newton's towards
    the compliant directions, where the linearization at the iterate can be trusted.
    Without a radius (an estimate's first step) lambda is (sigma_max / CONDITION_LIMIT)^2:
    the poorly observable directions (the axial force) barely move until the others fit,
    since there the pose error is mostly the others' second-order effect (the end disk
    drops as it swings sideways) that a first-order model reads as axial load.
    """
    left, values, right = np.linalg.svd(block)
    weights = values * (left.T @ error)
    with np.errstate(divide='ignore', invalid='ignore'):
        newton = -right.T @ (weights / values ** 2)
    size = float(np.linalg.norm(newton))
    if radius is None:  # the first step: damp the directions the pose hardly observes
        damped = -right.T @ (weights / (values ** 2 + (values[0] / CONDITION_LIMIT) ** 2))
        return damped, size
    if size <= radius or not math.isfinite(size):
        return newton, size
    top = float(np.linalg.norm(weights)) / radius  # |step| <= |J^T e| / lambda
    grid = np.geomspace(max(1e-6 * values[-1] ** 2, 1e-12 * top), top, 200)
    sizes = np.linalg.norm(weights[None, :] / (values[None, :] ** 2 + grid[:, None]), axis=1)
    damping = grid[int(np.argmax(sizes <= radius))]
    return -right.T @ (weights / (values ** 2 + damping)), size


def estimate(found: Search, target: Target, started: float) -> WrenchEstimate:
    """Build the WrenchEstimate of a search (covariance, conditioning, verdicts, message)."""
    best = found.best
    if best is None:
        return WrenchEstimate(np.full(3, np.nan), np.full(3, np.nan), None, False, None,
                              False, math.nan, math.nan, [], found.message,
                              estimated=_estimated(target), iterations=found.iterations,
                              solves=found.solves,
                              estimate_time_s=time.perf_counter() - started)
    rows, free = list(target.rows), list(target.free)
    sensitivity = np.zeros((6, len(rows)))
    covariance = None
    try:
        sensitivity[free] = np.linalg.inv(best.compliance[np.ix_(rows, free)])
    except np.linalg.LinAlgError:
        sensitivity[free] = np.nan
    if target.covariance is not None:
        covariance = sensitivity @ target.covariance @ sensitivity.T
    condition, directions = observability(best.compliance, rows, free, target.length,
                                          target.labels, covariance, best.analysis)
    error = frame_twist(target.frame, best.frame)
    messages = [found.message]
    if best.stable is False:
        messages.append('past buckling: the matching equilibrium is unstable')
    elif best.stable is None:
        messages.append('stability unknown')
    elif best.margin < AMBIGUOUS_MARGIN:
        messages.append(f'near a bifurcation (stability margin {best.margin:.3g}): another '
                        'wrench may match this pose')
    if not best.accuracy_met:
        messages.append('the forward solve misses its accuracy target')
    if found.alternative is not None:
        messages.append('ambiguous: the moment ' + ', '.join(
            f'{value:.4g}' for value in found.alternative[3:]) + ' N m matches too')
    if directions:
        messages.append('poorly observable: ' + ', '.join(
            f"{direction['label']} ({direction['ratio']:.3g} x)" for direction in directions))
    accuracy_met = (found.converged and best.accuracy_met and best.stable is True
                    and not best.margin < AMBIGUOUS_MARGIN and found.alternative is None)
    rotation = quaternion_xyzw(best.frame[:3, :3])
    return WrenchEstimate(
        force=best.wrench[:3].copy(), moment=best.wrench[3:].copy(), covariance=covariance,
        converged=found.converged, stable=best.stable, accuracy_met=accuracy_met,
        residual_m=float(np.linalg.norm(error[:3])),
        residual_deg=(math.degrees(float(np.linalg.norm(error[3:]))) if len(rows) == 6
                      else math.nan),
        conditioning=directions, message='; '.join(messages), estimated=_estimated(target),
        condition_number=condition, ill_conditioned=bool(directions),
        stability_margin=best.margin, iterations=found.iterations, solves=found.solves,
        alternative=found.alternative,
        estimate_time_s=time.perf_counter() - started, position=best.frame[:3, 3].copy(),
        quaternion_xyzw=rotation, sensitivity=sensitivity, solution=best.solution)


def _estimated(target: Target) -> str:
    """Name what was estimated: 'wrench', 'force' or 'moment'."""
    return 'wrench' if len(target.free) == 6 else 'force' if target.free[0] == 0 else 'moment'


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
    # made at another wrench (docs/explanation), and near zero it decides the ambiguity
    compliance = result.compliance.matrix
    scale = np.repeat([1.0, solver.params.stack_height], 3)
    try:
        stiffness = np.linalg.inv(scale[:, None] * compliance * scale[None, :])
        margin = float(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0]
                       / solver._origin().smallest_stiffness)
    except np.linalg.LinAlgError:
        margin = -math.inf
    return Evaluation(wrench.copy(), result.frames['de'], compliance, result.stable, margin,
                      bool(result.accuracy_met), result.message, result.compliance, result)


def estimate_wrench(solver: 'TranslatorSolver', position: ArrayLike,
                    quaternion_xyzw: Optional[ArrayLike] = None, *,
                    pose_covariance: Optional[ArrayLike] = None,
                    moment: Optional[ArrayLike] = None,
                    force: Optional[ArrayLike] = None) -> WrenchEstimate:
    """Return the end-disk wrench matching a measured pose (TranslatorSolver's method)."""
    started = time.perf_counter()
    length = solver.params.stack_height
    target = replace(measured_target(position, quaternion_xyzw, pose_covariance, moment, force,
                                     length),
                     load_limit=LOAD_LIMIT * load_scale(solver._origin()))
    reach = float(np.linalg.norm(target.frame[:3, 3]))
    if reach > REACH * length:
        return estimate(Search(None, False, f'unreachable: the end disk cannot be {reach:.4g} m '
                               f'from the base (stack height {length:.4g} m)'),
                        target, started)
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

    A warm search that fails is repeated from no load after ``reset`` (the previous
    estimate may sit past buckling or far away), within ``deadline``; a converged one is
    the next warm start. A moment from a position is searched again from no moment and
    from the match moved either way along its least observable direction (by a tenth of
    the load scale w*): a position sees the moment only through the couplings of the
    compliance, and several moments put the end disk at the same point (each of five
    random moments within 0.5 N m tried had another match within 0.6 N m); a second match
    found is ``alternative``.
    """
    start = _STARTS.get(owner) if warm else None
    found = search(evaluate, start, target, deadline)
    if not found.converged and start is not None and time.perf_counter() < deadline:
        reset()
        restart = search(evaluate, None, target, deadline)
        restart.iterations += found.iterations
        restart.solves += found.solves
        restart.message += ' (after a restart from no load)'
        found = restart
    if found.converged and found.best is not None and _estimated(target) == 'moment':
        found.alternative = _other_match(evaluate, found, target, deadline)
    if found.converged and found.best is not None:
        _STARTS[owner] = found.best
    else:
        _STARTS.pop(owner, None)
    return estimate(found, target, started)
