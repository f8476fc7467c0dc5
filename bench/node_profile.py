"""
translator_node with a CPU account: where each thread's time goes, per stage and per wrench.

Usage: python -m bench.node_profile OUT.md [--ros-args ...]   (bench.node_latency --profile)

Runs the node as ``translator_node`` would, with timers around its stages (the subscription
callback, decoding and checks, the solve, building, filling, serializing, publishing and
logging the outputs): per stage the calls, the CPU time of the calling thread
(``time.thread_time``: the work itself) and the wall time (work plus waiting for the GIL
and being descheduled). When the node closes it writes to OUT.md that table, and the CPU
time of every thread of the process by the kernel's account (/proc/self/task: the DDS
threads, the executor, the solver thread) and of its MCAP log process, so that the node's CPU per
wrench that bench.node_latency reports can be split up. The timers cost about 1 us a call.
"""

from collections import defaultdict
import functools
import os
from pathlib import Path
import sys
import threading
import time
from typing import Any, Callable, Dict, List

from bench.node_latency import child_pids
from cdr_translator.interface import messages, wrench_processing
from cdr_translator.ros import node_log, serialization, topics, translator
from rclpy.publisher import Publisher

#: stage -> [calls, thread CPU s, wall s]
STAGES: Dict[str, List[float]] = defaultdict(lambda: [0, 0.0, 0.0])
#: Python thread names by native id (the kernel's thread ids).
THREAD_NAMES: Dict[int, str] = {}
#: The account starts at this received wrench (the handshake's and first calls' costs apart).
START_AT = 20
#: Thread CPU times when the account started.
START: Dict[int, tuple] = {}


def timed(stage: str, function: Callable) -> Callable:
    """Wrap ``function`` so that each call adds its CPU and wall time to ``stage``."""
    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        THREAD_NAMES[threading.get_native_id()] = threading.current_thread().name
        cpu, wall = time.thread_time(), time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            entry = STAGES[stage]
            entry[0] += 1
            entry[1] += time.thread_time() - cpu
            entry[2] += time.perf_counter() - wall
    return wrapper


def wrap(owner: Any, name: str, stage: str) -> None:
    """Put a timer around ``owner.name`` if it exists (another checkout may lack it)."""
    if hasattr(owner, name):
        setattr(owner, name, timed(stage, getattr(owner, name)))


def process_cpu(pid: int) -> float:
    """Return the CPU time (user + system, s) of process ``pid`` so far (0 once gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def thread_cpu() -> Dict[int, tuple]:
    """Return {thread id: (name, CPU s)} of every thread of this process (Linux /proc)."""
    ticks = os.sysconf('SC_CLK_TCK')
    found = {}
    for task in Path('/proc/self/task').iterdir():
        try:
            stat = (task / 'stat').read_text()
        except OSError:
            continue
        name = stat[stat.index('(') + 1:stat.rindex(')')]
        fields = stat.rsplit(')', 1)[1].split()
        found[int(task.name)] = (name, (int(fields[11]) + int(fields[12])) / ticks)
    return found


def start(node: Any) -> None:
    """Clear the stage account and note every thread's CPU time (at the START_AT-th wrench)."""
    STAGES.clear()
    START.update(thread_cpu())
    START.update({-pid: ('', process_cpu(pid)) for pid in child_pids(os.getpid())})
    START[0] = ('counts', node.received, node._mailbox.skipped)


def report(out: Path, node: Any, threads: Dict[int, tuple]) -> None:
    """
    Write the stage and thread tables to ``out``.

    ``threads``: thread_cpu() at the end, and the child processes as -PID: (name, CPU s).
    """
    received = max(node.received - START[0][1], 1)
    answered = max(STAGES['solve'][0], 1)
    lines = [f'from the {START_AT}th wrench on: received {received}, solved {answered}, '
             f'skipped {node._mailbox.skipped - START[0][2]}', '',
             '| stage | calls | CPU ms per call | wall ms per call | CPU ms per received | '
             'CPU ms per solve |', '|---|---|---|---|---|---|']
    for stage, (calls, cpu, wall) in sorted(STAGES.items(), key=lambda item: -item[1][1]):
        lines.append(f'| {stage} | {calls} | {1e3 * cpu / max(calls, 1):.3f} | '
                     f'{1e3 * wall / max(calls, 1):.3f} | {1e3 * cpu / received:.3f} | '
                     f'{1e3 * cpu / answered:.3f} |')
    lines += ['', '| thread | CPU s | CPU ms per received | CPU ms per solve |',
              '|---|---|---|---|']
    used = {tid: (name, cpu - START.get(tid, (name, 0.0))[1])
            for tid, (name, cpu) in threads.items()}
    total = sum(cpu for _, cpu in used.values())
    used[0] = ('all threads and the log process', total)
    for tid, (name, cpu) in sorted(used.items(), key=lambda item: -item[1][1]):
        label = f'{name} ({THREAD_NAMES[tid]})' if tid in THREAD_NAMES else name
        if cpu > 0.0:
            lines.append(f'| {label} | {cpu:.2f} | {1e3 * cpu / received:.3f} | '
                         f'{1e3 * cpu / answered:.3f} |')
    out.write_text('\n'.join(lines) + '\n')


def install(out: Path) -> None:
    """Put the timers around the node's stages; the report is written when it closes."""
    node_class = translator.TranslatorNode
    callback = timed('callback (executor thread)', node_class._on_wrench)

    def on_wrench(self: Any, data: Any) -> None:
        if self.received + 1 == START_AT:
            start(self)
        callback(self, data)
    setattr(node_class, '_on_wrench', on_wrench)  # noqa: B010 - a method replaced
    wrap(node_class, '_checked', 'checks')
    wrap(node_class, '_counts', 'counts')
    wrap(node_class, '_wanted', 'subscription counts')  # before the CDR encoding
    wrap(topics.SubscriberCounts, 'subscribed', 'subscription counts')
    wrap(translator, 'deserialize_message', 'decode')
    wrap(serialization, 'decode', 'decode')
    wrap(wrench_processing, 'solve_wrench', 'solve')   # the processor's, looked up per call
    wrap(translator, 'solve_wrench', 'solve')   # where an older checkout kept it
    wrap(translator, 'fill_message', 'fill rclpy message')
    wrap(translator, 'serialize_message', 'serialize')
    if hasattr(translator, 'serialization'):
        make_encoder = serialization.encoder
        serialization.encoder = lambda message_class: timed('encode', make_encoder(message_class))
    if hasattr(serialization, 'decoder'):  # a decoder bound at start, not the wrapped decode
        make_decoder = serialization.decoder
        setattr(serialization, 'decoder',  # noqa: B010 - replaced for the profile
                lambda message_class: timed('decode', make_decoder(message_class)))
    for name in ('pose_message', 'joint_state_message', 'diagnostics_message',
                 'solve_diagnostic_values', 'compliance_eigenvalues_message',
                 'compliance_message'):
        wrap(messages, name, f'build {name}')
    wrap(Publisher, 'publish', 'publish')
    wrap(Publisher, 'get_subscription_count', 'get_subscription_count')
    wrap(node_log.NodeLog, 'submit_many', 'log submit')
    close = node_class.close

    def close_and_report(self: Any) -> None:
        threads = thread_cpu()
        threads.update({-pid: (f'child process {pid} (MCAP log)', process_cpu(pid))
                        for pid in child_pids(os.getpid())})
        close(self)
        report(out, self, threads)
    setattr(node_class, 'close', close_and_report)  # noqa: B010 - a method replaced


def main() -> int:
    """Run translator_node with the timers; the report goes to the first argument."""
    out = Path(sys.argv[1])
    install(out)
    return translator.main([sys.argv[0], *sys.argv[2:]])


if __name__ == '__main__':
    sys.exit(main())
