"""
Fallback continuation for the loads where the default chord/Newton continuation stalls.

The default continuation (solver.py) predicts each step to first order with a stored,
possibly stale, factorization and corrects with chord/Newton steps to a fixed tolerance.
On the hardest cases (docs/explanation/solution_quality.md: PJ past 100 deg, torsion
40 N m, nine spacer disks per joint at 20 N) it stalls for two reasons, both measured:

* The solution path x(lambda) is smooth (no fold: the Jacobian's smallest singular value
  stays near 1e-2) but single shooting through the disk intervals makes the residual so
  curved that a tangent predictor lands outside Newton's basin even for tiny steps (at
  26 N m torsion, a tangent step of 0.2 N m lands at a residual three times the one of the
  unmoved state). A Hermite predictor through the last converged points and their exact
  tangents follows the curved path instead: its residual is ~30 times smaller there.
* Past about 34 N m torsion the shot amplifies rounding so much that the residual cannot
  reach 1e-10: perturbing the unknowns by 1e-16 (relative) changes it by 1e-10. Newton
  then never meets the tolerance and the steps collapse. The corrector here accepts a
  residual at the rounding floor NOISE_FACTOR eps max_i (|J| |x|)_i (what rounding of the
  unknowns alone produces) and says so.

Each corrector iteration takes the exact Jacobian (tangent.translator_jacobian) at the
iterate, so the converged state carries an exact factorization for the stability verdict,
the error estimate and the next tangent. :func:`track` is only called after the default
path failed, so the results of solves that converge by the default path are unchanged.
"""

from dataclasses import dataclass
import time
from typing import List, Optional, Tuple

import numpy as np
from scipy.linalg import lu_solve

from .._linalg import factorize, residual_norm
from ..bvp.problem import Problem

#: Converged points the Hermite predictor interpolates (value and tangent at each).
HISTORY = 3

#: First step, as a fraction of the remaining wrench change.
FIRST_STEP = 1e-2

#: A step shrinking below this fraction of the remaining wrench change ends the tracking.
MIN_STEP = 1e-7

#: Newton iterations of one corrector (each with a fresh exact Jacobian).
MAX_ITERATIONS = 10

#: Growth after a corrector that needed at most EASY iterations, shrink after more than HARD.
GROW, EASY, SHRINK, HARD = 1.5, 4, 0.7, 7

#: Rounding floor of the residual, in units of eps times max_i (|J| |x|)_i.
NOISE_FACTOR = 8.0


@dataclass
class _Corrected:
    """
    End of one corrector: nondimensional unknowns and residual, iterations and the reason.

    ``lu`` and ``pose`` (end-disk pose Jacobian, SI rows) are exact at ``xs`` when it
    converged; ``floor`` is the rounding floor of the residual there.
    """

    xs: np.ndarray
    rs: np.ndarray
    iterations: int
    converged: bool
    message: str
    floor: float = 0.0
    lu: Optional[tuple] = None
    pose: Optional[np.ndarray] = None


@dataclass
class Tracked(_Corrected):
    """End of a tracking: the last corrector's outcome, plus the accepted load steps."""

    steps: int = 0


def rounding_floor(jac: np.ndarray, xs: np.ndarray) -> float:
    """Return the residual that rounding the unknowns ``xs`` alone produces (NOISE_FACTOR)."""
    return NOISE_FACTOR * np.finfo(float).eps * float((np.abs(jac) @ np.abs(xs)).max())


def correct(problem: Problem, xs: np.ndarray, wrench: np.ndarray, tolerance: float,
            deadline: float, shift: Optional[np.ndarray] = None,
            max_iterations: int = MAX_ITERATIONS) -> _Corrected:
    """
    Newton with an exact Jacobian at every iterate and a backtracking line search.

    It solves residual(x, wrench) = ``shift`` (default zero, see :func:`track`).

    Converged when the largest residual is within the tolerance or the rounding floor,
    whichever is larger; the factorization and pose Jacobian at that point are returned.
    """
    rs = np.full(problem.size, np.inf)
    for iteration in range(max_iterations + 1):
        with np.errstate(over='ignore', invalid='ignore'):
            rs, jac, pose = problem.exact_jacobian(xs, wrench)
        rs = rs - shift if shift is not None else rs.copy()
        if not (np.isfinite(rs).all() and np.isfinite(jac).all()):
            return _Corrected(xs, rs, iteration, False, 'residual became non-finite')
        floor = rounding_floor(jac, xs)
        lu = factorize(jac)
        if np.abs(rs).max() <= max(tolerance, floor):
            return _Corrected(xs, rs, iteration, True, 'converged', floor, lu, pose.copy())
        if iteration == max_iterations:
            break
        if time.perf_counter() > deadline:
            return _Corrected(xs, rs, iteration, False, 'time limit reached')
        step = -lu_solve(lu, rs, check_finite=False)
        if not np.isfinite(step).all():
            return _Corrected(xs, rs, iteration, False, 'Newton step is not finite')
        norm, scale = residual_norm(rs), 1.0
        for _ in range(12):
            trial = xs + scale * step
            trial_rs = problem.residual(trial, wrench)
            if shift is not None:
                trial_rs = trial_rs - shift
            if residual_norm(trial_rs) < (1.0 - 1e-4 * scale) * norm:
                break
            scale *= 0.5
        else:
            return _Corrected(xs, rs, iteration + 1, False,
                              'line search found no decrease of the residual')
        xs = trial
    return _Corrected(xs, rs, max_iterations, False,
                      f'no convergence in {max_iterations} iterations')


def hermite(history: List[Tuple[float, np.ndarray, np.ndarray]], at: float) -> np.ndarray:
    """
    Extrapolate the path to parameter ``at`` from (parameter, value, tangent) points.

    The polynomial of degree 2k - 1 through the k points' values and tangents (the cubic
    Hermite predictor for k = 2, the tangent predictor for k = 1).
    """
    if len(history) == 1:
        origin, value, tangent = history[0]
        return value + (at - origin) * tangent
    reference = history[-1][0]
    scale = history[-1][0] - history[-2][0]
    size = 2 * len(history)
    powers = np.arange(size)
    matrix = np.zeros((size, size))
    rows = []
    for index, (parameter, value, tangent) in enumerate(history):
        u = (parameter - reference) / scale
        matrix[2 * index] = u ** powers
        matrix[2 * index + 1] = powers * np.where(powers > 0, u ** np.maximum(powers - 1, 0),
                                                  0.0)
        rows += [value, tangent * scale]
    coefficients = np.linalg.solve(matrix, np.array(rows))
    return ((at - reference) / scale) ** powers @ coefficients


def track(problem: Problem, xs: np.ndarray, start: np.ndarray, wrench: np.ndarray,
          tolerance: float, deadline: float) -> Tracked:
    """
    Follow the equilibrium path from the converged ``xs`` at ``start`` to ``wrench``.

    Natural-parameter continuation in the fraction of the wrench change, with a Hermite
    predictor through the last HISTORY converged points and their exact tangents
    dx/dlambda = -J^-1 (dr/dw) (w - start), corrected by :func:`correct`; a failed step is
    halved, an easy one grown. A failure is returned as a Tracked with converged False and
    the best state reached (its residual taken at ``wrench``).

    When ``xs`` is not a solution at ``start`` (e.g. the solution of a coarser grid, whose
    residual on this grid is r0), the path is that of the Newton homotopy
    r(x, start + lambda (wrench - start)) = (1 - lambda) r0, which starts at ``xs``.
    """
    change = wrench - start
    offset = problem.residual(xs, start)
    if not np.all(np.isfinite(offset)):
        return Tracked(xs, problem.residual(xs, wrench), 0, False,
                       'the starting state has a non-finite residual')
    if np.abs(offset).max() <= tolerance:
        offset = np.zeros_like(offset)
    # d/dlambda of r(x, start + lambda change) - (1 - lambda) r0
    sensitivity = problem.wrench_sensitivity @ change + offset
    first = correct(problem, xs, start, tolerance, deadline, offset)
    iterations, steps = first.iterations, 0
    if not first.converged or first.lu is None:
        return Tracked(xs, problem.residual(xs, wrench), iterations, False,
                       f'the starting state did not converge: {first.message}')
    history = [(0.0, first.xs, -lu_solve(first.lu, sensitivity, check_finite=False))]
    done, step = 0.0, FIRST_STEP
    last = first
    while done < 1.0:
        target = min(1.0, done + step)
        goal = start + target * change
        guess = hermite(history, target)
        outcome = correct(problem, guess, goal, tolerance, deadline, (1.0 - target) * offset)
        iterations += outcome.iterations
        if outcome.converged and outcome.lu is not None:
            tangent = -lu_solve(outcome.lu, sensitivity, check_finite=False)
            history = history[1 - HISTORY:] + [(target, outcome.xs, tangent)] \
                if HISTORY > 1 else [(target, outcome.xs, tangent)]
            done, last, steps = target, outcome, steps + 1
            if outcome.iterations <= EASY:
                step *= GROW
            elif outcome.iterations > HARD:
                step *= SHRINK
            continue
        step *= 0.5
        if step < MIN_STEP or time.perf_counter() > deadline:
            reason = ('time limit reached' if time.perf_counter() > deadline
                      else f'step below {MIN_STEP:g}: {outcome.message}')
            rs = problem.residual(last.xs, wrench)
            return Tracked(last.xs, rs, iterations, False,
                           f'stalled at {done:.1%} of the way ({reason})', steps=steps)
    assert last.lu is not None and last.pose is not None
    floor = last.floor if np.abs(last.rs).max() > tolerance else 0.0
    return Tracked(last.xs, last.rs, iterations, True, 'converged', floor, last.lu, last.pose,
                   steps)
