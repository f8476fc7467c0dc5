"""
Continuum Delta Robot forward statics: solve times and the platform's parasitic rotation.

Usage: python -m bench.delta_statics

Cold: from home (straight legs, no load), a fresh continuation. Warm: the sliders follow a
slow circle (q_i = A sin(t + 2 pi i / 3), 2 deg of t per solve) under a 1 kg payload, each
solve warm-started from the previous one. Sweep: at each slider setting a 1 kg (9.81 N)
and a 20 N payload in 26 directions (the cube's faces, edges and corners), solved in turn
(warm); reported are the platform's largest motion and turn away from its unloaded pose,
and the turn it already has without payload (the kinematic part).
"""

import itertools
import math
import statistics

from cdr_translator import geometry
from cdr_translator.robot.delta import DeltaRobot
import numpy as np

COLD_CASES = (((0.0, 0.0, 0.0), (0.0, 0.0, -9.81)),
              ((0.01, -0.005, 0.002), (0.0, 0.0, -9.81)),
              ((0.02, 0.0, -0.02), (2.0, 1.0, -9.81)),
              ((0.03, -0.03, 0.0), (0.0, 0.0, 0.0)))
SWEEP_SLIDERS = ((0.0, 0.0, 0.0), (0.01, -0.005, 0.002), (0.02, 0.0, -0.02))


def _cold(robot: DeltaRobot) -> None:
    print('cold solves (from home)')
    for sliders, payload in COLD_CASES:
        times = []
        for _ in range(3):
            robot.reset()
            result = robot.solve(sliders, payload)
            times.append(result.solve_time_s)
        print(f'  q = {sliders} m, payload {payload} N: converged {result.converged}, '
              f'{1e3 * statistics.median(times):.0f} ms (median of 3), '
              f'{result.iterations} Newton iterations, {result.leg_solves} leg solves, '
              f'equilibrium residual {result.equilibrium_residual_norm:.1e}')


def _warm(robot: DeltaRobot, amplitude: float = 0.015, samples: int = 180) -> None:
    robot.reset()
    phases = np.arange(3) * 2.0 * math.pi / 3.0
    times = []
    for k in range(samples + 1):
        sliders = amplitude * np.sin(math.radians(2.0 * k) + phases)
        result = robot.solve(sliders, (0.0, 0.0, -9.81))
        assert result.converged, result.message
        if k:
            times.append(result.solve_time_s)
    times.sort()
    print(f'warm solves (slider circle, amplitude {1e3 * amplitude:g} mm, {samples} steps): '
          f'median {1e3 * statistics.median(times):.1f} ms, '
          f'90th percentile {1e3 * times[int(0.9 * len(times))]:.1f} ms, '
          f'max {1e3 * times[-1]:.1f} ms')


def _sweep(robot: DeltaRobot) -> None:
    directions = [np.array(d, float) / np.linalg.norm(d)
                  for d in itertools.product((-1, 0, 1), repeat=3) if any(d)]
    print('payload sweep (26 directions)')
    for sliders in SWEEP_SLIDERS:
        robot.reset()
        unloaded = robot.solve(sliders, (0.0, 0.0, 0.0))
        print(f'  q = {sliders} m: rotation without payload '
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
            print(f'    |F| = {magnitude:5.2f} N: motion <= {1e3 * max(motion):.4f} mm, '
                  f'rotation <= {math.degrees(max(turn)):.4f} deg '
                  f'({math.degrees(max(turn)) / magnitude:.4f} deg/N), '
                  f'equilibrium residual <= {max(residual):.1e}, '
                  f'solve median {1e3 * statistics.median(times):.0f} ms')


def main() -> None:
    """Print the cold, warm and sweep measurements."""
    robot = DeltaRobot()
    _cold(robot)
    _warm(robot)
    _sweep(robot)


if __name__ == '__main__':
    main()
