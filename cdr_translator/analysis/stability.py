"""
Stability verdict of a converged translator solve, from the factorization the solve has.

Criterion (docs/explanation). The translator under a dead end-disk wrench is a conservative
elastic structure: an equilibrium is stable when the second variation of its potential
energy is positive definite (Lyapunov / Lagrange-Dirichlet; for rods Maddocks, "Stability
and folds", Arch. Rational Mech. Anal. 99:301-328, 1987). Two necessary conditions that the
solve's own LU factorization of the shooting Jacobian J = dr/dx gives almost for free:

1. **End-disk stiffness.** Eliminating every internal unknown, the Hessian restricted to
   the end-disk twist is the end-disk stiffness K = C^-1, with C = dT/dx J^-1 dr/dw the
   implicit compliance (Rucker & Webster, ICRA 2011). A stable equilibrium has a positive
   definite symmetric part of K (the Schur complement of a positive definite Hessian is
   positive definite). The *margin* is mu = lambda_min(sym K~) / lambda_min(sym K~0), where
   K~ = S^-1 K S^-1, S = diag(1, 1, 1, H, H, H), measures rotations by the displacement
   they cause at the stack height H (so all entries are N/m) and K~0 is the unloaded one:
   unit-free, 1 for the unloaded translator, 0 at a bifurcation or fold of the end-disk
   response, negative past it.
2. **Parity.** det J vanishes exactly where the energy Hessian is singular (a null vector of
   one gives one of the other: the shooting residual is the Euler-Lagrange system), so along
   any load path from the unloaded (stable) state sign(det J) flips each time an odd number
   of Hessian eigenvalues cross zero (Till & Rucker, "Elastic stability of Cosserat rods
   and parallel continuum robots", IEEE T-RO 33(3):718-733, 2017, use the same link
   between the shooting Jacobian and conjugate points). sign(det J) != sign(det J0) flags an
   internal instability that the end disk may not feel (e.g. a secondary buckling alone).

stable = (mu > 0) and (sign det J == sign det J0). Both conditions are necessary, not
sufficient: an even number of purely internal eigenvalue crossings that leave K positive
definite would go unseen. Cost: one 6-column LU solve and a 6x6 eigenproblem (tens of us).
"""

from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np
from scipy.linalg.lapack import dgesv, dsyevd

from .._jit import jit
from .._linalg import solve_lu

_IDENTITY = np.eye(6)

#: Below this stability margin another equilibrium branch is close: a verdict from a
#: factorization made elsewhere is recomputed on an exact Jacobian at the solution (near
#: zero a stale one could be on the wrong side), and a pose matched there is ambiguous.
CLOSE_BRANCH_MARGIN = 0.05


@dataclass(frozen=True)
class Stability:
    """Verdict, margin and the end-disk quantities it came from (SI)."""

    stable: bool
    margin: float
    parity_ok: bool
    compliance: np.ndarray
    critical_twist: np.ndarray
    message: str


def determinant_sign(lu: tuple) -> int:
    """
    Sign of det J from scipy's LU factorization (lu, piv): diagonal signs and swaps.

    0 when a diagonal entry is zero or not finite (J singular, or the factorization failed).
    """
    factors, pivots = lu
    return int(_determinant_sign(factors, pivots))


@jit
def _determinant_sign(factors, pivots):
    """``determinant_sign`` in one pass over the diagonal (numpy's took 19 us on 90 x 90)."""
    sign = 1
    for k in range(factors.shape[0]):
        diagonal = factors[k, k]
        if not math.isfinite(diagonal) or diagonal == 0.0:
            return 0
        if pivots[k] != k:
            sign = -sign
        if diagonal < 0.0:
            sign = -sign
    return sign


def pose_twist(pose_change: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """
    Map changes of the end-disk frame (12 rows) to end-disk twists [v; w] (6 rows).

    Rows of ``pose_change``: centre, then rotation matrix row-major; any number of columns.

    w is the spatial angular velocity, vee of the skew part of dR R^T (the convention of
    compliance.frame_twist).
    """
    change = np.asarray(pose_change, dtype=float)
    # contiguous float arrays only: one compiled signature, whatever slices come in
    columns = np.ascontiguousarray(change.reshape(12, -1))
    out = np.empty((6, columns.shape[1]))
    _pose_twist(columns, np.ascontiguousarray(rotation, dtype=float), 1.0, out)
    return out.reshape((6,) + change.shape[1:])


@jit
def _pose_twist(change, rotation, scale, out):
    """``scale`` times pose_twist of ``change`` (12, n) into ``out`` (6, n): a few us less."""
    for c in range(change.shape[1]):
        for i in range(3):
            out[i, c] = scale * change[i, c]
        # vee of the skew part of dR R^T is 1/2 sum_a R[:, a] x dR[:, a], dR[i, a] being
        # row 3 + 3 i + a
        w0 = w1 = w2 = 0.0
        for a in range(3):
            r0, r1, r2 = rotation[0, a], rotation[1, a], rotation[2, a]
            d0, d1, d2 = change[3 + a, c], change[6 + a, c], change[9 + a, c]
            w0 += r1 * d2 - r2 * d1
            w1 += r2 * d0 - r0 * d2
            w2 += r0 * d1 - r1 * d0
        out[3, c] = 0.5 * scale * w0
        out[4, c] = 0.5 * scale * w1
        out[5, c] = 0.5 * scale * w2


def compliance_from_factorization(lu: tuple, pose_jacobian: np.ndarray, rotation: np.ndarray,
                                  wrench_sensitivity: np.ndarray) -> np.ndarray:
    """C = -dT/dx J^-1 dr/dw: the end-disk compliance (SI) from one 6-column LU solve."""
    compliance = np.empty((6, 6))
    _pose_twist(np.ascontiguousarray(pose_jacobian @ solve_lu(lu, wrench_sensitivity)),
                np.ascontiguousarray(rotation, dtype=float), -1.0, compliance)
    return compliance


@dataclass(frozen=True)
class Reference:
    """The unloaded translator's smallest scaled stiffness and det J sign (the origin)."""

    length: float  # H of the scaling S
    smallest_stiffness: float  # lambda_min(sym K~0), N/m
    determinant_sign: int


def load_scale(origin: Reference) -> float:
    """
    Return w* = H lambda_min(sym K~0) (N): the load whose geometric stiffness matches K~0.

    The margin falls by about |dw| / w* per wrench change dw (``wrench_size``) at small loads:
    a dead load's geometric stiffness is proportional to it, over the stack height. For the
    shipped translator w* is 31.4 N and the margin falls at 1 / 29.4 N along pure axial
    compression (buckling at 29.3 N), the steepest of the directions measured (lateral
    force, moments about x and z fall 5-30 times slower).
    """
    return origin.length * origin.smallest_stiffness


def wrench_size(wrench: np.ndarray, length: float) -> float:
    """Return sqrt(|f|^2 + |m / H|^2) (N): moments as the force that makes them at H."""
    fx, fy, fz, mx, my, mz = wrench.tolist()  # floats: a tenth of numpy's time on 6 values
    return math.sqrt(fx * fx + fy * fy + fz * fz + (mx * mx + my * my + mz * mz) / length ** 2)


def _scaled_stiffness_eigen(compliance: np.ndarray, length: float
                            ) -> Tuple[np.ndarray, np.ndarray]:
    """
    Eigenvalues (ascending, N/m) and eigenvectors of sym(S^-1 K S^-1), K = C^-1.

    LAPACK called directly (dgesv, dsyevd): numpy.linalg's wrapping of inv and eigh cost
    twice the decompositions on a 6x6 (19 against 9 us). LinAlgError when S C S is singular
    or the eigen-decomposition fails.
    """
    scale = np.array((1.0, 1.0, 1.0, length, length, length))
    stiffness, info = dgesv(scale[:, None] * compliance * scale[None, :], _IDENTITY)[2:]
    if info != 0:
        raise np.linalg.LinAlgError('the compliance is singular')
    # the lower triangle, as numpy.linalg.eigh reads it: the same vectors, signs included
    values, vectors, info = dsyevd(0.5 * (stiffness + stiffness.T), lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f'dsyevd: no convergence ({info})')
    return values, vectors


def reference(lu: tuple, pose_jacobian: np.ndarray, rotation: np.ndarray,
              wrench_sensitivity: np.ndarray, length: float) -> Reference:
    """Build the Reference from the unloaded factorization; ``length`` the stack height."""
    compliance = compliance_from_factorization(lu, pose_jacobian, rotation, wrench_sensitivity)
    try:
        smallest = float(_scaled_stiffness_eigen(compliance, length)[0][0])
    except np.linalg.LinAlgError:
        smallest = -math.inf
    if not smallest > 0.0:
        raise ArithmeticError('the unloaded translator is not stable: check the parameters')
    return Reference(length, smallest, determinant_sign(lu))


def assess(lu: tuple, pose_jacobian: np.ndarray, rotation: np.ndarray,
           wrench_sensitivity: np.ndarray, origin: Reference) -> Stability:
    """Verdict and margin (see the module docstring) at the factorization ``lu``."""
    return assess_compliance(
        compliance_from_factorization(lu, pose_jacobian, rotation, wrench_sensitivity), lu,
        origin)


def assess_compliance(compliance: np.ndarray, lu: tuple, origin: Reference) -> Stability:
    """
    ``assess`` at the factorization ``lu`` given the compliance C made from it already.

    compliance.implicit_compliance makes C by ``compliance_from_factorization``, as
    ``assess`` does: the verdict at its factorization then costs the 6x6 eigenproblem.
    """
    sign = determinant_sign(lu)
    parity_ok = sign == origin.determinant_sign
    try:
        if sign == 0 or not np.all(np.isfinite(compliance)):
            raise np.linalg.LinAlgError
        values, vectors = _scaled_stiffness_eigen(compliance, origin.length)
    except np.linalg.LinAlgError:
        return Stability(False, -math.inf, parity_ok, compliance, np.zeros(6),
                         'unstable: the Jacobian at the solution is singular (at a '
                         'bifurcation or fold)')
    margin = float(values[0]) / origin.smallest_stiffness
    stable = margin > 0.0 and parity_ok
    if stable:
        message = ''
    elif margin <= 0.0:
        message = (f'unstable equilibrium: the end-disk stiffness has a negative direction '
                   f'(stability margin {margin:.3g})')
    else:
        message = ('unstable equilibrium: det of the shooting Jacobian changed sign from the '
                   'unloaded state (an internal mode buckled)')
    return Stability(stable, margin, parity_ok, compliance, vectors[:, 0], message)


def margin(compliance: np.ndarray, origin: Reference) -> float:
    """
    Return the stability margin mu of an end-disk compliance (module docstring).

    lambda_min(sym K~) / lambda_min(sym K~0), K = C^-1; -inf when C is singular.
    """
    try:
        values, _ = _scaled_stiffness_eigen(compliance, origin.length)
    except np.linalg.LinAlgError:
        return -math.inf
    return float(values[0]) / origin.smallest_stiffness


def critical_wrench(verdict: Stability, length: float) -> np.ndarray:
    """
    Unit-size wrench along the critical mode, for perturbing past a bifurcation.

    The critical eigenvector g of sym K~ (scaled twist: displacement, and rotation times H)
    is pushed on by the scaled wrench g itself, i.e. the wrench [g_v; H g_w] (N, N m),
    normalized so that |f| + |m| / H = 1.
    """
    twist = verdict.critical_twist
    wrench = np.concatenate([twist[:3], length * twist[3:]])
    return wrench / (np.linalg.norm(wrench[:3]) + np.linalg.norm(wrench[3:]) / length)


def optional_margin(stability: Optional[Stability]) -> float:
    """Margin, or NaN when no verdict was made."""
    return math.nan if stability is None else stability.margin
