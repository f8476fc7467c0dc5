"""
Per-answer kernel time of each fidelity level along the 1000-wrench sequence.

Usage: python -m bench.level_kernels [--repeats N]

Times the compiled batch entries (fidelity.level_kernels' sequence solves with their poses,
fidelity.linear_kernels' predictions) on bench.speed_vs_error's wrench sequence and prints
them with their ratio to the full model's warm solve (TranslatorSolver.solve along the same
sequence) measured in the same run: the machine is shared, so only ratios compare runs.
"""

import argparse
import functools
import statistics
import time
from typing import Callable, Dict

from bench.speed_vs_error import wrench_sequence
from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.fidelity.reduced import ReducedModel
import numpy as np


def _best_per_answer(run: Callable[[], object], count: int, repeats: int) -> float:
    """Smallest of ``repeats`` timings of ``run`` (s), divided by ``count`` answers."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        run()
        times.append(time.perf_counter() - started)
    return min(times) / count


def full_warm(params: TranslatorParams, sequence: np.ndarray) -> float:
    """Median time (s) of the full model's warm solves along the sequence."""
    solver = TranslatorSolver(params)
    times = []
    for wrench in sequence:
        started = time.perf_counter()
        result = solver.solve(wrench[:3], wrench[3:])
        times.append(time.perf_counter() - started)
        if not result.converged:
            raise RuntimeError(f'full model failed at {wrench}: {result.message}')
    return statistics.median(times)


def _solve_and_pose(model: ReducedModel, sequence: np.ndarray) -> object:
    """Solve the sequence with a reduced model's compiled loop and compute its poses."""
    return model.poses(sequence, model.solve_sequence(sequence)[0])


def level_times(params: TranslatorParams, sequence: np.ndarray, repeats: int) -> Dict[str, float]:
    """Per-answer kernel time (s) of 'cc', 'rod' (solve and pose) and 'linear'."""
    solver = FidelitySolver(params, fidelity='full')
    result = {}
    for level, model in solver.reduced.items():
        unknowns, _, status, _ = model.solve_sequence(sequence)
        if np.any(status != 0):
            raise RuntimeError(f'{level}: {np.count_nonzero(status)} rows failed')
        result[level] = _best_per_answer(functools.partial(_solve_and_pose, model, sequence),
                                         len(sequence), repeats)
    solver.cache_full_solution(sequence[0])
    result['linear'] = _best_per_answer(lambda: solver.tangent.poses(sequence),
                                        len(sequence), repeats)
    return result


def main() -> None:
    """Measure and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--repeats', type=int, default=5, help='timed runs per level')
    args = parser.parse_args()
    params = TranslatorParams.from_yaml()
    sequence = wrench_sequence()
    levels = level_times(params, sequence, args.repeats)
    full = full_warm(params, sequence)
    print(f'{len(sequence)}-wrench sequence, per answer (kernel, warm along the sequence)')
    print('| level | µs per answer | against full warm |')
    print('|---|---|---|')
    print(f'| full (TranslatorSolver.solve, median) | {1e6 * full:.1f} | 1 |')
    for level, seconds in levels.items():
        print(f'| {level} | {1e6 * seconds:.2f} | 1/{full / seconds:.0f} |')


if __name__ == '__main__':
    main()
