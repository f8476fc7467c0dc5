"""
Latency and throughput of translator_node over DDS (localhost, its own domain).

Usage: python -m bench.node_latency [--rates 50 200 1000] [--seconds 3] [--no-log]
                                     [--compliance]

Starts the node, streams a smooth wrench sequence (a 0.5 Hz sweep of 0-12 N lateral force,
the kind a force sensor sends) at each rate, and reports per rate: wrenches sent, received
by the node, answered with a pose, skipped (latest wins), and the latency from the wrench's
header stamp to the pose's arrival at the client (same clock): median, 95th and 99th
percentile and maximum. "No backlog" means every received wrench was answered (none
skipped) and the latency did not grow. ``--no-log`` runs without the MCAP log, to see
what logging costs; ``--compliance`` subscribes to the compliance eigenvalues too.
"""

import argparse
import math
import os
from pathlib import Path
import signal
import tempfile
import time

from cdr_translator.interface import messages
from cdr_translator.ros.client import diagnostic_values, isolated_ros_env, NodeProcess
from cdr_translator.ros.client import TranslatorClient
import numpy as np


def stream(client: TranslatorClient, rate_hz: float, seconds: float) -> list:
    """Publish the sweep at ``rate_hz`` for ``seconds``; return the stamps sent."""
    count = int(rate_hz * seconds)
    started = time.monotonic()
    stamps = []
    for index in range(count):
        delay = started + index / rate_hz - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        force = 6.0 - 6.0 * math.cos(math.pi * index / rate_hz)
        stamps.append(client.publish((force, 0.5 * force, 0.0)))
    return stamps


def measure(client: TranslatorClient, rate_hz: float, seconds: float) -> dict:
    """Stream at one rate and return the counts and latency percentiles (ms)."""
    before = len(client.received[messages.END_DISK_POSE_TOPIC])
    stamps = stream(client, rate_hz, seconds)
    last = stamps[-1]
    answered = client.wait_for(
        lambda: client.messages_stamped(messages.DIAGNOSTICS_TOPIC, last), 30.0)
    time.sleep(0.2)
    poses = client.received[messages.END_DISK_POSE_TOPIC][before:]
    latencies = np.array([received - messages.stamp_to_ns(pose.header.stamp)
                          for pose, received in poses]) * 1e-6
    values = diagnostic_values(client.received[messages.DIAGNOSTICS_TOPIC][-1][0])
    return {'rate': rate_hz, 'sent': len(stamps), 'answered_last': answered,
            'received': int(values['received']), 'poses': len(poses),
            'skipped': int(values['skipped']), 'latencies_ms': latencies}


def main() -> None:
    """Print one line per rate."""
    parser = argparse.ArgumentParser(description='translator_node latency and throughput.')
    parser.add_argument('--rates', type=float, nargs='+',
                        default=[50.0, 200.0, 500.0, 1000.0, 2000.0])
    parser.add_argument('--seconds', type=float, default=3.0)
    parser.add_argument('--no-log', action='store_true', help='run without the MCAP log')
    parser.add_argument('--compliance', action='store_true',
                        help='also subscribe to the compliance eigenvalues')
    args = parser.parse_args()
    env = isolated_ros_env()
    os.environ.update(env)
    with tempfile.TemporaryDirectory() as folder:
        ros_args = ['-p', 'log_to_mcap:=false'] if args.no_log else [
            '-p', f'mcap_path:={Path(folder) / "bench.mcap"}']
        topics = [messages.END_DISK_POSE_TOPIC, messages.DIAGNOSTICS_TOPIC]
        if args.compliance:
            topics.append(messages.COMPLIANCE_EIGENVALUES_TOPIC)
        with NodeProcess(ros_args, env, Path(folder) / 'node.log') as node:
            client = TranslatorClient(topics, depth=10000)
            try:
                if not client.handshake(120.0):
                    raise SystemExit(f'node did not answer:\n{node.text()}')
                print(f"{'rate Hz':>8} {'sent':>6} {'recv':>6} {'poses':>6} {'skipped':>8} "
                      f"{'p50 ms':>7} {'p95 ms':>7} {'p99 ms':>7} {'max ms':>7}")
                received = skipped = 0
                for rate in args.rates:
                    row = measure(client, rate, args.seconds)
                    p50, p95, p99 = np.percentile(row['latencies_ms'], [50, 95, 99])
                    print(f"{rate:8.0f} {row['sent']:6d} {row['received'] - received:6d} "
                          f"{row['poses']:6d} {row['skipped'] - skipped:8d} {p50:7.2f} "
                          f"{p95:7.2f} {p99:7.2f} {row['latencies_ms'].max():7.2f}")
                    received, skipped = row['received'], row['skipped']
                node.stop(signal.SIGINT)
                print(node.text().strip().splitlines()[-1])
            finally:
                client.close()


if __name__ == '__main__':
    main()
