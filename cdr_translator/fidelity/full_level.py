"""
The 'full' level: the paper's model (TranslatorSolver) behind the level protocol (level.py).

Its answers judge themselves (stability verdict, error estimate and refinement:
TranslatorSolver.solve); a run of rows is the full model's batch rows
(TranslatorSolver.solve_batch_rows: runs of usual warm rows in one compiled call), which
equal its single solves.
"""

from typing import Any, Dict, Mapping

import numpy as np

from .level import Asked, run_rows, tail
from ..analysis.compliance import compliance_analysis, ComplianceAnalysis
from ..solve.batch import BatchResult
from ..solve.result import SolveResult
from ..solve.solver import TranslatorSolver


class FullLevel:
    """The full model as a level; the TranslatorSolver keeps its own state."""

    name = 'full'

    def __init__(self, solver: TranslatorSolver) -> None:
        """Answer with ``solver``."""
        self.solver = solver

    def solve(self, wrench: np.ndarray, compliance: bool, options: Mapping[str, float],
              asked: Asked) -> SolveResult:
        """Solve the full model at ``wrench`` (warm from its last solution)."""
        result = self.solver.solve(wrench[:3], wrench[3:], compliance=compliance,
                                   **_analysis_options(options))
        result.message += tail('full', asked.reason)
        return result

    def solve_many(self, wrenches: np.ndarray, rows: range, batch: BatchResult,
                   compliance: bool, asked: Asked) -> int:
        """Answer ``rows``: several in one run of the full model's rows, one by its row."""
        if len(rows) > 1:
            self.solver.solve_batch_rows(batch, wrenches, rows, compliance)
            suffix = tail('full', asked.reason)
            for row in rows:
                if batch.message[row]:
                    batch.message[row] += suffix
                batch.solve_message[row] += suffix
        else:
            run_rows('full', asked, wrenches, rows, batch, compliance,
                     self.solver.solve_batch_row)
        return len(rows)

    def compliance(self, answer: SolveResult,
                   options: Mapping[str, float]) -> ComplianceAnalysis:
        """Return the implicit compliance at a converged ``answer`` (compliance.py)."""
        problem = self.solver.problem
        wrench = np.concatenate([answer.force, answer.moment])
        return compliance_analysis(problem, answer.unknowns / problem.x_scale, wrench,
                                   rotation=answer.frames['de'][:3, :3],
                                   **_analysis_options(options))[0]

    def reset(self) -> None:
        """Forget the full model's last solution."""
        self.solver.reset()


def _analysis_options(options: Mapping[str, float]) -> Dict[str, Any]:
    """Return the compliance-analysis options (compliance.analyse's keywords) to pass on."""
    return dict(options)
