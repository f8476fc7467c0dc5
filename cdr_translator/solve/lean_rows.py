"""
Rows of ``TranslatorSolver.solve_many``: the usual warm rows without a SolveResult.

Along a warm sequence almost every solve is the compiled warm step (warm_step.py), a
stability verdict kept from the stored factorization and an error estimate within the
target. Runs of such rows, without compliance, are one compiled call (``solve_rows``,
warm_rows.py). Any other row goes through ``solve_row``: a warm row with a verdict and
an estimate from its step's recorded frames straight into the batch's columns; any other
(no verdict, unstable, short of its accuracy target, kept refined steps) takes the rest of
the solve it has begun (``TranslatorSolver._judged``), so that every row is what ``solve``
gives.
"""

from functools import partial
import time
from typing import Callable, Optional, Tuple, TYPE_CHECKING

import numpy as np

from .batch import BatchResult, SolveDetails
from .branch import LOAD_FLOOR, STALE_WRENCH
from .continuation import warm_settings
from .correctors import Outcome
from .result import SolveResult
from .warm_rows import Checks, DJ, ERROR_DEG, ERROR_M, ERROR_RAD, PJ, POSITION, QUATERNION
from .warm_rows import Run, warm_rows
from .warm_step import residual_by_kind
from .._linalg import residual_norm
from ..analysis.accuracy import ErrorEstimate, meets
from ..analysis.compliance import compliance_analysis, ComplianceAnalysis
from ..analysis.stability import CLOSE_BRANCH_MARGIN, load_scale

if TYPE_CHECKING:
    from .solver import TranslatorSolver


def solve_rows(solver: 'TranslatorSolver', batch: BatchResult, wrenches: np.ndarray,
               rows: range, compliance: bool) -> None:
    """
    Solve ``rows`` of ``wrenches`` as consecutive ``solver.solve`` calls would.

    Runs of usual warm rows (without compliance) go to one compiled call, the other rows
    one by one (``solve_row``), each going on from the warm step that stopped the run.
    """
    row = rows.start
    solve_one = partial(solve_row, solver)
    state = solver._state
    while row < rows.stop:
        undo = None
        if not compliance:
            done, undo = usual_rows(solver, batch, wrenches, range(row, rows.stop))
            row += done
        if row < rows.stop:
            try:
                batch.run(row, solve_one, wrenches[row], compliance)
            finally:
                if state.handed_over is not None and undo is not None:
                    undo()  # the row's solve did not go on from the step: as if never taken
                state.handed_over = None  # only ever for this row's solve
            row += 1


def usual_rows(solver: 'TranslatorSolver', batch: BatchResult, wrenches: np.ndarray,
               rows: range) -> Tuple[int, Optional[Callable[[], None]]]:
    """
    Solve the usual warm rows at the head of ``rows`` in one compiled call (``usual_run``).

    Returns how many, and the ``warm_rows.Run.undo`` of the warm step handed to the next
    row's solve (``PathState.handed_over``); (0, None) when the solver's state is not that
    of a usual warm row.
    """
    started = time.perf_counter()
    run = usual_run(solver, wrenches[rows.start:rows.stop])
    if run is None or run.rows == 0:
        return 0, None if run is None else run.undo
    answers = run.answers
    batch.record_poses(slice(rows.start, rows.start + run.rows),
                       answers[:, POSITION:QUATERNION + 4],
                       answers[:, [PJ, PJ + 1, DJ, DJ + 1]], 'full',
                       (time.perf_counter() - started) / run.rows, stable=True,
                       estimate=answers[:, [ERROR_M, ERROR_DEG]])
    return run.rows, run.undo


def usual_run(solver: 'TranslatorSolver', wrenches: np.ndarray) -> Optional[Run]:
    """
    Solve the usual warm rows at the head of ``wrenches`` (n, 6) in one compiled call.

    The solver is left as that many ``solve`` calls leave it; the warm step taken at the
    row that stopped the run is handed to that row's solve (``PathState.handed_over``).
    None (nothing done) when the solver's state is not that of a usual warm row: a fast,
    judged solver on the default path, not at kept refined steps, with a stored
    factorization whose stable verdict (margin at least stability.CLOSE_BRANCH_MARGIN) the next
    solve would keep.
    """
    state, verdicts, problem = solver._state, solver._verdicts, solver.problem
    verdict, previous, pose = verdicts.verdict, state.previous, state.pose
    if (verdict is None or not verdict.stable or verdict.margin < CLOSE_BRANCH_MARGIN
            or verdicts.verdict_lu is not state.lu or state.lu is None or pose is None
            or pose[0] is None or previous is None or verdicts.origin is None
            or not solver.judge or solver.method != 'fast' or solver.path != 'default'
            or solver._refinements.kept is not None):
        return None
    count = state.path_count if state.path_last is previous[0] else 0
    target = solver.accuracy
    checks = Checks(pose[1], verdicts.origin.length, LOAD_FLOOR * load_scale(verdicts.origin),
                    min(STALE_WRENCH, 0.5 * verdict.margin), target.position_m,
                    target.angle_deg)
    run = warm_rows(problem, previous, (state.path_xs, state.path_wrenches, count),
                    wrenches, state.lu, pose[0],
                    warm_settings(state, solver.tolerance, solver.max_iterations, True), checks)
    if run.stopped_at is not None:  # the solve of the row that stopped it goes on from there
        state.handed_over = (wrenches[run.rows], *run.stopped_at)
    if run.rows == 0:
        return run
    state.previous = run.previous
    state.path_count, state.path_last = run.path_count, run.previous[0]
    state.exact_at = None
    last = run.answers[-1]
    solver._refinements.last_estimate = ErrorEstimate(
        float(last[ERROR_M]), float(last[ERROR_RAD]), problem.params.steps_per_segment,
        run.coarse_steps)
    return run


def solve_warm(solver: 'TranslatorSolver', wrench: np.ndarray, started: float,
               compliance_options: dict) -> SolveResult:
    """
    Return ``solver.solve``'s warm result at ``wrench`` (no compliance, no verification).

    A usual warm row is one compiled call (``usual_solve``, the batch's row; no BLAS in it,
    so no thread limit to set); any other goes on from the warm step that call took.
    """
    usual, undo = solver._usual_solve(wrench, started)
    if usual is not None:
        return usual
    try:
        return solver._solve(wrench, started, True, False, False, compliance_options)
    finally:
        if undo is not None and solver._state.handed_over is not None:
            undo()  # the solve did not go on from the step: as if never taken
        solver._state.handed_over = None


def usual_solve(solver: 'TranslatorSolver', wrench: np.ndarray, started: float
                ) -> Tuple[Optional[SolveResult], Optional[Callable[[], None]]]:
    """
    Return ``solver.solve``'s result at ``wrench`` when it is a usual warm row.

    The row is one compiled call (``usual_run``); its result is the one the whole solve
    gives (the same step, kept verdict and estimate). Else (None, undo): the general
    solve goes on from the warm step taken (``PathState.handed_over``), and ``undo``
    (when a step was taken) puts the Broyden updates back if that solve does not.
    """
    run = usual_run(solver, wrench.reshape(1, 6))
    if run is None or run.rows == 0:
        return None, None if run is None else run.undo
    problem = solver.problem
    iterations, slot, residual, report = run.last_step
    points, frames = problem.recorded_shape(slot)
    verdict, estimate = solver._verdicts.verdict, solver._refinements.last_estimate
    assert verdict is not None and estimate is not None  # usual_run's conditions
    return SolveResult(
        True, 'converged', iterations, residual_norm(residual), residual_by_kind(report),
        wrench[:3].copy(), wrench[3:].copy(),
        {'pe': frames[0], 'pm': frames[1], 'dm': frames[2], 'de': frames[3]}, points,
        time.perf_counter() - started, solver.method, run.previous[0] * problem.x_scale,
        stable=verdict.stable, stability_margin=verdict.margin,
        error_estimate_m=estimate.position_m, error_estimate_deg=estimate.angle_deg,
        accuracy_met=True, steps_per_segment=problem.params.steps_per_segment), None


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
    analysis: Optional[ComplianceAnalysis] = None
    message = ''
    if compliance:
        try:
            analysis = compliance_at(solver, outcome, wrench, frames[3][:3, :3])
        except ArithmeticError as error:
            message = f'{outcome.message}; no compliance: {error}'
    details = SolveDetails(outcome.iterations, residual_norm(outcome.rs), verdict.stable,
                           verdict.margin, solver.problem.params.steps_per_segment,
                           solver.method, message or outcome.message, analysis)
    batch.record_pose(row, frames, verdict.stable, estimate,
                      None if analysis is None else analysis.matrix, message, details=details)
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
