"""
``make demo``: translator_node live on a sample bag over DDS, recorded to MCAP, summarized.

Usage: python scripts/demo.py [--bags FILE.mcap ...] [--out FILE.mcap] [--speed FACTOR]

Starts the node (its own ROS_DOMAIN_ID, localhost discovery) with its MCAP log at ``--out``,
plays the WrenchStamped messages of the bags (default: the 100 Hz oblique sinusoid, then
the hard cases with their four bad messages) to ``wrench`` with the bags' timing
(restamped now, so the latency from stamp to pose can be measured), waits for the last
answer, stops
the node with SIGINT and prints a summary of the recorded run: messages per topic, the
node's counts, solve-time and latency percentiles, angle ranges (the bending directions by
circular mean and standard deviation: they wrap) and end-disk position ranges.
Exit code 0 when the node answered and exited cleanly.
"""

import argparse
import datetime
import os
from pathlib import Path
import signal
import sys
import time
from typing import Any, Dict, List, Sequence, Tuple

from cdr_translator.interface import messages
from cdr_translator.interface.joint_summary import JointSummary
from cdr_translator.ros.client import diagnostic_values, isolated_ros_env, NodeProcess
from cdr_translator.ros.client import TranslatorClient
from cdr_wire.reader import McapSource
from geometry_msgs.msg import WrenchStamped
from mcap_ros2.reader import read_ros2_messages
import numpy as np
from rclpy.serialization import deserialize_message

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BAGS = (ROOT / 'bags' / 'sinusoid_oblique.mcap', ROOT / 'bags' / 'hard_cases.mcap')
START_TIMEOUT_S = 120.0
ANSWER_TIMEOUT_S = 30.0


def read_wrenches(bag: Path) -> List[Tuple[int, WrenchStamped]]:
    """Return (log time ns, message) of every WrenchStamped in the bag, in file order."""
    source = McapSource(bag)
    found = [(raw.log_time_ns, deserialize_message(raw.data, WrenchStamped))
             for raw in source.messages() if raw.schema_name == messages.WRENCH_TYPE]
    if not found:
        raise SystemExit(f'{bag}: no {messages.WRENCH_TYPE} messages')
    return found


def play(client: TranslatorClient, wrenches: Sequence[Tuple[int, WrenchStamped]],
         speed: float) -> List[dict]:
    """Publish the wrenches with the bag's spacing divided by ``speed``; return the stamps."""
    first = wrenches[0][0]
    started = time.monotonic()
    stamps: List[dict] = []
    for log_time_ns, message in wrenches:
        delay = started + (log_time_ns - first) * 1e-9 / speed - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        stamp = messages.stamp_from_ns(time.time_ns())
        message.header.stamp.sec, message.header.stamp.nanosec = stamp['sec'], stamp['nanosec']
        client.publisher.publish(message)
        stamps.append(stamp)
    return stamps


def percentiles_ms(values_ms: Sequence[float]) -> str:
    """Return 'p50 / p90 / p99 / max' of values in ms."""
    if not len(values_ms):
        return 'none'
    p50, p90, p99 = np.percentile(values_ms, [50, 90, 99])
    return f'{p50:.3f} / {p90:.3f} / {p99:.3f} / {max(values_ms):.3f}'


def summary(recorded: Path, latencies_ms: Sequence[float]) -> List[Tuple[str, str]]:
    """Return the (name, value) rows describing the recorded run."""
    by_topic: Dict[str, List[Any]] = {}
    for message in read_ros2_messages(str(recorded)):
        by_topic.setdefault(message.channel.topic, []).append(message.ros_msg)
    rows = [(f'messages {topic}', str(len(found))) for topic, found in sorted(by_topic.items())]
    diagnostics = by_topic.get(messages.DIAGNOSTICS_TOPIC, [])
    if diagnostics:   # the last aggregated array: the node's closing counts
        last = diagnostic_values(diagnostics[-1])
        rows += [(f'node {key}', last[key]) for key in
                 ('received', 'solved', 'rejected', 'not_converged', 'skipped')]
    statuses = by_topic.get('/' + messages.SOLVE_STATUS_TOPIC, [])
    solve_ms = [float(diagnostic_values(d)['solve_time_ms']) for d in statuses
                if 'solve_time_ms' in diagnostic_values(d)]
    rows.append(('solve time ms p50/p90/p99/max', percentiles_ms(solve_ms)))
    rows.append(('latency stamp->pose ms p50/p90/p99/max', percentiles_ms(latencies_ms)))
    joints = JointSummary()
    for angles in by_topic.get('/bending_angles', []):
        joints.add(list(angles.position))
    rows += joints.rows()
    positions = 1e3 * np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z]
                                for p in by_topic.get('/end_disk_pose', [])])
    for column, axis in enumerate('xyz' if len(positions) else ''):
        rows.append((f'end disk {axis} mm min..max',
                     f'{positions[:, column].min():.3f} .. {positions[:, column].max():.3f}'))
    return rows


def demo_parser() -> argparse.ArgumentParser:
    """Return the demo's argument parser (every flag with its help)."""
    parser = argparse.ArgumentParser(
        description='translator_node live on sample bags over DDS, recorded to MCAP, '
                    'summarized.')
    parser.add_argument('--bags', type=Path, nargs='+', default=list(DEFAULT_BAGS),
                        metavar='FILE.mcap',
                        help='WrenchStamped recordings played to the node, in order, with '
                             'their timing (default: bags/sinusoid_oblique.mcap, then '
                             'bags/hard_cases.mcap)')
    parser.add_argument('--out', type=Path, default=ROOT / 'cdr_runs' / datetime.datetime.now(
        datetime.timezone.utc).strftime('demo_%Y-%m-%d_%H-%M-%S.mcap'), metavar='FILE.mcap',
        help="the node's MCAP log (default: cdr_runs/demo_<UTC time>.mcap); its console "
             'output goes beside it (.log)')
    parser.add_argument('--speed', type=float, default=1.0, metavar='FACTOR',
                        help='playback speed factor: 2 plays twice as fast (default: 1)')
    return parser


def main() -> int:
    """Run the demo; return the exit code."""
    args = demo_parser().parse_args()
    bags = [(bag, read_wrenches(bag)) for bag in args.bags]
    env = isolated_ros_env()
    os.environ.update(env)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    print(f'translator_node (ROS_DOMAIN_ID {env["ROS_DOMAIN_ID"]}) recording to {args.out}')
    with NodeProcess(['-p', f'mcap_path:={args.out}'], env,
                     args.out.with_suffix('.log')) as node:
        client = TranslatorClient()
        try:
            if not client.handshake(START_TIMEOUT_S):
                print(f'the node did not answer:\n{node.text()}', file=sys.stderr)
                return 1
            stamps = []
            for bag, wrenches in bags:
                print(f'playing {bag.name}: {len(wrenches)} wrenches over '
                      f'{(wrenches[-1][0] - wrenches[0][0]) * 1e-9 / args.speed:.2f} s')
                stamps += play(client, wrenches, args.speed)
            answered = client.wait_for(lambda: bool(client.messages_stamped(
                messages.SOLVE_STATUS_TOPIC, stamps[-1])), ANSWER_TIMEOUT_S)
            played = {(stamp['sec'], stamp['nanosec']) for stamp in stamps}
            latencies_ms = [1e-6 * (received - messages.stamp_to_ns(pose.header.stamp))
                            for pose, received in client.received[messages.END_DISK_POSE_TOPIC]
                            if (pose.header.stamp.sec, pose.header.stamp.nanosec) in played]
        finally:
            client.close()
        began = time.monotonic()
        code = node.stop(signal.SIGINT)
        stopped_s = time.monotonic() - began
    handshakes = len(client.handshake_stamps)
    rows = [('wrenches played', f'{len(stamps)} (and {handshakes} handshake '
             f'wrench{"es" if handshakes > 1 else ""} before them)'),
            ('played wrenches answered', f'{len(latencies_ms)} of {len(stamps)} '
             '(a wrench that arrives before the solver took the previous one replaces it)')]
    rows += summary(args.out, latencies_ms)
    rows.append(('last wrench answered', 'yes' if answered else 'NO'))
    rows.append(('node exit (SIGINT)', f'code {code} after {stopped_s:.2f} s'))
    width = max(len(name) for name, _ in rows)
    print('\n'.join(f'{name:<{width}}  {value}' for name, value in rows))
    print(f'node output: {args.out.with_suffix(".log")}')
    return 0 if answered and code == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
