"""
The full model on rough wrench streams: seeded random walks of a sensor's noise and a replay.

Usage: python -m bench.walks [--count N]   (writes bench/results/walks.md)

Three seeded random walks of the end-disk force (``random_walk``): sigma = 0.02 N per sample
(a force/torque sensor's noise at 1 kHz), 0.1 N and 0.4 N (the replay bench's walk), the
force kept within 15 N, no moment. Measured in one run, on the full model at its default
settings:

* ``solve()`` per answer, one call per wrench (mean, p50, p95, p99), with the Newton
  iterations per answer and the mean expressed in shots (one residual shot, timed in the
  same run: a ratio that the machine's load cancels from);
* ``solve_many`` per answer over the whole walk, from a fresh solver warm at its start;
* the compliance on top of a warm solve: its own time (``ComplianceAnalysis.time_s``, and
  its analysis', made when first read) and what ``compliance=True`` adds to the whole solve
  with the analysis read, on the sigma = 0.02 N walk, exact (the default) and from the
  stored factorization (``compliance_tolerance``);
* the corrector iterations a prediction from the exact tangent would leave
  (``predictor_iterations``), against those of the solver's own prediction.

Each target row is printed with the measured figure, the target, their ratio and the ratio
to one shot. The machine is shared (2 cores, several agents at once): the loop and the
batch alternate, the best of ``REPEATS`` passes counts, and the figures are compared within
this run.
"""

import argparse
import os
from pathlib import Path
import platform
import statistics
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

from bench.compliance_costs import compliance_time_s, computed_compliance
from bench.solve_many import overhead
from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.bvp.problem import Problem
import numpy as np
from scipy.linalg import lu_factor, lu_solve

#: Where the tables go.
RESULT = Path(__file__).resolve().parent / 'results' / 'walks.md'

#: The walks: standard deviation of each force component's step (N per sample).
SIGMAS = (0.02, 0.1, 0.4)

#: The largest force of a walk (N); the walk is pulled back onto this sphere.
MAX_FORCE = 15.0

#: Where every walk starts (N): loaded, so that no answer is a cold solve from zero.
START = (8.0, 2.0, -1.0)

#: Passes of each measurement; the fastest counts.
REPEATS = 2

#: The compliances measured: name and the solve's compliance options.
COMPLIANCE_OPTIONS: Dict[str, Dict[str, float]] = {
    'exact (default)': {}, 'stored factorization (compliance_tolerance 0.05)':
        {'compliance_tolerance': 0.05}}

#: The targets (seconds; shots per answer has none).
TARGETS = {'solve_mean': 60e-6, 'solve_many': 120e-6, 'compliance': 50e-6}


def random_walk(sigma: float, count: int, seed: int = 35) -> np.ndarray:
    """
    Return ``count`` wrenches (count, 6): a seeded Gaussian walk of the force from START.

    Each force component moves by N(0, sigma^2) per sample; a force beyond MAX_FORCE is
    scaled back onto that sphere (the walk goes on from there). The moment is zero.
    """
    steps = np.random.default_rng(seed).normal(scale=sigma, size=(count, 3))
    wrenches = np.zeros((count, 6))
    force = np.array(START, dtype=float)
    for row in range(count):
        force = force + steps[row]
        size = float(np.linalg.norm(force))
        if size > MAX_FORCE:
            force *= MAX_FORCE / size
        wrenches[row, :3] = force
    return wrenches


def shot_time(params: TranslatorParams, wrench: np.ndarray) -> float:
    """Median time of one residual shot at the solution under ``wrench`` (s)."""
    solver = TranslatorSolver(params)
    result = solver.solve(wrench[:3], wrench[3:])
    problem = solver.problem
    xs = result.unknowns / problem.x_scale
    samples = []
    for _ in range(200):
        started = time.perf_counter()
        problem.residual(xs, wrench)
        samples.append(time.perf_counter() - started)
    return statistics.median(samples)


def loop_and_batch(params: TranslatorParams, wrenches: np.ndarray) -> Dict[str, float]:
    """
    Per-answer times of a solve() loop and of solve_many along ``wrenches``, best of REPEATS.

    Both start from a solver warm at the first wrench (not timed). Every answer must have
    converged. Wall-clock times (mean, percentiles; 'batch') and the thread's CPU time
    ('cpu_mean', 'batch_cpu': what the answers cost without the time the process waited for
    a core) of the pass with the least CPU time count.
    """
    best: Dict[str, float] = {}
    for _ in range(REPEATS):
        looped = TranslatorSolver(params)
        looped.solve(wrenches[0, :3], wrenches[0, 3:])
        times, cpu, iterations = [], [], []
        for wrench in wrenches[1:]:
            started, started_cpu = time.perf_counter(), time.thread_time()
            result = looped.solve(wrench[:3], wrench[3:])
            times.append(time.perf_counter() - started)
            cpu.append(time.thread_time() - started_cpu)
            iterations.append(result.iterations)
            assert result.converged, result.message
        mean = statistics.fmean(cpu)
        if mean < best.get('cpu_mean', np.inf):
            best.update(cpu_mean=mean, mean=statistics.fmean(times),
                        p50=float(np.percentile(times, 50)),
                        p95=float(np.percentile(times, 95)),
                        p99=float(np.percentile(times, 99)),
                        iterations=statistics.fmean(iterations))
        batched = TranslatorSolver(params)
        batched.solve(wrenches[0, :3], wrenches[0, 3:])
        started, started_cpu = time.perf_counter(), time.thread_time()
        batch = batched.solve_many(wrenches[1:, :3], wrenches[1:, 3:])
        per_answer = (time.perf_counter() - started) / len(batch)
        cpu_per_answer = (time.thread_time() - started_cpu) / len(batch)
        assert batch.converged.all(), set(batch.message)
        if cpu_per_answer < best.get('batch_cpu', np.inf):
            best.update(batch_cpu=cpu_per_answer, batch=per_answer)
    return best


def compliance_times(params: TranslatorParams, wrenches: np.ndarray,
                     **options: Any) -> Dict[str, float]:
    """
    Median compliance time on top of warm solves along ``wrenches``, best of REPEATS.

    'own': the compliance's own time_s and its analysis' (made when first read);
    'added': a solve with compliance=True (and ``options``), its analysis read, minus the
    plain solve of the same wrench, each from the same warm state
    (two solvers in step), in the thread's CPU time; 'error': the largest estimated relative
    error of a compliance along the walk.
    """
    best = {'own': np.inf, 'added': np.inf, 'error': 0.0}
    for _ in range(REPEATS):
        plain, with_compliance = TranslatorSolver(params), TranslatorSolver(params)
        for solver in (plain, with_compliance):
            solver.solve(wrenches[0, :3], wrenches[0, 3:])
        own, added = [], []
        for wrench in wrenches[1:]:
            started = time.thread_time()
            plain.solve(wrench[:3], wrench[3:])
            middle = time.thread_time()
            result = with_compliance.solve(wrench[:3], wrench[3:], compliance=True, **options)
            own.append(compliance_time_s(result))  # C and its analysis, made when first read
            ended = time.thread_time()
            added.append((ended - middle) - (middle - started))
            best['error'] = max(best['error'], computed_compliance(result).estimated_error)
        best['own'] = min(best['own'], statistics.median(own))
        best['added'] = min(best['added'], statistics.median(added))
    return best


def _chord_iterations(problem: Problem, xs: np.ndarray, wrench: np.ndarray,
                      step: Callable[[np.ndarray, np.ndarray], np.ndarray],
                      tolerance: float) -> int:
    """Return the steps x -= step(x, r(x)) from ``xs`` until max |r| <= tolerance (<= 12)."""
    for done in range(12):
        residual = problem.residual(xs, wrench)
        if np.abs(residual).max() <= tolerance:
            return done
        xs = xs - step(xs, residual)
    return 12


def predictor_iterations(params: TranslatorParams, wrenches: np.ndarray,
                         every: int = 8) -> Dict[str, float]:
    """
    Mean corrector iterations per answer along ``wrenches`` (every ``every``-th), three ways.

    'stored': the solver's own (first-order prediction and chord steps on its stored
    factorization, as ``solve()`` makes them); 'tangent': the prediction from the exact
    tangent at the previous solution (dx/dw from its exact Jacobian) and chord steps on that
    Jacobian; 'newton': the same prediction, then Newton with an exact Jacobian at every
    iterate. No line search in the last two (none was needed).
    """
    solver = TranslatorSolver(params)
    problem = solver.problem
    tolerance = solver.tolerance
    counts: Dict[str, List[int]] = {'stored': [], 'tangent': [], 'newton': []}
    for row, wrench in enumerate(wrenches):
        previous = solver.engine.previous_solution
        measured = row > 20 and row % every == 0 and previous is not None
        if measured and previous is not None:
            xs, at = previous
            _, jacobian, _ = problem.exact_jacobian(xs, at)
            lu = lu_factor(jacobian)
            predicted = xs - lu_solve(lu, problem.wrench_sensitivity @ (wrench - at))
            counts['tangent'].append(_chord_iterations(
                problem, predicted, wrench, lambda _, residual: lu_solve(lu, residual),
                tolerance))
            counts['newton'].append(_chord_iterations(
                problem, predicted, wrench, lambda x, residual: np.linalg.solve(
                    problem.exact_jacobian(x, wrench)[1], residual), tolerance))
        result = solver.solve(wrench[:3], wrench[3:])
        if measured:
            counts['stored'].append(result.iterations)
    return {name: statistics.fmean(values) for name, values in counts.items()}


def kernel_split(params: TranslatorParams, wrenches: np.ndarray) -> Dict[str, float]:
    """
    Median solve, time inside the compiled warm kernels and the rest (Python), along ``wrenches``.

    bench.solve_many's measurement of the full model (``overhead``: the usual warm row's
    compiled call and the warm step's, timed by ``timed_kernel``), on this walk.
    """
    split = overhead(params, 'full', wrenches)
    return {'solve': split['solve'], 'kernel': split['kernel'], 'python': split['overhead']}


def _us(seconds: float) -> str:
    return f'{1e6 * seconds:.1f}'


def main() -> None:
    """Measure, print and write RESULT."""
    parser = argparse.ArgumentParser(description='The full model on random-walk streams.')
    parser.add_argument('--count', type=int, default=2000, help='wrenches per walk')
    args = parser.parse_args()
    params = TranslatorParams.from_yaml()
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    walks = {sigma: random_walk(sigma, args.count) for sigma in SIGMAS}
    shot = shot_time(params, walks[SIGMAS[0]][0])
    measured = {sigma: loop_and_batch(params, wrenches) for sigma, wrenches in walks.items()}
    split = kernel_split(params, walks[SIGMAS[0]])
    predictors = {sigma: predictor_iterations(params, wrenches[:400])
                  for sigma, wrenches in walks.items()}
    compliance = {name: compliance_times(params, walks[SIGMAS[0]][:min(args.count, 500)],
                                         **options)
                  for name, options in COMPLIANCE_OPTIONS.items()}
    lines = ['| walk (N per sample) | solve() CPU mean µs | wall mean | p50 | p95 | p99 | '
             'iterations per answer | solve() CPU mean in shots | solve_many CPU µs per '
             'answer | wall | in shots |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for sigma, times in measured.items():
        lines.append(f"| {sigma:g} | {_us(times['cpu_mean'])} | {_us(times['mean'])} | "
                     f"{_us(times['p50'])} | {_us(times['p95'])} | {_us(times['p99'])} | "
                     f"{times['iterations']:.2f} | {times['cpu_mean'] / shot:.1f} | "
                     f"{_us(times['batch_cpu'])} | {_us(times['batch'])} | "
                     f"{times['batch_cpu'] / shot:.1f} |")
    rows: List[Tuple[str, str, Optional[float], float]] = [
        ('full, `solve()` mean per answer, σ = 0.02 N walk', 'solve_mean',
         measured[SIGMAS[0]]['cpu_mean'], measured[SIGMAS[0]]['mean']),
        ('full, `solve_many` per answer, σ = 0.4 N walk', 'solve_many',
         measured[SIGMAS[-1]]['batch_cpu'], measured[SIGMAS[-1]]['batch'])]
    for name, times in compliance.items():
        rows.append((f'compliance on top of a warm solve, {name} (C and its analysis, their own '
                     'time, wall, median, σ = 0.02 N walk)', 'compliance', None, times['own']))
    targets = ['| measure | measured µs (CPU) | wall µs | target µs | measured / target | met '
               '| in shots |', '|---|---|---|---|---|---|---|']
    for name, key, cpu, wall in rows:
        value = wall if cpu is None else cpu
        targets.append(f'| {name} | {"-" if cpu is None else _us(cpu)} | {_us(wall)} | '
                       f'{_us(TARGETS[key])} | {value / TARGETS[key]:.2f} | '
                       f'{"yes" if value <= TARGETS[key] else "no"} | {value / shot:.1f} |')
    added = '; '.join(f"{name}: {_us(times['added'])} µs (largest estimated relative error "
                      f"{times['error']:.1e})" for name, times in compliance.items())
    text = '\n'.join([
        '# The full model on random-walk wrench streams',
        '',
        f'Generated by `python -m bench.walks --count {args.count}` '
        f'({platform.python_implementation()} {platform.python_version()}, '
        f'{platform.machine()}, {os.cpu_count()} cores; load average {load_before:.1f} at '
        f'the start, {os.getloadavg()[0]:.1f} at the end: the machine is shared, so compare '
        'within this run). Seeded random walks of the force (each component N(0, σ²) per '
        f'sample, |f| ≤ {MAX_FORCE:g} N, from {START} N, no moment), full model, default '
        f'settings. One residual shot: {_us(shot)} µs (median) in this run. CPU: the '
        "thread's CPU time (``time.thread_time``), free of the time the process waited for a "
        'core; wall: ``time.perf_counter``, which a loaded machine inflates (its p95 and '
        'p99 are mostly waits).',
        '',
        *targets,
        '',
        f'What `compliance=True` adds to the whole warm solve, its analysis read (median CPU '
        f'difference of two solvers in step): {added}.',
        '',
        *lines,
        '',
        f'Where a `solve()` on the σ = {SIGMAS[0]:g} N walk goes (wall medians): '
        f"{_us(split['solve'])} µs per answer, {_us(split['kernel'])} µs inside the compiled "
        f"warm kernels (the shots, chord steps and error estimate), {_us(split['python'])} µs "
        'around them (Python).',
        '',
        'Corrector iterations per answer after the prediction (every 8th of the first 400 '
        'answers of each walk; one shot each): as solved (first-order prediction and chord '
        'steps on the stored factorization), with the prediction from the exact tangent at '
        'the previous solution and chord steps on its Jacobian (an exact Jacobian and its LU '
        'per answer), and with Newton on an exact Jacobian at every iterate.',
        '',
        '| walk (N per sample) | as solved | exact tangent at the previous solution | Newton |',
        '|---|---|---|---|',
        *(f"| {sigma:g} | {counts['stored']:.2f} | {counts['tangent']:.2f} | "
          f"{counts['newton']:.2f} |" for sigma, counts in predictors.items()),
        '',
        f'Run time {time.perf_counter() - started:.0f} s.',
        ''])
    print(text)
    RESULT.write_text(text)


if __name__ == '__main__':
    main()
