"""
Discretization-error estimate of a converged solve (docs/explanation/solution_quality.md).

The solver integrates every rod segment with N fixed RK4 steps, a method of order 4: at the
converged unknowns x_N the computed quantities q_N differ from the exact continuum ones by
e_N ~ c N^-4. One more shot at M steps per segment (M = N / 2, or 2 N when N = 1) gives
q_M - q_N = c (M^-4 - N^-4), hence the Richardson estimate (Hairer, Norsett & Wanner,
Solving ODEs I, Sec. II.4, "step doubling")

    |e_N| ~ |q_M - q_N| / |(N / M)^4 - 1|     (1/15 of the difference for M = N / 2).

It is applied to two families of quantities, and the estimate is the larger of them:

* at fixed x_N: the frames {pm}, {dm}, {de} and the defects of the disk conditions
  r_M(x_N) (hole offsets and clamp positions in m, tangent tilts and clamp rotations in
  rad). These are exactly what ``cdr_translator.solve.verify`` measures with an accurate
  integrator, so a result whose estimate is well inside the paper's tolerances verifies;
* the end-disk pose of the *solution*: the M-step solution is x_N + dx with
  J dx = -(r_M(x_N) - r_N(x_N)) (one Newton step on the solve's factorization), and the
  pose moves by the difference of the shots plus dT/dx dx (stability.pose_twist).

Cost: one residual shot at M = N / 2 steps (half a solve iteration) and one LU solve. When
that coarse shot overflows (a state so curved that N / 2 steps diverge), the comparison is
made with M = 2 N instead (factor 16/15; two solve iterations' worth).
"""

from dataclasses import dataclass
import math
from typing import Optional

import numpy as np

from .._jit import jit
from .._linalg import lu_solve
from ..bvp.layout import N_RODS
from ..bvp.problem import Problem
from ..bvp.shooting import translator_residual


@dataclass(frozen=True)
class ErrorEstimate:
    """Estimate of the discretization error (m, rad) at ``steps`` steps per segment."""

    position_m: float
    angle_rad: float
    steps: int
    coarse_steps: int

    @property
    def angle_deg(self) -> float:
        """Return the angle estimate in degrees."""
        return math.degrees(self.angle_rad)


@jit
def coarse_steps(steps: int) -> int:
    """Return the steps of the comparison shot: half (rounded down), or 2 for 1 step."""
    return steps // 2 if steps >= 2 else 2


def estimate(problem: Problem, xs: np.ndarray, wrench: np.ndarray, rs: np.ndarray,
             frames: np.ndarray, lu: Optional[tuple] = None,
             pose: Optional[np.ndarray] = None) -> ErrorEstimate:
    """
    Estimate the error at converged unknowns ``xs`` (residual ``rs``, frames ``frames``).

    ``lu`` and ``pose`` (the solve's factorization and end-disk pose derivative) add the
    solution's end-disk pose change; without them only the fixed-x part is estimated.
    One compiled call (``estimate_kernel``): the comparison shot and both measures.
    """
    steps = problem.params.steps_per_segment
    with_solution = lu is not None and pose is not None
    factors, pivots = lu if lu is not None else (_NO_FACTORS, _NO_PIVOTS)
    position, angle, other = estimate_kernel(
        xs, wrench, problem.x_scale, problem.residual_scale, problem.residual_kind,
        problem.model_args, rs, frames, factors, pivots,
        pose if pose is not None else _NO_POSE, with_solution)
    return ErrorEstimate(position, angle, steps, other)


#: Stand-ins of the factorization and pose derivative when a solve has none (same types).
_NO_FACTORS = np.empty((0, 0), order='F')
_NO_PIVOTS = np.empty(0, dtype=np.int32)
_NO_POSE = np.empty((12, 0))


@jit
def estimate_kernel(xs, wrench, x_scale, residual_scale, kind, model_args, rs, frames,
                    factors, pivots, pose, with_solution):
    """Return (position, angle, comparison steps) of ``estimate`` (see the module docstring)."""
    pitch_radius, spacing, tube_length, spacers, steps, inv_kse, inv_kbt = model_args
    size = xs.shape[0]
    unknowns = np.empty(size)
    for i in range(size):
        unknowns[i] = xs[i] * x_scale[i]
    other = coarse_steps(steps)
    no_points = np.empty((N_RODS, 0, 3))
    frames_other = np.empty((4, 4, 4))
    defect = np.empty(size)
    for attempt in range(2):
        translator_residual(unknowns, wrench, pitch_radius, spacing, tube_length, spacers,
                            other, inv_kse, inv_kbt, defect, no_points, frames_other)
        finite = True
        for i in range(size):
            defect[i] = defect[i] / residual_scale[i] - rs[i]
            finite = finite and math.isfinite(defect[i])
        if finite or other > steps:
            break
        # the coarse shot overflowed (a very curved state): compare with a finer one instead
        other = 2 * steps
    if not finite:
        return math.inf, math.inf, other
    factor = 1.0 / abs((steps / other) ** 4 - 1.0)
    si = np.empty(size)
    for i in range(size):
        si[i] = abs(defect[i] * residual_scale[i])
    position, angle = _fixed_x_measures(si, kind, frames, frames_other)
    if with_solution:
        # the end disk of the other discretization's solution: one Newton step from x_N
        for i in range(size):
            defect[i] = -defect[i]
        step = np.empty(size)
        lu_solve(factors, pivots, defect, step)
        change = np.zeros(12)
        for r in range(12):
            for i in range(size):
                change[r] += pose[r, i] * step[i]
        moved, turned = _solution_measures(change, frames[3], frames_other[3])
        position, angle = max(position, moved), max(angle, turned)
    return factor * position, factor * angle, other


@jit
def _fixed_x_measures(si, kind, frames, frames_other):
    """
    Largest position and angle differences at fixed unknowns (m, rad).

    The disk-condition defects ``si`` by ``kind`` (0 positions, 1 angles), and the centre
    distance and rotation angle between the two shots' frames {pm}, {dm}, {de}.
    """
    position = 0.0
    angle = 0.0
    for row in range(si.shape[0]):
        if kind[row] == 0:
            position = max(position, si[row])
        elif kind[row] == 1:
            angle = max(angle, si[row])
    for k in range(1, 4):
        distance = 0.0
        for c in range(3):
            distance += (frames_other[k, c, 3] - frames[k, c, 3]) ** 2
        position = max(position, math.sqrt(distance))
        angle = max(angle, _angle(frames[k], frames_other[k]))
    return position, angle


@jit
def _solution_measures(change, frame, frame_other):
    """
    Centre distance and rotation angle of the end disk of the other solution (m, rad).

    ``change`` (12) is dT/dx dx; the shots' frame difference is added, and the rotation
    part turned into a spatial angle with the convention of stability.pose_twist.
    """
    distance = 0.0
    for c in range(3):
        distance += (change[c] + frame_other[c, 3] - frame[c, 3]) ** 2
    spin = np.zeros((3, 3))  # dR R^T
    for a in range(3):
        for b in range(3):
            for c in range(3):
                d_rot = change[3 + 3 * a + c] + frame_other[a, c] - frame[a, c]
                spin[a, b] += d_rot * frame[b, c]
    wx = 0.5 * (spin[2, 1] - spin[1, 2])
    wy = 0.5 * (spin[0, 2] - spin[2, 0])
    wz = 0.5 * (spin[1, 0] - spin[0, 1])
    return math.sqrt(distance), math.sqrt(wx * wx + wy * wy + wz * wz)


#: Largest factor by which one refinement multiplies the steps: the refined solve starts
#: from the coarser solution, which must stay inside Newton's basin (8 -> 256 at once
#: failed where 8 -> 24 -> 72 -> 216 converges).
MAX_GROWTH = 3.0


@jit
def _angle(first, second):
    """Rotation angle of first^T second (3x3 blocks): atan2(|vee skew|, (trace - 1) / 2)."""
    relative = np.zeros((3, 3))
    for a in range(3):
        for b in range(3):
            for c in range(3):
                relative[a, b] += first[c, a] * second[c, b]
    sine = 0.5 * math.sqrt((relative[2, 1] - relative[1, 2]) ** 2
                           + (relative[0, 2] - relative[2, 0]) ** 2
                           + (relative[1, 0] - relative[0, 1]) ** 2)
    return math.atan2(sine, 0.5 * (relative[0, 0] + relative[1, 1] + relative[2, 2] - 1.0))


def meets(current: ErrorEstimate, position_target: float, angle_target: float) -> bool:
    """Say whether ``current`` is within both targets (a zero target is always met)."""
    return ((position_target <= 0.0 or current.position_m <= position_target)
            and (angle_target <= 0.0 or current.angle_deg <= angle_target))


def _error_ratio(current: ErrorEstimate, position_target: float, angle_target: float
                 ) -> float:
    """Return the larger of estimate / target over both kinds (0 when both are off)."""
    ratio = 0.0
    if position_target > 0.0:
        ratio = max(ratio, current.position_m / position_target)
    if angle_target > 0.0:
        ratio = max(ratio, math.degrees(current.angle_rad) / angle_target)
    return ratio


def refined_steps(current: ErrorEstimate, position_target: float, angle_target: float,
                  ceiling: int) -> int:
    """
    Return the steps per segment expected to meet the targets (error ~ N^-4, 25 % margin).

    At most MAX_GROWTH times the current steps and ``ceiling``; returns ``current.steps``
    when both targets are met (a zero target is always met).
    """
    ratio = _error_ratio(current, position_target, angle_target)
    if ratio <= 1.0:
        return current.steps
    wanted = MAX_GROWTH if not math.isfinite(ratio) else min(MAX_GROWTH, 1.25 * ratio ** 0.25)
    return min(ceiling, max(current.steps + 1, math.ceil(wanted * current.steps)))


#: A warm solve at kept steps per segment lets the next one step down only to at most this
#: fraction of them (fewer steps save little, and every count is its own solver).
STEP_DOWN = 0.75


def kept_steps(current: ErrorEstimate, position_target: float, angle_target: float,
               floor: int) -> int:
    """
    Return the steps per segment the next warm solve starts at, after one that met the targets.

    The steps are kept (a refined warm sequence stays refined) unless the estimate has room
    for ``floor`` or at most STEP_DOWN of them with refined_steps' 25 % margin: then the
    fewest such, at least ``floor``. A refinement lands about 1.25^4 = 2.4 times inside the
    target, a step down that far inside it, and a step down needs the error to fall that
    much and (above ``floor``) about 1 / STEP_DOWN^4 = 3.2 times further first: the count
    does not oscillate (hysteresis).
    """
    ratio = _error_ratio(current, position_target, angle_target)
    if not ratio <= 1.0:
        return current.steps
    wanted = math.ceil(1.25 * ratio ** 0.25 * current.steps)
    if wanted <= floor:
        return floor
    return wanted if wanted <= STEP_DOWN * current.steps else current.steps
