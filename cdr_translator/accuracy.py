"""
Discretization-error estimate of a converged solve (docs/accuracy.md).

The solver integrates every rod segment with N fixed RK4 steps, a method of order 4: at the
converged unknowns x_N the computed quantities q_N differ from the exact continuum ones by
e_N ~ c N^-4. One more shot at M steps per segment (M = N / 2, or 2 N when N = 1) gives
q_M - q_N = c (M^-4 - N^-4), hence the Richardson estimate (Hairer, Norsett & Wanner,
Solving ODEs I, Sec. II.4, "step doubling")

    |e_N| ~ |q_M - q_N| / |(N / M)^4 - 1|     (1/15 of the difference for M = N / 2).

It is applied to two families of quantities, and the estimate is the larger of them:

* at fixed x_N: the frames {pm}, {dm}, {de} and the defects of the disk conditions
  r_M(x_N) (hole offsets and clamp positions in m, tangent tilts and clamp rotations in
  rad). These are exactly what ``cdr_translator.verify`` measures with an accurate
  integrator, so a result whose estimate is well inside the paper's tolerances verifies;
* the end-disk pose of the *solution*: the M-step solution is x_N + dx with
  J dx = -(r_M(x_N) - r_N(x_N)) (one Newton step on the solve's factorization), and the
  pose moves by the difference of the shots plus dT/dx dx (stability.pose_twist).

Cost: one residual shot at M = N / 2 steps (half a solve iteration) and one LU solve.
"""

from dataclasses import dataclass
import math
from typing import Optional

import numpy as np

from . import stability
from .problem import Problem


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
    """
    steps = problem.params.steps_per_segment
    other = coarse_steps(steps)
    factor = 1.0 / abs((steps / other) ** 4 - 1.0)
    rs_other, frames_other = problem.shot_with_steps(xs, wrench, other)
    defect = rs_other - rs
    si = np.abs(defect * problem.residual_scale)
    if not np.all(np.isfinite(si)):
        return ErrorEstimate(math.inf, math.inf, steps, other)
    kind = problem.residual_kind
    positions = [float(si[kind == 0].max(initial=0.0))]
    angles = [float(si[kind == 1].max(initial=0.0))]
    # the tube faces and the end disk: centre distances and rotation angles between shots
    positions.append(float(np.linalg.norm(frames_other[1:, :3, 3] - frames[1:, :3, 3],
                                          axis=1).max()))
    angles.append(max(_angle(frames[k, :3, :3], frames_other[k, :3, :3]) for k in (1, 2, 3)))
    if lu is not None and pose is not None:
        # the end disk of the other discretization's solution: one Newton step from x_N
        change = pose @ stability.solve_lu(lu, -defect)
        change[:3] += frames_other[3, :3, 3] - frames[3, :3, 3]
        change[3:] += (frames_other[3, :3, :3] - frames[3, :3, :3]).ravel()
        twist = stability.pose_twist(change, frames[3, :3, :3])
        positions.append(float(np.linalg.norm(twist[:3])))
        angles.append(float(np.linalg.norm(twist[3:])))
    return ErrorEstimate(factor * max(positions), factor * max(angles), steps, other)


#: Largest factor by which one refinement multiplies the steps: the refined solve starts
#: from the coarser solution, which must stay inside Newton's basin (8 -> 256 at once
#: failed where 8 -> 24 -> 72 -> 216 converges).
MAX_GROWTH = 3.0


def _angle(first: np.ndarray, second: np.ndarray) -> float:
    """Rotation angle of first^T second: atan2(|vee of its skew part|, (trace - 1) / 2)."""
    relative = first.T @ second
    sine = 0.5 * math.sqrt((relative[2, 1] - relative[1, 2]) ** 2
                           + (relative[0, 2] - relative[2, 0]) ** 2
                           + (relative[1, 0] - relative[0, 1]) ** 2)
    return math.atan2(sine, 0.5 * (relative[0, 0] + relative[1, 1] + relative[2, 2] - 1.0))


def refined_steps(current: ErrorEstimate, position_target: float, angle_target: float,
                  ceiling: int) -> int:
    """
    Return the steps per segment expected to meet the targets (error ~ N^-4, 25 % margin).

    At most MAX_GROWTH times the current steps and ``ceiling``; returns ``current.steps``
    when both targets are met (a zero target is always met).
    """
    ratio = 1.0
    if position_target > 0.0:
        ratio = max(ratio, current.position_m / position_target)
    if angle_target > 0.0:
        ratio = max(ratio, math.degrees(current.angle_rad) / angle_target)
    if ratio <= 1.0:
        return current.steps
    wanted = MAX_GROWTH if not math.isfinite(ratio) else min(MAX_GROWTH, 1.25 * ratio ** 0.25)
    return min(ceiling, max(current.steps + 1, math.ceil(wanted * current.steps)))
