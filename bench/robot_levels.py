"""
The Continuum Delta Robot on every leg level: its error against full legs, and its speed.

Usage: python -m bench.robot_levels  (prints, and writes bench/results/robot_levels.md and
robot_levels.json, the numbers the speed-against-error figure's robot panel reads)

Error: at SETTINGS slider settings over the whole slider box (a scrambled Halton sample of
the stroke cube) times PAYLOADS downward payloads, each level's cold forward statics
against full legs: the platform position error (m), its rotation error (deg) and the
largest entry of the platform compliance's error relative to the largest entry. Time: the
warm forward statics along delta_statics' slider circle under 1 kg (median of WARM_SAMPLES
solves, no compliance), and the atlas's chunk solve (robot/samples.solve_chunk, one
process, compliance and verdicts included, no Dask) at each level, as ratios to full in
the same run.
"""

import json
import math
import os
from pathlib import Path
import platform
import statistics
import time
from typing import Dict, List

from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.samples import AtlasSpec, solve_chunk
import numpy as np
from scipy.stats import qmc

RESULT = Path(__file__).resolve().parent / 'results' / 'robot_levels.md'
NUMBERS = RESULT.with_suffix('.json')

LEVELS = ('full', 'rod', 'cc')
SETTINGS = 24
PAYLOADS = (0.0, 9.81, 19.62)
WARM_AMPLITUDE = 0.015
WARM_SAMPLES = 180
#: Atlas grids timed per level (grid^3 samples in one chunk); full is slower.
ATLAS_GRID = {'full': 4, 'rod': 6, 'cc': 10}


def errors(robots: Dict[str, DeltaRobot]) -> Dict[str, Dict[str, float]]:
    """Largest and median errors of each reduced level against full legs."""
    stroke = robots['full'].geometry.slider_stroke
    sliders = (2.0 * qmc.Halton(d=3, seed=7).random(SETTINGS) - 1.0) * stroke
    found: Dict[str, Dict[str, List[float]]] = {
        level: {'position': [], 'angle': [], 'compliance': [], 'unvalidated': []}
        for level in LEVELS[1:]}
    for setting in sliders:
        for load in PAYLOADS:
            payload = (0.0, 0.0, -load)
            full = robots['full'].solve(setting, payload, warm_start=False, compliance=True)
            for level in LEVELS[1:]:
                result = robots[level].solve(setting, payload, warm_start=False,
                                             compliance=True)
                if not (full.converged and result.converged):
                    continue
                record = found[level]
                record['position'].append(float(np.linalg.norm(
                    result.platform_position - full.platform_position)))
                record['angle'].append(math.degrees(float(np.linalg.norm(
                    result.platform_rotation_vector - full.platform_rotation_vector))))
                assert full.platform_compliance is not None  # asked for: compliance=True
                assert result.platform_compliance is not None
                scale = np.abs(full.platform_compliance).max()
                record['compliance'].append(float(np.abs(
                    result.platform_compliance - full.platform_compliance).max() / scale))
                record['unvalidated'].append(
                    float(not np.all(np.isfinite(result.leg_error_bound_m))))
    return {level: {'samples': len(values['position']),
                    'max_position_m': max(values['position']),
                    'median_position_m': statistics.median(values['position']),
                    'max_angle_deg': max(values['angle']),
                    'max_compliance_rel': max(values['compliance']),
                    'unvalidated_share': statistics.mean(values['unvalidated'])}
            for level, values in found.items()}


def warm_time(robot: DeltaRobot) -> Dict[str, float]:
    """
    Warm forward statics along the slider circle under 1 kg: median time (s) and work.

    The work per solve (means): Newton iterations and leg Jacobians made (for reduced legs,
    the coupled Newton's leg linearizations; each iterate evaluates every leg's residual).
    """
    times, iterations, jacobians = [], [], []
    robot.reset()
    for step in range(WARM_SAMPLES + 1):
        angle = math.radians(2.0 * step)
        sliders = [WARM_AMPLITUDE * math.sin(angle + 2.0 * math.pi * k / 3) for k in range(3)]
        started = time.perf_counter()
        result = robot.solve(sliders, (0.0, 0.0, -9.81))
        times.append(time.perf_counter() - started)
        iterations.append(result.iterations)
        jacobians.append(result.leg_jacobians)
    return {'median_s': statistics.median(times[1:]),
            'iterations': statistics.mean(iterations[1:]),
            'leg_jacobians': statistics.mean(jacobians[1:])}


def atlas_rate(level: str) -> float:
    """Atlas samples per second of one process at ``level`` (one chunk, cold start)."""
    grid = ATLAS_GRID[level]
    spec = AtlasSpec.build(grid, [(0.0, 0.0, -9.81)], fidelity=level)
    solve_chunk(spec, 0, min(8, spec.size))  # the robot is built and warmed once per process
    started = time.perf_counter()
    solve_chunk(spec, 0, spec.size)
    return spec.size / (time.perf_counter() - started)


def main() -> None:
    """Measure, print and write bench/results/robot_levels.md and robot_levels.json."""
    robots = {level: DeltaRobot(fidelity=level) for level in LEVELS}
    error = errors(robots)
    work = {level: warm_time(robots[level]) for level in LEVELS}
    warm = {level: values['median_s'] for level, values in work.items()}
    rate = {level: atlas_rate(level) for level in LEVELS}
    lines = ['# The robot on every leg level', '',
             f'`python -m bench.robot_levels` on {platform.processor() or platform.machine()}, '
             f'{os.cpu_count()} cores, one process; ratios within this run.', '',
             f'Error against full legs, cold solves at {SETTINGS} slider settings (Halton over '
             f'the stroke cube) x payloads {PAYLOADS} N downward:', '',
             '| level | samples | max position error | median | max rotation error | '
             'max compliance error (rel.) | legs outside the validated box |',
             '|---|---|---|---|---|---|---|']
    for level, values in error.items():
        lines.append(f"| {level} | {values['samples']} | {values['max_position_m']:.2e} m | "
                     f"{values['median_position_m']:.2e} m | "
                     f"{values['max_angle_deg']:.2e} deg | "
                     f"{values['max_compliance_rel']:.2e} | "
                     f"{values['unvalidated_share']:.0%} of solves |")
    lines += ['', 'Speed: warm forward statics along the slider circle (1 kg, no compliance, '
              'median; with the mean Newton iterations and leg Jacobians made per solve) and '
              'atlas samples/s (one chunk of grid^3 samples, started cold, in one process: '
              f'grids {ATLAS_GRID}; compliance and verdicts, no Dask, no Zarr: the '
              "solver's rate; the `atlas` command's, in chunks on Dask workers with Zarr "
              'writes, is in atlas_scale.md):', '',
              '| level | warm forward statics | vs full | iterations | leg Jacobians | '
              'atlas samples/s | vs full |',
              '|---|---|---|---|---|---|---|']
    for level in LEVELS:
        lines.append(f'| {level} | {warm[level] * 1e6:.0f} us | '
                     f'{warm["full"] / warm[level]:.1f}x faster | '
                     f'{work[level]["iterations"]:.2f} | {work[level]["leg_jacobians"]:.2f} | '
                     f'{rate[level]:.0f} | {rate[level] / rate["full"]:.1f}x |')
    lines += ['', f'Targets: cc warm forward statics <= 20 us (measured '
              f'{warm["cc"] * 1e6:.0f} us); atlas at cc >= 1e4 samples/s on one worker '
              f'(measured {rate["cc"]:.0f}/s); atlas at full >= 300 samples/s (measured '
              f'{rate["full"]:.0f}/s).']
    text = '\n'.join(lines) + '\n'
    print(text)
    RESULT.write_text(text)
    NUMBERS.write_text(json.dumps({
        'machine': f'{platform.machine()}, {os.cpu_count()} cores',
        'settings': SETTINGS, 'payloads_n': PAYLOADS, 'errors_against_full': error,
        'warm_forward_statics_s': warm, 'warm_forward_statics_work': work,
        'atlas_samples_per_s': rate}, indent=1) + '\n')


if __name__ == '__main__':
    main()
