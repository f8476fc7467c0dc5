"""
Issue 13's targets: exact against forward-difference Jacobian, measured in one run.

Usage: python -m bench.targets [--skip-paper] [--spacers-slope]

Prints, and writes to bench/results/targets.md:

* one Jacobian, exact (tangent-linear shot) and forward differences, 1 and 3 spacer disks;
* warm solves along the 1000-sample sequence of bench.speed_vs_error (median);
* cold solves of the paper's Table II cases (median of 5 each);
* compliance on top of a solve (its own time, median along 200 warm samples);
* 3 spacer disks per joint: cold (20 N) and warm (sequence, first 200 samples);
* the stability verdict and error estimate together, as a fraction of the warm solve;
* optionally (--spacers-slope) cold 2 N solves for 1..9 spacer disks per joint;
* the paper baseline (method='paper', cold 12 N) for the ratio, unless --skip-paper.

Every solve here is a whole solve: stability verdict and error estimate included. The
machine is shared (2 cores, several agents at once): the figures carry that noise, the
ratios measured in the same run much less.
"""

import argparse
from pathlib import Path
import platform
import statistics
import time
from typing import Callable, Dict, List

from bench.speed_vs_error import wrench_sequence
from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.paper import TABLE_II
import numpy as np

RESULT = Path(__file__).resolve().parent / 'results' / 'targets.md'

#: Issue 13's targets (seconds).
TARGETS = {'warm': 0.1e-3, 'cold': 3e-3, 'compliance': 0.03e-3, 'spacers3_cold': 10e-3,
           'spacers3_warm': 0.4e-3, 'overhead': 0.10}


def _median(samples: List[float]) -> float:
    return statistics.median(samples)


def _time(call: Callable[[], object], repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        samples.append(time.perf_counter() - started)
    return _median(samples)


def jacobian_times(params: TranslatorParams) -> Dict[str, float]:
    """Median time of one Jacobian at a 12 N state, both ways."""
    times = {}
    for jacobian in ('exact', 'fd'):
        solver = TranslatorSolver(params, jacobian=jacobian)
        result = solver.solve((12.0, 0.0, 0.0))
        problem = solver.problem
        xs = result.unknowns / problem.x_scale
        wrench = np.array([12.0, 0, 0, 0, 0, 0])
        rs = problem.residual(xs, wrench)
        times[jacobian] = _time(lambda: problem.jacobian(xs, wrench, rs), 30)
    return times


def warm_sequence(solver: TranslatorSolver, sequence: np.ndarray,
                  overhead: bool = False) -> Dict[str, float]:
    """Median warm solve along ``sequence``; with ``overhead`` also stability+estimate."""
    solver.reset()
    solver.solve(sequence[0][:3], sequence[0][3:])
    spent = []
    if overhead:  # time the two per-solve extras inside every solve
        for name in ('_stability', '_estimate_error'):
            original = getattr(solver, name)

            def timed(*args, _original=original, **kwargs):
                started = time.perf_counter()
                value = _original(*args, **kwargs)
                spent.append(time.perf_counter() - started)
                return value
            setattr(solver, name, timed)
    times, extras = [], []
    for wrench in sequence:
        spent.clear()
        started = time.perf_counter()
        result = solver.solve(wrench[:3], wrench[3:])
        times.append(time.perf_counter() - started)
        extras.append(sum(spent))
        assert result.converged, result.message
    for name in ('_stability', '_estimate_error'):
        solver.__dict__.pop(name, None)
    return {'median_s': _median(times), 'overhead_median_s': _median(extras),
            'overhead_fraction': _median(extras) / _median(times)}


def cold_cases(solver: TranslatorSolver) -> Dict[float, float]:
    """Median of 5 cold solves per Table II case."""
    out = {}
    for case in TABLE_II:
        def cold():
            solver.reset()
            assert solver.solve(case.force).converged
        out[case.force[0]] = _time(cold, 5)
    return out


def compliance_time(solver: TranslatorSolver, sequence: np.ndarray) -> float:
    """Median compliance time on top of warm solves (its own time_s)."""
    solver.reset()
    samples = []
    for wrench in sequence[:200]:
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
        samples.append(result.compliance.time_s)
    return _median(samples)


def spacers(params: TranslatorParams, count: int, sequence: np.ndarray,
            jacobian: str) -> Dict[str, float]:
    """Cold 20 N and warm (first 200 sequence samples) with ``count`` spacer disks."""
    changed = params.with_changes(spacers_per_joint=count, tube_length=0.1383 - 0.02 * (count - 1))
    solver = TranslatorSolver(changed, jacobian=jacobian)

    def cold():
        solver.reset()
        assert solver.solve((20.0, 0.0, 0.0)).converged
    return {'cold_s': _time(cold, 3),
            'warm_s': warm_sequence(solver, sequence[:200])['median_s']}


def spacer_slope(params: TranslatorParams) -> Dict[int, float]:
    """Cold 2 N solve time against spacer disks per joint."""
    out = {}
    for count in range(1, 10):
        changed = params.with_changes(spacers_per_joint=count)
        solver = TranslatorSolver(changed, time_limit_s=60.0)

        def cold():
            solver.reset()
            assert solver.solve((2.0, 0.0, 0.0)).converged
        out[count] = _time(cold, 2)
    return out


def paper_baseline(params: TranslatorParams) -> float:
    """One cold 12 N solve with the paper's numerics (interpreted kernel, LM, FD)."""
    solver = TranslatorSolver(params, method='paper', time_limit_s=900.0)
    started = time.perf_counter()
    solver.solve((12.0, 0.0, 0.0))
    return time.perf_counter() - started


def _ms(seconds: float) -> str:
    return f'{1e3 * seconds:.3f}'


def main() -> None:
    """Measure, print and write bench/results/targets.md."""
    parser = argparse.ArgumentParser(description="Issue 13's targets, exact vs FD.")
    parser.add_argument('--skip-paper', action='store_true', help='omit the slow baseline')
    parser.add_argument('--spacers-slope', action='store_true',
                        help='also time 1..9 spacer disks per joint (slow)')
    args = parser.parse_args()
    params = TranslatorParams.from_yaml()
    sequence = wrench_sequence()
    started = time.perf_counter()
    jac = jacobian_times(params)
    jac3 = jacobian_times(params.with_changes(spacers_per_joint=3, tube_length=0.0983))
    rows = {}
    for jacobian in ('exact', 'fd'):
        solver = TranslatorSolver(params, jacobian=jacobian)
        rows[jacobian] = {'warm': warm_sequence(solver, sequence, overhead=True),
                          'cold': cold_cases(solver),
                          'compliance': compliance_time(solver, sequence),
                          'spacers3': spacers(params, 3, sequence, jacobian)}
    paper = None if args.skip_paper else paper_baseline(params)
    slope = spacer_slope(params) if args.spacers_slope else None
    exact, fd = rows['exact'], rows['fd']
    cold_exact = max(exact['cold'].values())
    cold_fd = max(fd['cold'].values())

    def line(name, target, measured, reference, met=None):
        met = measured <= target if met is None else met
        ratio_fd = reference / measured
        ratio_paper = f'{paper / measured:.0f}' if paper else '-'
        return (f'| {name} | {_ms(target)} | {_ms(measured)} | {"yes" if met else "no"} | '
                f'{_ms(reference)} | {ratio_fd:.1f} | {ratio_paper} |')

    lines = [
        '# Issue 13 targets: exact Jacobian, stability and error estimate on every solve',
        '',
        f'Generated by `python -m bench.targets` ({platform.python_implementation()} '
        f'{platform.python_version()}, {platform.machine()}). **The machine was shared by '
        'several agents while this ran (2 cores, 5 sessions): absolute times are inflated '
        'and noisy; the ratios, measured in the same run, are the robust figures.** Every '
        'solve includes its stability verdict and error estimate.',
        '',
        '| quantity | target (ms) | measured, exact (ms) | met | forward differences (ms) '
        '| fd / exact | paper / exact |',
        '|---|---|---|---|---|---|---|',
        *(f'| one Jacobian ({label}) | - | {_ms(times["exact"])} | - | {_ms(times["fd"])} | '
          f'{times["fd"] / times["exact"]:.1f} | - |'
          for label, times in (('1 spacer disk per joint', jac),
                               ('3 spacer disks per joint', jac3))),
        line('full model, warm, 1000-sample sequence (median)', TARGETS['warm'],
             exact['warm']['median_s'], fd['warm']['median_s']),
        line('full model, cold, paper cases (worst median)', TARGETS['cold'], cold_exact,
             cold_fd),
        line('compliance on top of a solve (median)', TARGETS['compliance'],
             exact['compliance'], fd['compliance']),
        line('3 spacer disks per joint, cold 20 N', TARGETS['spacers3_cold'],
             exact['spacers3']['cold_s'], fd['spacers3']['cold_s']),
        line('3 spacer disks per joint, warm (median)', TARGETS['spacers3_warm'],
             exact['spacers3']['warm_s'], fd['spacers3']['warm_s']),
        '',
        'Stability verdict + error estimate inside a warm solve: median '
        f"{_ms(exact['warm']['overhead_median_s'])} ms = "
        f"{100 * exact['warm']['overhead_fraction']:.0f} % of the warm solve (target "
        f"{100 * TARGETS['overhead']:.0f} %: "
        f"{'met' if exact['warm']['overhead_fraction'] <= TARGETS['overhead'] else 'missed'}).",
        '',
        'Cold Table II cases (median of 5, ms): ' + ', '.join(
            f'{force:g} N: exact {_ms(exact["cold"][force])}, fd {_ms(fd["cold"][force])}'
            for force in exact['cold']) + '.',
    ]
    if paper:
        lines += ['', f'Paper baseline (method=paper, cold 12 N): {paper:.2f} s.']
    if slope:
        counts = np.array(list(slope))
        values = np.array([slope[c] for c in counts])
        fit = np.polyfit(counts, values, 1)
        lines += ['', 'Cold 2 N solve against spacer disks per joint (ms): ' + ', '.join(
            f'{c}: {_ms(slope[c])}' for c in slope)
            + f'. Linear fit slope {_ms(fit[0])} ms per spacer disk.']
    lines += ['', f'Run time {time.perf_counter() - started:.0f} s.', '']
    text = '\n'.join(lines)
    print(text)
    RESULT.write_text(text)


if __name__ == '__main__':
    main()
