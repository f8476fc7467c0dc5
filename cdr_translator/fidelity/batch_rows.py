"""
Runs of rows of ``FidelitySolver.solve_many``: rows chosen at one level, in order.

A run at 'cc' or 'rod' without compliance goes through the level's compiled sequence
(``ReducedModel.continue_sequence``) and a run at 'linear' through the compiled poses of the
expansion (``TangentModel.poses``): one call for many rows, each row what ``solve`` gives,
and the solver left as those solves would leave it; a run at 'full' goes through the full
model's rows (``lean_rows.solve_rows``: runs of usual warm rows in one compiled call). Any
other row is solved by a row function (``RowSolver``): a reduced or linear row without a
SolveResult, or a whole ``solve`` where the level choice needs one.
"""

from functools import partial
import math
import time
from typing import Optional, TYPE_CHECKING

import numpy as np

from .validation import box_scale, box_scales
from .verdicts import carried_rows, note
from .. import lean_rows
from ..batch import BatchResult, RowSolver, SolveDetails
from ..compliance import ComplianceAnalysis

if TYPE_CHECKING:
    from .solver import FidelitySolver

#: A compiled run has no deadline of its own: it is used when the time limit is at least
#: this (s), far above the microseconds between a single solve's start and its deadline check.
COMPILED_RUN_MIN_TIME_LIMIT_S = 1e-3


def compiled_runs(solver: 'FidelitySolver') -> bool:
    """Whether runs at a reduced level go through its compiled sequence (see the constant)."""
    return solver.time_limit_s >= COMPILED_RUN_MIN_TIME_LIMIT_S


def solve_run(solver: 'FidelitySolver', level: str, reason: str, wrenches: np.ndarray,
              rows: range, batch: BatchResult, compliance: bool,
              estimates: Optional[np.ndarray] = None) -> None:
    """
    Solve ``rows`` of ``wrenches``, all chosen at ``level`` for ``reason``.

    ``estimates`` (len(rows), 2: m, deg): the reduced rows' errors as 'auto' validated them
    (``FidelitySolver._solve_at``'s); None: not estimated.
    """
    if level in solver.reduced and not compliance and compiled_runs(solver):
        _reduced_run(solver, level, reason, wrenches, rows, batch, estimates=estimates)
    elif level == 'linear' and solver.tangent.ready:
        _linear_run(solver, reason, wrenches, rows, batch, compliance, estimates)
    else:
        _rows(solver, level, reason, wrenches, rows, batch, compliance, estimates)


def judge_rows(solver: 'FidelitySolver', wrenches: np.ndarray, rows: np.ndarray,
               batch: BatchResult, estimates: Optional[np.ndarray]) -> None:
    """
    Give converged reduced ``rows`` their carried verdicts and estimates (verdicts.py).

    As ``FidelitySolver._judge_reduced`` gives a single answer them: a carried verdict wins
    over the compliance's in ``stable``; ``estimates`` (len(rows), 2) or None.
    """
    references = solver.verdict_references()
    chosen = carried_rows(wrenches[rows], references, solver.load_scale,
                          solver.params.stack_height)
    converged = batch.converged[rows].astype(bool)
    for index, reference in enumerate(references):
        judged = rows[converged & (chosen == index)]
        batch.stable[judged] = batch.verdict[judged] = reference.stable
        batch.stability_margin[judged] = reference.margin
    if estimates is not None:
        met = ((estimates[:, 0] <= solver.max_position_error)
               & (estimates[:, 1] <= solver.max_angle_error_deg))
        batch.error_estimate_m[rows[converged]] = estimates[converged, 0]
        batch.error_estimate_deg[rows[converged]] = estimates[converged, 1]
        batch.accuracy_met[rows[converged]] = [bool(value) for value in met[converged]]


def _rows(solver: 'FidelitySolver', level: str, reason: str, wrenches: np.ndarray,
          rows: range, batch: BatchResult, compliance: bool,
          estimates: Optional[np.ndarray] = None) -> None:
    """Solve ``rows`` one by one with the row function of ``level``."""
    whole = False
    solve_row: RowSolver
    if level in solver.reduced:
        solve_row = partial(_reduced_row, solver, level)
    elif level == 'linear' and solver.tangent.ready:
        solve_row = partial(_linear_row, solver)
    elif level == 'full':
        if len(rows) > 1:  # the fixed 'full' level: one run (in 'auto' a run is one row)
            _full_rows(solver, reason, wrenches, rows, batch, compliance)
            return
        solve_row = partial(lean_rows.solve_row, solver.full)
    else:  # 'linear' without an expansion: the row makes one
        solve_row, whole = partial(_result_row, solver, level, reason), True
    for row in rows:
        batch.fidelity[row] = level  # what a row that raises was tried at
        batch.run(row, solve_row, wrenches[row], compliance)
        if not whole:  # a whole solve's message names its level
            suffix = f' [{batch.fidelity[row]}: {reason}]'
            if level != 'full' and batch.converged[row]:
                judge_rows(solver, wrenches, np.array([row]), batch,
                           None if estimates is None else estimates[row - rows.start:][:1])
                suffix = note(level, solver.carried_verdict(wrenches[row])) + suffix
            batch.solve_message[row] += suffix
            if batch.message[row]:
                batch.message[row] += suffix
        solver._last_wrench = wrenches[row]
        solver._last_level = str(batch.fidelity[row])


def reduced_run_to_failure(solver: 'FidelitySolver', level: str, wrenches: np.ndarray,
                           rows: range, batch: BatchResult,
                           estimates: Optional[np.ndarray] = None) -> int:
    """
    Solve the rows of a run at a reduced level up to the first that fails; how many.

    That row is left unsolved, the solver as the rows before it left it: 'auto' tries the
    next level there. Without compliance, the level's compiled run (``compiled_runs``).
    """
    return _reduced_run(solver, level, '', wrenches, rows, batch, stop_at_failure=True,
                        estimates=estimates)


def _reduced_run(solver: 'FidelitySolver', level: str, reason: str, wrenches: np.ndarray,
                 rows: range, batch: BatchResult, stop_at_failure: bool = False,
                 estimates: Optional[np.ndarray] = None) -> int:
    """
    Solve a run at a reduced level in compiled sequences, as row-by-row solves would.

    A single solve starts from the unloaded state where that is nearer than the last
    solution (``FidelitySolver._reduced_outcome``): each such row begins a new sequence. A
    row that fails ends its sequence and is solved again by the row function, from the
    state the rows before it left, for its message; with ``stop_at_failure`` the run ends
    there instead. Returns the number of rows solved. ``estimates``: ``solve_run``'s.
    """
    model = solver.reduced[level]
    run = wrenches[rows.start:rows.stop]
    scales = box_scales(run)
    # rows (of the run) whose single solve starts cold: the unloaded state is nearer
    cold = np.flatnonzero(box_scales(np.diff(run, axis=0)) > scales[1:]) + 1
    first = 0
    while first < len(run):
        start = solver._previous[level]
        if start is not None and box_scale(run[first] - start[1]) > scales[first]:
            start = None
        later = cold[cold > first]
        stop = int(later[0]) if len(later) else len(run)
        started = time.perf_counter()
        unknowns, converged = model.continue_sequence(run[first:stop], start)
        if converged:
            solved = slice(first, first + converged)
            pose, bending = model.poses(run[solved], unknowns[:converged])
            elapsed = time.perf_counter() - started
            batch.record_poses(slice(rows.start + first, rows.start + first + converged),
                               pose, bending, level, elapsed / converged)
            judge_rows(solver, wrenches,
                       np.arange(rows.start + first, rows.start + first + converged), batch,
                       None if estimates is None else estimates[first:first + converged])
            last = first + converged - 1
            solver._previous[level] = (unknowns[converged - 1].copy(), run[last].copy())
            solver._last_wrench, solver._last_level = run[last], level
        first += converged
        if first < stop and stop_at_failure:
            return first
        if first < stop:  # this row failed: its own solve gives its message
            row = rows.start + first
            _rows(solver, level, reason, wrenches, range(row, row + 1), batch, False,
                  None if estimates is None else estimates[first:first + 1])
            first += 1
    return first


def _linear_run(solver: 'FidelitySolver', reason: str, wrenches: np.ndarray, rows: range,
                batch: BatchResult, compliance: bool,
                estimates: Optional[np.ndarray] = None) -> None:
    """Solve a run at 'linear' by the compiled poses; its compliance is the cached one's."""
    analysis: Optional[ComplianceAnalysis] = None
    if compliance:
        try:
            analysis = solver.tangent.compliance()
        except ArithmeticError:
            analysis = None
        if analysis is None or not analysis.stable:  # rows that are not good: one by one
            _rows(solver, 'linear', reason, wrenches, rows, batch, compliance, estimates)
            return
    started = time.perf_counter()
    pose, bending = solver.tangent.poses(wrenches[rows.start:rows.stop])
    elapsed = time.perf_counter() - started
    batch.record_poses(slice(rows.start, rows.stop), pose, bending, 'linear',
                       elapsed / len(rows), None if analysis is None else analysis.stable,
                       None if analysis is None else analysis.matrix)
    judge_rows(solver, wrenches, np.arange(rows.start, rows.stop), batch, estimates)
    solver._last_wrench, solver._last_level = wrenches[rows[-1]], 'linear'


def _result_row(solver: 'FidelitySolver', level: str, reason: str, batch: BatchResult,
                row: int, wrench: np.ndarray, compliance: bool) -> float:
    """Row by a whole ``solve`` at ``level``."""
    result = solver._solve_at(level, reason, wrench, compliance, {})
    batch.record(row, result)
    return result.solve_time_s


def _full_rows(solver: 'FidelitySolver', reason: str, wrenches: np.ndarray, rows: range,
               batch: BatchResult, compliance: bool) -> None:
    """Rows of the full level in one run (TranslatorSolver's lean_rows.solve_rows)."""
    lean_rows.solve_rows(solver.full, batch, wrenches, rows, compliance)
    for row in rows:
        if batch.message[row]:
            batch.message[row] += f' [full: {reason}]'
        batch.solve_message[row] += f' [full: {reason}]'
        solver._last_wrench = wrenches[row]
        solver._last_level = 'full'


def _linear_row(solver: 'FidelitySolver', batch: BatchResult, row: int, wrench: np.ndarray,
                compliance: bool) -> float:
    """Row of the 'linear' level: the expansion's frames."""
    started = time.perf_counter()
    frames = solver.tangent.frames(wrench)
    elapsed = time.perf_counter() - started
    analysis = solver.tangent.compliance() if compliance else None
    batch.record_pose(row, frames, None if analysis is None else analysis.stable, None,
                      None if analysis is None else analysis.matrix, fidelity='linear')
    return elapsed


def _reduced_row(solver: 'FidelitySolver', level: str, batch: BatchResult, row: int,
                 wrench: np.ndarray, compliance: bool) -> float:
    """Row of a reduced level: its frames, or its result when it is not a good row."""
    outcome, elapsed = solver._reduced_outcome(level, wrench)
    analysis, failure = (solver._reduced_compliance(level, outcome, wrench, {})
                         if compliance and outcome.converged else (None, ''))
    if not outcome.converged or failure:
        result = solver._reduced_result(level, outcome, wrench, elapsed)
        result.message += failure
        batch.record(row, result)
        return elapsed
    details = SolveDetails(outcome.iterations, float(np.sqrt(outcome.rs @ outcome.rs)), None,
                           math.nan, 0, 'fast', outcome.message, analysis)
    batch.record_pose(row, solver.reduced[level].frames(outcome.x, wrench),
                      None if analysis is None else analysis.stable, None,
                      None if analysis is None else analysis.matrix, fidelity=level,
                      details=details)
    return elapsed
