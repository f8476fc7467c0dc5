"""DeltaResult: what one forward-statics solve of the Continuum Delta Robot gives."""

from dataclasses import dataclass
import math
from typing import Any, Callable, Iterable, List, Optional, overload, Sequence, Tuple, Union

import numpy as np

from .held_leg import HeldVerdict
from .kernels import small_rotation_vector
from .. import geometry
from ..solve.result import SolveResult

__all__ = ['DeltaResult', 'INPUT_NAMES', 'LegResults', 'rotation_vector']

#: Names of the 12 inputs whose sensitivities ``DeltaResult.input_sensitivity`` holds.
INPUT_NAMES = ('slider 1', 'slider 2', 'slider 3', 'force x', 'force y', 'force z',
               'moment x', 'moment y', 'moment z', 'offset x', 'offset y', 'offset z')


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """
    Rotation vector (axis times angle, rad) of a rotation matrix.

    Below 90 deg from the skew part and the trace (kernels.small_rotation_vector); beyond
    (where the skew part loses the axis near 180 deg) from geometry.quaternion_xyzw.
    A few us, where scipy's Rotation.from_matrix took 0.3 ms.
    """
    out = np.empty(3)
    if small_rotation_vector(np.asarray(rotation, dtype=float), out):
        return out
    x, y, z, w = geometry.quaternion_xyzw(rotation).tolist()
    sine = math.sqrt(x * x + y * y + z * z)
    factor = 2.0 * math.atan2(sine, w) / sine
    return np.array([factor * x, factor * y, factor * z])


class LegResults(Sequence[SolveResult]):
    """
    The legs' SolveResults, each built on first access and kept: a read-only sequence.

    A converged coupled CDR solve has each leg's unknowns already; building a leg's result
    from them (shape, stability verdict, error estimate: TranslatorSolver.result_at) costs
    more than the rest of a warm solve, so it is deferred until someone asks. Compares
    equal to the tuple of its results.
    """

    def __init__(self, builders: Iterable[Callable[[], SolveResult]],
                 bending: Optional[Callable[[], np.ndarray]] = None) -> None:
        """
        Keep one builder per leg (each called at most once, on first access).

        ``bending``, when given, returns the legs' PJ and DJ bending angles (n, 2) as their
        results would, without building them (one shot per leg, not the verdicts).
        """
        self._builders = tuple(builders)
        self._results: List[Optional[SolveResult]] = [None] * len(self._builders)
        self._bending = bending

    def bending(self) -> np.ndarray:
        """(n, 2): PJ and DJ bending angle of each leg (rad), building no result for it."""
        if self._bending is None or None not in self._results:
            return np.array([[leg.pj_bending[0], leg.dj_bending[0]] for leg in self])
        return self._bending()

    def __len__(self) -> int:
        """Return the number of legs."""
        return len(self._builders)

    @overload
    def __getitem__(self, index: int) -> SolveResult: ...

    @overload
    def __getitem__(self, index: slice) -> Tuple[SolveResult, ...]: ...

    def __getitem__(self, index: Union[int, slice]) -> Any:
        """Return leg ``index``'s result (built now if not yet), or a tuple for a slice."""
        if isinstance(index, slice):
            return tuple(self[k] for k in range(len(self))[index])
        result = self._results[index]
        if result is None:
            result = self._builders[index]()
            self._results[index] = result
        return result

    def __eq__(self, other: object) -> bool:
        """Equal to any sequence of the same results (a tuple, another LegResults)."""
        if not isinstance(other, Sequence):
            return NotImplemented
        return tuple(self) == tuple(other)

    __hash__ = None  # type: ignore[assignment]  # mutable cache: not hashable

    def __repr__(self) -> str:
        """Show the results built so far (the others as <deferred>)."""
        return 'LegResults(' + ', '.join('<deferred>' if result is None else repr(result)
                                         for result in self._results) + ')'


@dataclass
class DeltaResult:
    """
    Outcome of one forward-statics solve (SI, rad; platform pose in the world frame {w}).

    ``leg_tip_wrenches`` (3, 6): the wrench [f; m] the platform applies to each leg's end
    disk, in that leg's base frame {pe_i}, moment about the end-disk centre.
    ``equilibrium_residual`` (6,): payload plus leg reactions on the platform, force and
    moment about the platform origin in {w} (N, N m). ``compatibility_residual`` (3, 6):
    per leg, the solved end-disk pose minus the platform attachment pose in {pe_i}
    (position m, rotation vector rad). Failure to converge is a result (``converged``
    False, ``message`` says why) holding the best iterate found. ``leg_results``: each
    leg's SolveResult at that state (shape, bending, the leg's own stability verdict and
    error estimate), a LegResults: each built from the solved leg unknowns on first access
    (TranslatorSolver.result_at, 0.3-1 ms a leg, not in ``solve_time_s``). The work the
    solve took: ``leg_solves`` (full TranslatorSolver solves of a leg, not judged),
    ``leg_shots`` (residual shots of one leg in the coupled Newton) and ``leg_jacobians``
    (exact leg Jacobians, one tangent-linear shot each: the costly part; for reduced legs,
    the leg linearizations, H with dx/dw and the compliance, a coupled Newton made).

    With ``solve(..., compliance=True)`` (a converged solve) the linearization of the
    assembled closed chain at the solution is added, from the Newton Jacobian J exact at
    the solution (the legs enter through their 6x6 compliances, each from its leg's exact
    Jacobian there; one made by the iteration within 1e-9 of the solution in the scaled
    unknowns is reused, else three leg Jacobians are made for it):

    * ``platform_compliance`` (6, 6): C maps a small extra wrench [f; m] on the platform,
      force at the platform origin, components in {w}, to the small twist [v; w] of the
      platform: v the displacement of its origin, w its rotation (R <- exp([w]) R), in {w}.
      C = -(J^-1)[pose, equilibrium]. SI: C[:3, :3] m/N, C[:3, 3:] m/(N m), C[3:, :3] rad/N,
      C[3:, 3:] rad/(N m) (the translator's convention, cdr_translator/analysis/compliance.py,
      moved from the end disk in {pe} to the platform in {w}). Dead-load geometric stiffness of
      the payload and the leg reactions' moment arms are included.
    * ``input_sensitivity`` (6, 12): d[platform position; rotation] / d[inputs], inputs
      ``INPUT_NAMES`` (sliders m, force N, moment N m, offset m); the inverse statics
      Newton uses its slider columns.
    * ``stable``: the robot's stability verdict: the symmetric part of the platform
      stiffness K = C^-1, rotations expressed as displacements over the leg stack height H
      (K_s = S K S, S = diag(1, 1, 1, 1/H, 1/H, 1/H)), is positive definite (its smallest
      eigenvalue is ``stiffness_margin``, N/m) and every leg is stable with both ends held
      (``leg_stability``), which that condensation presumes. A singular J (no compliance)
      is unstable (``stable`` False, ``message`` says so); a leg whose verdict could not be
      made leaves it None (unknown) unless another part is unstable. None when not computed.
    * ``leg_stability``: per leg, its verdict with both end disks held
      (cdr_translator/robot/held_leg.py: parity of det J_d and the axial compression against the
      held buckling load of the straight leg, with a margin).

    ``leg_fidelity``: the level each leg was solved at ('full', 'rod', 'cc';
    robot/levels.py). ``leg_error_bound_m`` / ``leg_error_bound_deg``: a reduced leg's
    validated end-disk position and angle error at its tip wrench (fidelity/validation.py;
    NaN outside the validated box), NaN for a full leg, whose own error estimate is its
    SolveResult's.
    """

    converged: bool
    message: str
    iterations: int
    sliders: np.ndarray
    payload_force: np.ndarray
    payload_moment: np.ndarray
    payload_offset: np.ndarray
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    home_position: np.ndarray
    leg_results: Sequence[SolveResult]  # a tuple, or LegResults (built on first access)
    leg_tip_wrenches: np.ndarray
    equilibrium_residual: np.ndarray
    compatibility_residual: np.ndarray
    solve_time_s: float
    leg_solves: int
    platform_compliance: Optional[np.ndarray] = None
    input_sensitivity: Optional[np.ndarray] = None
    stable: Optional[bool] = None
    stiffness_margin: float = math.nan
    leg_shots: int = 0
    leg_jacobians: int = 0
    leg_stability: Optional[Tuple[HeldVerdict, ...]] = None
    leg_fidelity: Tuple[str, ...] = ('full', 'full', 'full')
    leg_error_bound_m: Tuple[float, ...] = (math.nan, math.nan, math.nan)
    leg_error_bound_deg: Tuple[float, ...] = (math.nan, math.nan, math.nan)

    @property
    def compliance_eigenvalues(self) -> Tuple[np.ndarray, np.ndarray]:
        """
        Eigenvalues of the symmetric parts of C's translational (m/N) and rotational blocks.

        Ascending; NaN when the compliance was not computed.
        """
        if self.platform_compliance is None:
            return np.full(3, np.nan), np.full(3, np.nan)
        matrix = self.platform_compliance
        translation, rotation = matrix[:3, :3], matrix[3:, 3:]
        return (np.linalg.eigvalsh(0.5 * (translation + translation.T)),
                np.linalg.eigvalsh(0.5 * (rotation + rotation.T)))

    @property
    def leg_axial_forces(self) -> np.ndarray:
        """(3,): tension of each leg at its end disk, the tip force along {pe_i} z (N)."""
        return self.leg_tip_wrenches[:, 2].copy()

    @property
    def platform_rotation_angle(self) -> float:
        """Total rotation angle of the platform from its home orientation (rad)."""
        return geometry.rotation_angle(self.platform_rotation)

    @property
    def platform_rotation_vector(self) -> np.ndarray:
        """Rotation vector of the platform from its home orientation, in {w} (rad)."""
        return rotation_vector(self.platform_rotation)

    @property
    def platform_quaternion_xyzw(self) -> np.ndarray:
        """Platform orientation in {w} as a unit quaternion (x, y, z, w), w >= 0."""
        return geometry.quaternion_xyzw(self.platform_rotation)

    @property
    def platform_displacement(self) -> np.ndarray:
        """Platform position relative to its home position, in {w} (m)."""
        return self.platform_position - self.home_position

    @property
    def leg_bending(self) -> np.ndarray:
        """(3, 2): PJ and DJ bending angle of each leg (rad)."""
        if isinstance(self.leg_results, LegResults):
            return self.leg_results.bending()
        return np.array([[leg.pj_bending[0], leg.dj_bending[0]] for leg in self.leg_results])

    @property
    def equilibrium_residual_norm(self) -> float:
        """Euclidean norm of the equilibrium residual (N and N m mixed, SI)."""
        return float(np.linalg.norm(self.equilibrium_residual))

    def to_dict(self) -> dict:
        """JSON-ready summary; degrees only here, at the edge."""
        return {
            'converged': bool(self.converged),
            'message': self.message,
            'iterations': int(self.iterations),
            'platform_position_m': self.platform_position.tolist(),
            'platform_displacement_m': self.platform_displacement.tolist(),
            'platform_rotation_deg': math.degrees(self.platform_rotation_angle),
            'platform_rotation_vector_deg': np.degrees(self.platform_rotation_vector).tolist(),
            'platform_quaternion_xyzw': self.platform_quaternion_xyzw.tolist(),
            'leg_bending_deg': np.degrees(self.leg_bending).tolist(),
            'leg_tip_wrench': self.leg_tip_wrenches.tolist(),
            'equilibrium_residual_norm': self.equilibrium_residual_norm,
            'equilibrium_residual': self.equilibrium_residual.tolist(),
            'compatibility_residual_max': {
                'position_m': float(np.abs(self.compatibility_residual[:, :3]).max()),
                'rotation_rad': float(np.abs(self.compatibility_residual[:, 3:]).max())},
            'sliders_m': self.sliders.tolist(),
            'payload_force_n': self.payload_force.tolist(),
            'payload_moment_nm': self.payload_moment.tolist(),
            'payload_offset_m': self.payload_offset.tolist(),
            'solve_time_s': float(self.solve_time_s),
            'leg_solves': int(self.leg_solves),
            'leg_shots': int(self.leg_shots),
            'leg_jacobians': int(self.leg_jacobians),
            'leg_fidelity': list(self.leg_fidelity),
            'leg_error_bound_position_m': _finite_or_none(self.leg_error_bound_m),
            'leg_error_bound_angle_deg': _finite_or_none(self.leg_error_bound_deg),
            **self._linearization_dict(),
        }

    def _linearization_dict(self) -> dict:
        """Return the compliance / stability keys (None when not computed)."""
        legs = (None if self.leg_stability is None
                else [verdict.to_dict() for verdict in self.leg_stability])
        if self.platform_compliance is None:
            return {'stable': self.stable, 'platform_compliance': None,
                    'platform_compliance_eigenvalues': None,
                    'stiffness_margin_n_per_m': None, 'leg_stability': legs}
        translation, rotation = self.compliance_eigenvalues
        return {
            'stable': None if self.stable is None else bool(self.stable),
            'leg_stability': legs,
            'platform_compliance': self.platform_compliance.tolist(),
            'platform_compliance_eigenvalues': {
                'translation_m_per_n': translation.tolist(),
                'rotation_rad_per_nm': rotation.tolist()},
            'stiffness_margin_n_per_m': float(self.stiffness_margin),
        }


def _finite_or_none(values: Sequence[float]) -> List[Optional[float]]:
    """JSON-ready list: NaN (no bound) as None."""
    return [float(value) if math.isfinite(value) else None for value in values]
