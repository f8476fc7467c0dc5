"""SolveResult: everything one solve produces, and the one place its JSON keys are defined."""

from dataclasses import dataclass, field
from functools import cached_property
import math
from typing import Any, Callable, Dict, Mapping, Optional, TYPE_CHECKING

import numpy as np

from .. import geometry
from ..analysis.compliance import ComplianceAnalysis


#: Frame names, in the order the kernel writes them: base, tube ends, end disk.
FRAME_NAMES = ('pe', 'pm', 'dm', 'de')

#: The paper's convergence tolerances (Section III.D), SI.
PAPER_TOLERANCES = {'position_m': 2e-4, 'orientation_rad': 1e-4, 'force_n': 1e-4,
                    'moment_nm': 1e-4}


@dataclass
class Verification:
    """
    Outcome of ``solve.verify.verify``: each check's worst value, its limit, a verdict.

    ``checks`` and ``limits`` share keys whose suffix names the unit (``_m``, ``_rad``,
    ``_n``, ``_nm``). ``passed`` is True when every check is within its limit.
    """

    passed: bool
    message: str
    checks: Dict[str, float] = field(default_factory=dict)
    limits: Dict[str, float] = field(default_factory=dict)

    def worst(self) -> str:
        """Name the check closest to (or furthest beyond) its limit ('' if none ran)."""
        return max(self.checks, key=lambda name: self.checks[name] / self.limits[name],
                   default='')

    def to_dict(self) -> dict:
        """JSON-ready form: the keys SolveResult.to_dict adds when a solve was verified."""
        return {'verified': bool(self.passed), 'verification_message': self.message,
                'verification_checks': {key: float(value)
                                        for key, value in self.checks.items()},
                'verification_limits': {key: float(value)
                                        for key, value in self.limits.items()}}


@dataclass
class SolveResult:
    """
    Outcome of one translator solve. SI units and radians; frames are 4x4 in {pe}.

    ``backbones`` holds the centre-line points of the five rods, shape (5, rows, 3), rod 0
    the primary; the first half of the rows of each rod belong to the PJ, the second half
    to the DJ (the straight run inside the tube joins them). Failure to converge is a result
    (``converged`` False, ``message`` says why) holding the best iterate found. A result made
    by ``deferred`` builds some fields (the shape, the residual dictionary) on first read.
    """

    converged: bool
    message: str
    iterations: int
    residual_norm: float
    residual_by_type: Dict[str, float]
    force: np.ndarray
    moment: np.ndarray
    frames: Dict[str, np.ndarray]
    backbones: np.ndarray
    solve_time_s: float
    method: str
    unknowns: np.ndarray = field(repr=False)
    #: end-disk compliance and its analysis, when the solve was asked for it
    compliance: Optional[ComplianceAnalysis] = field(default=None, repr=False)
    #: independent re-check (cdr_translator.solve.verify), when the solve was asked for it
    verification: Optional[Verification] = field(default=None, repr=False)
    #: the model that produced the result: 'full', or a reduced level of
    #: cdr_translator.fidelity ('cc', 'rod', 'linear')
    fidelity: str = 'full'
    #: stability verdict of the equilibrium (cdr_translator.analysis.stability; docs/explanation):
    #: None when not assessed (not converged, or the paper's method; the message says why).
    #: A reduced level ('rod', 'cc', 'linear') has no stability analysis of its own: its
    #: answer carries the verdict of a full solution near it (cdr_translator.fidelity's
    #: borrowed verdict: the unloaded state, the linear expansion's solution or the last
    #: full answer), kept by the rule the full model keeps a verdict made at another wrench
    #: by, and its message names that solution; None, with the message saying so, when no
    #: full solution lies near enough
    stable: Optional[bool] = None
    #: smallest generalized eigenvalue of the end-disk stiffness against the unloaded one:
    #: 1 unloaded, 0 at a bifurcation, negative past it (NaN when not assessed); for a
    #: reduced level, the margin of the full solution whose verdict it carries
    stability_margin: float = math.nan
    #: estimated error of the end-disk pose (and of what ``verify`` checks), m and deg: the
    #: full model's discretization error (cdr_translator.analysis.accuracy); for a reduced level
    #: under an error budget, the level's validated or checked error there
    #: (cdr_translator.fidelity); NaN when not estimated
    error_estimate_m: float = math.nan
    error_estimate_deg: float = math.nan
    #: whether the estimate is within its target: the solver's accuracy target (full), the
    #: error budget (a reduced level under 'auto'); None when nothing was estimated
    accuracy_met: Optional[bool] = None
    #: RK4 steps per disk interval of this result (more than the parameters' after an
    #: automatic refinement; 0 when not recorded)
    steps_per_segment: int = 0

    @classmethod
    def deferred(cls, makers: Mapping[str, Callable[[], Any]], **fields: Any) -> 'SolveResult':
        """
        Return a result whose fields named in ``makers`` are made on first read.

        Each maker returns its field's value (it must not depend on anything that changes
        after the solve); ``fields`` are the others. A solve along a sequence whose caller
        reads only the end-disk pose then skips the backbone points and the dictionaries.
        """
        placeholders: Dict[str, Any] = dict.fromkeys(makers)
        result = cls(**placeholders, **fields)
        for name in makers:
            del result.__dict__[name]
        result.__dict__['_makers'] = dict(makers)
        return result

    if not TYPE_CHECKING:  # mypy keeps checking attribute names: this serves deferred fields
        def __getattr__(self, name: str) -> Any:
            """Make a deferred field on its first read (``deferred``)."""
            makers = self.__dict__.get('_makers')
            if makers is None or name not in makers:
                raise AttributeError(f'{type(self).__name__!r} object has no attribute {name!r}')
            value = makers.pop(name)()
            self.__dict__[name] = value
            return value

    def __getstate__(self) -> dict:
        """Pickle and copy every field made: the makers stay with the solver's process."""
        for name in list(self.__dict__.get('_makers', ())):
            getattr(self, name)
        state = dict(self.__dict__)
        state.pop('_makers', None)
        return state

    @property
    def verified(self) -> Optional[bool]:
        """Whether the independent re-check passed; None when it was not asked for."""
        return None if self.verification is None else self.verification.passed

    @property
    def end_disk_position(self) -> np.ndarray:
        """Position of the DJ end-disk centre in {pe} (m)."""
        return self.frames['de'][:3, 3].copy()

    @property
    def end_disk_quaternion_xyzw(self) -> np.ndarray:
        """Orientation of the DJ end disk in {pe} as a unit quaternion (x, y, z, w)."""
        return geometry.quaternion_xyzw(self.frames['de'][:3, :3])

    @cached_property
    def pj_bending(self) -> tuple:
        """(bending angle, bending-plane direction) of the PJ: {pm} relative to {pe} (rad)."""
        return geometry.bending_between(self.frames['pe'], self.frames['pm'])

    @cached_property
    def dj_bending(self) -> tuple:
        """(bending angle, bending-plane direction) of the DJ: {de} relative to {dm} (rad)."""
        return geometry.bending_between(self.frames['dm'], self.frames['de'])

    @property
    def end_disk_rotation(self) -> float:
        """Total rotation angle of the end disk {de} relative to the base {pe} (rad)."""
        return geometry.rotation_angle(self.frames['de'][:3, :3])

    @cached_property
    def max_arc_deviation(self) -> Dict[str, float]:
        """
        Largest distance of any backbone of each joint from its fitted circle (m).

        Computed on first use only: the circle fits cost more than a warm solve.
        """
        half = self.backbones.shape[1] // 2
        return {joint: max(geometry.circle_deviation(rod[rows]) for rod in self.backbones)
                for joint, rows in (('pj', slice(0, half)), ('dj', slice(half, None)))}

    def to_dict(self) -> dict:
        """JSON-ready summary; degrees and millimetres only here, at the edge."""
        pj_theta, pj_delta = self.pj_bending
        dj_theta, dj_delta = self.dj_bending
        return {
            'converged': bool(self.converged),
            'message': self.message,
            'iterations': int(self.iterations),
            'residual_norm': float(self.residual_norm),
            'residual_by_type': {key: float(value)
                                 for key, value in self.residual_by_type.items()},
            'pj_bending_deg': math.degrees(pj_theta),
            'pj_direction_deg': math.degrees(pj_delta),
            'dj_bending_deg': math.degrees(dj_theta),
            'dj_direction_deg': math.degrees(dj_delta),
            'end_disk_rotation_deg': math.degrees(self.end_disk_rotation),
            'end_disk_position_m': self.end_disk_position.tolist(),
            'end_disk_quaternion_xyzw': self.end_disk_quaternion_xyzw.tolist(),
            'max_arc_deviation_mm': {joint: 1e3 * value
                                     for joint, value in self.max_arc_deviation.items()},
            'solve_time_s': float(self.solve_time_s),
            'force_n': self.force.tolist(),
            'moment_nm': self.moment.tolist(),
            'method': self.method,
            'fidelity': self.fidelity,
            **(self.compliance.to_dict() if self.compliance is not None else {}),
            **(self.verification.to_dict() if self.verification is not None else {}),
            'error_estimate_m': _finite_or_none(self.error_estimate_m),
            'error_estimate_deg': _finite_or_none(self.error_estimate_deg),
            # null when not assessed: no estimate (a reduced fidelity level without a
            # budget, the paper's method, no convergence) is no evidence of the target met
            'accuracy_met': None if self.accuracy_met is None else bool(self.accuracy_met),
            'steps_per_segment': int(self.steps_per_segment),
            # the solve's own verdict (docs/explanation) wins over the compliance's; null
            # when neither was assessed
            'stable': (bool(self.stable) if self.stable is not None
                       else bool(self.compliance.stable) if self.compliance is not None
                       else None),
            'stability_margin': _finite_or_none(self.stability_margin),
        }


def _finite_or_none(value: float) -> Optional[float]:
    """JSON has no NaN or infinity: those become null."""
    return float(value) if math.isfinite(value) else None
