"""
translator_node's MCAP log: one writer per file, write errors as diagnostics.

Also a clean shutdown that states what was written and lost, and log times in order per
channel.

Each test runs the node as a child process in this module's own ROS_DOMAIN_ID (localhost
discovery); every wait is bounded.
"""

import re
import signal
import sys
import time

from cdr_translator.interface import messages
from cdr_translator.params.translator_params import NODE_NAME
from cdr_translator.ros.client import NodeProcess, TranslatorClient
from cdr_translator.ros.node_log import NodeLog
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource
from mcap.reader import make_reader
from nodes import ANSWER_TIMEOUT_S, DIAGNOSTICS, POSE, Running, START_TIMEOUT_S, STATUS

LOG_DIAGNOSTIC = f'{NODE_NAME}: mcap_log'
#: Bound on each wait for the log's state (checked every 1 s) to be reported.
RESUME_TIMEOUT_S = 30.0
#: Pause between wrenches once the log has failed: the 400 kB file of the limited node
#: holds about 110 of them (3.5 kB each), so a fresh one lasts over 2 s: more than the
#: 1 s log check.
RESUMED_PACE_S = 0.02
CLOSED = re.compile(r'MCAP log closed: (\d+) records written, (\d+) lost')

#: The node under RLIMIT_FSIZE (the kernel's EFBIG once a file reaches the limit; SIGXFSZ
#: ignored so that it is an error, not a kill): a real write error without root.
LIMITED_COMMAND = (sys.executable, '-c', (
    'import resource, runpy, signal, sys\n'
    'signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n'
    'resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, resource.RLIM_INFINITY))\n'
    'sys.argv = ["translator_node"] + sys.argv[1:]\n'
    'runpy.run_module("cdr_translator.ros.translator_node", run_name="__main__")\n'))


def log_diagnostics(run):
    """Return the MCAP log's statuses in the /diagnostics arrays ``run``'s client received."""
    return [status for message, _ in list(run.client.received[DIAGNOSTICS])
            for status in message.status if status.name == LOG_DIAGNOSTIC]


def _solve_until(run, force, pace_s, reported):
    """
    Send wrenches (each answered) until a log diagnostic is ``reported``; return the last stamp.

    The node checks its log once a second: the wait is bounded by time, not by a count of
    wrenches (a fast machine answers a thousand within that second).
    """
    deadline = time.monotonic() + RESUME_TIMEOUT_S
    index = 0
    while True:
        stamp = run.client.publish((force + 0.01 * (index % 100), 0.0, 0.0))
        index += 1
        assert run.answered(POSE, stamp), run.node.text()
        time.sleep(pace_s)
        if any(reported(status) for status in log_diagnostics(run)):
            return stamp
        if time.monotonic() > deadline:
            return stamp


def _closing(text):
    """Return (written, lost) of the node's closing MCAP log line."""
    found = CLOSED.findall(text)
    assert len(found) == 1, text
    return tuple(map(int, found[0]))


def test_second_node_on_the_same_path_stops_at_start(tmp_path, ros_env):
    """Two legs given one mcap_path: the second exits 2 naming the file and the first's PID."""
    path = tmp_path / 'leg.mcap'
    with Running(tmp_path, ros_env, mcap=path, name='first') as first:
        with NodeProcess(['-p', f'mcap_path:={path}'], ros_env, tmp_path / 'second.log') as second:
            assert second.process.wait(START_TIMEOUT_S) == 2, second.text()
            text = second.text()
            assert f'{path} is being written by another writer (PID {first.node.process.pid}' \
                in text and 'Traceback' not in text
        stamp = first.client.publish((5.0, 0.0, 0.0))
        assert first.answered(POSE, stamp)
        assert first.node.stop(signal.SIGINT) == 0
        written, lost = _closing(first.node.text())
    source = McapSource(path)
    assert sum(1 for _ in source.messages()) == written and lost == 0
    assert source.report.complete
    # the finished log is not overwritten by a later run either
    with NodeProcess(['-p', f'mcap_path:={path}'], ros_env, tmp_path / 'third.log') as third:
        assert third.process.wait(START_TIMEOUT_S) == 2, third.text()
        assert 'already exists' in third.text()


def test_write_error_is_an_error_diagnostic_and_the_node_goes_on(tmp_path, ros_env):
    """The MCAP file hits the file-size limit: ERROR diagnostic, poses go on, exit 0."""
    path = tmp_path / 'run.mcap'
    ros_args = ['-p', 'log_backbones:=true', '-p', 'log_compliance:=true',
                '-p', 'mcap_flush_messages:=20']
    with Running(tmp_path, ros_env, ros_args, command=LIMITED_COMMAND, mcap=path) as run:
        _solve_until(run, 2.0, 0.0, lambda status: status.level == bytes([messages.ERROR]))
        errors = [status for status in log_diagnostics(run)
                  if status.level == bytes([messages.ERROR])]
        assert errors, run.node.text()
        assert 'File too large' in errors[0].message
        values = {pair.key: pair.value for pair in errors[0].values}
        assert int(values['records_lost']) > 0 and int(values['write_errors']) > 0
        # Still solving and publishing; the log tries a new file once 1 s has passed. Paced,
        # so that the new file takes longer than the node's 1 s log check to reach the limit
        # again, on any machine: otherwise the resumption may never be seen.
        stamp = _solve_until(run, 3.0, RESUMED_PACE_S,
                             lambda status: 'resumed in' in status.message)
        assert any(status.level == bytes([messages.WARN]) and 'resumed in' in status.message
                   for status in log_diagnostics(run)), run.node.text()
        last = run.counts_after(stamp)
        assert int(last['log_records_lost']) > 0 and int(last['received']) > 0
        assert run.node.stop(signal.SIGINT) == 0, run.node.text()
        text = run.node.text()
    assert 'Traceback' not in text
    written, lost = _closing(text)
    assert written > 0 and lost > 0
    files = sorted(tmp_path.glob('run*.mcap'))
    assert len(files) >= 2, files   # resumed in run_1.mcap after the first error
    readable = 0
    for file in files:
        source = McapSource(file)
        readable += sum(1 for _ in source.messages())
        assert source.report.unread_bytes == 0, source.report.describe()
        assert file.stat().st_size <= 400_000
    assert readable == written


def test_log_times_never_go_back_on_a_channel(tmp_path, ros_env):
    """
    A 1 kHz burst with rejections: every channel's log times are non-decreasing.

    Two publishers of /wrench (DDS may hand their samples over out of receive order);
    rejections and solves each give a status on solve_status, the timer an array on
    /diagnostics: the log thread must keep each channel in order.
    """
    path = tmp_path / 'run.mcap'
    with Running(tmp_path, ros_env, mcap=path) as run:
        other = TranslatorClient((DIAGNOSTICS,))   # a second publisher of /wrench
        try:
            assert other.wait_for(lambda: run.node.process.poll() is None and
                                  other.node.count_subscribers('/wrench') > 0, 30.0)
            started = time.monotonic()
            for index in range(1500):
                delay = started + index * 1e-3 - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)
                force = ((float('nan'), 0.0, 0.0) if index % 7 == 0 else
                         (0.01 * index, 0.0, 0.0))
                stamp = (run.client if index % 2 else other).publish(force)
        finally:
            other.close()
        assert run.client.wait_for(lambda: run.client.messages_stamped(STATUS, stamp),
                                   ANSWER_TIMEOUT_S)
        assert run.node.stop(signal.SIGINT) == 0
    last = {}
    count = 0
    with open(path, 'rb') as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            assert message.log_time >= last.get(channel.topic, 0), channel.topic
            last[channel.topic] = message.log_time
            count += 1
    assert count > 200 and {'/wrench', '/solve_status', '/diagnostics',
                            '/end_disk_pose'} <= set(last)


def test_log_process_holds_back_an_earlier_log_time(tmp_path):
    """Records handed over out of time order: written in order, each held-back one counted."""
    wrench = messages.wrench_message([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], '',
                                     messages.stamp_from_ns(0))
    with McapLog(tmp_path / 'scratch.mcap') as scratch:
        data = scratch._encoder(messages.WRENCH_TYPE)(wrench)
    log = NodeLog(tmp_path / 'run.mcap', flush_every_s=0.0)
    for topic, time_ns in [('/wrench', 5), ('/wrench', 3), ('/other', 1), ('/wrench', 7),
                           ('/wrench', 6), ('/other', 2)]:
        log.submit(topic, messages.WRENCH_TYPE, data, time_ns, time_ns)
    status = log.close()
    assert (status.written, status.lost, log.reordered) == (6, 0, 2)
    with open(tmp_path / 'run.mcap', 'rb') as stream:
        times = [(channel.topic, message.log_time, message.publish_time) for _, channel, message
                 in make_reader(stream).iter_messages(log_time_order=False)]
    assert times == [('/wrench', 5, 5), ('/wrench', 5, 3), ('/other', 1, 1), ('/wrench', 7, 7),
                     ('/wrench', 7, 6), ('/other', 2, 2)]
