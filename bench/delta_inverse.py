"""
Continuum Delta Robot inverse statics: warm per 1 mm path step and cold, against forward solves.

Usage: python -m bench.delta_inverse  (prints, and writes bench/results/delta_inverse.md)

The first line is the target row: the settled warm steps' median and mean against TARGET_S,
as ratios with the absolute times beside them, their thread CPU time (without the waits for
a core of a shared machine), and the forward solve at the same sliders, which a warm step
makes once, against the same target.

Paths: PATHS straight target paths of STEPS steps of 1 mm under a 1 kg payload, each from
where random sliders (within START_STROKE of the stroke) put the platform, in a random
direction; a path ends early where it leaves the reachable set. Warm: every step's
``DeltaRobot.inverse`` (its ``solve_time_s``: the platform compliance of the answer is
made on first read of ``forward``, timed apart), its work counts, and, in the same run,
on second and third robots: the forward statics along the same sliders (warm, without
compliance) and the exact-slope Newton (``exact_slope_inverse``: every iterate a forward
solve with compliance, the method before the secants). Forward solves are timed around
the call, as the inverse's ``solve_time_s`` times its own. Cold: the first target of each
path from home (``warm_start=False``), against a cold forward solve at its sliders and the
exact-slope Newton from the sliders at home.
"""

import os
from pathlib import Path
import platform
import statistics
import time
from typing import Dict, List, Optional, Tuple

from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.inverse import InverseResult, POSITION_TOLERANCE
import numpy as np

RESULT = Path(__file__).resolve().parent / 'results' / 'delta_inverse.md'

PAYLOAD = (0.0, 0.0, -9.81)
PATHS = 6
STEPS = 15
STEP_M = 0.001
START_STROKE = 0.4

#: The target of a warm inverse per 1 mm path step (s): the bench prints the settled steps'
#: median and mean against it as ratios (1 or less: met), absolute figures beside them.
TARGET_S = 0.5e-3

#: The warm steps counted: after the first few of a path, whose extrapolation has not yet
#: the points it needs (they are reported apart).
SETTLED_AFTER = 5


def exact_slope_inverse(robot: DeltaRobot, target: np.ndarray, payload=PAYLOAD,
                        sliders: Optional[np.ndarray] = None, warm_start: bool = True,
                        tolerance: float = POSITION_TOLERANCE,
                        max_iterations: int = 40) -> Tuple[np.ndarray, np.ndarray, int]:
    """
    Newton on the sliders with the exact dp/dq at every iterate, for a target inside reach.

    Every iterate is a forward solve with ``compliance`` (its ``input_sensitivity``), from
    ``sliders`` (default: home; along a path the previous answer plus the first-order
    prediction with its slope). Returns the sliders, dp/dq there and the count of forward
    solves.
    """
    sliders = np.zeros(3) if sliders is None else np.array(sliders, dtype=float)
    result = robot.solve(sliders, payload, warm_start=warm_start, compliance=True)
    solves = 1
    while True:
        if solves > max_iterations or result.input_sensitivity is None:
            raise RuntimeError(f'exact-slope Newton failed at {target}: {result.message}')
        slope = result.input_sensitivity[:3, :3]
        error = result.platform_position - target
        if np.linalg.norm(error) <= tolerance:
            return sliders, slope, solves
        sliders = sliders - np.linalg.solve(slope, error)
        result = robot.solve(sliders, payload, compliance=True)
        solves += 1


def straight_paths(seed: int = 7) -> List[np.ndarray]:
    """PATHS target paths (STEPS + 1, 3): STEP_M apart on a line from a reachable start."""
    robot = DeltaRobot()
    rng = np.random.default_rng(seed)
    stroke = robot.geometry.slider_stroke
    paths = []
    for _ in range(PATHS):
        sliders = rng.uniform(-START_STROKE * stroke, START_STROKE * stroke, 3)
        start = robot.solve(sliders, PAYLOAD, warm_start=False).platform_position
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        paths.append(start + STEP_M * np.arange(STEPS + 1)[:, None] * direction)
    return paths


def _timed_read(result: InverseResult) -> float:
    """Time the first read of ``result.forward`` (its compliance made then), s."""
    started = time.perf_counter()
    forward = result.forward
    if forward is None or forward.platform_compliance is None:
        raise RuntimeError(f'no compliance at the answer: {result.message}')
    return time.perf_counter() - started


def measure(paths: List[np.ndarray]) -> Dict[str, list]:
    """Solve every path (inverse, forward along its sliders, exact-slope Newton)."""
    robot, forward, reference = DeltaRobot(), DeltaRobot(), DeltaRobot()
    robot.inverse(paths[0][0], PAYLOAD, warm_start=False)  # kernels loaded
    data: Dict[str, list] = {name: [] for name in (
        'cold', 'cold_forward', 'cold_exact', 'warm', 'first', 'forward', 'exact', 'read',
        'gap', 'forward_jacobians', 'warm_cpu', 'forward_cpu')}
    for path in paths:
        cold = robot.inverse(path[0], PAYLOAD, warm_start=False)
        assert cold.reachable, cold.message
        data['cold'].append((cold.solve_time_s, cold))
        started = time.perf_counter()
        forward.solve(cold.sliders, PAYLOAD, warm_start=False)
        data['cold_forward'].append(time.perf_counter() - started)
        started = time.perf_counter()
        previous, slope, _ = exact_slope_inverse(reference, path[0], warm_start=False)
        data['cold_exact'].append(time.perf_counter() - started)
        data['read'].append(_timed_read(cold))
        for step, target in enumerate(path[1:], start=1):
            cpu = time.thread_time()
            result = robot.inverse(target, PAYLOAD)
            cpu = time.thread_time() - cpu
            if not result.reachable:
                break  # the path left the reachable set
            key = 'warm' if step > SETTLED_AFTER else 'first'
            data[key].append((result.solve_time_s, result))
            if key == 'warm':
                data['warm_cpu'].append(cpu)
            started, cpu = time.perf_counter(), time.thread_time()
            alone = forward.solve(result.sliders, PAYLOAD)
            data['forward'].append(time.perf_counter() - started)
            data['forward_cpu'].append(time.thread_time() - cpu)
            data['forward_jacobians'].append(alone.leg_jacobians)
            started = time.perf_counter()
            guess = previous + np.linalg.solve(slope, target - path[step - 1])
            answer, slope, solves = exact_slope_inverse(reference, target, sliders=guess)
            data['exact'].append((time.perf_counter() - started, solves))
            data['gap'].append(float(np.abs(answer - result.sliders).max()))
            previous = answer
            data['read'].append(_timed_read(result))
    return data


def _counts(results: List[InverseResult]) -> str:
    mean = {name: statistics.mean(getattr(result, name) for result in results)
            for name in ('forward_solves', 'exact_slopes', 'iterations', 'leg_solves',
                         'leg_jacobians')}
    forward = {name: statistics.mean(getattr(result.solution, name) for result in results
                                     if result.solution is not None)
               for name in ('iterations', 'leg_shots')}
    return ', '.join([f'{value:.2f} {name}' for name, value in mean.items()]
                     + [f'{value:.2f} forward {name}' for name, value in forward.items()])


def _verdict(seconds: float) -> str:
    """Say whether a time meets TARGET_S."""
    return 'met' if seconds <= TARGET_S else 'not met'


def report(data: Dict[str, list]) -> List[str]:
    """Return the measurements as lines: times in ms and as ratios to a forward solve."""
    forward = statistics.median(data['forward'])
    warm = [time for time, _ in data['warm']]
    first = [time for time, _ in data['first']]
    exact = statistics.median(time for time, _ in data['exact'])
    cold = [time for time, _ in data['cold']]
    read = statistics.median(data['read'])
    cold_forward = statistics.median(data['cold_forward'])
    ms = 1e3
    median, mean = statistics.median(warm), statistics.mean(warm)
    return [
        f'target row, robot inverse statics warm per {ms * STEP_M:g} mm step (target '
        f'<= {ms * TARGET_S:g} ms): median {ms * median:.3f} ms = {median / TARGET_S:.2f} x '
        f'target ({_verdict(median)}), mean {ms * mean:.3f} ms = {mean / TARGET_S:.2f} x '
        f'target ({_verdict(mean)}); its thread CPU time median '
        f'{ms * statistics.median(data["warm_cpu"]):.3f} ms = '
        f'{statistics.median(data["warm_cpu"]) / TARGET_S:.2f} x target (waits for a shared '
        f'core left out); the forward solve it makes alone (same run): {ms * forward:.3f} '
        f'ms = {forward / TARGET_S:.2f} x target, thread CPU time median '
        f'{ms * statistics.median(data["forward_cpu"]):.3f} ms',
        f'forward solve along the same sliders (warm, no compliance): median '
        f'{ms * forward:.3f} ms, {statistics.mean(data["forward_jacobians"]):.2f} leg_jacobians '
        'a solve',
        f'warm inverse per {ms * STEP_M:g} mm step, steps {SETTLED_AFTER + 1} to {STEPS} '
        f'({len(warm)} steps): median {ms * statistics.median(warm):.3f} ms '
        f'({statistics.median(warm) / forward:.2f} forward solves), mean '
        f'{ms * statistics.mean(warm):.3f} ms; per step {_counts([r for _, r in data["warm"]])}',
        f'warm inverse, steps 1 to {SETTLED_AFTER} ({len(first)} steps): median '
        f'{ms * statistics.median(first):.3f} ms ({statistics.median(first) / forward:.2f} '
        f'forward solves); per step {_counts([r for _, r in data["first"]])}',
        f'compliance of an answer, made on first read: median {ms * read:.3f} ms '
        f'({read / forward:.2f} forward solves)',
        f'exact-slope Newton per step (every iterate a forward solve with compliance): '
        f'median {ms * exact:.3f} ms ({exact / forward:.2f} forward solves), '
        f'{statistics.mean(solves for _, solves in data["exact"]):.2f} forward solves a step; '
        f'largest slider difference to the inverse {max(data["gap"]):.1e} m',
        f'cold inverse ({len(cold)} targets): median {ms * statistics.median(cold):.2f} ms, '
        f'max {ms * max(cold):.2f} ms ({statistics.median(cold) / forward:.1f} warm forward '
        f'solves; {statistics.median(cold) / cold_forward:.2f} cold forward solves at its '
        f'sliders, median {ms * cold_forward:.2f} ms); '
        f'per solve {_counts([r for _, r in data["cold"]])}',
        f'exact-slope Newton cold (from the sliders at home): median '
        f'{ms * statistics.median(data["cold_exact"]):.2f} ms '
        f'({statistics.median(data["cold_exact"]) / forward:.1f} warm forward solves)',
    ]


def main() -> None:
    """Print the warm and cold measurements; write them to RESULT."""
    lines = report(measure(straight_paths()))
    text = '\n'.join(lines)
    print(text)
    RESULT.write_text(
        '# CDR inverse statics: warm path steps and cold solves against forward solves\n\n'
        f'Generated by `python -m bench.delta_inverse` ({platform.python_implementation()} '
        f'{platform.python_version()}, {platform.machine()}, load average '
        f'{os.getloadavg()[0]:.1f} when it ended: the machine is shared, 2 cores; the ratios '
        'are measured in the same run).\n\n'
        f'```\n{text}\n```\n')


if __name__ == '__main__':
    main()
