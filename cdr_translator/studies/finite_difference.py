"""
Finite-difference checks of what the solver computes analytically: the paper's way.

``finite_difference_compliance`` builds C from central differences of 12 loaded solves
(the paper's ref. [15]); cdr_translator.analysis.compliance computes it by implicit
differentiation, and the two agree to about 1e-8 relative (tests/analysis/test_compliance.py).
"""

import numpy as np
from numpy.typing import ArrayLike

from ..analysis.compliance import frame_twist
from ..params.translator_params import Accuracy, TranslatorParams
from ..solve.solver import TranslatorSolver


def finite_difference_compliance(params: TranslatorParams, force: ArrayLike,
                                 moment: ArrayLike = (0.0, 0.0, 0.0),
                                 force_step: float = 1e-3, moment_step: float = 1e-4,
                                 tolerance: float = 1e-12) -> np.ndarray:
    """
    C by central differences of 12 loaded solves around (force, moment): the check.

    Uses its own solver (warm-started along the 12 solves) so no caller's state changes.
    The default steps keep the truncation error (step^2) and the solve tolerance's share
    (tolerance / step) both near 1e-8 of C.
    """
    # one fixed discretization and branch for all 12 solves
    solver = TranslatorSolver(params, tolerance=tolerance, accuracy=Accuracy(0.0, 0.0),
                              follow_stable_branch=False)
    base = np.concatenate([np.asarray(force, float), np.asarray(moment, float)])

    def end_frame(wrench: np.ndarray) -> np.ndarray:
        result = solver.solve(wrench[:3], wrench[3:])
        if not result.converged:
            raise ArithmeticError(f'finite-difference solve at {wrench.tolist()} failed: '
                                  f'{result.message}')
        return result.frames['de']

    end_frame(base)
    compliance = np.empty((6, 6))
    for column in range(6):
        step = force_step if column < 3 else moment_step
        offset = np.zeros(6)
        offset[column] = step
        plus, minus = end_frame(base + offset), end_frame(base - offset)
        compliance[:, column] = frame_twist(minus, plus) / (2.0 * step)
    return compliance
