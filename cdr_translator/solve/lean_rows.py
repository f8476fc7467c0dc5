"""
The batch-row calls of cdr_translator/fidelity/batch_rows.py, until it calls the solver's own.

The rows of a batch are ``TranslatorSolver.solve_batch_rows`` and ``solve_batch_row``
(``Engine.solve_rows``, engine.py). cdr_translator.fidelity is being restructured apart
and still imports this module; once it calls those methods, this module goes.
"""

import numpy as np

from .batch import BatchResult
from .solver import TranslatorSolver

__all__ = ['solve_row', 'solve_rows']


def solve_rows(solver: TranslatorSolver, batch: BatchResult, wrenches: np.ndarray,
               rows: range, compliance: bool) -> None:
    """Solve ``rows`` of ``wrenches`` into ``batch`` (``TranslatorSolver.solve_batch_rows``)."""
    solver.solve_batch_rows(batch, wrenches, rows, compliance)


def solve_row(solver: TranslatorSolver, batch: BatchResult, row: int, wrench: np.ndarray,
              compliance: bool) -> float:
    """Solve one row of ``batch`` (``TranslatorSolver.solve_batch_row``); its time (s)."""
    return solver.solve_batch_row(batch, row, wrench, compliance)
