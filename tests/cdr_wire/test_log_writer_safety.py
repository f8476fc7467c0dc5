"""McapLog: one writer per file, write errors as events."""

import errno
import os
from pathlib import Path
import subprocess
import sys
import threading
import time

from cdr_translator.interface import messages
from cdr_wire import mcap_log
from cdr_wire.errors import LogFileBusyError, LogFileExistsError
from cdr_wire.mcap_log import _FileSink, McapLog
from cdr_wire.reader import McapSource
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _write(log, first, count):
    """Write wrenches ``first`` .. ``first + count - 1`` (log time = 1 ms * index)."""
    for k in range(first, first + count):
        log.write('/wrench', messages.WRENCH_TYPE, messages.wrench_message(
            [0.1 * k, 0.0, 0.0], [0.0, 0.0, 0.0], '', messages.stamp_from_ns(10**6 * k)),
            log_time_ns=10**6 * k)


def _times(path):
    """Return (log times in ms, report) of every readable message of ``path``."""
    source = McapSource(path)
    times = [m.log_time_ns // 10**6 for m in source.messages()]
    return times, source.report


# ------------------------------------------------------------------------ one writer per file
def test_second_writer_in_this_process_fails_naming_path_and_holder(tmp_path):
    """Same path twice: the second fails at once (any if_exists); the first loses nothing."""
    path = tmp_path / 'run.mcap'
    with McapLog(path, flush_every_messages=5, flush_every_s=0.0) as first:
        _write(first, 0, 12)
        for if_exists in ('fail', 'overwrite'):
            with pytest.raises(LogFileBusyError) as caught:
                McapLog(path, if_exists=if_exists)
            assert str(path) in str(caught.value)
            assert f'PID {os.getpid()}' in str(caught.value)
        _write(first, 12, 8)
    times, report = _times(path)
    assert times == list(range(20)) and report.complete


def test_second_writer_names_the_other_process(tmp_path):
    """A writer in another process: the error names its PID and command line."""
    path = tmp_path / 'leg.mcap'
    holder = subprocess.Popen(
        [sys.executable, '-c', 'import sys, time\nfrom cdr_wire.mcap_log import McapLog\n'
         'log = McapLog(sys.argv[1])\nprint("open", flush=True)\nsys.stdin.read()\n'
         'log.close()', str(path)],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == 'open'
        with pytest.raises(LogFileBusyError, match=f'(?s)PID {holder.pid}: .*McapLog') as caught:
            McapLog(path, if_exists='overwrite')
        assert caught.value.path == str(path)
    finally:
        holder.communicate('', timeout=60)
    assert holder.returncode == 0
    assert McapSource(path).channel_overview()[2] == {}   # the holder's file, intact


def test_existing_file_fails_unless_overwrite_or_rename(tmp_path):
    """A finished log is not overwritten by default; rename picks a new name and says so."""
    path = tmp_path / 'run.mcap'
    with McapLog(path) as log:
        _write(log, 0, 3)
    with pytest.raises(LogFileExistsError, match='already exists'):
        McapLog(path)
    with McapLog(path, if_exists='rename') as renamed:
        assert renamed.path == tmp_path / 'run_1.mcap'
        assert 'run_1.mcap instead' in renamed.status().message
    assert _times(path)[0] == [0, 1, 2]
    with McapLog(path, if_exists='overwrite') as log:
        _write(log, 7, 1)
    assert _times(path)[0] == [7]


def test_many_threads_racing_for_one_path_get_one_writer(tmp_path):
    """Eight writers started at once on one path: exactly one wins, the rest fail."""
    path = tmp_path / 'race.mcap'
    outcomes, start = [], threading.Barrier(8)

    def contend(if_exists):
        start.wait()
        try:
            outcomes.append(McapLog(path, if_exists=if_exists, flush_every_s=0.0))
        except (LogFileBusyError, LogFileExistsError) as error:
            outcomes.append(error)

    threads = [threading.Thread(target=contend, args=('fail' if k % 2 else 'overwrite',))
               for k in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    logs = [item for item in outcomes if isinstance(item, McapLog)]
    assert len(logs) == 1 and len(outcomes) == 8
    _write(logs[0], 0, 4)
    logs[0].close()
    assert _times(path)[0] == [0, 1, 2, 3]


# ------------------------------------------------------------------------ write errors
class _Faults:
    """Make every os.write of McapLog fail with ENOSPC while ``on``."""

    def __init__(self, monkeypatch):
        self.on = False
        self.calls = 0
        original = _FileSink.os_write

        def write(fd, data):
            self.calls += 1
            if self.on:
                raise OSError(errno.ENOSPC, 'No space left on device')
            return original(fd, data)

        monkeypatch.setattr(_FileSink, 'os_write', staticmethod(write))


def test_disk_full_mid_run_is_counted_and_writing_resumes(tmp_path, monkeypatch):
    """ENOSPC for a while: no exception, lost records counted, a new file once it works."""
    faults = _Faults(monkeypatch)
    path = tmp_path / 'run.mcap'
    log = McapLog(path, flush_every_messages=10, flush_every_s=0.0, retry_s=0.0)
    _write(log, 0, 25)                    # 20 on disk, 5 pending in the open chunk
    assert log.status().written == 20 and log.status().pending == 5
    faults.on = True
    _write(log, 25, 20)                   # the flush at 30 fails: 20..44 are lost
    status = log.status()
    assert not status.ok and status.errors == 1 and status.lost == 25
    assert 'No space left on device' in status.message and 'readable up to byte' in \
        status.message
    faults.on = False
    _write(log, 45, 12)
    final = log.close()
    assert final.ok and final.written == 32 and final.lost == 25 and final.pending == 0
    assert final.files == (str(path), str(tmp_path / 'run_1.mcap'))
    assert 'resumed in' in final.message
    first, report = _times(path)
    assert first == list(range(20)) and report.mode == 'salvaged' and report.unread_bytes == 0
    second, report = _times(tmp_path / 'run_1.mcap')
    assert second == list(range(45, 57)) and report.complete
    assert log.close() is final           # idempotent


def test_flush_thread_error_is_an_event_not_a_traceback(tmp_path, monkeypatch):
    """The periodic flush meets ENOSPC: no exception escapes the thread; close() is clean."""
    faults = _Faults(monkeypatch)
    escaped = []
    monkeypatch.setattr(threading, 'excepthook', lambda args: escaped.append(args))
    log = McapLog(tmp_path / 'run.mcap', flush_every_messages=0, flush_every_s=0.02,
                  retry_s=3600.0)
    _write(log, 0, 6)
    deadline = time.monotonic() + 10
    while log.status().written < 6 and time.monotonic() < deadline:
        time.sleep(0.01)
    faults.on = True
    _write(log, 6, 4)
    while log.status().ok and time.monotonic() < deadline:
        time.sleep(0.01)
    _write(log, 10, 3)                    # while failing: counted as lost at once
    final = log.close()
    assert escaped == []
    assert (final.ok, final.written, final.lost, final.errors) == (False, 6, 7, 1)
    assert 'written, 7 lost' in final.describe()
    assert _times(tmp_path / 'run.mcap')[0] == list(range(6))


def test_file_size_limit_is_a_real_write_error(tmp_path):
    """RLIMIT_FSIZE (EFBIG from the kernel): the file ends at its last complete chunk."""
    script = """
import resource, signal, sys
from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (20000, resource.RLIM_INFINITY))
log = McapLog(sys.argv[1], flush_every_messages=20, flush_every_s=0.0, retry_s=3600.0)
for k in range(2000):
    log.write('/wrench', messages.WRENCH_TYPE, messages.wrench_message(
        [float(k), 0.0, 0.0], [0.0, 0.0, 0.0], 'f%d' % k, messages.stamp_from_ns(k)),
        log_time_ns=k)
status = log.close()
print(status.written, status.lost, status.errors)
print(status.message)
"""
    path = tmp_path / 'small.mcap'
    process = subprocess.run([sys.executable, '-c', script, str(path)], cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
    assert process.returncode == 0 and 'Traceback' not in process.stderr, process.stderr
    counts, message = process.stdout.splitlines()
    written, lost, errors = map(int, counts.split())
    assert written + lost == 2000 and 0 < written < 2000 and errors == 1
    assert 'File too large' in message
    source = McapSource(path)
    assert sum(1 for _ in source.messages()) == written
    assert source.report.unread_bytes == 0 and path.stat().st_size <= 20000


def test_removed_file_is_a_write_error_and_its_records_count_as_lost(tmp_path):
    """The log file deleted under the writer: its records are lost, a new file is started."""
    path = tmp_path / 'run.mcap'
    log = McapLog(path, flush_every_messages=5, flush_every_s=0.0, retry_s=0.0)
    _write(log, 0, 10)
    path.unlink()
    _write(log, 10, 5)                    # the flush at 15 notices
    _write(log, 15, 5)
    final = log.close()
    assert final.lost == 15 and final.written == 5 and final.errors == 1
    assert 'removed' in final.message or 'resumed' in final.message
    assert _times(path)[0] == list(range(15, 20))


def test_a_failed_retry_says_why(tmp_path, monkeypatch):
    """The file removed, then its folder read-only: the status names the retry's OSError."""
    path = tmp_path / 'run.mcap'
    log = McapLog(path, flush_every_messages=5, flush_every_s=0.0, retry_s=0.0)
    _write(log, 0, 10)
    path.unlink()

    def read_only(requested, if_exists):
        raise PermissionError(errno.EACCES, 'Permission denied', str(requested))

    # as root a chmod does not stop the open: the folder's refusal is injected
    monkeypatch.setattr(mcap_log, 'open_exclusive', read_only)
    _write(log, 10, 5)                    # the flush at 15 notices the removal
    _write(log, 15, 1)                    # the retry fails
    status = log.status()
    assert not status.ok and 'removed' in status.message
    assert 'a new file cannot be created either: PermissionError' in status.message
    assert 'Permission denied' in status.message
    final = log.close()
    assert (final.written, final.lost) == (0, 16)
