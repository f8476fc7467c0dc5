"""
WrenchEstimate: a wrench estimated from a measured pose, and how well the pose observes it.

Observability. Near the solution a pose error e maps to a wrench error C_b^-1 e, C_b the
block of the compliance (cdr_translator/compliance.py) from the estimated wrench
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
import math
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .compliance import analyse, ComplianceAnalysis

__all__ = ['CONDITION_LIMIT', 'json_safe', 'observability', 'TRANSLATOR_WRENCH_LABELS',
           'WrenchEstimate']

#: A wrench direction is poorly observable, and the estimate ill-conditioned, when the
#: largest length-scaled singular value of the compliance block is more than this many
#: times its singular value.
CONDITION_LIMIT = 100.0

#: Names of the end-disk wrench components [f; m] in {pe}, the primary's axis along z.
TRANSLATOR_WRENCH_LABELS = ('lateral force x', 'lateral force y', 'axial force',
                            'bending moment x', 'bending moment y', 'torsion')


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
    The wrench [f; m] putting the model's pose at a measured one (SI, in the base frame).

    ``estimated`` names the components solved for: 'wrench' (all six, the orientation was
    measured), 'force' (position only, the moment given) or 'moment' (position only, the
    force given); the given ones are returned as given. ``covariance`` (6x6, N and N m) is
    the pose covariance Sigma propagated through the stiffness at the solution, G Sigma
    G^T with G = ``sensitivity`` (6 x 6, or 6 x 3 for a position) the derivative of the
    wrench by the measured pose components (the given components' rows zero); None
    without a pose covariance. ``converged``: the model's pose
    matches the measured one to the rounding of the forward solve; ``residual_m`` and
    ``residual_deg`` are what is left (position and orientation; the angle NaN when the
    orientation was not measured). ``stable`` is the forward solve's verdict at the
    estimate and ``stability_margin`` its margin (docs/explanation). ``accuracy_met``:
    converged, the forward solve's discretization error within its target, the equilibrium
    stable and not so close to a bifurcation that another wrench could match the pose, and
    no other match found (``alternative``: a moment from a position is searched from
    several starts, cdr_translator/estimation.py); ``message`` says which failed.
    ``conditioning`` lists the poorly observable wrench directions (module docstring),
    each a dict: 'label' (the wrench component it mostly
    is), 'direction' (unit in the scaled units, SI components), 'singular_value' (m/N,
    scaled), 'ratio' (largest singular value over it), 'twist' and 'role' (the
    primary-mobility analysis' label and role of the eigen-twist it moves the pose along),
    and 'standard_deviation' (of the scaled wrench along the direction, N, from
    ``covariance``; None without one). ``position`` and ``quaternion_xyzw`` are the
    solved equilibrium's pose.
    """

    force: np.ndarray
    moment: np.ndarray
    covariance: Optional[np.ndarray]
    converged: bool
    stable: Optional[bool]
    accuracy_met: bool
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
    #: the forward solve at the estimate (a SolveResult, or a DeltaResult for the robot)
    solution: Any = field(default=None, repr=False)

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
                'alternative')
        return {key: json_safe(getattr(self, key)) for key in keys}


def _scale(length: float) -> np.ndarray:
    """S = diag(1, 1, 1, H, H, H): twists times S are in m, wrenches over S in N."""
    return np.repeat([1.0, length], 3)


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
    scale = _scale(length)
    rows, free = list(rows), list(free)
    block = scale[rows, None] * compliance[np.ix_(rows, free)] * scale[None, free]
    _, values, right = np.linalg.svd(block)
    largest = float(values[0])
    condition = largest / float(values[-1]) if values[-1] > 0.0 else math.inf
    if analysis is None:
        analysis = analyse(compliance, length)
    twists = scale[:, None] * analysis.eigenvectors
    twists /= np.linalg.norm(twists, axis=0)
    directions = []
    for value, vector in zip(values.tolist(), right):
        ratio = largest / value if value > 0.0 else math.inf
        if not ratio > CONDITION_LIMIT:
            continue
        dominant = int(np.argmax(np.abs(vector)))
        unit = np.zeros(6)  # scaled, pointing along its dominant component
        unit[free] = vector * math.copysign(1.0, vector[dominant])
        direction = unit * scale  # back to N and N m
        match = int(np.argmax(np.abs(twists.T @ (scale * (compliance @ direction)))))
        along = unit / scale  # the scaled wrench's component along the direction
        spread = (None if covariance is None
                  else math.sqrt(max(float(along @ covariance @ along), 0.0)))
        directions.append({'label': labels[free[dominant]], 'direction': direction.tolist(),
                           'singular_value': value, 'ratio': ratio,
                           'twist': analysis.labels[match], 'role': analysis.roles[match],
                           'standard_deviation': spread})
    return condition, directions
