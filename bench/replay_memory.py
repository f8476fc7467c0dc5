"""
Peak RSS of ``msg_tools replay`` and ``msg_tools info`` against the number of messages.

Usage: python -m bench.replay_memory [--counts 10000 1000000] [--out bench/results]

Writes one WrenchStamped file per count (the CDR of a few messages, the stamp patched per
message, 100 Hz): every ``--solve-every``-th wrench is a valid 0.5-5 N force (a sawtooth
of 10 levels, solved warm-started); the others exceed max_force and are rejected with an
ERROR diagnostic, so every message is read, decoded, checked, answered and written while
the run fits in minutes (a solve costs about 3 ms on this shared machine). Then it runs
``python -m msg_tools replay --no-compliance`` and ``python -m msg_tools info`` on each in
a child process of its own and reads the child's
peak RSS from ``os.wait4``. Writes bench/results/replay_memory.md (the growth from
10 k to 1 M messages must stay within 20 MB).
"""

import argparse
import os
from pathlib import Path
import platform
import subprocess
import sys
import tempfile
import time
from typing import Any, Dict, List, Sequence, Tuple

from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
from msg_tools.synth import DEFAULT_START_NS

ROOT = Path(__file__).resolve().parent.parent


def write_input(path: Path, count: int, solve_every: int) -> None:
    """Write ``count`` WrenchStamped at 100 Hz; every ``solve_every``-th one solvable."""
    with McapLog(path, flush_every_messages=0, flush_every_s=0.0, if_exists='overwrite',
                 chunk_size=4 * 1024 * 1024) as log:
        log.register('/wrench', messages.WRENCH_TYPE, qos='sensor_data')
        levels = 10
        encode = log._encoder(messages.WRENCH_TYPE)
        templates = [bytearray(encode(messages.wrench_message(
            [0.5 * (k + 1), 0.0, 0.0], [0.0, 0.0, 0.0], '', {'sec': 0, 'nanosec': 0})))
            for k in range(levels)]
        rejected = bytearray(encode(messages.wrench_message(
            [1e6, 0.0, 0.0], [0.0, 0.0, 0.0], '', {'sec': 0, 'nanosec': 0})))
        for k in range(count):
            stamp = DEFAULT_START_NS + 10_000_000 * k
            data = (templates[(k // (100 * solve_every)) % levels] if k % solve_every == 0
                    else rejected)
            data[4:8] = (stamp // 1_000_000_000).to_bytes(4, 'little')
            data[8:12] = (stamp % 1_000_000_000).to_bytes(4, 'little')
            log.write_serialized('/wrench', messages.WRENCH_TYPE, bytes(data), stamp)


def peak_rss_mb(command: Sequence[str]) -> Tuple[float, float, int]:
    """Run ``command``; return (peak RSS in MB, wall time in s, exit code)."""
    started = time.perf_counter()
    process = subprocess.Popen(list(command), cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    stderr = process.stderr.read().decode() if process.stderr else ''
    if process.returncode not in (0,):
        print(stderr[-2000:], file=sys.stderr)
    return usage.ru_maxrss / 1024.0, time.perf_counter() - started, process.returncode


def main() -> None:
    """Measure and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--counts', type=int, nargs='+', default=[10_000, 1_000_000])
    parser.add_argument('--out', default=str(ROOT / 'bench' / 'results'))
    parser.add_argument('--work', default='', help='folder for the (large) files; default tmp')
    parser.add_argument('--solve-every', type=int, default=100,
                        help='every N-th wrench is solvable, the others rejected; default 100')
    args = parser.parse_args()
    work = Path(args.work or tempfile.mkdtemp(prefix='replay_memory_'))
    rows: List[Dict[str, Any]] = []
    for count in args.counts:
        source = work / f'wrenches_{count}.mcap'
        started = time.perf_counter()
        write_input(source, count, args.solve_every)
        written_s = time.perf_counter() - started
        for tool, command in (
                ('info', [sys.executable, '-m', 'msg_tools', 'info', str(source)]),
                ('replay', [sys.executable, '-m', 'msg_tools', 'replay', str(source), '--out',
                            str(work / f'out_{count}.mcap'), '--no-compliance',
                            '--progress', 'never'])):
            rss, wall, code = peak_rss_mb(command)
            rows.append({'tool': tool, 'count': count, 'rss': rss, 'wall': wall, 'code': code,
                         'size': source.stat().st_size})
            print(f'{tool} {count}: peak RSS {rss:.1f} MB, {wall:.1f} s, exit {code} '
                  f'(input written in {written_s:.1f} s)', flush=True)
        (work / f'out_{count}.mcap').unlink(missing_ok=True)
        source.unlink()
    lines = ['# Peak RSS of replay and info against the number of messages', '',
             f'`python -m bench.replay_memory --counts {" ".join(map(str, args.counts))}` on '
             f'{platform.node() or "this machine"}, Python {platform.python_version()}: '
             'one child process per run, peak RSS from `os.wait4`. Input: WrenchStamped at '
             f'100 Hz; every {args.solve_every}-th a 0.5-5 N force solved warm-started, the '
             'others above max_force and rejected with an ERROR diagnostic (so every message '
             'is read, decoded, checked, answered and written); replay with '
             '`--no-compliance`.', '',
             '| tool | messages | input MB | peak RSS MB | wall s | exit |',
             '|---|---|---|---|---|---|']
    for row in rows:
        lines.append(f'| {row["tool"]} | {row["count"]:,} | {int(row["size"]) / 1e6:.1f} | '
                     f'{row["rss"]:.1f} | {row["wall"]:.1f} | {row["code"]} |')
    for tool in ('info', 'replay'):
        measured = sorted((int(row['count']), float(row['rss'])) for row in rows
                          if row['tool'] == tool)
        if len(measured) >= 2:
            growth = measured[-1][1] - measured[0][1]
            lines += ['', f'{tool}: growth from {measured[0][0]:,} to {measured[-1][0]:,} '
                          f'messages: {growth:+.1f} MB (limit 20 MB: '
                          f'{"met" if growth <= 20.0 else "NOT met"}).']
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'replay_memory.md').write_text('\n'.join(lines) + '\n')
    print(f'wrote {out / "replay_memory.md"}')


if __name__ == '__main__':
    main()
