"""
An McapLog written by a process of its own, so that the writing takes no time from the caller.

A node's MCAP writing (the mcap writer's records, chunking, zstd, CRCs: 25-50 us of Python
per record) held the GIL its solver needs; ``LogProcess`` hands serialized records over a
pipe to a child process (``python -m cdr_wire.log_process``) that owns the McapLog, and
costs the caller one pickled send per batch. The file is created and locked here, before
the child starts (``open_exclusive``: an existing file or another writer is an OSError
naming it and its holder's PID, this process's for a file it writes), and the child
inherits the descriptor. The child reports the McapLog's status about every
``STATUS_PERIOD_S`` s and when it closes the file, so ``status()`` never waits for it.

Nothing is lost silently: a child that dies (killed, crashed) makes ``status()`` not ok
with the records it never confirmed counted as lost, and records that cannot be handed
over are counted too. When the caller dies, the child sees the pipe close, finishes the
file (summary and all) and exits; it ignores SIGINT and SIGTERM, which a terminal or a
launcher sends the whole process group, so that the caller's shutdown decides when the
log ends. In the child, ``RecordWriter`` writes the records to the McapLog, their log
times kept in order per channel, and counts them.
"""

from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from cdr_wire.file_lock import open_exclusive
from cdr_wire.log_status import LogStatus
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource

#: How often the child reports the log's status (s), and how often it looks for news.
STATUS_PERIOD_S = 0.1
#: How often the caller's sender thread hands the records gathered meanwhile over (s): one
#: pipe write per period (a write per record cost the caller 50-200 us of CPU, mostly the
#: kernel waking the child).
BATCH_PERIOD_S = 0.02
#: Records gathered before a caller waits for the sender (never dropped, never unbounded).
CAPACITY = 20000
#: How long a LogProcess waits for its child to start, and to finish the file at close (s).
START_TIMEOUT_S = 30.0
CLOSE_TIMEOUT_S = 30.0

#: One record: topic, type name, CDR bytes, log time (ns), publish time (ns, None: the log
#: time).
Record = Tuple[str, str, bytes, int, Optional[int]]


class RecordWriter:
    """
    Write records to an McapLog; log times never go back on a channel; count what fails.

    A record whose log time is earlier than the previous one of its topic (several
    producers, or receive stamps out of step) is written with that previous time and
    counted in ``reordered`` (MCAP readers and ``mcap doctor`` expect ordered channels).
    A record the McapLog refuses (ValueError, e.g. after close) counts in ``errors``; write
    errors are the McapLog's to count (its ``status()``).
    """

    def __init__(self, log: McapLog) -> None:
        """Write to ``log``."""
        self.log = log
        self.written = 0
        self.errors = 0
        self.reordered = 0
        self.last_error = ''
        self.write_time_s = 0.0
        self._last_log_time: Dict[str, int] = {}

    def write(self, topic: str, type_name: str, data: bytes, log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """Write one record."""
        started = time.perf_counter()
        previous = self._last_log_time.get(topic, 0)
        if log_time_ns < previous:
            log_time_ns = previous
            self.reordered += 1
        self._last_log_time[topic] = log_time_ns
        try:
            self.log.write_serialized(topic, type_name, data, log_time_ns, publish_time_ns)
            self.written += 1
        except Exception as error:  # noqa: B902 - a bad record must not end the log
            self.errors += 1
            self.last_error = f'{topic}: {error}'
        self.write_time_s += time.perf_counter() - started


def closing_line(status: LogStatus, refused: int, unsent: int = 0) -> Tuple[bool, str]:
    """
    Return (all written, a writer's closing log line) from its final status.

    ``refused``: records the McapLog would not take (not serializable as their type);
    ``unsent``: records that never reached the writer (its process was gone).
    """
    lost = status.lost + refused + unsent
    never = f', {unsent} never handed over to the writer' if unsent else ''
    text = (f'MCAP log closed: {status.written} records written, {lost} lost '
            f'({status.lost} not written, {refused} not serializable{never}) in '
            f'{", ".join(status.files)}')
    if status.message:
        text += f'; {status.message}'
    return lost == 0, text


@dataclass(frozen=True)
class WriterState:
    """What the child reports: the McapLog's status and the RecordWriter's counts."""

    status: LogStatus
    written: int
    errors: int
    reordered: int
    last_error: str
    write_time_s: float
    final: bool = False


class LogProcess:
    """
    The caller's end of an McapLog in a child process: ``submit`` records, read ``status``.

    ``submit`` only appends to a list; a sender thread hands what has gathered to the child
    every ``BATCH_PERIOD_S`` (one pickled pipe write), and a caller waits only when
    ``CAPACITY`` records are waiting. ``submitted``, ``enqueue_wait_s`` and
    ``max_enqueue_wait_s`` measure the hand-over;
    ``written``, ``errors``, ``reordered``, ``last_error`` and ``write_time_s`` are the
    child's RecordWriter's as last reported. ``topics`` are (topic, type name, qos) to
    register up front.
    """

    def __init__(self, path: Union[str, Path], *, topics: Sequence[Tuple[str, str, str]] = (),
                 if_exists: str = 'fail', flush_every_messages: int = 100,
                 flush_every_s: float = 1.0) -> None:
        """Create and lock ``path``, start the child on it, wait until it has started."""
        fd, opened = open_exclusive(path, if_exists)
        to_child, from_parent = os.pipe()
        from_child, to_parent = os.pipe()
        source = str(Path(__file__).resolve().parent.parent)
        env = dict(os.environ)
        env['PYTHONPATH'] = os.pathsep.join(
            [source, *filter(None, [env.get('PYTHONPATH', '')])])
        try:
            self._process = subprocess.Popen(
                [sys.executable, '-m', 'cdr_wire.log_process', str(fd), str(opened),
                 str(path), str(flush_every_messages), repr(float(flush_every_s)),
                 str(to_child), str(to_parent)],
                pass_fds=(fd, to_child, to_parent), stdin=subprocess.DEVNULL, env=env)
        finally:
            for own in (fd, to_child, to_parent):
                os.close(own)
        self._outbox = Connection(from_parent, readable=False)
        self._inbox = Connection(from_child, writable=False)
        self._send_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self.submitted = 0
        self.unsent = 0
        self.enqueue_wait_s = 0.0
        self.max_enqueue_wait_s = 0.0
        self._died = ''
        #: Records the files hold, counted once the child is gone (None: not counted).
        self._in_files: Optional[int] = None
        self._state = WriterState(LogStatus(True, str(opened), (str(opened),), 0, 0, 0, 0, ''),
                                  0, 0, 0, '', 0.0)
        self._closed = threading.Event()
        self._pending: List[Record] = []
        self._pending_lock = threading.Lock()
        self._drained = threading.Condition(self._pending_lock)
        self._stop = threading.Event()
        if topics:
            self._send(('register', list(topics)), 0)
        if not self._inbox.poll(START_TIMEOUT_S):
            self._process.kill()
            raise OSError(f'the MCAP log writer process did not start in {START_TIMEOUT_S:g} s')
        try:
            first = self._inbox.recv()
        except EOFError:
            code = self._process.wait()
            raise OSError(f'the MCAP log writer process exited with code {code} at start'
                          ) from None
        if first[0] == 'failed':
            self._process.wait()
            raise OSError(first[1])
        self._state = WriterState(*first[1])
        self._reader = threading.Thread(target=self._read, name='mcap_log_status', daemon=True)
        self._reader.start()
        self._sender = threading.Thread(target=self._send_batches, name='mcap_log_sender',
                                        daemon=True)
        self._sender.start()

    # the counts, as last reported ----------------------------------------------------------
    @property
    def path(self) -> str:
        """Return the file being written (a new one after a write error)."""
        return self._state.status.path

    @property
    def written(self) -> int:
        """Return how many records the child has handed to its McapLog."""
        return self._state.written

    @property
    def errors(self) -> int:
        """Return the records refused by the McapLog plus those never handed over."""
        return self._state.errors + self.unsent

    @property
    def refused(self) -> int:
        """Return how many records the McapLog would not take (not serializable as their type)."""
        return self._state.errors

    @property
    def reordered(self) -> int:
        """Return the log times held back to keep each channel in order."""
        return self._state.reordered

    @property
    def last_error(self) -> str:
        """Return the last record error (or why the child is gone)."""
        return self._died or self._state.last_error

    @property
    def write_time_s(self) -> float:
        """Return the child's time spent writing records (s)."""
        return self._state.write_time_s

    def status(self) -> LogStatus:
        """
        Return the McapLog's status as last reported, or a failure once the child is gone.

        A child gone before closing the file: the records its files hold (read back, the
        last reports may be behind) are written, the rest of what was handed over is lost.
        """
        with self._state_lock:
            status = self._state.status
            if self._died:
                written = status.written if self._in_files is None else self._in_files
                lost = self.submitted - self.unsent - self._state.errors - written
                return replace(status, ok=False, pending=0, written=written,
                               lost=max(lost, status.lost), message=self._died)
            return status

    # hand-over -----------------------------------------------------------------------------
    def submit(self, topic: str, type_name: str, data: bytes, log_time_ns: int,
               publish_time_ns: Optional[int] = None) -> None:
        """Hand one record to the child."""
        self.submit_many([(topic, type_name, data, log_time_ns, publish_time_ns)])

    def submit_many(self, records: Sequence[Record]) -> None:
        """Queue records for the child (waits only while CAPACITY records wait already)."""
        started = time.perf_counter()
        with self._pending_lock:
            while len(self._pending) >= CAPACITY and not self._stop.is_set():
                self._drained.wait(1.0)
            self._pending.extend(records)
            self.submitted += len(records)
        waited = time.perf_counter() - started
        self.enqueue_wait_s += waited
        self.max_enqueue_wait_s = max(self.max_enqueue_wait_s, waited)

    def _send_batches(self) -> None:
        """Sender thread: hand the gathered records over every BATCH_PERIOD_S until closed."""
        while True:
            stopping = self._stop.wait(BATCH_PERIOD_S)
            with self._pending_lock:
                batch, self._pending = self._pending, []
                self._drained.notify_all()
            if batch:
                self._send(('records', batch), len(batch))
            if stopping:
                return

    def _send(self, item: Any, count: int) -> None:
        """Send ``item`` to the child; count ``count`` records as unsent if that fails."""
        with self._send_lock:
            if self._died or self._closed.is_set():
                self.unsent += count
                return
            try:
                self._outbox.send(item)
            except (OSError, ValueError):
                self.unsent += count

    def _read(self) -> None:
        """Reader thread: take the child's reports until it closes the pipe."""
        while True:
            try:
                kind, state = self._inbox.recv()
            except (EOFError, OSError):
                break
            with self._state_lock:
                self._state = WriterState(*state)
            if kind == 'final':
                self._closed.set()
                return
        code = self._process.wait()
        if self._closed.is_set():
            return
        in_files = records_in(self._state.status.files)
        with self._state_lock:
            self._in_files = in_files
            self._died = (f'the MCAP log writer process (PID {self._process.pid}) '
                          f'exited with code {code} before the log was closed: what it '
                          f'had not written is lost')

    # shutdown ------------------------------------------------------------------------------
    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> LogStatus:
        """Let the child write what it has, close the file and exit; idempotent, no raise."""
        self._stop.set()
        self._sender.join(timeout_s)
        with self._send_lock:
            if not self._outbox.closed:
                try:
                    self._outbox.send(None)
                except (OSError, ValueError):
                    pass
                self._outbox.close()
        self._reader.join(timeout_s)
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()
            with self._state_lock:
                self._died = self._died or (
                    f'the MCAP log writer process did not finish in {timeout_s:g} s; killed')
        self._closed.set()
        return self.status()

    def closing_line(self) -> Tuple[bool, str]:
        """Return (all written, the closing log line) after ``close()``."""
        return closing_line(self.status(), self.refused, self.unsent)


def records_in(files: Sequence[str]) -> Optional[int]:
    """Return the messages readable in ``files`` (a removed one holds none; None: unknown)."""
    count = 0
    for file in files:
        if not os.path.lexists(file):
            continue
        try:
            count += sum(1 for _ in McapSource(file, check_data_crc=False).messages())
        except (OSError, ValueError):
            return None
    return count


def _state(writer: RecordWriter, final: bool = False) -> tuple:
    """Return the child's report: WriterState's fields (the child runs as __main__)."""
    return (writer.log.status(), writer.written, writer.errors, writer.reordered,
            writer.last_error, writer.write_time_s, final)


def _report(outbox: Connection, item: tuple) -> bool:
    """Send ``item`` to the caller; False when the caller is gone (its end is closed)."""
    try:
        outbox.send(item)
    except OSError:   # BrokenPipeError: the caller died; the file is finished all the same
        return False
    return True


def serve(inbox: Connection, outbox: Connection, writer: RecordWriter) -> None:
    """
    Child: write what arrives until None or the pipe closes, reporting the status.

    A caller that dies (its pipe ends close) ends the reports; the file is still finished.
    """
    listening = _report(outbox, ('status', _state(writer)))
    reported = time.monotonic()
    while True:
        if inbox.poll(STATUS_PERIOD_S):
            try:
                item = inbox.recv()
            except (EOFError, OSError):
                break
            if item is None:
                break
            kind, payload = item
            if kind == 'register':
                for topic, type_name, qos in payload:
                    writer.log.register(topic, type_name, qos=qos)
            else:
                for record in payload:
                    writer.write(*record)
        if listening and time.monotonic() - reported >= STATUS_PERIOD_S:
            listening = _report(outbox, ('status', _state(writer)))
            reported = time.monotonic()
    writer.log.close()
    if listening:
        _report(outbox, ('final', _state(writer, final=True)))


def main(argv: List[str]) -> int:
    """Child: ``FD OPENED_PATH REQUESTED_PATH FLUSH_MESSAGES FLUSH_S IN_FD OUT_FD``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    fd, opened, requested, flush_messages, flush_s, in_fd, out_fd = argv
    inbox = Connection(int(in_fd), writable=False)
    outbox = Connection(int(out_fd), readable=False)
    try:
        log = McapLog(requested, flush_every_messages=int(flush_messages),
                      flush_every_s=float(flush_s), if_exists='rename',
                      opened=(int(fd), Path(opened)))
    except (OSError, ValueError) as error:
        _report(outbox, ('failed', f'{requested}: {error}'))
        return 1
    serve(inbox, outbox, RecordWriter(log))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
