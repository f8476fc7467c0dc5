"""
Calibration from a synthetic recording: what it recovers, how fast, how honest its errors.

Usage: python -m bench.calibration [--count N] [--trials K] [--out DIR]

A seeded random-walk recording of ``--count`` wrenches (force up to 10, 10, 5 N, moment up
to 0.1 N m per axis) whose measured poses come from a hidden prototype (HIDDEN: another
modulus and tube length) with 0.2 mm / 0.1 deg noise, once in the base frame and once
seen by a tracker offset by OFFSET. ``python -m msg_tools calibrate`` fits modulus and
tube length (and the frame); the report gives the recovered values, their errors against
the truth in standard errors, and the times of the fit and of its 5-fold
cross-validation against one ``solve_many`` pass over the same wrenches (the unit a fit
is made of). ``--trials K`` repeats the first fit on K noise seeds without
cross-validation: the z-scores (error / standard error) should scatter like N(0, 1).
Writes DIR/calibration.md, DIR/calibration.json and DIR/calibration.png.
"""

import argparse
import contextlib
from datetime import datetime, timezone
import io
import json
import os
from pathlib import Path
import platform
import tempfile
import time
from typing import Any, Dict, List

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.params.translator_params import Accuracy
from msg_tools import synth
from msg_tools.__main__ import main
from msg_tools.calibration import yaml_number
import numpy as np

#: The prototype the measurements come from.
HIDDEN = {'youngs_modulus': 8.2e10, 'tube_length': 0.1405}
#: The tracker frame of the second scenario: x y z (m), rotation vector (rad).
OFFSET = [0.05, -0.02, 0.3, 0.1, -0.2, 0.4]
FRAME_NAMES = ('frame_x', 'frame_y', 'frame_z', 'frame_rx', 'frame_ry', 'frame_rz')


def run(*args: Any) -> Dict[str, Any]:
    """Run ``python -m msg_tools`` in this process; return the JSON it prints (or {})."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main([str(arg) for arg in args])
    text = out.getvalue()
    report = json.loads(text) if text.strip().startswith('{') else {}
    report['exit_code'] = code
    return report


def record(folder: Path, name: str, count: int, seed: int, *extra: Any) -> Path:
    """Write a synthetic recording of the hidden prototype; return its path."""
    path = folder / f'{name}.mcap'
    result = run('synth', path, '--profile', 'random-walk', '--count', count, '--seed', seed,
                 '--force', 10, 10, 5, '--moment', 0.1, 0.1, 0.1, '--measured-pose-noise',
                 2e-4, 0.1, '--true-params', folder / 'hidden.yaml', *extra)
    assert result['exit_code'] == 0, result
    return path


def one_pass_s(count: int, seed: int) -> float:
    """Time one solve_many pass over the recording's wrenches (best of 3), as a fit does."""
    samples = synth.generate('random-walk', count=count, force=(10, 10, 5),
                             moment=(0.1, 0.1, 0.1), seed=seed)
    forces = np.array([sample.force for sample in samples])
    moments = np.array([sample.moment for sample in samples])
    times = []
    for _ in range(3):
        solver = TranslatorSolver(TranslatorParams.from_yaml(), accuracy=Accuracy(0.0, 0.0))
        started = time.perf_counter()
        solver.solve_many(forces, moments)
        times.append(time.perf_counter() - started)
    return min(times)


def z_scores(report: Dict[str, Any], truth: Dict[str, float]) -> Dict[str, float]:
    """Return (fitted - true) / standard error of each parameter with a known truth."""
    return {name: (entry['value'] - truth[name]) / entry['standard_error']
            for name, entry in report['parameters'].items() if name in truth}


def table(rows: List[Dict[str, Any]], truth: Dict[str, float]) -> List[str]:
    """Return the Markdown rows of recovered parameters."""
    lines = ['| scenario | parameter | true | start | fitted | error | standard error | '
             'error / s.e. |', '|---|---|---|---|---|---|---|---|']
    for row in rows:
        for name, entry in row['report']['parameters'].items():
            error = entry['value'] - truth[name]
            lines.append(f"| {row['scenario']} | {name} | {truth[name]:.6g} | "
                         f"{entry['initial']:.6g} | {entry['value']:.6g} | {error:.3g} | "
                         f"{entry['standard_error']:.3g} | "
                         f"{error / entry['standard_error']:+.2f} |")
    return lines


def main_bench() -> None:
    """Run the scenarios and write the report."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--count', type=int, default=200)
    parser.add_argument('--trials', type=int, default=0)
    parser.add_argument('--out', default='bench/results')
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    truth = dict(HIDDEN, **dict(zip(FRAME_NAMES, OFFSET)))
    rows: List[Dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as folder_name:
        folder = Path(folder_name)
        (folder / 'hidden.yaml').write_text('translator_node:\n  ros__parameters:\n' + ''.join(
            f'    {name}: {yaml_number(value)}\n' for name, value in HIDDEN.items()))
        unit = one_pass_s(args.count, 7)
        base = record(folder, 'base', args.count, 7)
        tracker = record(folder, 'tracker', args.count, 7, '--frame-offset', *OFFSET)
        for scenario, path, extra in (
                ('base frame', base, ['--plot', out / 'calibration.png']),
                ('tracker frame fitted', tracker, ['--fit-frame'])):
            started = time.perf_counter()
            report = run('calibrate', path, '--fit', 'youngs_modulus', 'tube_length',
                         '--json', *extra)
            rows.append({'scenario': scenario, 'wall_s': time.perf_counter() - started,
                         'report': report})
        trials = []
        for seed in range(args.trials):
            path = record(folder, f'trial{seed}', args.count, 100 + seed)
            report = run('calibrate', path, '--fit', 'youngs_modulus', 'tube_length',
                         '--json', '--folds', 0)
            trials.append(z_scores(report, truth))
    stamp = datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    lines = [
        '# Calibration from a synthetic recording', '',
        f'Generated by `python -m bench.calibration --count {args.count} --trials '
        f'{args.trials}` ({stamp}; CPython {platform.python_version()}, '
        f'{platform.machine()}, {os.cpu_count()} cores; load average '
        f'{", ".join(f"{value:.1f}" for value in os.getloadavg())}). {args.count} random-walk '
        'wrenches, poses of a hidden prototype with 0.2 mm / 0.1 deg noise; '
        '[measurements.md](../../docs/howto/measurements.md) explains the fit.', '',
        *table(rows, truth), '',
        '| scenario | rms position | rms angle | cross-validated rms position | fit | '
        'cross-validation | model passes | one pass | whole command |',
        '|---|---|---|---|---|---|---|---|---|']
    for row in rows:
        report, timing = row['report'], row['report']['timing']
        lines.append(
            f"| {row['scenario']} | {report['rms_position_error_m'] * 1e3:.3f} mm | "
            f"{report['rms_angle_error_deg']:.3f} deg | "
            f"{report['cross_validated_rms_position_error_m'] * 1e3:.3f} mm | "
            f"{timing['fit_s']:.1f} s ({timing['fit_s'] / unit:.0f} passes) | "
            f"{timing['cross_validation_s']:.1f} s | {timing['model_passes']} | "
            f"{unit:.2f} s | {row['wall_s']:.1f} s |")
    if trials:
        scores = {name: [trial[name] for trial in trials] for name in HIDDEN}
        lines += ['', f'Over {len(trials)} noise seeds (no cross-validation), error / standard '
                  'error: ' + '; '.join(
                      f'{name} mean {np.mean(values):+.2f}, standard deviation '
                      f'{np.std(values, ddof=1):.2f}' for name, values in scores.items())
                  + ' (N(0, 1) expected).']
    lines += ['', '![calibration](calibration.png)']
    (out / 'calibration.md').write_text('\n'.join(lines) + '\n')
    (out / 'calibration.json').write_text(json.dumps(
        {'count': args.count, 'one_pass_s': unit, 'scenarios': rows, 'trials': trials},
        indent=1) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main_bench()
