"""
The 'rod' and 'cc' levels: a reduced model (reduced.py) behind the level protocol (level.py).

A level owns its warm start, the last solution it converged to. A single answer continues
from it (or from the unloaded state where that is nearer), restarting from the unloaded
state when the warm start fails; its compliance is central differences of its own solves.
A run of rows without compliance goes through the model's compiled sequence
(``ReducedModel.continue_sequence``): one call for many rows, each row what ``solve``
gives, and the level left as those solves would leave it.
"""

from functools import partial
import math
import time
from typing import Mapping, Optional, Tuple

import numpy as np

from .level import Asked, run_rows, tail
from .reduced import ReducedModel, ReducedOutcome
from .validation import box_scale, box_scales
from ..analysis.compliance import analyse, analysis_options, ComplianceAnalysis, frame_twist
from ..solve.batch import BatchResult, SolveDetails
from ..solve.result import FRAME_NAMES, SolveResult

#: Wrench steps of the finite-difference compliance of a reduced level (N, N m).
COMPLIANCE_STEPS = (1e-3, 1e-4)

#: A compiled run has no deadline of its own: it is used when the time limit is at least
#: this (s), far above the microseconds between a single solve's start and its deadline check.
COMPILED_RUN_MIN_TIME_LIMIT_S = 1e-3

#: Cap of the finite-difference compliance's solves (s).
COMPLIANCE_TIME_LIMIT_S = 10.0


def compiled_runs(time_limit_s: float) -> bool:
    """Whether runs at a reduced level go through its compiled sequence (see the constant)."""
    return time_limit_s >= COMPILED_RUN_MIN_TIME_LIMIT_S


class ReducedLevel:
    """A reduced model as a level, with its warm start."""

    def __init__(self, model: ReducedModel, characteristic_length: float) -> None:
        """Answer with ``model``; compliance analysed at ``characteristic_length`` (m)."""
        self.model = model
        self.name = model.name
        self.characteristic_length = characteristic_length
        #: (unknowns, wrench) of the last converged solve, the next warm start (None: cold)
        self.previous: Optional[Tuple[np.ndarray, np.ndarray]] = None

    def reset(self) -> None:
        """Forget the warm start."""
        self.previous = None

    # single answers ---------------------------------------------------------------------------
    def solve(self, wrench: np.ndarray, compliance: bool, options: Mapping[str, float],
              asked: Asked) -> SolveResult:
        """Answer ``wrench``: the outcome, its compliance when asked, judged (level.py)."""
        outcome, elapsed = self.outcome(wrench, asked.time_limit_s)
        result = self.result(outcome, wrench, elapsed)
        if compliance and outcome.converged:
            result.compliance, failure = self._compliance_of(outcome, wrench, options)
            result.message += failure
        if result.converged:
            asked.judge.answer(result, wrench, asked.estimates)
        result.message += tail(self.name, asked.reason)
        return result

    def outcome(self, wrench: np.ndarray, time_limit_s: float) -> Tuple[ReducedOutcome, float]:
        """Solve from the warm start (or unloaded); (outcome, time)."""
        model = self.model
        started = time.perf_counter()
        start = self.previous
        if start is not None and box_scale(wrench - start[1]) > box_scale(wrench):
            start = None  # the unloaded state is nearer than the last solution
        outcome = model.solve(wrench, start, started + time_limit_s)
        if not outcome.converged and start is not None:
            # the warm start may sit too far away: restart from the unloaded state
            restart = model.solve(wrench, None, started + time_limit_s)
            restart.iterations += outcome.iterations
            if restart.converged:
                outcome = restart
        elapsed = time.perf_counter() - started
        if outcome.converged:
            self.previous = (outcome.x, wrench)
        return outcome, elapsed

    def result(self, outcome: ReducedOutcome, wrench: np.ndarray,
               elapsed: float) -> SolveResult:
        """Return an outcome's result; its shape and residual dictionary made when read."""
        model, x, rs = self.model, outcome.x, outcome.rs
        return SolveResult.deferred(
            {'frames': lambda: dict(zip(FRAME_NAMES, model.frames(x, wrench))),
             'backbones': lambda: model.points(x, wrench),
             'residual_by_type': lambda: model.residual_by_kind(rs)},
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, residual_norm=float(np.sqrt(rs @ rs)),
            force=wrench[:3].copy(), moment=wrench[3:].copy(), solve_time_s=elapsed,
            method='fast', unknowns=x * model.unknown_scale, fidelity=self.name)

    def compliance(self, answer: SolveResult,
                   options: Mapping[str, float]) -> ComplianceAnalysis:
        """Return the central-difference compliance at a converged ``answer`` of this level."""
        return finite_difference_compliance(
            self.model, answer.unknowns / self.model.unknown_scale,
            np.concatenate([answer.force, answer.moment]), self.characteristic_length,
            options)

    def _compliance_of(self, outcome: ReducedOutcome, wrench: np.ndarray,
                       options: Mapping[str, float]
                       ) -> Tuple[Optional[ComplianceAnalysis], str]:
        """(compliance of a converged outcome, or None and the message tail saying why)."""
        try:
            analysis: Optional[ComplianceAnalysis] = finite_difference_compliance(
                self.model, outcome.x, wrench, self.characteristic_length, options)
            failure = ''
        except ArithmeticError as error:
            analysis, failure = None, f'; no compliance: {error}'
        self.previous = (outcome.x, wrench)  # the differences moved the model
        return analysis, failure

    # runs of rows -------------------------------------------------------------------------------
    def solve_many(self, wrenches: np.ndarray, rows: range, batch: BatchResult,
                   compliance: bool, asked: Asked) -> int:
        """
        Answer ``rows``: compiled sequences without compliance, else row by row.

        With ``asked.stop_at_failure`` the run ends at the first row the level fails,
        unanswered ('auto' tries the next level there). Returns the rows answered.
        """
        if not compliance and compiled_runs(asked.time_limit_s):
            return self._compiled_run(wrenches, rows, batch, asked)
        run_rows(self.name, asked, wrenches, rows, batch, compliance,
                 partial(self._row, time_limit_s=asked.time_limit_s))
        return len(rows)

    def _compiled_run(self, wrenches: np.ndarray, rows: range, batch: BatchResult,
                      asked: Asked) -> int:
        """
        Answer a run in compiled sequences, as row-by-row solves would.

        A single solve starts from the unloaded state where that is nearer than the last
        solution (``outcome``): each such row begins a new sequence. A row that fails ends
        its sequence and is solved again by the row function, from the state the rows
        before it left, for its message (or, with ``stop_at_failure``, ends the run).
        """
        model = self.model
        estimates = asked.estimates
        run = wrenches[rows.start:rows.stop]
        scales = box_scales(run)
        # rows (of the run) whose single solve starts cold: the unloaded state is nearer
        cold = np.flatnonzero(box_scales(np.diff(run, axis=0)) > scales[1:]) + 1
        first = 0
        while first < len(run):
            start = self.previous
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
                answered = np.arange(rows.start + first, rows.start + first + converged)
                batch.record_poses(slice(answered[0], answered[-1] + 1), pose, bending,
                                   self.name, elapsed / converged)
                asked.judge.rows(batch, wrenches, answered,
                                 None if estimates is None else estimates[solved])
                last = first + converged - 1
                self.previous = (unknowns[converged - 1].copy(), run[last].copy())
            first += converged
            if first < stop and asked.stop_at_failure:
                return first
            if first < stop:  # this row failed: its own solve gives its message
                row = rows.start + first
                one = asked.with_estimates(None if estimates is None
                                           else estimates[first:first + 1])
                run_rows(self.name, one, wrenches, range(row, row + 1), batch, False,
                         partial(self._row, time_limit_s=asked.time_limit_s))
                first += 1
        return first

    def _row(self, batch: BatchResult, row: int, wrench: np.ndarray, compliance: bool, *,
             time_limit_s: float) -> float:
        """Row of the level: its frames, or its result when it is not a good row."""
        outcome, elapsed = self.outcome(wrench, time_limit_s)
        analysis, failure = (self._compliance_of(outcome, wrench, {})
                             if compliance and outcome.converged else (None, ''))
        if not outcome.converged or failure:
            result = self.result(outcome, wrench, elapsed)
            result.message += failure
            batch.record(row, result)
            return elapsed
        details = SolveDetails(outcome.iterations, float(np.sqrt(outcome.rs @ outcome.rs)),
                               None, math.nan, 0, 'fast', outcome.message, analysis)
        batch.record_pose(row, self.model.frames(outcome.x, wrench),
                          None if analysis is None else analysis.stable, None,
                          None if analysis is None else analysis.matrix, fidelity=self.name,
                          details=details)
        return elapsed


def finite_difference_compliance(model: ReducedModel, x: np.ndarray, wrench: np.ndarray,
                                 characteristic_length: float,
                                 options: Mapping[str, float]) -> ComplianceAnalysis:
    """Compliance of a reduced model by central differences of its own solves."""
    started = time.perf_counter()
    matrix = np.empty((6, 6))
    deadline = started + COMPLIANCE_TIME_LIMIT_S
    for column in range(6):
        offset = np.zeros(6)
        offset[column] = COMPLIANCE_STEPS[column // 3]
        ends = []
        for sign in (1.0, -1.0):
            outcome = model.solve(wrench + sign * offset, (x, wrench), deadline)
            if not outcome.converged:
                raise ArithmeticError(f'{model.name} compliance solve failed: {outcome.message}')
            ends.append(model.frames(outcome.x, wrench + sign * offset)[3])
        matrix[:, column] = frame_twist(ends[1], ends[0]) / (2.0 * offset[column])
    return analyse(matrix, characteristic_length, method=f'{model.name} finite differences',
                   time_s=time.perf_counter() - started, **analysis_options(options))
