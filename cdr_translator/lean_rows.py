"""
Rows of ``TranslatorSolver.solve_many``: the usual warm row without a SolveResult.

Along a warm sequence almost every solve is the compiled warm step (warm_step.py), a
stability verdict from the stored factorization and an error estimate within the target.
Such a row goes from the step's recorded frames straight into the batch's columns; any
other row (no verdict, unstable, short of its accuracy target, kept refined steps) takes
the rest of the solve it has begun (``TranslatorSolver._judged``), so that every row is
what ``solve`` gives.
"""

import time
from typing import TYPE_CHECKING

import numpy as np

from .accuracy import meets
from .batch import BatchResult
from .compliance import compliance_analysis, ComplianceAnalysis
from .correctors import Outcome

if TYPE_CHECKING:
    from .solver import TranslatorSolver


def solve_row(solver: 'TranslatorSolver', batch: BatchResult, row: int, wrench: np.ndarray,
              compliance: bool) -> float:
    """Solve row ``row`` of ``batch`` as ``solver.solve`` would; return its solve time (s)."""
    started = time.perf_counter()
    if solver._refinements.kept is not None:
        result = solver.solve(wrench[:3], wrench[3:], compliance=compliance)
        batch.record(row, result)
        return result.solve_time_s
    outcome = solver._correct(wrench, True, started)
    verdict = solver._verdict(outcome, wrench)
    estimate = outcome.estimate
    target = solver.accuracy
    if (verdict is None or not verdict.stable or estimate is None or outcome.shape is None
            or not meets(estimate, target.position_m, target.angle_deg)):
        result = solver._judged(outcome, verdict, wrench, started, compliance, False, {})
        batch.record(row, result)
        return result.solve_time_s
    # judged stable and accurate: what _judged finds, without the result
    solver._refinements.last_estimate = estimate
    elapsed = time.perf_counter() - started
    frames = outcome.shape[2]
    matrix, message = None, ''
    if compliance:
        try:
            matrix = compliance_at(solver, outcome, wrench, frames[3][:3, :3]).matrix
        except ArithmeticError as error:
            message = f'{outcome.message}; no compliance: {error}'
    batch.record_pose(row, frames, verdict.stable, estimate, matrix, message)
    return elapsed


def compliance_at(solver: 'TranslatorSolver', outcome: Outcome, wrench: np.ndarray,
                  rotation: np.ndarray, **options: float) -> ComplianceAnalysis:
    """Compliance at a converged outcome; its exact factorization becomes the stored one."""
    state = solver._state
    stored = state.pose[0] if state.pose is not None else None
    factorization = ((state.lu, stored) if state.exact_at is outcome.xs
                     and state.lu is not None and stored is not None else None)
    analysis, state.lu, pose = compliance_analysis(solver.problem, outcome.xs, wrench,
                                                   factorization, rotation, **options)
    state.pose = (pose, wrench.copy())
    state.exact_at = outcome.xs
    return analysis
