"""
The seam between the fidelity front (and 'auto') and each level: one Protocol.

A level ('full': full_level, 'rod' and 'cc': reduced_level, 'linear': linear_level)
answers one wrench (``solve``), a run of rows of a batch (``solve_many``) and gives the
end-disk compliance of an answer it gave (``compliance``). It owns its memory (warm
starts, the expansion) and ``reset`` forgets it. What the caller asks with each call
travels in an ``Asked``: why the level was chosen (the tail of each answer's message), how
answers below the full model are judged (verdicts.Judge), the errors 'auto' validated for
them and the time limit. ``run_rows`` is the loop the levels share for rows answered one at
a time.
"""

from typing import Mapping, NamedTuple, Optional, Protocol

import numpy as np

from .verdicts import Judge
from ..analysis.compliance import ComplianceAnalysis
from ..solve.batch import BatchResult, RowSolver
from ..solve.result import SolveResult


class Asked(NamedTuple):
    """What a caller asks of a level with one call (arguments, never set on the level)."""

    #: why the level answers: ends each answer's message as ``[level: reason]``
    reason: str
    #: verdicts and budget for answers below the full model
    judge: Judge
    #: cap of one solve (s)
    time_limit_s: float
    #: errors (m, deg) 'auto' validated for the answers: (2,) for ``solve``, (len(rows), 2)
    #: for ``solve_many``; None: not estimated
    estimates: Optional[np.ndarray] = None
    #: ``solve_many`` of a reduced level: stop at the first row the level fails, unanswered
    stop_at_failure: bool = False

    def with_estimates(self, estimates: Optional[np.ndarray]) -> 'Asked':
        """Return the same ask with ``estimates`` in place of this one's."""
        return Asked(self.reason, self.judge, self.time_limit_s, estimates,
                     self.stop_at_failure)


class Level(Protocol):
    """What the front and 'auto' use of a fidelity level."""

    #: the level's name, as ``SolveResult.fidelity`` says it
    name: str

    def solve(self, wrench: np.ndarray, compliance: bool, options: Mapping[str, float],
              asked: Asked) -> SolveResult:
        """Answer ``wrench`` (6,), with its compliance when asked (``options``: analyse's)."""

    def solve_many(self, wrenches: np.ndarray, rows: range, batch: BatchResult,
                   compliance: bool, asked: Asked) -> int:
        """Answer ``rows`` of ``wrenches`` into ``batch`` as ``solve`` calls would; how many."""

    def compliance(self, answer: SolveResult,
                   options: Mapping[str, float]) -> ComplianceAnalysis:
        """Return the end-disk compliance of an ``answer`` this level gave."""

    def reset(self) -> None:
        """Forget the level's memory: the next answer starts cold."""


def tail(level: str, reason: str) -> str:
    """Return the tail ``[level: reason]`` every answer's message ends with."""
    return f' [{level}: {reason}]'


def run_rows(level: str, asked: Asked, wrenches: np.ndarray, rows: range, batch: BatchResult,
             compliance: bool, solve_row: RowSolver, whole: bool = False) -> None:
    """
    Answer ``rows`` one by one with ``solve_row`` (BatchResult.run's row function).

    Each row's messages end as a single answer's: a converged row below the full model is
    judged (``asked.judge``, with ``asked.estimates`` aligned with ``rows``) and says where
    its verdict comes from, then the tail. ``whole``: the row function records a whole
    answer, whose message already ends so.
    """
    for row in rows:
        batch.fidelity[row] = level  # what a row that raises was tried at
        batch.run(row, solve_row, wrenches[row], compliance)
        if whole:
            continue
        suffix = tail(str(batch.fidelity[row]), asked.reason)
        if level != 'full' and batch.converged[row]:
            offset = row - rows.start
            estimates = (None if asked.estimates is None
                         else asked.estimates[offset:offset + 1])
            asked.judge.rows(batch, wrenches, np.array([row]), estimates)
            suffix = asked.judge.note(level, wrenches[row]) + suffix
        batch.solve_message[row] += suffix
        if batch.message[row]:
            batch.message[row] += suffix
