"""
Latency and throughput of translator_node over DDS (localhost, its own domain).

Usage: python -m bench.node_latency [--rates 100 200 500 1000 2000] [--seconds 3] [--no-log]
                                     [--compliance] [--node-python PY] [--label TEXT]
                                     [--markdown FILE] [--profile OUT.md] [--rest-noise N]
                                     [--param NAME:=VALUE]...

Starts the node, streams a smooth wrench sequence (a 0.5 Hz sweep of 0-12 N lateral force,
the kind a force sensor sends; with ``--rest-noise N`` instead a sensor at rest: Gaussian
noise of N newtons on each force component around zero, seeded) at each rate, and reports
per rate: wrenches sent, received by the node, answered with a pose, skipped (latest wins),
and the latency from the wrench's header stamp to the pose's arrival at the client (same
clock): median, 95th and 99th percentile and maximum. "No backlog" means every received
wrench was answered (none skipped) and the latency did not grow. ``--no-log`` runs without
the MCAP log, to see what logging costs; ``--compliance`` subscribes to the compliance
eigenvalues too. ``--node-python`` runs the node with another checkout's interpreter (``-m
cdr_translator.ros.translator_node`` of that venv, without this checkout on PYTHONPATH), so
two checkouts' nodes can be measured with the same client in the same minutes;
``--markdown`` appends the table to a file (bench/results/node_rate.md). ``--profile`` runs
this checkout's node under bench.node_profile (timers around its stages, every thread's CPU
time), which writes its account to OUT.md when the node stops (use one rate per run to see
that rate's split).
``--param`` sets one of the node's parameters (``-p NAME:=VALUE``, e.g. pending_wrenches:=1).

The publisher sleeps between wrenches (no busy spin); the client runs without the cyclic
garbage collector (a collection over the messages it keeps stalled it by 0.2-0.3 s). The
client process (publisher and recorder) shares the machine with the node: on a loaded
machine both lose time, so compare rows measured in the same run only.
"""

import argparse
import datetime
import gc
import math
import os
from pathlib import Path
import signal
import sys
import tempfile
import time
from typing import List, Tuple

from cdr_translator.interface import messages
from cdr_translator.ros.client import diagnostic_values, isolated_ros_env, MODULE_COMMAND
from cdr_translator.ros.client import NodeProcess, TranslatorClient
import numpy as np


def stream(client: TranslatorClient, rate_hz: float, seconds: float,
           rest_noise: float = 0.0) -> list:
    """Publish the sweep (or noise at rest) at ``rate_hz`` for ``seconds``; return the stamps."""
    count = int(rate_hz * seconds)
    noise = np.random.default_rng(int(rate_hz)).normal(scale=rest_noise, size=(count, 3))
    started = time.monotonic()
    stamps = []
    for index in range(count):
        delay = started + index / rate_hz - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        if rest_noise > 0.0:
            stamps.append(client.publish(tuple(noise[index])))
            continue
        force = 6.0 - 6.0 * math.cos(math.pi * index / rate_hz)
        stamps.append(client.publish((force, 0.5 * force, 0.0)))
    return stamps


def cpu_seconds(pid: int) -> float:
    """
    Return the CPU time (user + system, s) process ``pid`` and its children used so far.

    Its running children (the MCAP log process) count too (Linux /proc).
    """
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    total = (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    return total + sum(cpu_seconds(child) for child in child_pids(pid))


def child_pids(pid: int) -> List[int]:
    """Return the running child processes of ``pid`` (a scan of /proc/*/stat)."""
    found = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / 'stat').read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(entry.name))
    return found


def measure(client: TranslatorClient, rate_hz: float, seconds: float, pid: int,
            rest_noise: float = 0.0) -> dict:
    """Stream at one rate and return the counts, latencies (ms) and the node's CPU time (s)."""
    before = len(client.received[messages.END_DISK_POSE_TOPIC])
    cpu_before = cpu_seconds(pid)
    stamps = stream(client, rate_hz, seconds, rest_noise)
    last = stamps[-1]
    answered = client.wait_for(
        lambda: bool(client.messages_stamped(messages.DIAGNOSTICS_TOPIC, last)), 30.0)
    time.sleep(0.2)
    cpu = cpu_seconds(pid) - cpu_before
    poses = client.received[messages.END_DISK_POSE_TOPIC][before:]
    latencies = np.array([received - messages.stamp_to_ns(pose.header.stamp)
                          for pose, received in poses]) * 1e-6
    values = diagnostic_values(client.received[messages.DIAGNOSTICS_TOPIC][-1][0])
    return {'rate': rate_hz, 'sent': len(stamps), 'answered_last': answered,
            'received': int(values['received']), 'poses': len(poses),
            'skipped': int(values['skipped']), 'latencies_ms': latencies, 'cpu_s': cpu}


def main() -> None:
    """Print one line per rate (and append them to --markdown)."""
    parser = argparse.ArgumentParser(description='translator_node latency and throughput.')
    parser.add_argument('--rates', type=float, nargs='+',
                        default=[100.0, 200.0, 500.0, 1000.0, 2000.0])
    parser.add_argument('--seconds', type=float, default=3.0)
    parser.add_argument('--no-log', action='store_true', help='run without the MCAP log')
    parser.add_argument('--compliance', action='store_true',
                        help='also subscribe to the compliance eigenvalues')
    parser.add_argument('--node-python', default=None,
                        help='interpreter of the checkout whose node to run (default: this one)')
    parser.add_argument('--label', default='this checkout', help='name of the node measured')
    parser.add_argument('--markdown', type=Path, default=None,
                        help='append the table to this markdown file')
    parser.add_argument('--profile', type=Path, default=None,
                        help="write the node's CPU account (bench.node_profile) to this file")
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help="a parameter of the node's (-p NAME:=VALUE), e.g. "
                             'pending_wrenches:=1; repeatable')
    parser.add_argument('--rest-noise', type=float, default=0.0,
                        help='stream a sensor at rest: this much Gaussian noise (N) per force '
                             'component around zero, instead of the sweep')
    args = parser.parse_args()
    env = isolated_ros_env()
    os.environ.update(env)
    node_env, checkout = dict(env), None
    command: Tuple[str, ...] = MODULE_COMMAND
    if args.node_python:
        node_env.pop('PYTHONPATH', None)
        command = (args.node_python, *MODULE_COMMAND[1:])
        # CHECKOUT/.venv/bin/python (not resolved: the venv's python is a symlink); -m
        # imports from the working directory, which must be that checkout (until
        # 2026-12-02 it was this one, so such runs measured this checkout's node)
        checkout = Path(args.node_python).absolute().parents[2]
        if not (checkout / 'cdr_translator').is_dir():
            raise SystemExit(f'--node-python: no cdr_translator beside {checkout / ".venv"}')
    elif args.profile:
        command = (sys.executable, '-m', 'bench.node_profile', str(args.profile.resolve()))
    with tempfile.TemporaryDirectory() as folder:
        ros_args = ['-p', 'log_to_mcap:=false'] if args.no_log else [
            '-p', f'mcap_path:={Path(folder) / "bench.mcap"}']
        for assignment in args.param:
            ros_args += ['-p', assignment]
        topics = [messages.END_DISK_POSE_TOPIC, messages.DIAGNOSTICS_TOPIC]
        if args.compliance:
            topics.append(messages.COMPLIANCE_EIGENVALUES_TOPIC)
        with NodeProcess(ros_args, node_env, Path(folder) / 'node.log', command,
                         checkout) as node:
            client = TranslatorClient(topics, depth=10000)
            # the client keeps every message it receives: a full collection over them
            # stalled its callbacks by 190-320 ms once per 1-2 kHz row (counted as the
            # node's latency until 2026-12-02); nothing here needs the cyclic collector
            gc.disable()
            try:
                if not client.handshake(120.0):
                    raise SystemExit(f'node did not answer:\n{node.text()}')
                print(f"{'rate Hz':>8} {'sent':>6} {'recv':>6} {'poses':>6} {'skipped':>8} "
                      f"{'p50 ms':>7} {'p95 ms':>7} {'p99 ms':>7} {'max ms':>7} "
                      f"{'cpu ms/recv':>11}")
                table: List[str] = []
                received = skipped = 0
                for rate in args.rates:
                    row = measure(client, rate, args.seconds, node.process.pid,
                                  args.rest_noise)
                    p50, p95, p99 = np.percentile(row['latencies_ms'], [50, 95, 99])
                    count = row['received'] - received
                    # counts come from the diagnostic of the last wrench; '*': it never came
                    # (lost on the way), so they are those of an earlier one
                    mark = '' if row['answered_last'] else '*'
                    cpu_ms = 1e3 * row['cpu_s'] / max(count, 1)
                    print(f"{rate:8.0f} {row['sent']:6d} {count:6d}{mark} "
                          f"{row['poses']:6d} {row['skipped'] - skipped:8d} {p50:7.2f} "
                          f"{p95:7.2f} {p99:7.2f} {row['latencies_ms'].max():7.2f} "
                          f'{cpu_ms:11.2f}')
                    table.append(f"| {rate:.0f} | {row['sent']} | {count}{mark} | "
                                 f"{row['poses']} | {row['skipped'] - skipped} | {p50:.2f} | "
                                 f"{p99:.2f} | {row['latencies_ms'].max():.2f} | {cpu_ms:.2f} |")
                    received, skipped = row['received'], row['skipped']
                node.stop(signal.SIGINT)
                print(node.text().strip().splitlines()[-1])
            finally:
                client.close()
    if args.markdown is not None:
        _append_markdown(args.markdown, args, table)


def _append_markdown(path: Path, args: argparse.Namespace, table: List[str]) -> None:
    """Append one run's table, with what was measured and the machine's load, to ``path``."""
    load = ', '.join(f'{value:.1f}' for value in os.getloadavg())
    when = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    setup = ('no MCAP log' if args.no_log else 'MCAP log on') + (
        ', compliance subscribed' if args.compliance else '') + (
        f', at rest with {args.rest_noise:g} N noise' if args.rest_noise > 0.0 else '') + ''.join(
        f', {assignment}' for assignment in args.param)
    with open(path, 'a') as stream:
        stream.write(f'\n### {args.label} ({when}, {setup}, {args.seconds:g} s per rate, '
                     f'load average {load})\n\n'
                     '| rate Hz | sent | received | answered | skipped | p50 ms | p99 ms | '
                     'max ms | node CPU ms per received |\n'
                     '|---|---|---|---|---|---|---|---|---|\n' + '\n'.join(table) + '\n')


if __name__ == '__main__':
    main()
