"""
Speed against error of every fidelity level; writes bench/results/.

Usage: python -m bench.speed_vs_error [--skip-paper] [--skip-node] [--skip-validation]
                                      [--repeats N]
       python -m bench.speed_vs_error --redraw

Every level and discretization is timed (wall clock around ``solve``, median) and compared
with the reference (the full model at 32 RK4 steps per disk interval, residual 1e-12) on
fixed scenes: the paper's two cases, larger lateral loads, torsion, combined loads (cold
solves), and a 1000-sample wrench sequence (warm-started). Times are also given as ratios
to the paper's numerics (``method='paper'``) measured in the same run on the paper's two
cases. The 'auto' rows also answer RANDOM_COUNT seeded random wrenches of every size in the
validated box, one at a time and in one batch. Also measured: the compliance's cost, and
translator_node's sustained wrench rate over DDS.
Writes speed_vs_error.md (tables), speed_vs_error.png (time against error) and
speed_vs_error.json (every number) into bench/results/, and the validated ranges of the
reduced levels into config/fidelity_validation.yaml (what FidelitySolver's error budget
reads; ``--skip-validation`` keeps the file as it is). ``--redraw`` measures nothing: it
writes speed_vs_error.md and speed_vs_error.png again from speed_vs_error.json. The figure's
robot panel reads bench/results/robot_levels.json (bench.robot_levels) when it exists.
"""

import argparse
from dataclasses import dataclass, field
import datetime
import functools
import json
import math
import os
from pathlib import Path
import platform
import signal
import statistics
import tempfile
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

from bench.compliance_costs import compliance_costs
from bench.speed_vs_error_figure import save_speed_error_figure
from bench.speed_vs_error_report import format_ms, markdown
from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.fidelity import FidelitySolver, pose_errors, reference_solver
from cdr_translator.fidelity import validation
from cdr_translator.fidelity.reduced import ROD_STEPS
from cdr_translator.studies import fidelity_validation
import numpy as np

RESULTS = Path(__file__).resolve().parent / 'results'
ROBOT_NUMBERS = RESULTS / 'robot_levels.json'

#: Static scenes, solved cold: name -> wrench [f (N); m (N m)] in {pe}.
SCENES = {
    'paper 12 N': (12.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    'paper 20 N': (20.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    'lateral 30 N': (30.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    'oblique 28 N': (20.0, 20.0, 0.0, 0.0, 0.0, 0.0),
    'torsion 0.5 N m': (0.0, 0.0, 0.0, 0.0, 0.0, 0.5),
    'combined': (15.0, -8.0, -5.0, 0.3, 0.2, 0.2),
}
PAPER_SCENES = ('paper 12 N', 'paper 20 N')

#: Error budgets of the 'auto' rows: (position m, angle deg).
BUDGETS = ((10e-3, 3.0), (1e-3, 0.5), (0.1e-3, 0.05), (0.01e-3, 0.01))

SEQUENCE_LENGTH = 1000

#: Random wrenches the 'auto' rows answer, and their seed.
RANDOM_COUNT = 300
RANDOM_SEED = 2718


def random_wrenches(count: int = RANDOM_COUNT, seed: int = RANDOM_SEED) -> np.ndarray:
    """Return wrenches uniform in the validated box scaled by a size uniform in [0, 1)."""
    rng = np.random.default_rng(seed)
    sizes = rng.uniform(0.0, 1.0, (count, 1))
    return rng.uniform(-1.0, 1.0, (count, 6)) * sizes * validation.box_half_widths()


def wrench_sequence(count: int = SEQUENCE_LENGTH) -> np.ndarray:
    """Return a smooth 6-D wrench sequence inside the validated box (at most 0.05 N per sample)."""
    t = np.linspace(0.0, 1.0, count)
    return np.stack([10.0 + 8.0 * np.sin(2 * np.pi * t), 6.0 * np.sin(3 * np.pi * t + 0.3),
                     -4.0 * np.sin(1.4 * np.pi * t), 0.15 * np.sin(2.6 * np.pi * t),
                     0.1 * np.cos(1.8 * np.pi * t), 0.2 * np.sin(4.2 * np.pi * t)], axis=1)


@dataclass
class Row:
    """One level/discretization and everything measured for it."""

    level: str
    setting: str
    unknowns: str
    make: Callable[[], FidelitySolver]
    sequence_setup: Optional[Callable[[FidelitySolver, np.ndarray], object]] = None
    spacers: int = 1  # the structure whose reference the errors are measured against
    static: Dict[str, dict] = field(default_factory=dict)
    sequence: dict = field(default_factory=dict)
    random: dict = field(default_factory=dict)


def _maker(params: TranslatorParams, **options: Any) -> Callable[[], FidelitySolver]:
    """Return a factory of ``FidelitySolver(params, **options)``."""
    return functools.partial(FidelitySolver, params, **options)


def rows(params: TranslatorParams) -> List[Row]:
    """Every configuration the benchmark measures."""
    result = []
    for steps in (2, 4, 8, 16):
        result.append(Row('full', f'{steps} steps' + (' (default)' if steps == 8 else ''), '90',
                          _maker(params.with_changes(steps_per_segment=steps), fidelity='full')))
    result.append(Row('full', "8 steps, tolerance 1e-6 (about the paper's)", '90',
                      _maker(params, fidelity='full', tolerance=1e-6)))
    for spacers in (2, 3):
        result.append(Row('full', f'{spacers} spacer disks per joint, 8 steps (longer joints: '
                          'errors against its own reference)', str(30 + 20 * (2 * spacers + 1)),
                          _maker(params.with_changes(spacers_per_joint=spacers),
                                 fidelity='full'),
                          spacers=spacers))
    for steps in (1, 2, 4):
        result.append(Row('rod', f'{steps} steps per interval' + (
            ' (default)' if steps == ROD_STEPS else ''), '7',
            _maker(params, fidelity='rod', rod_steps=steps)))
    result.append(Row('cc', 'one arc per joint', '8', _maker(params, fidelity='cc')))
    result.append(Row('linear', "about the unloaded state / the sequence's first sample",
                      '0', _linear_solver(params),
                      lambda solver, first: solver.cache_full_solution(first)))
    for position, angle in BUDGETS:
        result.append(Row('auto', f'budget {1e3 * position:g} mm, {angle:g} deg', '-',
                          _maker(params, max_position_error=position,
                                 max_angle_error_deg=angle)))
    return result


def _linear_solver(params: TranslatorParams) -> Callable[[], FidelitySolver]:
    def make() -> FidelitySolver:
        solver = FidelitySolver(params, fidelity='linear')
        solver.cache_full_solution(np.zeros(6))
        return solver
    return make


def reference_solutions(params: TranslatorParams, sequence: np.ndarray) -> tuple:
    """Return the reference results of every scene (cold) and of the sequence (warm-started)."""
    reference = reference_solver(params)
    static = {}
    for name, wrench in SCENES.items():
        reference.reset()
        static[name] = reference.solve(wrench[:3], wrench[3:])
    reference.reset()
    return static, [reference.solve(w[:3], w[3:]) for w in sequence]


def timed_solve(solver, wrench: np.ndarray, **options):
    """Solve and return (result, wall seconds)."""
    started = time.perf_counter()
    result = solver.solve(wrench[:3], wrench[3:], **options)
    return result, time.perf_counter() - started


def measure_static(row: Row, references: dict, repeats: int) -> None:
    """Cold solves of every scene: median time and errors."""
    solver = row.make()
    for name, scene in SCENES.items():
        wrench = np.array(scene)
        times = []
        for _ in range(repeats):
            if row.level != 'linear':
                solver.reset()
            result, elapsed = timed_solve(solver, wrench)
            times.append(elapsed)
        position, angle = pose_errors(result, references[name])
        row.static[name] = {'time_s': statistics.median(times), 'position_m': position,
                            'angle_deg': math.degrees(angle), 'converged': result.converged,
                            'fidelity': result.fidelity}


def measure_sequence(row: Row, sequence: np.ndarray, expected: list) -> None:
    """Run the warm-started sequence: median time, errors, levels used."""
    row.sequence = answer_series(row, sequence, expected)


def answer_series(row: Row, sequence: np.ndarray, expected: list) -> dict:
    """Answer ``sequence`` one at a time and in one batch: times, errors, levels used."""
    solver = row.make()
    if row.sequence_setup is not None:
        row.sequence_setup(solver, sequence[0])
    times, positions, angles = [], [], []
    used: Dict[str, int] = {}
    solver_answers = []
    for wrench, reference in zip(sequence, expected):
        result, elapsed = timed_solve(solver, wrench)
        times.append(elapsed)
        solver_answers.append(result.end_disk_position)
        position, angle = pose_errors(result, reference)
        positions.append(position)
        angles.append(math.degrees(angle))
        used[result.fidelity] = used.get(result.fidelity, 0) + 1
    batch_s, deviation = batch_per_answer(row, sequence, solver_answers)
    return {'median_time_s': statistics.median(times),
            'batch_per_answer_s': batch_s, 'batch_deviation_m': deviation,
            'p95_time_s': float(np.percentile(times, 95)),
            'mean_time_s': float(np.mean(times)),
            'max_position_m': max(positions), 'median_position_m': float(np.median(positions)),
            'max_angle_deg': max(angles), 'median_angle_deg': float(np.median(angles)),
            'levels': used, 'auto_counts': dict(solver.auto.counts)}


def batch_per_answer(row: Row, sequence: np.ndarray, answers: list,
                     passes: int = 3) -> Tuple[float, float]:
    """
    Return (time per answer, distance) of ``solve_many`` along the sequence.

    The time is the fastest of ``passes``, each from a fresh solver; the distance (m) is the
    largest of its rows' end-disk positions from the single solves' ``answers``.
    """
    best = math.inf
    for _ in range(passes):
        solver = row.make()
        if row.sequence_setup is not None:
            row.sequence_setup(solver, sequence[0])
        started = time.perf_counter()
        batch = solver.solve_many(sequence[:, :3], sequence[:, 3:])
        best = min(best, (time.perf_counter() - started) / len(sequence))
    deviation = float(np.abs(batch.end_disk_position - np.array(answers)).max())
    return best, deviation


def paper_baseline(params: TranslatorParams, references: dict) -> dict:
    """Time the paper's numerics on its two cases, cold, once each."""
    solver = TranslatorSolver(params, method='paper', time_limit_s=600.0)
    measured = {}
    for name in PAPER_SCENES:
        wrench = np.array(SCENES[name])
        solver.reset()
        result, elapsed = timed_solve(solver, wrench)
        position, angle = pose_errors(result, references[name])
        measured[name] = {'time_s': elapsed, 'converged': result.converged,
                          'position_m': position, 'angle_deg': math.degrees(angle),
                          'iterations': result.iterations}
    return measured


def node_rate(seconds: float = 3.0, rate_hz: float = 1000.0) -> dict:
    """translator_node's sustained answers per second under a wrench burst over DDS."""
    try:
        from bench.node_latency import measure
        from cdr_translator.ros.client import isolated_ros_env, NodeProcess, TranslatorClient
        from cdr_translator.interface import messages
    except ImportError as error:
        return {'error': f'node tools unavailable: {error}'}
    env = isolated_ros_env()
    os.environ.update(env)
    with tempfile.TemporaryDirectory() as folder:
        with NodeProcess(['-p', 'log_to_mcap:=false'], env, Path(folder) / 'node.log') as node:
            client = TranslatorClient([messages.END_DISK_POSE_TOPIC,
                                       messages.DIAGNOSTICS_TOPIC], depth=100000)
            try:
                if not client.handshake(120.0):
                    return {'error': f'node did not answer: {node.text()[-500:]}'}
                row = measure(client, rate_hz, seconds, node.process.pid)
                node.stop(signal.SIGINT)
            finally:
                client.close()
    return {'offered_hz': rate_hz, 'seconds': seconds, 'sent': row['sent'],
            'received': row['received'], 'answered': row['poses'],
            'answers_per_s': row['poses'] / seconds,
            'latency_p50_ms': float(np.median(row['latencies_ms']))}


def targets(report: dict, table_rows: List[Row]) -> list:
    """Measured against the issue's targets."""
    default = next(row for row in table_rows if row.setting == '8 steps (default)')
    paper_tol = next(row for row in table_rows if 'tolerance 1e-6' in row.setting)
    cold = max(default.static[name]['time_s'] for name in PAPER_SCENES)
    cold_all = statistics.median(value['time_s'] for value in default.static.values())
    warm = default.sequence['median_time_s']
    result = [
        ('full model, warm along a sequence <= 0.5 ms median',
         f'{format_ms(warm)} ms at the default tolerance 1e-10; '
         f"{format_ms(paper_tol.sequence['median_time_s'])} ms at 1e-6 (about the paper's)"),
        ('full model cold <= 10 ms',
         f'{format_ms(cold)} ms (slower paper case); median over all six scenes '
         f'{format_ms(cold_all)} ms'),
        ('compliance <= 0.2 ms on top of a solve',
         f"{format_ms(report['compliance']['implicit_along_sequence_median_s'])} ms along the "
         f"sequence, {format_ms(report['compliance']['implicit_after_cold_median_s'])} ms "
         'after a cold solve')]
    auto = next(row for row in table_rows if row.setting == 'budget 1 mm, 0.5 deg')
    batch = default.sequence['batch_per_answer_s'] / auto.sequence['batch_per_answer_s']
    result.append((
        "'auto' at 1 mm / 0.5° along the sequence >= 10× faster than full",
        f"batch {batch:.2g}× ({'met' if batch >= 10.0 else 'missed'}: full "
        f"{1e6 * default.sequence['batch_per_answer_s']:.0f} µs, auto "
        f"{1e6 * auto.sequence['batch_per_answer_s']:.0f} µs per answer); "
        + ', '.join(f'{name} {default.sequence[key] / auto.sequence[key]:.2g}×'
                    for name, key in (('median', 'median_time_s'), ('mean', 'mean_time_s')))
        + '; interleaved passes and noisy walks: bench/results/auto_speed.md'))
    if report['paper_mean_s']:
        result.insert(2, ('>= 1000× faster than the paper baseline',
                          f"{report['paper_mean_s'] / cold:,.0f}× cold, "
                          f"{report['paper_mean_s'] / warm:,.0f}× warm"))
    return result


def write_report(report: dict) -> None:
    """
    Write speed_vs_error.md and speed_vs_error.png of ``report`` (its JSON form).

    The figure's robot panel reads bench.robot_levels' robot_levels.json when there is one.
    """
    (RESULTS / 'speed_vs_error.md').write_text(
        markdown(report, PAPER_SCENES, BUDGETS, SEQUENCE_LENGTH))
    robot = json.loads(ROBOT_NUMBERS.read_text()) if ROBOT_NUMBERS.exists() else None
    save_speed_error_figure(report, PAPER_SCENES, SEQUENCE_LENGTH,
                            RESULTS / 'speed_vs_error.png', robot)


def main() -> None:
    """Run everything and write bench/results/ (and config/fidelity_validation.yaml)."""
    parser = argparse.ArgumentParser(description='Speed against error of every fidelity level.')
    parser.add_argument('--skip-paper', action='store_true', help='omit the slow baseline')
    parser.add_argument('--skip-node', action='store_true', help='omit the DDS burst')
    parser.add_argument('--skip-validation', action='store_true',
                        help='keep config/fidelity_validation.yaml as it is')
    parser.add_argument('--repeats', type=int, default=5, help='cold solves per scene')
    parser.add_argument('--redraw', action='store_true',
                        help='only write speed_vs_error.md and .png again from '
                        'speed_vs_error.json')
    args = parser.parse_args()
    if args.redraw:
        write_report(json.loads((RESULTS / 'speed_vs_error.json').read_text()))
        return
    started = time.perf_counter()
    params = TranslatorParams.from_yaml()
    report: Dict[str, Any] = {
        'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        'machine': f'{platform.machine()}, {os.cpu_count()} cores, Python '
                   f'{platform.python_version()}',
        'load_before': ', '.join(f'{v:.1f}' for v in os.getloadavg())}
    if not args.skip_validation:
        print('validating the reduced levels against the reference ...', flush=True)
        data = fidelity_validation.validate(params, FidelitySolver(params).rod_steps)
        data.save(validation.DEFAULT_VALIDATION_PATH,
                  'Validated ranges of the reduced fidelity levels (cdr_translator.fidelity).\n'
                  'Written by bench/speed_vs_error.py (make bench); do not edit by hand.')
    stored = validation.Validation.load(validation.DEFAULT_VALIDATION_PATH)
    report['validation'] = None if stored is None else {
        level: bound.to_dict() for level, bound in stored.levels.items()}
    sequence = wrench_sequence()
    table_rows = rows(params)
    references = {}
    for spacers in sorted({row.spacers for row in table_rows}):
        print(f'reference solutions, {spacers} spacer disks per joint ...', flush=True)
        references[spacers] = reference_solutions(
            params.with_changes(spacers_per_joint=spacers), sequence)
    random = random_wrenches()
    random_expected = reference_solutions(params, random)[1]
    for row in table_rows:
        print(f'{row.level}: {row.setting} ...', flush=True)
        static, expected = references[row.spacers]
        measure_static(row, static, args.repeats)
        measure_sequence(row, sequence, expected)
        if row.level == 'auto' or row.setting == '8 steps (default)':
            row.random = answer_series(row, random, random_expected)
    print('compliance ...', flush=True)
    report['compliance'] = compliance_costs(params, SCENES, sequence)
    report['paper_baseline'] = {}
    if not args.skip_paper:
        print('paper baseline (slow) ...', flush=True)
        report['paper_baseline'] = paper_baseline(params, references[1][0])
    report['paper_mean_s'] = statistics.mean(
        value['time_s'] for value in report['paper_baseline'].values()) \
        if report['paper_baseline'] else None
    report['node'] = {'error': 'skipped (--skip-node)'} if args.skip_node else node_rate()
    report['load_after'] = ', '.join(f'{v:.1f}' for v in os.getloadavg())
    report['targets'] = targets(report, table_rows)
    report['rows'] = [{'level': row.level, 'setting': row.setting, 'unknowns': row.unknowns,
                       'static': row.static, 'sequence': row.sequence, 'random': row.random}
                      for row in table_rows]
    report['random_count'] = RANDOM_COUNT
    report['runtime_s'] = time.perf_counter() - started
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / 'speed_vs_error.json').write_text(json.dumps(report, indent=1, default=str))
    write_report(report)
    print((RESULTS / 'speed_vs_error.md').read_text())
    print(f"benchmark took {report['runtime_s']:.0f} s")


if __name__ == '__main__':
    main()
