"""
Continuum Delta Robot forward statics: solve times and the platform's parasitic rotation.

Usage: python -m bench.delta_statics  (prints, and writes bench/results/delta_statics.md)

Cold: from home (straight legs, no load), a fresh continuation. Warm: the sliders follow a
slow circle (q_i = A sin(t + 2 pi i / 3), 2 deg of t per solve) under a 1 kg payload, each
solve warm-started from the previous one. Sweep: at each slider setting a 1 kg (9.81 N)
and a 20 N payload in 26 directions (the cube's faces, edges and corners), solved in turn
(warm); reported are the platform's largest motion and turn away from its unloaded pose,
and the turn it already has without payload (the kinematic part).
"""

import itertools
import math
import os
from pathlib import Path
import platform
import statistics
from typing import List, Tuple

from cdr_translator import geometry
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.result import DeltaResult
import numpy as np

RESULT = Path(__file__).resolve().parent / 'results' / 'delta_statics.md'

COLD_CASES = (((0.0, 0.0, 0.0), (0.0, 0.0, -9.81)),
              ((0.01, -0.005, 0.002), (0.0, 0.0, -9.81)),
              ((0.02, 0.0, -0.02), (2.0, 1.0, -9.81)),
              ((0.03, -0.03, 0.0), (0.0, 0.0, 0.0)))
SWEEP_SLIDERS = ((0.0, 0.0, 0.0), (0.01, -0.005, 0.002), (0.02, 0.0, -0.02))


#: The warm sequence's payload (1 kg) and slider circle (amplitude m, steps of 2 deg).
WARM_PAYLOAD = (0.0, 0.0, -9.81)
WARM_AMPLITUDE = 0.015
WARM_SAMPLES = 180


def slider_circle(amplitude: float = WARM_AMPLITUDE, samples: int = WARM_SAMPLES) -> np.ndarray:
    """Slider positions (samples + 1, 3) along q_i = A sin(t + 2 pi i / 3), 2 deg of t apart."""
    phases = np.arange(3) * 2.0 * math.pi / 3.0
    return np.array([amplitude * np.sin(math.radians(2.0 * k) + phases)
                     for k in range(samples + 1)])


def cold_solves(robot: DeltaRobot, repeats: int = 3) -> List[Tuple[float, DeltaResult]]:
    """Median cold solve time (s) of each COLD_CASES case, and its last result."""
    out = []
    for sliders, payload in COLD_CASES:
        times = []
        for _ in range(repeats):
            robot.reset()
            result = robot.solve(sliders, payload)
            times.append(result.solve_time_s)
        out.append((statistics.median(times), result))
    return out


def warm_solves(robot: DeltaRobot, amplitude: float = WARM_AMPLITUDE,
                samples: int = WARM_SAMPLES) -> List[DeltaResult]:
    """Warm solves along the slider circle after one from home (not returned); all converge."""
    robot.reset()
    results = []
    for sliders in slider_circle(amplitude, samples):
        result = robot.solve(sliders, WARM_PAYLOAD)
        assert result.converged, result.message
        results.append(result)
    return results[1:]


def _work(result: DeltaResult) -> str:
    return (f'{result.iterations} Newton iterations, {result.leg_solves} leg solves, '
            f'{result.leg_shots} leg shots, {result.leg_jacobians} leg Jacobians')


def _cold(robot: DeltaRobot) -> List[str]:
    lines = ['cold solves (from home)']
    for (sliders, payload), (median, result) in zip(COLD_CASES, cold_solves(robot)):
        lines.append(f'  q = {sliders} m, payload {payload} N: converged {result.converged}, '
                     f'{1e3 * median:.1f} ms (median of 3), {_work(result)}, '
                     f'equilibrium residual {result.equilibrium_residual_norm:.1e}')
    return lines


def _warm(robot: DeltaRobot) -> List[str]:
    results = warm_solves(robot)
    times = sorted(result.solve_time_s for result in results)
    mean = {name: statistics.mean(getattr(result, name) for result in results)
            for name in ('iterations', 'leg_solves', 'leg_shots', 'leg_jacobians')}
    return [f'warm solves (slider circle, amplitude {1e3 * WARM_AMPLITUDE:g} mm, '
            f'{WARM_SAMPLES} steps): median {1e3 * statistics.median(times):.2f} ms, '
            f'90th percentile {1e3 * times[int(0.9 * len(times))]:.2f} ms, '
            f'max {1e3 * times[-1]:.2f} ms; mean per solve '
            + ', '.join(f'{value:.2f} {name}' for name, value in mean.items())]


def _sweep(robot: DeltaRobot) -> List[str]:
    directions = [np.array(d, float) / np.linalg.norm(d)
                  for d in itertools.product((-1, 0, 1), repeat=3) if any(d)]
    lines = ['payload sweep (26 directions)']
    for sliders in SWEEP_SLIDERS:
        robot.reset()
        unloaded = robot.solve(sliders, (0.0, 0.0, 0.0))
        lines.append(f'  q = {sliders} m: rotation without payload '
                     f'{math.degrees(unloaded.platform_rotation_angle):.3f} deg')
        for magnitude in (9.81, 20.0):
            motion, turn, times, residual = [], [], [], []
            for direction in directions:
                result = robot.solve(sliders, magnitude * direction)
                assert result.converged, result.message
                motion.append(np.linalg.norm(result.platform_position
                                             - unloaded.platform_position))
                turn.append(geometry.rotation_angle(result.platform_rotation
                                                    @ unloaded.platform_rotation.T))
                times.append(result.solve_time_s)
                residual.append(result.equilibrium_residual_norm)
            lines.append(f'    |F| = {magnitude:5.2f} N: motion <= {1e3 * max(motion):.4f} mm, '
                         f'rotation <= {math.degrees(max(turn)):.4f} deg '
                         f'({math.degrees(max(turn)) / magnitude:.4f} deg/N), '
                         f'equilibrium residual <= {max(residual):.1e}, '
                         f'solve median {1e3 * statistics.median(times):.1f} ms')
    return lines


def main() -> None:
    """Print the cold, warm and sweep measurements; write them to RESULT."""
    robot = DeltaRobot()
    lines = [*_cold(robot), *_warm(robot), *_sweep(robot)]
    text = '\n'.join(lines)
    print(text)
    RESULT.write_text(
        '# CDR forward statics: solve times, work per solve, parasitic rotation\n\n'
        f'Generated by `python -m bench.delta_statics` ({platform.python_implementation()} '
        f'{platform.python_version()}, {platform.machine()}, load average '
        f'{os.getloadavg()[0]:.1f} when it ended: the machine is shared, 2 cores).\n\n'
        f'```\n{text}\n```\n')


if __name__ == '__main__':
    main()
