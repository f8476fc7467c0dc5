"""
Replay with measured poses against the same replay without them: the cost of the estimates.

Usage: python -m bench.replay_poses [--count 200] [--rounds 15] [--out bench/results]

The recording is what ``python -m msg_tools synth OUT --profile random-walk --count 200
--measured-pose-noise 0.0002 0.1`` writes: 200 wrenches of a seeded random walk and, for
each, its end-disk pose at a tracker's noise (0.2 mm, 0.1 deg) on both measured-pose topics
(PoseStamped and PoseWithCovarianceStamped): 400 poses. The same walk without poses is the
reference. Each is replayed as a user replays it, ``python -m msg_tools replay`` in a
process of its own (the first solves load the compiled kernels), in turns, the order
swapped every round, with the estimate's default components (all six) and with 'lateral'
(the axial force and the moment held). The replay's own wall time (its summary line) is
taken; the median of the rounds is the row, the range beside it, the ratio per round. The
target: with poses within 3 times the replay without, judged on the distribution-free 95 %
confidence interval of the median ratio (scipy.stats.quantile_test: order statistics, no
assumption on the spread of a shared machine's times): met when the whole interval is
within it, missed when the whole interval is beyond it, else not decided by the rounds
measured (more rounds narrow the interval). Beside it the steady ratio: both
replayed again in this process after a warm-up, so that what loads once is left out and
only the per-message costs compare. Prints the table and writes
bench/results/replay_poses.md anew.
"""

import argparse
import math
from pathlib import Path
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Callable, Dict, List, Optional, Tuple

from msg_tools import synth
from msg_tools.replay import replay
from msg_tools.synth_poses import measure, PoseNoise
from scipy.stats import quantile_test

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / 'bench' / 'results'

#: The tracker's noise of the recording: position (m) and angle (deg).
NOISE = PoseNoise(0.0002, 0.1)

#: The replay with poses should take at most this many times the replay without.
TARGET_RATIO = 3.0

#: Confidence of the interval of the median ratio the verdict is judged on.
CONFIDENCE = 0.95

#: The estimate's components of each row (None: the params file's default, all six).
CHOICES: Tuple[Tuple[str, Optional[str]], ...] = (('wrench (default)', None),
                                                  ('lateral', 'lateral'))

#: The replay summary's line of its own wall time.
WALL_LINE = re.compile(r'^wall time s\s+([0-9.]+)$', re.MULTILINE)


def recordings(folder: Path, count: int) -> Tuple[Path, Path]:
    """Write the walk with its poses and the walk alone (synth's defaults, seed 0)."""
    samples = synth.generate('random-walk', count=count)
    poses, frame_id = measure(samples, NOISE)
    with_poses, alone = folder / 'walk_and_poses.mcap', folder / 'walk.mcap'
    synth.write_wrenches(with_poses, samples, poses=poses, pose_frame_id=frame_id)
    synth.write_wrenches(alone, samples)
    return with_poses, alone


def command_line_replay(bag: Path, out: Path, components: Optional[str]) -> float:
    """Replay ``bag`` by ``python -m msg_tools replay``; return its wall time (s)."""
    command = [sys.executable, '-m', 'msg_tools', 'replay', str(bag), '--out', str(out)]
    if components is not None:
        command += ['--estimate', components]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=True)
    match = WALL_LINE.search(done.stdout)
    if match is None:
        raise RuntimeError(f'no wall time in the replay summary:\n{done.stdout}')
    return float(match.group(1))


def in_process_replay(bag: Path, out: Path, components: Optional[str]) -> Tuple[float, str]:
    """Replay ``bag`` in this process; return its wall time (s) and its pose counts."""
    parameters = None if components is None else {'estimate_components': components}
    summary = replay(bag, out, parameters=parameters)
    return summary.wall_s, (f'{summary.poses}: {summary.estimated} estimated, '
                            f'{summary.flagged} flagged, {summary.failed} failed')


def in_turns(run: Callable[[Path], float], with_poses: Path, alone: Path,
             rounds: int) -> Dict[str, List[float]]:
    """Call ``run(bag)`` on both recordings ``rounds`` times, the order swapped each round."""
    times: Dict[str, List[float]] = {'alone': [], 'poses': []}
    order = [('alone', alone), ('poses', with_poses)]
    for index in range(rounds):
        for name, bag in order if index % 2 == 0 else list(reversed(order)):
            times[name].append(run(bag))
    return times


def _median_range(values: List[float]) -> str:
    """Return 'median (min-max)', 3 significant digits."""
    return f'{statistics.median(values):.3g} ({min(values):.3g}-{max(values):.3g})'


def _ratios(times: Dict[str, List[float]]) -> List[float]:
    """Return the ratio with poses to without, per round."""
    return [poses / alone for poses, alone in zip(times['poses'], times['alone'])]


def verdict(ratios: List[float], target: float = TARGET_RATIO) -> str:
    """
    Judge the median of ``ratios`` against ``target`` on its CONFIDENCE interval.

    'met' when the whole interval is at most ``target``, 'missed' when it is all beyond it,
    else 'not decided' (the interval holds the target); the interval in brackets. Fewer
    than six rounds have no such interval (their widest, the range, covers 94 %).
    """
    interval = quantile_test(ratios, q=target, p=0.5).confidence_interval(CONFIDENCE)
    low, high = float(interval.low), float(interval.high)
    if math.isnan(low) or math.isnan(high):
        return (f'not decided ({len(ratios)} rounds are too few for a {CONFIDENCE:.0%} '
                'interval of the median)')
    decided = 'met' if high <= target else 'missed' if low > target else 'not decided'
    return f'{decided} (median {CONFIDENCE:.0%} interval {low:.3g}-{high:.3g})'


def measure_choice(label: str, components: Optional[str], with_poses: Path, alone: Path,
                   folder: Path, rounds: int) -> str:
    """Measure one choice of components; return its markdown row."""
    out = folder / 'out.mcap'
    cli = in_turns(lambda bag: command_line_replay(bag, out, components), with_poses, alone,
                   rounds)
    in_process_replay(alone, out, components)  # warm-up: kernels loaded, imports done
    counts = in_process_replay(with_poses, out, components)[1]
    steady = in_turns(lambda bag: in_process_replay(bag, out, components)[0], with_poses,
                      alone, rounds)
    return (f"| {label} | {_median_range(cli['alone'])} | {_median_range(cli['poses'])} | "
            f'{_median_range(_ratios(cli))} | {TARGET_RATIO:g}x: {verdict(_ratios(cli))} | '
            f'{_median_range(_ratios(steady))} | {counts} |')


def main() -> None:
    """Measure every choice of components; print and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--count', type=int, default=200, help='wrenches; default 200')
    parser.add_argument('--rounds', type=int, default=15,
                        help='timed rounds; default 15 (fewer than 6 cannot decide the '
                             'target: see verdict)')
    parser.add_argument('--out', type=Path, default=RESULTS, help='results folder')
    args = parser.parse_args()
    lines = ['| estimate | without poses, s | with poses, s | ratio | target | '
             'steady ratio (in one process) | poses |', '|---|---|---|---|---|---|---|']
    with tempfile.TemporaryDirectory() as folder:
        with_poses, alone = recordings(Path(folder), args.count)
        for label, components in CHOICES:
            lines.append(measure_choice(label, components, with_poses, alone, Path(folder),
                                        args.rounds))
            print(lines[-1], flush=True)
    header = [
        '# Replay with measured poses',
        '',
        f'`python -m bench.replay_poses --count {args.count} --rounds {args.rounds}`, '
        f'{time.strftime("%Y-%m-%d")}, {platform.machine()}, 2 cores. A random walk of '
        f'{args.count} wrenches with its end-disk pose at {NOISE.position_m * 1e3:g} mm / '
        f'{NOISE.angle_deg:g} deg on both measured-pose topics ({2 * args.count} poses), '
        'replayed by `python -m msg_tools replay` against the same walk without poses '
        '(module docstring of `bench/replay_poses.py`). Times are the own wall time of the '
        f'replay, median (range) of {args.rounds} rounds; ratios per round, the target judged '
        f'on the {CONFIDENCE:.0%} confidence interval of their median. The steady ratio '
        'leaves out what a process loads once.',
        '']
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'replay_poses.md').write_text('\n'.join(header + lines) + '\n')
    print(f"wrote {args.out / 'replay_poses.md'}")


if __name__ == '__main__':
    main()
