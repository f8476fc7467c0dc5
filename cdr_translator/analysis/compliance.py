"""
Compliance of the end disk and its primary-mobility (screw) analysis (paper Section IV.B).

Convention: C maps a small extra wrench [f; m] (components in the base frame {pe}, applied at
the end-disk centre) to the small twist [v; w] of the end disk: v the velocity of its centre,
w its angular velocity, both in {pe}. SI units: C[:3, :3] m/N, C[:3, 3:] m/(N m),
C[3:, :3] rad/N, C[3:, 3:] rad/(N m).

Two computations that agree to about 1e-8 relative (tests/analysis/test_compliance.py):

* ``implicit_compliance`` (the default): implicit differentiation of the shooting problem
  at the converged solution (Rucker & Webster, ICRA 2011). r(x, w) = 0 gives
  dx/dw = -J^-1 dr/dw; the twist is the derivative of the end-disk pose along each column.
  The exact Jacobian and the end-disk pose derivative come from one tangent-linear shot;
  C is then one 6-column solve with that factorization (no refinement sweeps).
* ``cdr_translator.studies.finite_difference.finite_difference_compliance``: central
  differences of loaded solves, the paper's way (its ref. [15]); the check.

A warm solve converges on a factorization made earlier (chord steps), at a nearby
solution: ``stored_compliance`` makes C from that one instead of a new Jacobian (one
6-column solve), and measures its own error with one probe shot along a fixed wrench
direction (``PROBE_DIRECTION``). Along the seeded random walks of the tests it is 0.3-2 %
off, for a fifth of the exact one's cost; a solve takes it when the error it states is
within the caller's ``compliance_tolerance`` (default 0: always the exact one).
"""

from dataclasses import dataclass
from functools import cached_property
import math
import time
from typing import Any, Dict, Mapping, NamedTuple, Optional, Tuple

import numpy as np
from scipy.linalg.lapack import dgeev, dgesv, dsyevd

from . import stability
from .. import _linalg
from .._jit import jit
from ..bvp.problem import Problem
from ..checks import check_number

#: Human-readable names of the six twist/wrench axes, in the order of C's rows.
AXIS_LABELS = ('translation x', 'translation y', 'translation z',
               'rotation x', 'rotation y', 'rotation z')

#: Default relative threshold below which a coupling term is zeroed in C_s (see ``analyse``).
SPARSITY_THRESHOLD = 0.2

#: Default ratio to the most compliant direction above which an eigen-twist is a mobility.
MOBILITY_RATIO = 0.2

#: Largest perturbation of the nondimensional unknowns in a directional difference
#: (fidelity/linear.py: the tube frames' and points' sensitivities).
DIRECTIONAL_STEP = 1e-5


class _Mobility(NamedTuple):
    """The primary-mobility analysis of a compliance (``analyse``'s, made when first read)."""

    sparse_matrix: np.ndarray
    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    labels: Tuple[str, ...]
    roles: Tuple[str, ...]


@dataclass(frozen=True)
class ComplianceAnalysis:
    """
    The 6x6 compliance C at one loaded configuration and its eigen/screw analysis.

    ``sparse_matrix`` is the paper's C_s; ``eigenvalues`` (xi) and ``eigenvectors`` (Gamma,
    one column per eigenvalue) are those of C_s, ordered by ``labels`` (the axis each
    eigenvector mostly moves along). ``roles`` marks each column 'mobility' (a primary-mobility
    twist) or 'constraint' (it spans the constraint-wrench space); ``primary_mobility``
    lists the labels of the mobilities. ``stable`` says whether the symmetric part of the
    stiffness C^-1 is positive definite. ``time_s`` is the cost of computing C and
    ``estimated_error`` machine epsilon times a condition estimate of J (C is exact to
    rounding: no differencing is involved).

    The analysis (C_s and its eigen-decomposition; the stiffness' smallest eigenvalue) is
    made when one of its attributes is first read, then kept: a compliance that only feeds a
    computation, as in the forward solves an estimate steps through, costs no
    decomposition (``analyse`` checks its settings at once).
    """

    matrix: np.ndarray
    sparsity_threshold: float
    mobility_ratio: float
    characteristic_length: float
    method: str
    time_s: float
    estimated_error: float = 0.0

    @cached_property
    def _mobility(self) -> _Mobility:
        """Make C_s, its eigen-decomposition and the twists' labels and roles."""
        sparse = np.empty((6, 6))
        _sparsify(np.ascontiguousarray(self.matrix, dtype=float),
                  float(self.sparsity_threshold), sparse)
        values, vectors = _real_eigen(sparse)
        dominant = np.empty(6, dtype=np.int64)
        mobile = np.empty(6, dtype=np.bool_)
        values, vectors = _arrange(values, np.asfortranarray(vectors),
                                   float(self.characteristic_length),
                                   float(self.mobility_ratio), dominant, mobile)
        return _Mobility(sparse, values, vectors,
                         tuple(AXIS_LABELS[axis] for axis in dominant.tolist()),
                         tuple('mobility' if flag else 'constraint'
                               for flag in mobile.tolist()))

    @property
    def sparse_matrix(self) -> np.ndarray:
        """Return C_s: C with its coupling terms below the sparsity threshold zeroed."""
        return self._mobility.sparse_matrix

    @property
    def eigenvalues(self) -> np.ndarray:
        """Return the eigenvalues xi of C_s, in the order of ``labels``."""
        return self._mobility.eigenvalues

    @property
    def eigenvectors(self) -> np.ndarray:
        """Return the eigenvectors Gamma of C_s, one column per eigenvalue."""
        return self._mobility.eigenvectors

    @property
    def labels(self) -> Tuple[str, ...]:
        """Return the axis each eigenvector mostly moves along (AXIS_LABELS)."""
        return self._mobility.labels

    @property
    def roles(self) -> Tuple[str, ...]:
        """Return 'mobility' or 'constraint' for each eigenvector."""
        return self._mobility.roles

    @property
    def primary_mobility(self) -> Tuple[str, ...]:
        """Return the labels of the primary-mobility twists."""
        return tuple(label for label, role in zip(self.labels, self.roles)
                     if role == 'mobility')

    @cached_property
    def smallest_stiffness_eigenvalue(self) -> float:
        """Return the smallest eigenvalue of the symmetric part of K = C^-1 (-inf: singular)."""
        return _smallest_stiffness_eigenvalue(self.matrix)

    @property
    def stable(self) -> bool:
        """Return whether the symmetric part of the stiffness C^-1 is positive definite."""
        return self.smallest_stiffness_eigenvalue > 0.0

    def to_dict(self) -> dict:
        """JSON-ready form; the keys of ``solve --compliance --json``."""
        return {
            'compliance': self.matrix.tolist(),
            'compliance_sparse': self.sparse_matrix.tolist(),
            'compliance_eigenvalues': self.eigenvalues.tolist(),
            'compliance_eigenvectors': self.eigenvectors.tolist(),
            'compliance_labels': list(self.labels),
            'compliance_roles': list(self.roles),
            'primary_mobility': list(self.primary_mobility),
            'stable': bool(self.stable),
            'compliance_method': self.method,
            'compliance_time_s': float(self.time_s),
            'compliance_estimated_error': float(self.estimated_error),
        }


# implicit differentiation -------------------------------------------------------------------
def implicit_compliance(problem: Problem, xs: np.ndarray, wrench: np.ndarray,
                        factorization: Optional[Tuple[tuple, np.ndarray]] = None,
                        rotation: Optional[np.ndarray] = None
                        ) -> Tuple[np.ndarray, tuple, float]:
    """
    Return (C, lu, estimated relative error of C) at the converged unknowns ``xs``.

    Implicit differentiation with the exact Jacobian: r(x, w) = 0 gives dx/dw = -J^-1 dr/dw
    and C = dT/dx dx/dw, T the end-disk twist (Rucker & Webster, ICRA 2011). J and dT/dx
    come from one tangent-linear shot (problem.exact_jacobian) unless ``factorization``
    = (lu, pose Jacobian) already holds them at ``xs``; then C is one 6-column LU solve.
    ``rotation``: the end disk's rotation matrix at ``xs`` if known (else one more shot).
    No refinement sweeps: C is exact to rounding, so the error estimate is cond(J) times
    the machine epsilon, bounded by the 1-norm condition estimate of the factorization.
    ArithmeticError if J is singular or not finite at ``xs``.
    """
    if factorization is None:
        _, jacobian, pose = problem.exact_jacobian(xs, wrench)
        lu = _factorization(jacobian)
    else:
        lu, pose = factorization
    if rotation is None:  # the end disk's orientation at xs, unless the caller has it
        rotation = problem.residual_and_end_frame(xs, wrench)[1][:3, :3]
    compliance = stability.compliance_from_factorization(lu, pose, rotation,
                                                         problem.wrench_sensitivity)
    if not np.all(np.isfinite(compliance)):
        raise ArithmeticError('the Jacobian at the solution is singular')
    diagonal = np.abs(np.diag(lu[0]))
    error = float(np.finfo(float).eps * diagonal.max() / diagonal.min())
    return compliance, lu, error


#: The probe's wrench direction, in scaled units (forces in N, moments over the stack height
#: H): every component at the same size, signs mixed, so that no column of C goes unseen.
PROBE_DIRECTION = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0])

#: Largest change of a nondimensional unknown along the probe's difference: small against
#: the residual's curvature (the neglected second-order term), large against its rounding.
PROBE_STEP = 1e-6

#: The stated error is the probe's measure times this. The probe measures |D v| for one
#: direction v (D the scaled error of C): its expectation is the Frobenius norm of D, a
#: single one fell to 0.45 of it at worst over 120 solves of three random walks
#: (tests/analysis/test_compliance.py checks every stated error against the exact C).
PROBE_SAFETY = 3.0

#: ``ComplianceAnalysis.method`` of a compliance from the stored factorization.
STORED_METHOD = 'implicit, stored factorization'

#: ``compliance_tolerance``'s default: no error accepted, the exact compliance always.
EXACT = 0.0


def check_tolerance(tolerance: float) -> float:
    """Return ``compliance_tolerance`` as a float; ValueError unless finite and >= 0."""
    return check_number('compliance_tolerance', tolerance, low=0.0)


def analysis_options(options: Mapping[str, Any]) -> Dict[str, Any]:
    """
    Return ``options`` as ``analyse`` takes them: ``compliance_tolerance`` checked, left out.

    For a compliance made without a stored factorization to accept or refuse (a reduced
    level's, the linear level's): the tolerance has nothing to choose there.
    """
    kept = dict(options)
    check_tolerance(kept.pop('compliance_tolerance', EXACT))
    return kept


def stored_compliance(problem: Problem, xs: np.ndarray, wrench: np.ndarray, rs: np.ndarray,
                      end_frame: np.ndarray, lu: tuple,
                      pose_jacobian: np.ndarray) -> Tuple[np.ndarray, float]:
    """
    Return (C, its estimated relative error) from a factorization made near the solution.

    ``xs`` (nondimensional) converged at ``wrench`` with residual ``rs`` and end-disk frame
    ``end_frame`` (4x4); ``lu`` factorizes the Jacobian J~ made elsewhere (a stored one)
    and ``pose_jacobian`` is the end-disk pose derivative made with it. C~ = dT/dx~ X~,
    X~ = -J~^-1 dr/dw: one 6-column solve, no new Jacobian.

    Its error: one shot at (xs + h X~ v, w + h v), v = S PROBE_DIRECTION (S = diag(1, 1, 1,
    H, H, H)), gives by difference the linear system's defect (J X~ + dr/dw) v and the true
    pose change dT/dx X~ v; then C v = dT/dx (X~ v - J^-1 (J X~ + dr/dw) v) to second order
    (J^-1 taken as J~^-1 on the small defect). The stated error is PROBE_SAFETY times
    |S (C~ - C) v| over |S C~ S| (Frobenius norm): relative, rotations measured by the
    displacement they cause at H. ArithmeticError when C~ or the probe is not finite.
    """
    response = _linalg.solve_lu(lu, problem.wrench_sensitivity)  # J~^-1 dr/dw = -X~
    length = problem.params.stack_height
    scale = np.array((1.0, 1.0, 1.0, length, length, length))
    probe = scale * PROBE_DIRECTION
    direction = response @ probe  # -X~ v
    largest = float(np.abs(direction).max())
    if not (math.isfinite(largest) and largest > 0.0):
        raise ArithmeticError('the stored factorization gives no finite compliance')
    step = PROBE_STEP / largest
    moved_rs, moved = problem.residual_and_end_frame(xs - step * direction,
                                                     wrench + step * probe)
    # pose changes, twisted at once (the twist is linear in them for a fixed rotation):
    # columns 0-5 those of C~, column 6 what C~ v misses of C v
    changes = np.empty((12, 7))
    np.matmul(pose_jacobian, response, out=changes[:, :6])
    changes[:, :6] *= -1.0
    moved_pose = np.concatenate((moved[:3, 3] - end_frame[:3, 3],
                                 (moved[:3, :3] - end_frame[:3, :3]).ravel()))
    defect = (moved_rs - rs) / step
    changes[:, 6] = (changes[:, :6] @ probe - moved_pose / step
                     + pose_jacobian @ _linalg.solve_lu(lu, defect))
    twists = stability.pose_twist(changes, end_frame[:3, :3])
    compliance = np.ascontiguousarray(twists[:, :6])
    scaled = (scale[:, None] * compliance * scale[None, :]).ravel()
    size = math.sqrt(float(scaled @ scaled))
    miss = scale * twists[:, 6]
    error = PROBE_SAFETY * math.sqrt(float(miss @ miss)) / size
    if not (math.isfinite(error) and math.isfinite(size)):
        raise ArithmeticError('the stored factorization gives no finite compliance')
    return compliance, error


def _factorization(jacobian: np.ndarray) -> tuple:
    if not np.all(np.isfinite(jacobian)):
        raise ArithmeticError('the Jacobian at the solution is not finite')
    return _linalg.factorize(jacobian)


def frame_twist(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """
    Twist [dp; dtheta] taking 4x4 frame ``before`` to ``after``, both in the base frame.

    dp is the displacement of the origin, dtheta the rotation vector of
    after[:3, :3] before[:3, :3]^T (a spatial rotation increment). On floats, entry by
    entry (a few microseconds: an estimate takes one per pose and step).
    """
    (a0, a1, a2, ap), (a3, a4, a5, aq), (a6, a7, a8, ar) = after[:3].tolist()
    (b0, b1, b2, bp), (b3, b4, b5, bq), (b6, b7, b8, br) = before[:3].tolist()
    # R = A B^T: only its trace and skew part are needed
    r01 = a0 * b3 + a1 * b4 + a2 * b5
    r02 = a0 * b6 + a1 * b7 + a2 * b8
    r10 = a3 * b0 + a4 * b1 + a5 * b2
    r12 = a3 * b6 + a4 * b7 + a5 * b8
    r20 = a6 * b0 + a7 * b1 + a8 * b2
    r21 = a6 * b3 + a7 * b4 + a8 * b5
    trace = (a0 * b0 + a1 * b1 + a2 * b2) + (a3 * b3 + a4 * b4 + a5 * b5) + (
        a6 * b6 + a7 * b7 + a8 * b8)
    s0, s1, s2 = (r21 - r12) / 2.0, (r02 - r20) / 2.0, (r10 - r01) / 2.0
    sine = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    angle = math.atan2(sine, (trace - 1.0) / 2.0)
    scale = angle / sine if sine > 1e-12 else 1.0 + angle ** 2 / 6.0
    return np.array([ap - bp, aq - bq, ar - br, scale * s0, scale * s1, scale * s2])


# eigen / screw analysis -----------------------------------------------------------------------
def analyse(compliance: np.ndarray, characteristic_length: float,
            sparsity_threshold: float = SPARSITY_THRESHOLD,
            mobility_ratio: float = MOBILITY_RATIO, method: str = 'implicit',
            time_s: float = 0.0, estimated_error: float = 0.0) -> ComplianceAnalysis:
    """
    Primary-mobility analysis of C in the manner of the paper (Table III).

    C_s zeroes every coupling term whose magnitude is below ``sparsity_threshold`` times
    sqrt(|C_ii C_jj|) (a unit-free measure, unlike a threshold on raw entries whose units
    differ). Eigenvalues and eigenvectors are those of C_s. An eigen-direction gamma is a
    primary-mobility twist when its compliance in length units, xi |gamma|^2 /
    |S^-1 gamma|^2 with S = diag(1, 1, 1, L, L, L) (rotations measured as the displacement
    they cause at ``characteristic_length`` L), is at least ``mobility_ratio`` times the
    largest such value; otherwise it spans the constraint-wrench space.
    """
    if not 0.0 <= sparsity_threshold < 1.0:
        raise ValueError(f'sparsity_threshold must lie in [0, 1), got {sparsity_threshold}')
    if not 0.0 < mobility_ratio <= 1.0:
        raise ValueError(f'mobility_ratio must lie in (0, 1], got {mobility_ratio}')
    if not characteristic_length > 0.0:
        raise ValueError(f'characteristic_length must be positive, got {characteristic_length}')
    return ComplianceAnalysis(
        matrix=compliance, sparsity_threshold=sparsity_threshold, mobility_ratio=mobility_ratio,
        characteristic_length=characteristic_length, method=method, time_s=time_s,
        estimated_error=estimated_error)


@jit
def _sparsify(compliance, threshold, out):
    """C_s into ``out``: off-diagonal terms below threshold sqrt(|C_ii C_jj|) zeroed."""
    for i in range(6):
        for j in range(6):
            bound = threshold * math.sqrt(abs(compliance[i, i])) * math.sqrt(
                abs(compliance[j, j]))
            small = i != j and abs(compliance[i, j]) < bound  # NaN is never small
            out[i, j] = 0.0 if small else compliance[i, j]


@jit
def _arrange(values, vectors, length, ratio, dominant, mobile):
    """
    Order, scale and classify the eigen-pairs of C_s (``analyse``); return them.

    Each vector's dominant axis is its largest entry in scaled units (S = diag(1, 1, 1, L,
    L, L): rotations times ``length``); the pairs are sorted by dominant axis, then by
    decreasing eigenvalue (a stable sort); each vector gets unit length and a positive
    dominant entry. ``dominant`` and ``mobile`` (compliance in length units at least
    ``ratio`` times the largest; none if one is NaN) receive their flags in that order.
    """
    axis = np.empty(6, dtype=np.int64)
    for j in range(6):
        best, axis[j] = -1.0, 0
        for i in range(6):
            size = abs(vectors[i, j]) * (length if i >= 3 else 1.0)
            if size > best:
                best, axis[j] = size, i
    order = np.arange(6)
    for k in range(1, 6):  # insertion sort: stable, as numpy.lexsort
        current = order[k]
        m = k
        while m > 0 and (axis[order[m - 1]] > axis[current] or (
                axis[order[m - 1]] == axis[current] and values[order[m - 1]] < values[current])):
            order[m] = order[m - 1]
            m -= 1
        order[m] = current
    sorted_values = np.empty(6)
    sorted_vectors = np.empty((6, 6))
    in_length_units = np.empty(6)
    largest = -np.inf
    for k in range(6):
        j = order[k]
        dominant[k] = axis[j]
        sorted_values[k] = values[j]
        norm = 0.0
        for i in range(6):
            norm += vectors[i, j] * vectors[i, j]
        factor = math.copysign(1.0 / math.sqrt(norm), vectors[axis[j], j])
        scaled = 0.0
        for i in range(6):
            entry = factor * vectors[i, j]
            sorted_vectors[i, k] = entry
            entry /= length if i >= 3 else 1.0
            scaled += entry * entry
        in_length_units[k] = values[j] / scaled
        if np.isnan(in_length_units[k]) or np.isnan(largest):
            largest = np.nan
        else:
            largest = max(largest, in_length_units[k])
    for k in range(6):
        mobile[k] = in_length_units[k] >= ratio * largest
    return sorted_values, sorted_vectors


_IDENTITY = np.eye(6)


def _real_eigen(matrix: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """
    Real parts of the eigenvalues and eigenvectors of a real 6x6 matrix (LAPACK dgeev).

    dgeev stores a complex pair's vectors as (real part, imaginary part) in two columns;
    both columns get the real part here, as numpy.linalg.eig(...).real would give. Called
    directly: numpy.linalg.eig's wrapping cost twice the decomposition (42 against 18 us).
    """
    values, imaginary, _, vectors, info = dgeev(matrix, compute_vl=0)
    if info != 0:
        raise np.linalg.LinAlgError(f'dgeev: the QR algorithm failed to converge ({info})')
    pairs = np.flatnonzero(imaginary > 0.0)
    if pairs.size:  # second of each pair: the conjugate vector, same real part
        vectors[:, pairs + 1] = vectors[:, pairs]
    return values, vectors


def _smallest_stiffness_eigenvalue(compliance: np.ndarray) -> float:
    """Smallest eigenvalue of the symmetric part of K = C^-1 (-inf if C is singular)."""
    stiffness, info = dgesv(compliance, _IDENTITY)[2:]
    if info != 0 or not np.all(np.isfinite(stiffness)):  # singular C
        return -math.inf
    values, _, info = dsyevd(stiffness + stiffness.T, compute_v=0)
    return 0.5 * float(values[0]) if info == 0 else -math.inf


def compliance_analysis(problem: Problem, xs: np.ndarray, wrench: np.ndarray,
                        factorization: Optional[Tuple[tuple, np.ndarray]] = None,
                        rotation: Optional[np.ndarray] = None, started: Optional[float] = None,
                        **options: Any) -> Tuple[ComplianceAnalysis, tuple, np.ndarray]:
    """
    Implicit C at a converged solution and its analysis, plus the factorization used.

    Returns (analysis, lu, pose Jacobian) so that the caller can keep the exact
    factorization at the solution; ``factorization`` = (lu, pose Jacobian) at ``xs``
    skips the tangent shot. ``started``: when the compliance's time began (default now).
    A ``compliance_tolerance`` among ``options`` is checked and met: this C is exact.
    """
    started = time.perf_counter() if started is None else started
    check_tolerance(options.pop('compliance_tolerance', EXACT))
    if factorization is None:
        _, jacobian, pose = problem.exact_jacobian(xs, wrench)
        factorization = (_factorization(jacobian), pose.copy())
    compliance, lu, error = implicit_compliance(problem, xs, wrench, factorization, rotation)
    elapsed = time.perf_counter() - started
    analysis = analyse(compliance, problem.params.stack_height, time_s=elapsed,
                       estimated_error=error, **options)
    return analysis, lu, factorization[1]


def analysis_from_stored(problem: Problem, xs: np.ndarray, wrench: np.ndarray,
                         rs: np.ndarray, end_frame: np.ndarray, lu: tuple,
                         pose_jacobian: np.ndarray, tolerance: float, started: float,
                         **options: Any) -> Optional[ComplianceAnalysis]:
    """
    Return the analysis of ``stored_compliance`` when its stated error is within ``tolerance``.

    None when it is not (or C~ is not finite): the caller makes the exact one. ``started``:
    when the compliance's time began; ``options`` go to ``analyse``.
    """
    try:
        compliance, error = stored_compliance(problem, xs, wrench, rs, end_frame, lu,
                                              pose_jacobian)
    except ArithmeticError:
        return None
    if not error <= tolerance:
        return None
    return analyse(compliance, problem.params.stack_height, method=STORED_METHOD,
                   time_s=time.perf_counter() - started, estimated_error=error, **options)
