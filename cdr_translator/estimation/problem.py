"""
The estimation problem: what is measured, what is estimated, and what is known beforehand.

A Target holds a measured pose (and its covariance), the wrench components solved for
(the others held at given values) and a Gaussian prior on the wrench; Weights whitens
both, so that the estimate minimizes |W (y(w) - y_m)|^2 + |L (w_f - mu)|^2
(cdr_translator.estimation). Evaluation is the forward model at one wrench, Linearization
the whitened cost there and Derivative its derivative, Search where an iteration ended:
the types the search and the verdicts share.
"""

from collections import OrderedDict
import copy
from dataclasses import dataclass, field
from functools import cached_property
import math
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, TypeVar, Union

import numpy as np
from numpy.typing import ArrayLike

from .wrench_estimate import (block_index, COMPONENT_CHOICES, component_index, COMPONENT_NAMES,
                              Conditioning, conditioning, length_scale,
                              TRANSLATOR_WRENCH_LABELS)
from .._linalg import thin_svd
from ..analysis.compliance import ComplianceAnalysis, frame_twist
from ..checks import check_covariance, check_number, check_unit_quaternion, check_vector
from ..errors import InputError
from ..geometry import rotation_of_quaternion, rotation_of_vector

__all__ = ['Components', 'Curvature', 'DEFAULT_PRIOR_FORCE_SD', 'DEFAULT_PRIOR_MOMENT_SD',
           'DEFAULT_TARGET_FORCE_SD', 'DEFAULT_TARGET_MOMENT_SD', 'diagonal_prior',
           'Derivative', 'estimated_components', 'estimated_name', 'Evaluation',
           'EXACT_POSE_SD_M', 'linearized', 'Linearization', 'measured_target', 'Search',
           'Target', 'Weights']

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


@dataclass(frozen=True)
class Curvature:
    """
    How far an accepted step's pose fell from its linear prediction: the model's curvature.

    The miss is second order in the step, so a step of length l from the point it arrived
    at misses by about |W miss| (l / length)^2 (search.FINISH_MISS). Only along a direction
    like the measuring search's own: a search for another pose steps elsewhere, where the
    curvature may be larger (along a recorded walk, a new pose finished from the last
    estimate's curvature landed 0.106 standard deviations off, 7 times the extrapolation).
    So it serves the searches for the measured pose it was made for: its own, and the same
    pose again under another covariance (a second topic).
    """

    measured: np.ndarray  # the measured pose (4x4) of the search that made it
    rows: Tuple[int, ...]  # the measured twist components of ``miss``
    miss: np.ndarray  # the pose minus its linear prediction, those components (m, rad)
    length: float  # the step's length in scaled units (N)

    def scaled_miss(self, target: 'Target', length: float) -> Optional[float]:
        """
        Return the whitened miss expected of a step of ``length`` for ``target``.

        None when ``target`` measures another pose or other components.
        """
        if target.rows != self.rows or not np.array_equal(target.frame, self.measured):
            return None
        whitened = target.weights.pose @ self.miss
        return math.sqrt(float(whitened @ whitened)) * (length / self.length) ** 2


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
    #: the search's accepted step that arrived here was predicted within search.FINISH_GAIN:
    #: the linearization here is shown right over a step of about a standard deviation
    linear: bool = False
    #: what the search's accepted step that arrived here measured of the model's curvature
    #: (None: not measured)
    curvature: Optional['Curvature'] = None
    #: the whitened derivatives made at this compliance, each with the Weights it was made
    #: for (``derivative``); not an argument, so that a copy by dataclasses.replace (which
    #: may carry another compliance) starts without them; ``moved`` shares them
    derivatives: List[Tuple['Weights', 'Derivative']] = field(
        default_factory=list, init=False, repr=False, compare=False)
    #: the conditioning of the compliance blocks (``conditioning``), by rows, estimated
    #: components, length and labels; not an argument, as ``derivatives``
    conditionings: Dict[tuple, Conditioning] = field(
        default_factory=dict, init=False, repr=False, compare=False)

    def derivative(self, target: 'Target') -> 'Derivative':
        """
        Return the whitened derivative of ``target``'s cost at this compliance.

        Made once per whitening: along a stream an estimate's warm start is the last
        estimate's solve, whose derivative that estimate made already (the compliance is
        never changed in place).
        """
        weights = target.weights
        for made_for, derivative in self.derivatives:
            if made_for is weights:
                return derivative
        derivative = Derivative.made(target, self.compliance)
        self.derivatives.append((weights, derivative))
        del self.derivatives[:-DERIVATIVES_KEPT]
        return derivative

    def conditioning(self, target: 'Target') -> Conditioning:
        """
        Return how the compliance block of ``target`` observes the wrench, made once.

        It depends on the compliance alone, not on the pose covariance: along a stream the
        estimates of a pose on two topics (two covariances) share it.
        """
        key = (target.rows, target.free, target.length, target.labels)
        made = self.conditionings.get(key)
        if made is None:
            made = self.conditionings[key] = conditioning(
                self.compliance, target.rows, target.free, target.length, target.labels,
                self.analysis)
        return made

    def moved(self, change: np.ndarray) -> 'Evaluation':
        """
        Return this evaluation moved to the wrench ``change`` (6, SI) away, to first order.

        The pose moves by the compliance times the change (a twist: the origin's
        displacement and a spatial rotation increment, analysis.compliance.frame_twist's
        convention); the compliance, the stability verdict and the forward solve stay these,
        and so do the derivatives and conditionings made of the compliance (shared).
        """
        twist = self.compliance @ change
        frame = self.frame.copy()
        frame[:3, 3] += twist[:3]
        frame[:3, :3] = rotation_of_vector(twist[3:]) @ self.frame[:3, :3]
        moved = copy.copy(self)  # what is made of the compliance too: it is the same
        moved.wrench, moved.frame = self.wrench + change, frame
        return moved


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
    force_limit: float = math.inf  # largest |force| tried (N)
    moment_limit: float = math.inf  # largest |moment| tried (N m)

    def error(self, evaluation: Evaluation) -> np.ndarray:
        """Model pose minus measured pose, the measured components (m, rad)."""
        return frame_twist(self.frame, evaluation.frame)[self.row_index]

    @cached_property
    def weights(self) -> 'Weights':
        """Return the whitening of the pose and the prior (made once per Target)."""
        return Weights.of(self)

    # shared index arrays (wrench_estimate.component_index): a search and its verdicts
    # index with them often
    @property
    def row_index(self) -> np.ndarray:
        """Return ``rows`` as an index array (read-only)."""
        return component_index(self.rows)

    @property
    def free_index(self) -> np.ndarray:
        """Return ``free`` as an index array (read-only)."""
        return component_index(self.free)

    @property
    def held_index(self) -> np.ndarray:
        """Return the components not estimated as an index array (read-only)."""
        return component_index(tuple(index for index in range(6) if index not in self.free))

    @property
    def block(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return the index of the compliance block C[rows, free] (np.ix_, read-only)."""
        return block_index(self.rows, self.free)

    @property
    def scale(self) -> np.ndarray:
        """Return S = diag(1, 1, 1, H, H, H)'s diagonal: wrenches over it in N (read-only)."""
        return length_scale(self.length)


@dataclass(frozen=True)
class Weights:
    """The whitening of a Target: the pose's W and the estimated components' prior."""

    pose: np.ndarray  # W, (m, m): W^T W = Sigma^-1 (Sigma the pose covariance, or exact)
    prior: np.ndarray  # L, (k, k): L^T L = P^-1, P the prior of w_f given the held values
    mean: np.ndarray  # (k,) the prior mean of w_f given the held values
    #: L S_f: the prior term's derivative by the estimated components in scaled units (N)
    scaled_prior: np.ndarray

    @classmethod
    def of(cls, target: Target) -> 'Weights':
        """
        Whiten ``target``'s pose covariance and condition its prior on the held values.

        Along a stream the covariances and held values rarely change: the last few
        whitenings are kept (_WEIGHTS) and reused for equal inputs.
        """
        key = (target.rows, target.free, target.given[target.held_index].tobytes(), target.length,
               None if target.covariance is None else target.covariance.tobytes(),
               target.prior_mean.tobytes(), target.prior_covariance.tobytes())
        return _kept(_WEIGHTS, key, lambda: cls._made(target))

    @classmethod
    def _made(cls, target: Target) -> 'Weights':
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
        prior_root = _inverse_root(0.5 * (spread + spread.T))
        return cls(_inverse_root(covariance), prior_root, mean,
                   prior_root * target.scale[None, free])


Kept = TypeVar('Kept')

#: Whitenings kept for reuse (Weights.of), the most recent last.
WEIGHTS_KEPT = 16
_WEIGHTS: 'OrderedDict[tuple, Weights]' = OrderedDict()


def _inverse_root(covariance: np.ndarray) -> np.ndarray:
    """Return W with W^T W = covariance^-1: the inverse of its lower Cholesky factor."""
    factor = np.linalg.cholesky(covariance)
    return np.linalg.solve(factor, np.eye(len(factor)))


#: Whitened derivatives kept per compliance (Evaluation.derivatives): one per estimated
#: set of components and pose covariance in use.
DERIVATIVES_KEPT = 4


@dataclass(frozen=True, eq=False)  # by identity: the verdicts key what they make of it
class Derivative:
    """
    The whitened cost's derivative J = [W C_b S_f; L S_f] at one compliance, and its SVD.

    J is by the estimated components in scaled units (N: moments over H); its thin SVD
    J = U diag(values) V^T gives both the search's steps and the estimate's posterior.
    """

    jacobian: np.ndarray  # J, (m + k, k)
    left: np.ndarray  # U, (m + k, k)
    values: np.ndarray  # (k,), descending
    right: np.ndarray  # V^T, (k, k)

    @classmethod
    def made(cls, target: 'Target', compliance: np.ndarray) -> 'Derivative':
        """Return J of ``target``'s cost at ``compliance`` and its SVD."""
        weights = target.weights
        block = compliance[target.block] * target.scale[target.free_index]
        jacobian = np.concatenate((weights.pose @ block, weights.scaled_prior))
        left, values, right = thin_svd(jacobian)
        return cls(jacobian, left, values, right)


@dataclass(frozen=True)
class Linearization:
    """The whitened cost at one Evaluation: r = [W e; L (w_f - mu)] and its Derivative."""

    at: Evaluation  # the evaluation it was made at
    error: np.ndarray  # e: model pose minus measured pose, the measured components (m, rad)
    residual: np.ndarray  # r, (m + k,)
    derivative: Derivative

    @property
    def cost(self) -> float:
        """Return |r|^2."""
        return float(self.residual @ self.residual)


def linearized(target: Target, evaluation: Evaluation) -> Linearization:
    """Return the whitened cost of ``target`` at ``evaluation`` and its derivative."""
    weights = target.weights
    free = target.free_index
    error = target.error(evaluation)
    residual = np.concatenate((weights.pose @ error,
                               weights.prior @ (evaluation.wrench[free] - weights.mean)))
    return Linearization(evaluation, error, residual, evaluation.derivative(target))


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
    #: the last Gauss-Newton step (6, SI), taken from ``best`` without another forward
    #: solve (search's FINISH_CHI2); None when ``best`` is the estimate itself
    finish: Optional[np.ndarray] = None
    #: the cost at ``best`` (None: not made); the verdicts reuse its pose error and SVD
    linearization: Optional[Linearization] = None


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


#: The prior of an estimate that names none (made once: the default along a stream).
_DEFAULT_PRIOR = diagonal_prior()
_DEFAULT_PRIOR.setflags(write=False)


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
                    target_moment_sd: float = DEFAULT_TARGET_MOMENT_SD,
                    load_limit: float = math.inf, max_force: float = math.inf,
                    max_moment: float = math.inf) -> Target:
    """
    Check a measured pose, the components to estimate and the prior; return the Target.

    ``estimate`` (estimated_components) names the components solved for; the others are
    held at ``force`` and ``moment`` (default zero; their estimated components are
    ignored). ``covariance`` is 6x6 (position, then rotation about the base axes, as a ROS
    PoseWithCovariance) with the orientation; 3x3 or 6x6 (its position block used) without
    it. ``prior_mean`` (6, default zero) and ``prior_covariance`` (6x6, default
    diagonal_prior()) are the Gaussian prior on the wrench in the base frame.
    ``target_force_sd`` and ``target_moment_sd`` (N, N m) are the posterior standard
    deviations an estimate must reach to meet its accuracy target, ``load_limit`` the
    largest scaled wrench norm (N) a search tries, ``max_force`` and ``max_moment`` (N,
    N m) the largest force and moment magnitudes it tries. InputError (a ValueError)
    names a bad value.
    """
    frame = np.eye(4)
    frame[:3, 3] = check_vector(names[0], position)
    oriented = quaternion_xyzw is not None
    if quaternion_xyzw is not None:
        quaternion = check_unit_quaternion(names[1], quaternion_xyzw)
        frame[:3, :3] = rotation_of_quaternion(quaternion)
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
        checked = _checked_covariance(names[2], covariance, size)[:len(rows), :len(rows)]
    mean = np.zeros(6) if prior_mean is None else check_vector('prior_mean', prior_mean, 6)
    spread = _checked_prior(prior_covariance, free)
    targets = np.repeat([check_number('target_force_sd', target_force_sd, low=0.0,
                                      low_open=True, error=InputError),
                         check_number('target_moment_sd', target_moment_sd, low=0.0,
                                      low_open=True, error=InputError)], 3)
    limits = [value if value == math.inf  # no limit
              else check_number(name, value, low=0.0, error=InputError)
              for name, value in (('max_force', max_force), ('max_moment', max_moment))]
    return Target(frame, rows, free, given, checked, float(length), labels, mean, spread,
                  targets, load_limit, *limits)


#: Covariances already checked (the same along a stream), the most recent last.
_CHECKED: 'OrderedDict[tuple, np.ndarray]' = OrderedDict()


def _kept(cache: 'OrderedDict[tuple, Kept]', key: tuple, make: Callable[[], Kept]) -> Kept:
    """Return ``cache[key]``, made by ``make()`` the first time; the last WEIGHTS_KEPT stay."""
    if key in cache:
        cache.move_to_end(key)
        return cache[key]
    value = make()
    cache[key] = value
    while len(cache) > WEIGHTS_KEPT:
        cache.popitem(last=False)
    return value


def _remembered(key: tuple, check: Callable[[], np.ndarray]) -> np.ndarray:
    """Return ``check()``, kept under ``key`` for the next equal input, read-only."""
    def made() -> np.ndarray:
        checked = check()
        checked.setflags(write=False)  # shared by the targets made from equal inputs
        return checked
    return _kept(_CHECKED, key, made)


def _checked_covariance(name: str, values: ArrayLike, size: int) -> np.ndarray:
    """check_covariance, once per distinct matrix."""
    try:
        matrix = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        return check_covariance(name, values, size)  # it names what is wrong
    return _remembered((name, size, matrix.shape, matrix.tobytes()),
                       lambda: check_covariance(name, matrix, size))


def _checked_prior(prior_covariance: Optional[ArrayLike], free: Tuple[int, ...]
                   ) -> np.ndarray:
    """Return the checked prior covariance, positive definite over the ``free`` components."""
    spread = (_DEFAULT_PRIOR if prior_covariance is None
              else _checked_covariance('prior_covariance', prior_covariance, 6))

    def definite() -> np.ndarray:
        if np.linalg.eigvalsh(spread[np.ix_(free, free)])[0] <= 0.0:
            raise InputError('prior_covariance must be positive definite over the estimated '
                             f'components {[COMPONENT_NAMES[index] for index in free]}')
        return spread
    return _remembered(('prior', free, spread.tobytes()), definite)


def estimated_name(target: Target) -> str:
    """Name what ``target`` estimates: a COMPONENT_CHOICES name, or the components joined."""
    for name, indices in COMPONENT_CHOICES.items():
        if target.free == indices:
            return name
    return ','.join(COMPONENT_NAMES[index] for index in target.free)
