"""
Cost of the compliance for bench.speed_vs_error: implicit, by finite differences, reduced.

The implicit compliance after cold solves of the scenes and along warm solves of the
sequence, the finite-difference check, the reduced levels' central differences of their own
solves, and the linear level's expansion about a new cached solution.
"""

import statistics
import time
from typing import Mapping, Tuple

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.analysis.compliance import ComplianceAnalysis
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.solve.result import SolveResult
from cdr_translator.studies.finite_difference import finite_difference_compliance
import numpy as np


def computed_compliance(result: SolveResult) -> ComplianceAnalysis:
    """Return the compliance a solve with ``compliance=True`` computed (RuntimeError if none)."""
    if result.compliance is None:
        raise RuntimeError(f'no compliance: {result.message}')
    return result.compliance


def compliance_time_s(result: SolveResult) -> float:
    """
    Return the time of a solve's compliance and of its analysis (s).

    The compliance's ``time_s`` is C's own; its primary-mobility analysis is made when first
    read, so it is read and timed here: a compliance subscriber pays for both.
    """
    analysis = computed_compliance(result)
    started = time.perf_counter()
    _ = analysis.eigenvalues, analysis.smallest_stiffness_eigenvalue  # made when first read
    return analysis.time_s + time.perf_counter() - started


def compliance_costs(params: TranslatorParams, scenes: Mapping[str, Tuple[float, ...]],
                     sequence: np.ndarray) -> dict:
    """Cost of C: implicit after cold solves of ``scenes`` and along warm ones, the others."""
    solver = TranslatorSolver(params)
    cold, cold_solve = [], []
    for name in scenes:
        solver.reset()
        result = solver.solve(scenes[name][:3], scenes[name][3:], compliance=True)
        cold.append(compliance_time_s(result))
        cold_solve.append(result.solve_time_s)
    warm, warm_solve = [], []
    for wrench in sequence[:200]:
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
        warm.append(compliance_time_s(result))
        warm_solve.append(result.solve_time_s)
    started = time.perf_counter()
    finite_difference_compliance(params, scenes['paper 12 N'][:3])
    finite = time.perf_counter() - started
    reduced = {}
    for level in ('cc', 'rod'):
        model = FidelitySolver(params, fidelity=level)
        times = [compliance_time_s(model.solve(w[:3], w[3:], compliance=True))
                 for w in sequence[:100]]
        reduced[level] = statistics.median(times)
    tangent = FidelitySolver(params, fidelity='linear')
    builds = []
    for wrench in sequence[::100]:
        tangent.cache_full_solution(wrench)
        builds.append(tangent.tangent.build_time_s)
    return {'implicit_after_cold_median_s': statistics.median(cold),
            'cold_solve_median_s': statistics.median(cold_solve),
            'implicit_along_sequence_median_s': statistics.median(warm),
            'warm_solve_median_s': statistics.median(warm_solve),
            'finite_difference_s': finite, 'reduced_median_s': reduced,
            'linear_tangent_build_median_s': statistics.median(builds)}
