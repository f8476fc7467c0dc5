"""
Multiple shooting by the lifted Newton method, for translators with many spacer disks.

It solves the same equations as single shooting, the paper's Eq. 7-11 (Section III.C),
by another iteration; its kernels are in multiple_shooting_kernels.py and tangent.py.

Single shooting carries the rods' state through all 2 (S + 1) disk intervals of a shot, so
its residual compounds the nonlinearity of every interval: at nine spacer disks per joint
one exact Newton step from the 1.0 N solution to 1.1 N took the residual from 1.1e-3 to
0.15 (its linear prediction: 4e-15), and a cold 2 N solve needed about 40 continuation
steps. Multiple shooting makes the state at the start of every interval after the first a
variable of its own (a node z_t, layout.STATE_SIZE values), each interval shot from its
node, with the defects d_t = Phi_{t-1}(z_{t-1}, x) - z_t as extra equations: Newton then
linearizes every interval separately.

The lifted Newton method (Albersmeyer & Diehl, "The lifted Newton method and its
application in optimization", SIAM J. Optim. 20(3):1655-1684, 2010) takes that Newton step
at the cost of a single-shooting one. Condensing the node equations, dz_t = a_t + Z_t dx
with a_t = L_{t-1} a_{t-1} + d_t (L the interval's local derivative) and Z_t the tangent of
the carried state that the exact Jacobian chains anyway; a is one more tangent column
(layout.LIFT_COLUMN). The step solves J dx = -(r + R_z a), J the condensed Jacobian (at
zero defects the single-shooting one), then z_t += a_t + Z_t dx; a rotation that this
linear update leaves far from orthogonal is projected back onto SO(3)
(multiple_shooting_kernels.ORTHOGONALITY_SLACK). The steps are full Newton steps: a merit
function |r|^2 + |d|^2 rejected good ones (the first step from a consistent start raises
the defects from zero by design, and a line search then crept along at 1/128 steps), so
the iteration only ends, as not contracting, when that norm grows PATIENCE times in a
row, and the caller's continuation then shortens its load step. Converged means the lifted
equations and the single-shooting residual at x are within the tolerance (or the latter
at the shot's rounding floor, path_following.rounding_floor): the answer is the
single-shooting solution, the nodes only steer the iteration.
"""

from dataclasses import dataclass
import math
import time
from typing import Optional

import numpy as np
from scipy.linalg import lu_solve

from .path_following import rounding_floor
from .._linalg import factorize
from ..bvp.problem import Problem

#: Iterations in a row (after the first, which raises the defects from zero) whose
#: residuals and defects grow end the iteration as not contracting.
PATIENCE = 2


@dataclass
class Lifted:
    """
    End of a lifted Newton iteration: unknowns, nodes (SI), single-shooting residual, why.

    ``lu`` factorizes the last condensed Jacobian, ``pose`` its end-disk pose Jacobian
    (Problem.pose_jacobian), ``tangents`` its node tangents (Problem.node_tangents), all
    None if none was made.
    """

    xs: np.ndarray
    nodes: np.ndarray
    rs: np.ndarray
    iterations: int
    converged: bool
    message: str
    lu: Optional[tuple] = None
    pose: Optional[np.ndarray] = None
    tangents: Optional[np.ndarray] = None


def _merit(rs: np.ndarray, ds: np.ndarray) -> float:
    """Squared norm of the lifted system's equations (residuals and defects)."""
    with np.errstate(over='ignore', invalid='ignore'):
        value = float(rs @ rs + np.sum(ds * ds))
    return value if math.isfinite(value) else math.inf


def newton(problem: Problem, xs: np.ndarray, nodes: np.ndarray, wrench: np.ndarray,
           tolerance: float, max_iterations: int, deadline: float) -> Lifted:
    """
    Iterate lifted Newton from unknowns ``xs`` (nondimensional) and ``nodes`` (SI).

    Each iteration is one tangent shot with nodes (Problem.lifted_jacobian), one LU of the
    condensed Jacobian and one shot with nodes at the new iterate. Stops when converged
    (module docstring), after ``max_iterations``, at the deadline, or when the iteration
    does not contract.
    """
    xs = np.array(xs, dtype=float)
    nodes = np.array(nodes, dtype=float)
    lu: Optional[tuple] = None
    pose: Optional[np.ndarray] = None
    tangents: Optional[np.ndarray] = None
    rs, ds = problem.lifted_residual(xs, nodes, wrench)
    merit = _merit(rs, ds)
    done, rises, floor = 0, 0, 0.0

    def ended(converged: bool, message: str, single: Optional[np.ndarray] = None) -> Lifted:
        if single is None:
            single = problem.residual(xs, wrench)
        return Lifted(xs, nodes, single, done, converged, message, lu, pose, tangents)

    while True:
        if not math.isfinite(merit):
            return ended(False, 'residual became non-finite during the iteration')
        if max(np.abs(rs).max(), np.abs(ds).max(initial=0.0)) <= tolerance:
            single = problem.residual(xs, wrench)
            largest = np.abs(single).max()
            if largest <= tolerance:
                return ended(True, 'converged', single)
            if largest <= floor:
                return ended(True, f'converged; residual {largest:.2g} at the rounding floor '
                             f'{floor:.2g} of the shot, above the tolerance {tolerance:.2g}',
                             single)
        if done >= max_iterations:
            return ended(False, f'no convergence in {max_iterations} iterations')
        if time.perf_counter() > deadline:
            return ended(False, 'time limit reached')
        rs, ds, jac, lifted = problem.lifted_jacobian(xs, nodes, wrench)
        pose, tangents = problem.pose_jacobian, problem.node_tangents
        floor = rounding_floor(jac, xs)
        lu = factorize(jac)  # a singular J shows as a non-finite step
        step = -lu_solve(lu, rs + lifted, check_finite=False)
        done += 1
        if not np.all(np.isfinite(step)):
            return ended(False, 'Newton step is not finite (singular or non-finite Jacobian)')
        nodes = problem.advance_nodes(nodes, step)
        xs = xs + step
        rs, ds = problem.lifted_residual(xs, nodes, wrench)
        previous, merit = merit, _merit(rs, ds)
        rises = rises + 1 if done > 1 and merit >= previous and merit > tolerance ** 2 else 0
        if rises >= PATIENCE:
            return ended(False, 'the lifted Newton iteration does not contract')
