"""The log writer process and its caller killed with SIGKILL: quiet, and counts that are true."""

import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

from cdr_translator.interface import messages
from cdr_wire.log_process import LogProcess
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource

ROOT = Path(__file__).resolve().parents[2]
#: Bound on every wait (s).
TIMEOUT_S = 60.0
CLOSED = re.compile(r'MCAP log closed: (\d+) records written, (\d+) lost \((\d+) not written, '
                    r'(\d+) not serializable(?:, (\d+) never handed over to the writer)?\)')

#: A caller that hands 300 records to its log process, says so, and waits to be killed.
CALLER = """
import sys, time
from cdr_wire.log_process import LogProcess
log = LogProcess(sys.argv[1], flush_every_messages=10, flush_every_s=0.05)
data = bytes.fromhex(sys.argv[2])
for k in range(300):
    log.submit('/wrench', 'geometry_msgs/msg/WrenchStamped', data, k, k)
while log.written < 300:
    time.sleep(0.01)
print('handed over', flush=True)
time.sleep(600)
"""


def _wrench_cdr(tmp_path):
    """Return the CDR bytes of one WrenchStamped."""
    with McapLog(tmp_path / 'scratch.mcap') as scratch:
        return scratch._encoder(messages.WRENCH_TYPE)(messages.wrench_message(
            [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], '', messages.stamp_from_ns(0)))


def _wait(condition):
    """Wait (bounded) until ``condition()`` holds; return whether it did."""
    deadline = time.monotonic() + TIMEOUT_S
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.01)
    return condition()


def test_a_killed_caller_leaves_a_finished_file_and_no_traceback(tmp_path):
    """SIGKILL of the caller: the log process finishes the file and exits quietly."""
    path = tmp_path / 'run.mcap'
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    caller = subprocess.Popen([sys.executable, '-c', CALLER, str(path),
                               _wrench_cdr(tmp_path).hex()], cwd=ROOT, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert caller.stdout.readline().strip() == 'handed over', caller.stderr.read()
        time.sleep(0.3)   # the writer reports its status meanwhile: into the pipe to come
        caller.send_signal(signal.SIGKILL)
        _, errors = caller.communicate(timeout=TIMEOUT_S)   # EOF: the writer exited too
    finally:
        caller.kill()
    assert 'Traceback' not in errors and 'Error' not in errors, errors
    source = McapSource(path)
    assert sum(1 for _ in source.messages()) == 300
    assert source.report.complete, source.report.describe()


def test_a_killed_log_process_is_counted_from_the_file(tmp_path):
    """SIGKILL of the writer: written = the file's records; the rest lost, each kind named."""
    path = tmp_path / 'run.mcap'
    data = _wrench_cdr(tmp_path)
    log = LogProcess(path, flush_every_messages=1, flush_every_s=0.0)
    for k in range(200):
        log.submit('/wrench', messages.WRENCH_TYPE, data, k, k)
    assert _wait(lambda: log.written == 200)
    for k in range(200, 400):
        log.submit('/wrench', messages.WRENCH_TYPE, data, k, k)
    size = path.stat().st_size
    assert _wait(lambda: path.stat().st_size > size)
    os.kill(log._process.pid, signal.SIGKILL)
    assert _wait(lambda: not log.status().ok)
    for k in range(400, 450):   # after the writer is gone: never handed over
        log.submit('/wrench', messages.WRENCH_TYPE, data, k, k)
    status = log.close()
    in_file = sum(1 for _ in McapSource(path).messages())
    complete, line = log.closing_line()
    written, lost, not_written, refused, never = map(int, CLOSED.search(line).groups())
    assert not complete and 'exited with code -9' in line
    assert written == status.written == in_file and written + lost == 450, line
    assert (refused, never) == (0, 50) and not_written == 400 - in_file, line
