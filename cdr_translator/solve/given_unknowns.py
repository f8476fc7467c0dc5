"""
The SolveResult at shooting unknowns a caller converged itself (TranslatorSolver.result_at).

robot/delta.py's coupled Newton iterates on the legs' shooting residuals together with the
platform; once converged it asks each leg's solver for the result there: one shot with the
shape recorded, the stability verdict and the error estimate, from the same arithmetic as a
solve, without the continuation around it.
"""

import time
from typing import Optional, Tuple, TYPE_CHECKING

import numpy as np

from . import branch
from .correctors import Outcome
from .result import SolveResult

if TYPE_CHECKING:
    from .solver import TranslatorSolver

__all__ = ['result_at']


def result_at(solver: 'TranslatorSolver', xs: np.ndarray, wrench: np.ndarray,
              factorization: Optional[Tuple[tuple, np.ndarray, np.ndarray]] = None
              ) -> SolveResult:
    """
    Return the SolveResult at nondimensional unknowns ``xs`` under the checked ``wrench``.

    The verdict comes from ``factorization`` (as ``start_at`` takes it), else from an exact
    Jacobian at ``xs``; a residual above the solver's tolerance gives ``converged`` False
    and a message, never an iteration. The solver's warm start and stored factorization are
    left as they were.
    """
    started = time.perf_counter()
    xs = np.array(xs, dtype=float)
    state = solver._state
    saved = (state.lu, state.pose, state.exact_at)
    rs = solver.problem.residual_and_shape(xs, wrench)
    largest = float(np.abs(rs).max())
    converged = largest <= solver.tolerance
    lu, pose = (None, None) if factorization is None else (
        factorization[0], (factorization[1], np.array(factorization[2], dtype=float)))
    outcome = Outcome(xs, rs, 0, converged, 'converged' if converged else
                      f'residual {largest:.2g} above the tolerance {solver.tolerance:.2g} '
                      'at the given unknowns', lu, pose)
    outcome.shape = (xs, *solver.problem.recorded_shape(0))
    result = outcome.result(solver.problem, wrench, solver.method)
    if converged:
        try:
            if solver.method == 'fast':
                branch.apply_verdict(result, solver._stability(outcome, wrench,
                                                               result.frames['de'][:3, :3]))
            solver._estimate_error(result, outcome, wrench)
        finally:
            state.lu, state.pose, state.exact_at = saved
    result.solve_time_s = time.perf_counter() - started
    return result
