"""
A translator held at both end disks (displacement control): stability verdict, buckling load.

A leg of the Continuum Delta Robot is held at both ends: its base disk by the slider, its end
disk by the platform. The robot's condensed platform stiffness (robot/linearization.py) is
assembled from the legs' end-disk compliances, which is valid only if each leg's internal
equilibrium is stable with its end-disk pose held (Maddocks, "Stability of nonlinearly
elastic rods", Arch. Rational Mech. Anal. 85:311-354, 1984: load and displacement control
have different stability).

Mechanics. Load control: shooting unknowns x, residual r(x, w) = 0, Jacobian J = r_x, the
end-disk twist T = dT/dx, compliance C = -T J^-1 r_w (cdr_translator/analysis/compliance.py).
Displacement control (end-disk pose held, its wrench unknown) has the bordered Jacobian

    J_d = [[J, r_w], [T, 0]],   det J_d = det J det C,

singular where the held translator buckles. With the energy Hessian H of load control and
the constraint gradient B = T, the inertia of the bordered matrix gives (Haynsworth)
ind(H) + ind(-C) = ind(H | ker B) + 6, so ind_held = ind_load - (negative eigenvalues of C).
The sign of det J flips with the parity of ind_load (stability.py; Till & Rucker, IEEE T-RO
33(3):718-733, 2017), so sign(det J) sign(det C), against the unloaded translator's, flips
with the parity of ind_held: the conjugate-point (Jacobi) test of the held problem.

That parity misses a pair of modes crossing together, which the four-fold symmetry of the
backbones makes the rule along straight compression: the straight translator's held modes
in the x and y planes buckle at the same load. So the verdict also asks that the axial
compression stay below the held buckling load of the straight translator
(``held_critical_load``: the first load where J_d becomes singular along straight
compression). Both conditions are necessary; the second is exact for a straight leg and an
estimate for a bent one.
"""

from dataclasses import dataclass
import functools
import math
from typing import Optional, Tuple

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .._blas import one_blas_thread
from ..analysis.stability import determinant_sign, pose_twist
from ..bvp.problem import Problem
from ..params.translator_params import Accuracy, TranslatorParams
from ..solve.solver import TranslatorSolver

#: How the verdict is made (``HeldVerdict.method``).
HELD_METHOD = ('both end disks held: sign(det J) sign(det C) as unloaded, and axial '
               "compression below the straight translator's held buckling load")

#: Step of the march along straight compression, relative to the closed-form estimate: small
#: enough to separate the symmetric and antisymmetric held modes (1.3 % apart by default).
MARCH_STEP = 0.005

#: The march starts this fraction of the closed-form estimate (within 1 % of the numerical
#: load for the shipped translator) below it.
MARCH_START = 0.8


def euler_critical_load(params: TranslatorParams) -> float:
    """
    Closed-form Euler buckling load (N) of the straight translator under axial compression.

    The translating (S-shaped) mode: each joint is a column of bending stiffness 5 EI (the
    five backbones bend together) and length (S + 1) D; the tube is rigid; the base is
    clamped and the end disk keeps its orientation. By antisymmetry the tube's midpoint is
    an inflection point, so each half is a clamped column of length l carrying a rigid arm
    a = L_m / 2 to a moment-free tip: w = d (1 - cos k s), d = w(l) + a w'(l), which gives
    k l tan(k l) = l / a, and P = 5 EI k^2.
    """
    length = params.joint_length
    arm = 0.5 * params.tube_length
    root = brentq(lambda u: u * math.tan(u) - length / arm, 1e-12, 0.5 * math.pi - 1e-12)
    return 5.0 * params.bending_stiffness * (root / length) ** 2


def held_euler_load(params: TranslatorParams) -> float:
    """
    Closed-form buckling load (N) of the straight translator with both end disks held.

    As ``euler_critical_load``: each joint a column of bending
    stiffness 5 EI and length l = (S + 1) D, the tube rigid (length 2 a), the base clamped;
    the end disk now clamped too, free to move axially only. Two modes, the lower wins:

    * symmetric about the tube's middle: the tube translates without turning, each joint
      is a clamped-guided column, k l = pi;
    * antisymmetric: the tube turns about its middle, which stays on the axis and carries
      no moment: each half is a clamped column with a rigid arm a to a pin. With
      EI w'' + P w = R (l + a - s), w(0) = w'(0) = 0 and w(l) + a w'(l) = 0:
      tan(k l) = k l / (1 + a (l + a) k^2), first root above pi.

    P = 5 EI k^2.
    """
    length = params.joint_length
    arm = 0.5 * params.tube_length
    ratio = arm / length * (1.0 + arm / length)

    def pinned_arm(u: float) -> float:
        return math.sin(u) * (1.0 + ratio * u * u) - u * math.cos(u)

    antisymmetric = brentq(pinned_arm, math.pi, 1.5 * math.pi)
    return 5.0 * params.bending_stiffness * (min(math.pi, antisymmetric) / length) ** 2


def held_jacobian(problem: Problem, jacobian: np.ndarray, pose: np.ndarray,
                  rotation: np.ndarray) -> np.ndarray:
    """
    Nondimensional J_d = [[J, r_w], [T, 0]] from the shooting Jacobian and pose derivative.

    Unknowns: the nondimensional x and the end-disk wrench over the problem's wrench scale;
    rows: the nondimensional residual and the end-disk twist, displacement over the disk
    spacing (rotations in rad), so that its singular values compare.
    """
    size = problem.size
    held = np.zeros((size + 6, size + 6))
    held[:size, :size] = jacobian
    held[:size, size:] = problem.wrench_sensitivity * problem.wrench_scale
    twist = pose_twist(pose, rotation)
    twist[:3] /= problem.params.disk_spacing
    held[size:, :size] = twist
    return held


def end_pose_error(frame: np.ndarray, target: np.ndarray, spacing: float) -> np.ndarray:
    """Return [(centre - target centre) / spacing; rotation vector of R R_target^T]."""
    turn = frame[:3, :3] @ target[:3, :3].T
    skew = 0.5 * np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0],
                           turn[1, 0] - turn[0, 1]])
    sine = float(np.linalg.norm(skew))
    angle = math.atan2(sine, 0.5 * (np.trace(turn) - 1.0))
    scale = angle / sine if sine > 1e-12 else 1.0
    return np.concatenate([(frame[:3, 3] - target[:3, 3]) / spacing, scale * skew])


def held_solve(problem: Problem, xs: np.ndarray, wrench: np.ndarray, target: np.ndarray,
               tolerance: float = 1e-10, max_iterations: int = 40
               ) -> Tuple[np.ndarray, np.ndarray, bool]:
    """
    Newton's method on the held problem: end-disk frame ``target`` (4x4 in {pe}) imposed.

    Unknowns: the nondimensional ``xs`` and the end-disk wrench (SI), both started from the
    given values. Returns (xs, wrench, converged); converged when the largest residual,
    nondimensional shooting and pose error (``end_pose_error``), is within ``tolerance``.
    """
    xs = np.array(xs, dtype=float)
    wrench = np.array(wrench, dtype=float)
    spacing = problem.params.disk_spacing
    for _ in range(max_iterations):
        rs, jacobian, pose = problem.exact_jacobian(xs, wrench)
        frame = problem.residual_and_end_frame(xs, wrench)[1]
        residual = np.concatenate([rs, end_pose_error(frame, target, spacing)])
        if not np.all(np.isfinite(residual)):
            return xs, wrench, False
        if np.abs(residual).max() <= tolerance:
            return xs, wrench, True
        step = np.linalg.solve(held_jacobian(problem, jacobian, pose, frame[:3, :3]),
                               -residual)
        xs = xs + step[:problem.size]
        wrench = wrench + step[problem.size:] * problem.wrench_scale
    return xs, wrench, False


@dataclass(frozen=True)
class HeldCritical:
    """The held buckling load along straight compression and the singular values of J_d."""

    load_n: float
    smallest_singular_value: float  # of J_d there
    unloaded_singular_value: float
    estimate_n: float  # held_euler_load


def _compression_solver(params: TranslatorParams) -> TranslatorSolver:
    """Return a solver that follows the straight branch (no branch switching, no refinement)."""
    return TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False,
                            judge=False)


def smallest_held_singular_value(solver: TranslatorSolver, compression: float) -> float:
    """Smallest singular value of J_d at the straight state under ``compression`` (N)."""
    problem = solver.problem
    result = solver.solve((0.0, 0.0, -compression))
    if not result.converged:
        return math.inf
    wrench = np.array([0.0, 0.0, -compression, 0.0, 0.0, 0.0])
    xs = result.unknowns / problem.x_scale
    _, jacobian, pose = problem.exact_jacobian(xs, wrench)
    held = held_jacobian(problem, jacobian, pose, result.frames['de'][:3, :3])
    return float(np.linalg.svd(held, compute_uv=False)[-1])


@functools.lru_cache(maxsize=8)
@one_blas_thread
def held_critical_load(params: TranslatorParams) -> HeldCritical:
    """
    First load along straight compression where J_d is singular (the held buckling load).

    Marches up from MARCH_START of the closed-form estimate in steps of MARCH_STEP of it
    to the first local minimum of J_d's smallest singular value, then refines it (bounded
    Brent). ArithmeticError when no minimum near zero (below 1e-3 of the unloaded value)
    is found up to twice the estimate. Once per parameter set (cached: a few hundred ms).
    """
    estimate = held_euler_load(params)
    solver = _compression_solver(params)
    unloaded = smallest_held_singular_value(solver, 0.0)
    loads = [MARCH_START * estimate, (MARCH_START + MARCH_STEP) * estimate]
    values = [smallest_held_singular_value(solver, load) for load in loads]
    while loads[-1] < 2.0 * estimate:
        loads.append(loads[-1] + MARCH_STEP * estimate)
        values.append(smallest_held_singular_value(solver, loads[-1]))
        if values[-2] < values[-3] and values[-2] <= values[-1]:
            found = minimize_scalar(lambda load: smallest_held_singular_value(solver, load),
                                    bounds=(loads[-3], loads[-1]), method='bounded',
                                    options={'xatol': 1e-7 * estimate})
            if found.fun < 1e-3 * unloaded:
                return HeldCritical(float(found.x), float(found.fun), unloaded, estimate)
    raise ArithmeticError('no held buckling load found along straight compression up to '
                          f'{2.0 * estimate:.4g} N')


@dataclass(frozen=True)
class HeldReference:
    """What a held verdict compares with: the unloaded translator and its buckling load."""

    jacobian_sign: int  # sign det J of the unloaded translator
    compliance_sign: int  # sign det C of the unloaded translator (+1: C is definite)
    length: float  # stack height H: rotations as displacements at H for the stiffness
    critical_load_n: Optional[float]  # held_critical_load, None when not found


@dataclass(frozen=True)
class HeldVerdict:
    """
    One translator's stability with both end disks held (see the module docstring).

    ``stable`` None when no verdict could be made (``message`` says why); ``margin`` is
    1 - ``axial_load_n`` / ``critical_load_n`` (1 without axial load, 0 at the held buckling
    load); ``axial_load_n`` the compression (N, negative in tension); ``parity_ok`` whether
    sign(det J) sign(det C) is the unloaded one; ``negative_stiffness_directions`` the
    negative eigenvalues of the end-disk stiffness C^-1 (symmetric part), which the
    free-end instabilities the held translator does not feel account for.
    """

    stable: Optional[bool]
    margin: float
    axial_load_n: float
    critical_load_n: float
    parity_ok: Optional[bool]
    negative_stiffness_directions: Optional[int]
    message: str
    method: str = HELD_METHOD

    def to_dict(self) -> dict:
        """JSON-ready form: one entry of ``delta --json``'s ``leg_stability``."""
        return {'stable': self.stable, 'margin': _finite_or_none(self.margin),
                'axial_load_n': float(self.axial_load_n),
                'critical_load_n': _finite_or_none(self.critical_load_n),
                'parity_ok': self.parity_ok,
                'negative_stiffness_directions': self.negative_stiffness_directions,
                'method': self.method, 'message': self.message}


def _finite_or_none(value: float) -> Optional[float]:
    return float(value) if math.isfinite(value) else None


def _compliance_signs(compliance: np.ndarray, length: float) -> Tuple[int, int]:
    """Return (sign det C, negative eigenvalues of sym S^-1 K S^-1); ArithmeticError: singular."""
    if not np.all(np.isfinite(compliance)):
        raise ArithmeticError('the compliance is not finite')
    scale = np.repeat([1.0, length], 3)
    scaled = scale[:, None] * compliance * scale[None, :]
    sign = int(np.linalg.slogdet(scaled)[0])
    if sign == 0:
        raise ArithmeticError('the compliance is singular')
    stiffness = np.linalg.inv(scaled)
    values = np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))
    return sign, int(np.count_nonzero(values < 0.0))


def held_reference(lu: tuple, compliance: np.ndarray, length: float,
                   critical_load_n: Optional[float]) -> HeldReference:
    """Build the reference from the unloaded translator's factorization and compliance."""
    return HeldReference(determinant_sign(lu), _compliance_signs(compliance, length)[0],
                         length, critical_load_n)


def held_verdict(lu: tuple, compliance: np.ndarray, wrench: np.ndarray,
                 origin: HeldReference) -> HeldVerdict:
    """
    Verdict of the translator at the factorization ``lu``, compliance and end-disk wrench.

    ``lu`` and ``compliance``: its shooting Jacobian's LU and C there; ``wrench`` the
    end-disk wrench in {pe} (its z force is the tension).
    """
    compression = -float(wrench[2])
    critical = math.nan if origin.critical_load_n is None else origin.critical_load_n
    margin = 1.0 - compression / critical
    sign = determinant_sign(lu)
    try:
        if sign == 0:
            raise ArithmeticError('the shooting Jacobian is singular')
        compliance_sign, negative = _compliance_signs(compliance, origin.length)
    except (ArithmeticError, np.linalg.LinAlgError) as error:
        return HeldVerdict(None, margin, compression, critical, None, None,
                           f'no held verdict: {error}')
    parity_ok = sign * compliance_sign == origin.jacobian_sign * origin.compliance_sign
    if not parity_ok:
        return HeldVerdict(False, margin, compression, critical, False, negative,
                           'unstable held: sign(det J) sign(det C) changed from the unloaded '
                           'state (an odd number of held modes buckled)')
    if math.isnan(critical):
        return HeldVerdict(None, margin, compression, critical, True, negative,
                           'no held verdict: the held buckling load is unknown')
    if margin <= 0.0:
        return HeldVerdict(False, margin, compression, critical, True, negative,
                           f'unstable held: compression {compression:.4g} N at or past the '
                           f'held buckling load {critical:.4g} N')
    return HeldVerdict(True, margin, compression, critical, True, negative,
                       f'stable held: {axial_load_text(compression)}, below the held '
                       f'buckling load {critical:.4g} N, parity as unloaded')


def axial_load_text(compression: float) -> str:
    """Return a leg's axial load (N, compression positive) in words: 'tension 233.6 N'."""
    if compression > 0.0:
        return f'compression {compression:.4g} N'
    if compression < 0.0:
        return f'tension {-compression:.4g} N'
    return 'no axial load'
