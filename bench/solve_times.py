"""
Time cold, warm and paper-baseline solves of the Table II cases in one run.

Usage: python -m bench.solve_times [--skip-paper]

Cold: from the unloaded state (a fresh continuation). Warm: a 200-sample wrench sequence
that creeps around the case (0.05 N steps), each solve warm-started from the previous one.
Paper: method='paper', the published numerics (interpreted kernel, Levenberg-Marquardt with
a one-residual-per-column Jacobian, paper tolerances), cold, with the same load continuation.
Ratios are the paper time over the median cold or warm time.
"""

import argparse
import statistics
import time

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.params.paper import TABLE_II
import numpy as np


def _median_ms(samples):
    return 1e3 * statistics.median(samples)


def main() -> None:
    """Print one line per Table II case."""
    parser = argparse.ArgumentParser(description='Cold/warm/paper solve times.')
    parser.add_argument('--skip-paper', action='store_true', help='omit the slow baseline')
    args = parser.parse_args()
    params = TranslatorParams.from_yaml()
    fast = TranslatorSolver(params)
    paper = None if args.skip_paper else TranslatorSolver(params, method='paper',
                                                          time_limit_s=600.0)
    print(f"{'case':>10} {'cold ms':>9} {'warm ms':>9} {'paper s':>9} "
          f"{'paper/cold':>11} {'paper/warm':>11}")
    for case in TABLE_II:
        cold = []
        for _ in range(5):
            fast.reset()
            started = time.perf_counter()
            assert fast.solve(case.force).converged
            cold.append(time.perf_counter() - started)
        warm = []
        for offset in 0.05 * np.sin(np.linspace(0.0, 6.0 * np.pi, 200)):
            started = time.perf_counter()
            assert fast.solve((case.force[0] + offset, 0.3 * offset, 0.0)).converged
            warm.append(time.perf_counter() - started)
        line = f'{case.force[0]:>8g} N {_median_ms(cold):>9.2f} {_median_ms(warm):>9.3f}'
        if paper is not None:
            paper.reset()
            started = time.perf_counter()
            result = paper.solve(case.force)
            paper_s = time.perf_counter() - started
            line += (f' {paper_s:>9.2f} {paper_s / statistics.median(cold):>11.0f} '
                     f'{paper_s / statistics.median(warm):>11.0f}'
                     + ('' if result.converged else f'  (paper: {result.message})'))
        print(line)


if __name__ == '__main__':
    main()
