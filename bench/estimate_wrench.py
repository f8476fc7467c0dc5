"""
Cost of TranslatorSolver.estimate_wrench against a warm forward solve, in the same run.

Two streams of end-disk poses, solved from a smooth wrench path (forces within 8 N, moments
within 0.3 N m): a fine one (about 0.05 N between samples, a 1 kHz sensor) and a coarse one
(about 1 N). Each pose is estimated warm (along the stream, position and orientation) and,
for a subset, cold (a new solver), and position-only warm (the force under the known
moment). Prints the median and best times, the Newton iterations, and their ratios to the
median and best warm forward solve of the same stream, timed in the same iterations. On a
shared machine the best times are the compute: an estimate lasts ten times longer than a
warm forward solve, so the scheduler's time slices land in it ten times as often (a third
of its forward solves then take 5-9 ms instead of 0.3-0.9 ms).

    PYTHONPATH=$PWD python -m bench.estimate_wrench [--samples N] [--cold N]
"""

import argparse
import statistics
import time
from typing import Callable, Dict, List, Tuple

from cdr_translator import TranslatorSolver, WrenchEstimate
import numpy as np


def wrench_path(samples: int, step_n: float) -> np.ndarray:
    """Return a smooth path of ``samples`` wrenches about ``step_n`` (N) apart."""
    phase = np.cumsum(np.full(samples, step_n / 8.0))
    return np.stack([8.0 * np.sin(phase), 6.0 * np.cos(0.7 * phase),
                     -4.0 + 3.0 * np.sin(0.3 * phase), 0.3 * np.sin(0.5 * phase),
                     0.2 * np.cos(0.4 * phase), 0.3 * np.sin(0.9 * phase)], axis=1)


def timed(call: Callable[[], WrenchEstimate]) -> Tuple[float, WrenchEstimate]:
    """Time one call: return (wall time, its estimate)."""
    started = time.perf_counter()
    estimate = call()
    return time.perf_counter() - started, estimate


def stream(samples: int, step_n: float, cold: int) -> Dict[str, List[float]]:
    """
    Time forward solves and estimates along one stream of poses (module docstring).

    Each pose's forward solve and its estimates are timed in the same iteration, so that
    both see the same load of a shared machine.
    """
    forward, estimator, positioner = TranslatorSolver(), TranslatorSolver(), TranslatorSolver()
    times: Dict[str, List[float]] = {'forward': [], 'warm': [], 'cold': [], 'position': [],
                                     'warm iterations': [], 'cold iterations': []}
    for index, wrench in enumerate(wrench_path(samples, step_n)):
        started = time.perf_counter()
        result = forward.solve(wrench[:3], wrench[3:])
        times['forward'].append(time.perf_counter() - started)
        position, quaternion = result.end_disk_position, result.end_disk_quaternion_xyzw
        elapsed, estimate = timed(lambda: estimator.estimate_wrench(position, quaternion))
        if not estimate.converged:
            raise RuntimeError(f'warm estimate failed at {wrench}: {estimate.message}')
        times['warm'].append(elapsed)
        times['warm iterations'].append(estimate.iterations)
        times['position'].append(timed(lambda: positioner.estimate_wrench(
            position, moment=wrench[3:]))[0])
        if index % max(samples // cold, 1) == 0 and len(times['cold']) < cold:
            cold_solver = TranslatorSolver()  # no warm start at all
            elapsed, estimate = timed(lambda: cold_solver.estimate_wrench(position, quaternion))
            times['cold'].append(elapsed)
            times['cold iterations'].append(estimate.iterations)
    return times


def report(name: str, times: Dict[str, List[float]]) -> None:
    """Print one stream's medians, best times and ratios to the warm forward solve's."""
    skip = 5  # the first samples start the warm chains
    forward = times['forward'][skip:]
    print(f'{name}: warm forward solve median {statistics.median(forward) * 1e3:.3f} ms, '
          f'best {min(forward) * 1e3:.3f} ms')
    for key, label in (('warm', 'estimate warm'), ('position', 'estimate warm, position only'),
                       ('cold', 'estimate cold (new solver)')):
        values = times[key][skip:] if key != 'cold' else times[key]
        median, best = statistics.median(values), min(values)
        ratio = median / statistics.median(forward)
        print(f'  {label:30s} median {median * 1e3:8.3f} ms (x{ratio:6.1f})'
              f'  best {best * 1e3:8.3f} ms (x{best / min(forward):6.1f})')
    print(f'  Newton iterations: warm mean {np.mean(times["warm iterations"][skip:]):.2f}, '
          f'cold mean {np.mean(times["cold iterations"]):.2f}')


def main() -> None:
    """Run both streams and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--samples', type=int, default=200, help='poses per stream')
    parser.add_argument('--cold', type=int, default=20, help='cold estimates per stream')
    options = parser.parse_args()
    warm_up = TranslatorSolver()  # compiles the kernels before anything is timed
    solved = warm_up.solve([1.0, 0.0, 0.0], compliance=True)
    warm_up.estimate_wrench(solved.end_disk_position, solved.end_disk_quaternion_xyzw)
    for name, step in (('fine stream (0.05 N apart)', 0.05), ('coarse stream (1 N apart)', 1.0)):
        report(name, stream(options.samples, step, options.cold))


if __name__ == '__main__':
    main()
