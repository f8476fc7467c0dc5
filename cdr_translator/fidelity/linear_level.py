"""
The 'linear' level: the full model's first-order expansion (linear.py) behind the protocol.

The level owns the expansion and the verdict of the full solution it expands about (which
its answers, and the other reduced levels' near it, carry: verdicts.py). Without an
expansion an answer is a full solve that makes one (``expand``). A run of rows is the
expansion's compiled poses (``TangentModel.poses``); its compliance is the expansion's.
"""

from functools import partial
import time
from typing import Mapping, Optional

import numpy as np

from .level import Asked, run_rows, tail
from .linear import TangentModel
from .verdicts import FullVerdict
from ..analysis.compliance import ComplianceAnalysis
from ..bvp.problem import RESIDUAL_KINDS
from ..solve.batch import BatchResult
from ..solve.result import FRAME_NAMES, SolveResult
from ..solve.solver import TranslatorSolver


class LinearLevel:
    """The expansion about a full solution as a level."""

    name = 'linear'

    def __init__(self, full: TranslatorSolver) -> None:
        """Expand about solutions of ``full`` (its problem's tangent)."""
        self.full = full
        self.tangent = TangentModel(full.problem)
        #: the verdict of the full solution the expansion is about (None: no expansion)
        self.verdict: Optional[FullVerdict] = None

    @property
    def ready(self) -> bool:
        """Whether there is an expansion."""
        return self.tangent.ready

    def reset(self) -> None:
        """Forget the expansion."""
        self.tangent.clear()
        self.verdict = None

    # the expansion ------------------------------------------------------------------------------
    def expand(self, wrench: np.ndarray, compliance: bool,
               options: Mapping[str, float]) -> SolveResult:
        """Solve the full model at ``wrench`` and expand about its solution."""
        started = time.perf_counter()
        # warm start, compliance and verify given by position: the options are only floats
        result = self.full.solve(wrench[:3], wrench[3:], True, compliance, False, **options)
        self.expand_about(result, wrench)
        result.solve_time_s = time.perf_counter() - started
        return result

    def expand_about(self, result: SolveResult, wrench: np.ndarray) -> None:
        """Expand about a converged full ``result`` at ``wrench`` (its message says if not)."""
        if not result.converged:
            return
        try:
            self.tangent.build(result.unknowns / self.full.problem.x_scale, wrench)
        except ArithmeticError as error:
            self.reset()
            result.message += f'; no linear expansion here: {error}'
        else:
            self.verdict = None if result.stable is None else FullVerdict(
                wrench.copy(), bool(result.stable), float(result.stability_margin),
                f"the linear level's expansion point {self.tangent.origin_text}")

    # single answers ---------------------------------------------------------------------------
    def solve(self, wrench: np.ndarray, compliance: bool, options: Mapping[str, float],
              asked: Asked) -> SolveResult:
        """Answer by the expansion, judged (level.py); without one, a full solve makes it."""
        if not self.tangent.ready:
            result = self.expand(wrench, compliance, options)
            result.message += '; linear level: no cached solution yet, solved in full'
        else:
            result = self.answer(wrench, compliance, options)
            asked.judge.answer(result, wrench, asked.estimates)
        result.message += tail(result.fidelity, asked.reason)
        return result

    def answer(self, wrench: np.ndarray, compliance: bool,
               options: Mapping[str, float]) -> SolveResult:
        """Return the expansion's frames; its unknowns, points and dictionaries when read."""
        tangent = self.tangent
        started = time.perf_counter()
        frames = tangent.frames(wrench)
        elapsed = time.perf_counter() - started
        unknowns, points = tangent.unknowns_and_points(wrench)
        offset = max(map(abs, (wrench - tangent.origin).tolist()))
        # the level solves no equations: its residual is zero by construction
        result = SolveResult.deferred(
            {'frames': lambda: dict(zip(FRAME_NAMES, frames)), 'backbones': points,
             'unknowns': unknowns,
             'residual_by_type': lambda: dict.fromkeys(RESIDUAL_KINDS, 0.0)},
            converged=True, message=f'first-order expansion about the full solution at '
            f'{tangent.origin_text} (largest offset {offset:.3g})', iterations=0,
            residual_norm=0.0, force=wrench[:3].copy(), moment=wrench[3:].copy(),
            solve_time_s=elapsed, method='fast', fidelity='linear')
        if compliance:
            result.compliance = tangent.compliance(**options)
        return result

    def compliance(self, answer: SolveResult,
                   options: Mapping[str, float]) -> ComplianceAnalysis:
        """Return the compliance of the expansion (the level's, at every answer)."""
        return self.tangent.compliance(**options)

    # runs of rows -------------------------------------------------------------------------------
    def solve_many(self, wrenches: np.ndarray, rows: range, batch: BatchResult,
                   compliance: bool, asked: Asked) -> int:
        """
        Answer ``rows``: the compiled poses, or row by row.

        Row by row: without an expansion (each row a whole answer, the first makes one) or
        when the expansion's compliance is asked for and not good.
        """
        if not self.tangent.ready:
            run_rows(self.name, asked, wrenches, rows, batch, compliance,
                     partial(self._whole_row, asked), whole=True)
            return len(rows)
        analysis: Optional[ComplianceAnalysis] = None
        if compliance:
            try:
                analysis = self.tangent.compliance()
            except ArithmeticError:
                analysis = None
            if analysis is None or not analysis.stable:  # rows that are not good: one by one
                run_rows(self.name, asked, wrenches, rows, batch, compliance, self._row)
                return len(rows)
        started = time.perf_counter()
        pose, bending = self.tangent.poses(wrenches[rows.start:rows.stop])
        elapsed = time.perf_counter() - started
        batch.record_poses(slice(rows.start, rows.stop), pose, bending, 'linear',
                           elapsed / len(rows), None if analysis is None else analysis.stable,
                           None if analysis is None else analysis.matrix)
        asked.judge.rows(batch, wrenches, np.arange(rows.start, rows.stop), asked.estimates)
        return len(rows)

    def _whole_row(self, asked: Asked, batch: BatchResult, row: int, wrench: np.ndarray,
                   compliance: bool) -> float:
        """Row by a whole ``solve``."""
        result = self.solve(wrench, compliance, {}, asked.with_estimates(None))
        batch.record(row, result)
        return result.solve_time_s

    def _row(self, batch: BatchResult, row: int, wrench: np.ndarray,
             compliance: bool) -> float:
        """Row of the expansion: its frames."""
        started = time.perf_counter()
        frames = self.tangent.frames(wrench)
        elapsed = time.perf_counter() - started
        analysis = self.tangent.compliance() if compliance else None
        batch.record_pose(row, frames, None if analysis is None else analysis.stable, None,
                          None if analysis is None else analysis.matrix, fidelity='linear')
        return elapsed
