"""
Batch answers against a solve() loop, and the Python a single solve adds to its kernel.

Usage: python -m bench.solve_many [--count N]   (writes bench/results/solve_many.md)

Per level (full, cc, rod, linear, and auto at 1 mm / 0.5 deg), on speed_vs_error's smooth
wrench sequence, one run: the time per answer of ``solve()`` called once per wrench (median
and mean) and of one ``solve_many`` over the same wrenches (mean; each from a fresh
solver), and the ratio of the means. The overhead of a single warm solve is its time minus
the time spent inside the level's compiled kernel (the full model's warm step, the reduced
models' compiled continuation ``newton.continue_to``; for 'linear', whose kernel is the
expansion's frames, ``TangentModel.frames``), the median over the sequence: the kernels
are timed by wrapping them for the run.
"""

import argparse
from contextlib import contextmanager
import os
from pathlib import Path
import platform
import statistics
import time
from typing import Any, Callable, Dict, Iterator, List

from bench.speed_vs_error import wrench_sequence
from cdr_translator import TranslatorParams
from cdr_translator.fidelity import FidelitySolver, reduced
from cdr_translator.fidelity.linear import TangentModel
from cdr_translator.solve import warm_fast_path
import numpy as np

#: Where the tables go.
RESULT = Path(__file__).resolve().parent / 'results' / 'solve_many.md'

#: The levels measured and the FidelitySolver options of each.
LEVELS: Dict[str, Dict[str, Any]] = {
    'full': {'fidelity': 'full'}, 'cc': {'fidelity': 'cc'}, 'rod': {'fidelity': 'rod'},
    'linear': {'fidelity': 'linear'},
    'auto': {'fidelity': 'auto', 'max_position_error': 1e-3, 'max_angle_error_deg': 0.5}}

#: Where each level's kernels live: (object, attribute) pairs timed while the sequence runs
#: (the full model's usual warm row is the batch's compiled row, any other its warm step).
KERNELS = {'full': ((warm_fast_path, '_warm_rows'), (warm_fast_path, '_warm_step')),
           'cc': ((reduced.newton, 'continue_to'),), 'rod': ((reduced.newton, 'continue_to'),),
           'linear': ((TangentModel, 'frames'),)}


@contextmanager
def timed_kernel(level: str, spent: List[float]) -> Iterator[None]:
    """Add the time of each call of ``level``'s kernels to ``spent[0]`` while inside."""
    kernels = [(owner, name, getattr(owner, name)) for owner, name in KERNELS[level]]

    def timing(kernel: Callable) -> Callable:
        """Return ``kernel`` adding its time to ``spent[0]``."""
        def timed(*args, **kwargs):
            started = time.perf_counter()
            try:
                return kernel(*args, **kwargs)
            finally:
                spent[0] += time.perf_counter() - started
        return timed

    for owner, name, kernel in kernels:
        setattr(owner, name, timing(kernel))
    try:
        yield
    finally:
        for owner, name, kernel in kernels:
            setattr(owner, name, kernel)


def per_answer(params: TranslatorParams, options: dict, wrenches: np.ndarray,
               repeats: int = 3) -> Dict[str, float]:
    """
    Per-answer seconds of a solve() loop and of solve_many, each from a fresh solver.

    The loop reads each answer's end-disk pose, as the batch's columns hold it; a first
    pass loads every kernel both use (numba's cache), so that neither pays for that. The
    two alternate ``repeats`` times and the fastest pass of each counts: on a shared
    machine a burst of other work inflates single passes.
    """
    warmed = FidelitySolver(params, **options)
    warmed.solve_many(wrenches[:5, :3], wrenches[:5, 3:])
    warmed.solve(wrenches[5, :3], wrenches[5, 3:]).end_disk_quaternion_xyzw
    loops, batches, medians = [], [], []
    for _ in range(repeats):
        looped = FidelitySolver(params, **options)
        looped.solve(wrenches[0, :3], wrenches[0, 3:])  # the first (cold) answer: not timed
        times = []
        for wrench in wrenches[1:]:
            started = time.perf_counter()
            result = looped.solve(wrench[:3], wrench[3:])
            result.end_disk_position, result.end_disk_quaternion_xyzw, result.pj_bending
            times.append(time.perf_counter() - started)
        loops.append(sum(times) / len(times))
        medians.append(statistics.median(times))
        batched = FidelitySolver(params, **options)
        batched.solve(wrenches[0, :3], wrenches[0, 3:])
        started = time.perf_counter()
        batch = batched.solve_many(wrenches[1:, :3], wrenches[1:, 3:])
        batches.append((time.perf_counter() - started) / len(batch))
        assert batch.converged.all(), set(batch.message)
    return {'loop': min(medians), 'loop_mean': min(loops), 'batch_mean': min(batches)}


def overhead(params: TranslatorParams, level: str, wrenches: np.ndarray) -> Dict[str, float]:
    """Median (solve time, kernel time, solve minus kernel) of a warm single solve."""
    solver = FidelitySolver(params, **LEVELS[level])
    for wrench in wrenches[:20]:
        solver.solve(wrench[:3], wrench[3:])
    spent = [0.0]
    totals, kernels = [], []
    with timed_kernel(level, spent):
        for wrench in wrenches:
            spent[0] = 0.0
            started = time.perf_counter()
            solver.solve(wrench[:3], wrench[3:])
            totals.append(time.perf_counter() - started)
            kernels.append(spent[0])
    return {'solve': statistics.median(totals), 'kernel': statistics.median(kernels),
            'overhead': statistics.median(np.subtract(totals, kernels))}


def main() -> None:
    """Print a table of per-answer times and one of single-solve overheads; write RESULT."""
    parser = argparse.ArgumentParser(description='solve_many against a solve() loop.')
    parser.add_argument('--count', type=int, default=600, help='wrenches per level')
    args = parser.parse_args()
    params = TranslatorParams.from_yaml()
    wrenches = wrench_sequence(args.count)
    lines = ['| level | loop µs (median) | loop µs (mean) | solve_many µs | loop/batch |',
             '|---|---|---|---|---|']
    for level, options in LEVELS.items():
        times = per_answer(params, options, wrenches)
        lines.append(f"| {level} | {1e6 * times['loop']:.1f} | {1e6 * times['loop_mean']:.1f} "
                     f"| {1e6 * times['batch_mean']:.1f} "
                     f"| {times['loop_mean'] / times['batch_mean']:.2f} |")
        print(lines[-1])
    lines += ['', '| level | solve µs | kernel µs | overhead µs | overhead/kernel |',
              '|---|---|---|---|---|']
    for level in KERNELS:
        costs = overhead(params, level, wrenches)
        lines.append(f"| {level} | {1e6 * costs['solve']:.1f} | {1e6 * costs['kernel']:.1f} "
                     f"| {1e6 * costs['overhead']:.1f} "
                     f"| {costs['overhead'] / max(costs['kernel'], 1e-12):.2f} |")
        print(lines[-1])
    RESULT.write_text(
        '# Batch answers against a solve() loop; the Python around a single solve\n\n'
        f'Generated by `python -m bench.solve_many --count {args.count}` '
        f'({platform.python_implementation()} {platform.python_version()}, '
        f'{platform.machine()}, load average {os.getloadavg()[0]:.1f} when it ended: the '
        'machine is shared, 2 cores; compare within a table). Per answer along the smooth '
        'wrench sequence; the overhead of a single warm solve is its time minus the time '
        'inside its kernel (medians).\n\n' + '\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
