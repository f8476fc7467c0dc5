"""
WrenchEstimate: a wrench estimated from a measured pose, and how well the pose observes it.

Observability. Near the solution a pose error e maps to a wrench error C_b^-1 e, C_b the
block of the compliance (cdr_translator/analysis/compliance.py) from the estimated wrench
components to the measured pose components. Its singular values, in the length-scaled
units of the primary-mobility analysis (paper Section IV.B; forces in N, moments as the
force that makes them at the stack height H, rotations as the displacement they cause at
H, so every singular value is in m/N), say how far the pose moves per newton along each
wrench direction: a direction whose singular value is more than CONDITION_LIMIT times
below the largest is poorly observable (a pose error of a micrometre there means newtons).
The translator's axial force is always one: its axial stiffness is four orders above the
lateral one (docs/explanation/model.md, xi of translation z).
"""

from dataclasses import dataclass, field
from functools import lru_cache
import math
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .._linalg import thin_svd
from ..analysis.compliance import analyse, ComplianceAnalysis

__all__ = ['block_index', 'COMPONENT_CHOICES', 'component_index', 'COMPONENT_NAMES',
           'CONDITION_LIMIT', 'Conditioning', 'conditioning', 'json_safe', 'length_scale',
           'observability', 'TRANSLATOR_WRENCH_LABELS', 'WrenchEstimate']

#: A wrench direction is poorly observable, and the estimate ill-conditioned, when the
#: largest length-scaled singular value of the compliance block is more than this many
#: times its singular value.
CONDITION_LIMIT = 100.0

#: Names of the end-disk wrench components [f; m] in {pe}, the primary's axis along z.
TRANSLATOR_WRENCH_LABELS = ('lateral force x', 'lateral force y', 'axial force',
                            'bending moment x', 'bending moment y', 'torsion')

#: Short names of the six wrench components, as ``estimate=`` takes them.
COMPONENT_NAMES = ('fx', 'fy', 'fz', 'mx', 'my', 'mz')

#: Named sets of estimated components: all six; the force under a held moment (a point
#: contact at the tip: moment zero); the moment under a held force; the lateral force
#: under a held axial force and moment.
COMPONENT_CHOICES: Dict[str, Tuple[int, ...]] = {
    'wrench': (0, 1, 2, 3, 4, 5), 'force': (0, 1, 2), 'moment': (3, 4, 5), 'lateral': (0, 1)}


def json_safe(value: Any) -> Any:
    """JSON-safe form: arrays as nested lists, NaN and infinities as None."""
    if isinstance(value, np.ndarray):
        return [json_safe(item) for item in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [json_safe(item) for item in value]
    if isinstance(value, dict):
        return {key: json_safe(item) for key, item in value.items()}
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


@dataclass
class WrenchEstimate:
    """
    The wrench [f; m] best explaining a measured pose (SI, in the base frame).

    A maximum-a-posteriori estimate (cdr_translator/estimation): ``components`` names
    the components solved for (``estimated`` the same as 'wrench', 'force', 'moment',
    'lateral' or the names joined); the others are returned as held. ``covariance`` (6x6,
    N and N m; zero rows for held components) is the posterior's, (J^T J)^-1 with J the
    whitened derivative of the pose error and of the prior term: a direction the pose does
    not see comes back at the prior with the prior's spread. None without a pose
    covariance (the pose was taken as exact). ``standard_deviation`` (6,) is its diagonal's
    root (NaN without one) and ``target_sd`` (6,) the targets it is held to (NaN for held
    components). ``sensitivity`` (6 x 6, or 6 x 3 for a position) is the derivative of the
    estimate by the measured pose components.

    Verdicts. ``converged``: the cost's Gauss-Newton step fell below a tenth of a
    posterior standard deviation (with an exact pose: the pose matched to the forward
    solve's rounding). ``flags`` lists every reason not to act on the estimate: past
    buckling (``stable`` False), stability unknown, near a bifurcation where another
    wrench may match (``stability_margin``), the forward solve off its accuracy target,
    another match found (``alternative``: a moment from a position is searched from
    several starts), and with a pose covariance: a normalized pose residual that fails
    its chi-square test (``chi_square``, its tail probability ``chi_square_p``), a force
    or moment spread larger than both the load reported and the target (uninformative),
    and a posterior standard deviation above its target. ``accuracy_met`` is True only
    when a pose covariance was given and no flag was raised, False when the estimate did
    not converge or a flag was raised, and None (not assessed) for an exact pose that
    converged. ``message`` says all of it. ``residual_m`` and ``residual_deg`` are the
    pose error left (the angle NaN when the orientation was not measured).

    ``conditioning`` lists the poorly observable wrench directions (module docstring),
    each a dict: 'label' (the wrench component it mostly is), 'direction' (unit in the
    scaled units, SI components), 'singular_value' (m/N, scaled), 'ratio' (largest
    singular value over it), 'twist' and 'role' (the primary-mobility analysis' label and
    role of the eigen-twist it moves the pose along), and 'standard_deviation' (of the
    scaled wrench along the direction, N, from ``covariance``; None without one).
    ``position`` and ``quaternion_xyzw`` are the solved equilibrium's pose.
    """

    force: np.ndarray
    moment: np.ndarray
    covariance: Optional[np.ndarray]
    converged: bool
    stable: Optional[bool]
    accuracy_met: Optional[bool]
    residual_m: float
    residual_deg: float
    conditioning: List[Dict[str, Any]]
    message: str
    estimated: str = 'wrench'
    condition_number: float = math.nan
    ill_conditioned: bool = False
    stability_margin: float = math.nan
    iterations: int = 0
    solves: int = 0
    estimate_time_s: float = 0.0
    position: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    quaternion_xyzw: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    sensitivity: Optional[np.ndarray] = field(default=None, repr=False)
    #: another wrench that matches the pose as well (then ``accuracy_met`` is False)
    alternative: Optional[np.ndarray] = None
    components: Tuple[str, ...] = ('fx', 'fy', 'fz', 'mx', 'my', 'mz')
    standard_deviation: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))
    target_sd: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))
    chi_square: float = math.nan
    chi_square_p: float = math.nan
    flags: List[str] = field(default_factory=list)
    #: the forward solve at the estimate (a SolveResult, or a DeltaResult for the robot)
    solution: Any = field(default=None, repr=False)

    @property
    def flagged(self) -> bool:
        """Return True when the estimate is not to be acted on (``flags`` not empty)."""
        return bool(self.flags)

    @property
    def wrench(self) -> np.ndarray:
        """Return [force; moment] (6,)."""
        return np.concatenate([self.force, self.moment])

    def to_dict(self) -> Dict[str, Any]:
        """JSON-ready form (NaN as None); every field but ``solution``."""
        keys = ('force', 'moment', 'covariance', 'converged', 'stable', 'accuracy_met',
                'residual_m', 'residual_deg', 'conditioning', 'message', 'estimated',
                'condition_number', 'ill_conditioned', 'stability_margin', 'iterations',
                'solves', 'estimate_time_s', 'position', 'quaternion_xyzw', 'sensitivity',
                'alternative', 'components', 'standard_deviation', 'target_sd', 'chi_square',
                'chi_square_p', 'flags')
        return {key: json_safe(getattr(self, key)) for key in keys}


# The small arrays below are made once per distinct argument and shared read-only: every
# estimate along a stream uses the same ones, and making one costs as much as the small
# product it serves.

@lru_cache(maxsize=16)
def length_scale(length: float) -> np.ndarray:
    """S = diag(1, 1, 1, H, H, H) (read-only): twists times S are in m, wrenches over S in N."""
    return _read_only(np.repeat([1.0, length], 3))


@lru_cache(maxsize=64)
def component_index(components: Tuple[int, ...]) -> np.ndarray:
    """Return the tuple of component indices as an index array (read-only)."""
    return _read_only(np.array(components, dtype=np.intp))


@lru_cache(maxsize=64)
def block_index(rows: Tuple[int, ...], free: Tuple[int, ...]) -> Tuple[np.ndarray, np.ndarray]:
    """Return np.ix_(rows, free) (read-only): the index of the compliance block C[rows, free]."""
    index = np.ix_(rows, free)
    return _read_only(index[0]), _read_only(index[1])


def _read_only(array: np.ndarray) -> np.ndarray:
    """Return ``array`` made read-only (cached and shared)."""
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class Conditioning:
    """
    How a compliance block C[rows, free] observes the wrench (observability without spreads).

    ``directions`` are observability()'s dicts without 'standard_deviation', ``along``
    the scaled wrench's component along each (a 6-vector, N^-1 in scaled units): they
    depend on the compliance alone, so that the estimates at one solve share them
    whatever their pose covariance (``directions_with`` adds the spreads).
    """

    condition: float
    directions: Tuple[Dict[str, Any], ...]
    along: Tuple[np.ndarray, ...]

    def directions_with(self, covariance: Optional[np.ndarray]) -> List[Dict[str, Any]]:
        """Return the directions with their standard deviations from ``covariance`` (6x6)."""
        return [{**direction, 'direction': list(direction['direction']),
                 'standard_deviation': None if covariance is None
                 else math.sqrt(max(float(along @ covariance @ along), 0.0))}
                for direction, along in zip(self.directions, self.along)]


def conditioning(compliance: np.ndarray, rows: Sequence[int], free: Sequence[int],
                 length: float, labels: Sequence[str],
                 analysis: Optional[ComplianceAnalysis] = None) -> Conditioning:
    """Return the Conditioning of the block C[rows, free] (observability's arguments)."""
    scale = length_scale(length)
    rows, free = tuple(rows), tuple(free)
    index = block_index(rows, free)
    block = scale[index[0]] * compliance[index] * scale[index[1]]
    _, values, right = thin_svd(block)
    singular = values.tolist()
    largest = singular[0]
    condition = largest / singular[-1] if singular[-1] > 0.0 else math.inf
    if not condition > CONDITION_LIMIT:
        return Conditioning(condition, (), ())  # every direction observed: no eigen-twists
    if analysis is None:
        analysis = analyse(compliance, length)
    twists = scale[:, None] * analysis.eigenvectors
    twists /= np.sqrt(np.add.reduce(twists * twists, axis=0))  # np.linalg.norm(axis=0)'s sum
    directions, alongs = [], []
    for value, vector in zip(singular, right):
        ratio = largest / value if value > 0.0 else math.inf
        if not ratio > CONDITION_LIMIT:
            continue
        sizes = np.abs(vector).tolist()
        dominant = sizes.index(max(sizes))  # the first largest, as np.argmax
        unit = np.zeros(6)  # scaled, pointing along its dominant component
        unit[component_index(free)] = vector * math.copysign(1.0, vector[dominant])
        direction = unit * scale  # back to N and N m
        match = int(np.argmax(np.abs(twists.T @ (scale * (compliance @ direction)))))
        alongs.append(unit / scale)  # the scaled wrench's component along the direction
        directions.append({'label': labels[free[dominant]], 'direction': direction.tolist(),
                           'singular_value': value, 'ratio': ratio,
                           'twist': analysis.labels[match], 'role': analysis.roles[match]})
    return Conditioning(condition, tuple(directions), tuple(alongs))


def observability(compliance: np.ndarray, rows: Sequence[int], free: Sequence[int],
                  length: float, labels: Sequence[str],
                  covariance: Optional[np.ndarray] = None,
                  analysis: Optional[ComplianceAnalysis] = None
                  ) -> Tuple[float, List[Dict[str, Any]]]:
    """
    Return (condition number, poorly observable directions) of the block C[rows, free].

    See the module docstring; ``labels`` name the six wrench components, ``covariance``
    (6x6) gives each direction's standard deviation, ``analysis`` (of the whole C; made
    here when not given) each direction's eigen-twist label and role.
    """
    made = conditioning(compliance, rows, free, length, labels, analysis)
    return made.condition, made.directions_with(covariance)
