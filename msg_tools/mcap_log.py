"""
McapLog: a thread-safe ROS 2 MCAP writer that rosbag2, Foxglove and mcap_ros2 read as their own.

The file follows the MCAP ``ros2`` profile the way rosbag2 (Jazzy) writes it: schemas with
encoding ``ros2msg`` holding the complete message definition (``msgdefs``), channels with
message encoding ``cdr`` and the channel metadata ``offered_qos_profiles`` (the YAML list
rosbag2 stores) and ``topic_type_hash`` (RIHS01), zstd-compressed chunks, and a ``rosbag2``
metadata record with ``ROS_DISTRO``. Completed chunks are flushed to the file every N
messages and every T seconds (a background thread), so a writer killed with SIGKILL loses
at most the messages of that window; everything before stays readable (see
``msg_tools.reader`` for the salvage of such a file). ``close()`` writes the summary and
index and is idempotent.

One writer per file: the file is created exclusively (``if_exists`` 'fail', the default;
'overwrite' or 'rename' on request) and held with an exclusive ``flock`` while open, so a
second writer on the same path fails at once (``LogFileBusyError`` naming the holder's PID)
instead of interleaving. Write errors (disk full, I/O error, the file removed) never raise
from ``write``/``flush``/``close``: the file is cut back to its last complete chunk, the
records not written are counted, ``status()`` says what happened, and writing resumes in a
new file (``<stem>_<n><suffix>``) once that works again. See docs/logging.md.

CDR encoding of plain dicts uses ``mcap_ros2``'s dynamic encoder (``serialize_dynamic`` of
mcap-ros2-support 0.6.0, pinned in requirements.txt).
"""

from dataclasses import dataclass
import errno
import fcntl
import os
from pathlib import Path
import threading
import time
from typing import (Any, Callable, cast, Dict, IO, Iterator, List, Mapping, Optional, Tuple,
                    Union)

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer
from mcap_ros2._dynamic import serialize_dynamic
from msg_tools.errors import LogFileBusyError, LogFileExistsError
from msg_tools.msgdefs import MESSAGE_DEFINITIONS, TYPE_HASHES
import yaml

#: ROS distribution recorded in the file's ``rosbag2`` metadata record.
ROS_DISTRO = 'jazzy'

#: rmw's infinite duration as rosbag2 serializes it.
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}

#: The QoS profiles a topic can be registered with (rclpy's default publisher profile with
#: depth 10, and qos_profile_sensor_data), as rosbag2 serializes an offered profile.
QOS_PROFILES: Mapping[str, dict] = {
    'reliable': {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
                 'durability': 'volatile'},
    'sensor_data': {'history': 'keep_last', 'depth': 5, 'reliability': 'best_effort',
                    'durability': 'volatile'},
}


def offered_qos_profiles_yaml(qos: str) -> str:
    """Return the ``offered_qos_profiles`` channel metadata of one publisher with ``qos``."""
    if qos not in QOS_PROFILES:
        raise ValueError(f'qos must be one of {sorted(QOS_PROFILES)}, got {qos!r}')
    profile = dict(QOS_PROFILES[qos])
    profile.update({'deadline': dict(_INFINITE), 'lifespan': dict(_INFINITE),
                    'liveliness': 'automatic', 'liveliness_lease_duration': dict(_INFINITE),
                    'avoid_ros_namespace_conventions': False})
    return yaml.safe_dump([profile], sort_keys=False, default_flow_style=False).rstrip('\n')


#: What a writer does when its path exists: fail (the default), overwrite it, or pick a
#: new name ``<stem>_<n><suffix>``.
IF_EXISTS = ('fail', 'overwrite', 'rename')

#: Highest ``n`` tried for a new name.
_MAX_RENAME = 9999


def _flock_holder(path: Union[str, Path]) -> Optional[str]:
    """
    Return who holds a ``flock`` on ``path`` ('PID 123: command line'), None if nobody.

    Read from /proc/locks (Linux) without taking any lock, so looking never makes a real
    writer fail; without /proc/locks, a shared lock is tried for an instant instead.
    """
    try:
        status = os.stat(path)
        with open('/proc/locks') as locks:
            lines = locks.read().splitlines()
    except FileNotFoundError:
        return _probe(path)
    except OSError:
        return None
    device = f'{os.major(status.st_dev):02x}:{os.minor(status.st_dev):02x}:{status.st_ino}'
    for line in lines:
        fields = line.split()
        if '->' in fields or 'FLOCK' not in fields or len(fields) < 6:
            continue
        if fields[5] != device and fields[5].rsplit(':', 1)[-1] != str(status.st_ino):
            continue
        pid = fields[4]
        if pid == str(os.getpid()):
            return f'PID {pid}, this process'
        try:
            with open(f'/proc/{pid}/cmdline', 'rb') as command:
                text = command.read().replace(b'\0', b' ').decode(errors='replace').strip()
        except OSError:
            text = ''
        return f'PID {pid}: {text[:160]}' if text else f'PID {pid}'
    return None


def lock_holder(path: Union[str, Path]) -> str:
    """Describe the holder of the lock on ``path`` ('holder unknown' when it cannot tell)."""
    return _flock_holder(path) or 'holder unknown'


def _probe(path: Union[str, Path]) -> Optional[str]:
    """Try a shared lock on ``path`` for an instant: 'holder unknown' if it is held."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return 'holder unknown'
    finally:
        os.close(fd)
    return None


def _names(path: Path) -> Iterator[Path]:
    """Yield ``path`` then ``<stem>_1<suffix>``, ``<stem>_2<suffix>``, ..."""
    yield path
    for number in range(1, _MAX_RENAME + 1):
        yield path.with_name(f'{path.stem}_{number}{path.suffix}')


def open_exclusive(path: Union[str, Path], if_exists: str = 'fail') -> Tuple[int, Path]:
    """
    Create ``path`` (and its folders) for writing under an exclusive flock; return (fd, path).

    ``if_exists``: 'fail' raises LogFileExistsError for an existing file (LogFileBusyError
    when a writer holds it); 'overwrite' truncates it once the lock is held; 'rename' takes
    the first free ``<stem>_<n><suffix>``. A file locked by another writer is never opened
    for writing: LogFileBusyError names it and its holder. Other OSErrors (no permission, a
    file where a folder should be) propagate.
    """
    if if_exists not in IF_EXISTS:
        raise ValueError(f'if_exists must be one of {IF_EXISTS}, got {if_exists!r}')
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if if_exists == 'overwrite':
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise LogFileBusyError(path, lock_holder(path)) from None
        os.ftruncate(fd, 0)
        return fd, path
    for candidate in _names(path) if if_exists == 'rename' else [path]:
        try:
            fd = os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
        except FileExistsError:
            if if_exists == 'fail':
                holder = _flock_holder(candidate)
                if holder is not None:
                    raise LogFileBusyError(candidate, holder) from None
                raise LogFileExistsError(candidate) from None
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:   # an overwriting writer took the new file first
            os.close(fd)
            if if_exists == 'fail':
                raise LogFileBusyError(candidate, lock_holder(candidate)) from None
            continue
        return fd, candidate
    raise LogFileExistsError(path.with_name(f'{path.stem}_{_MAX_RENAME}{path.suffix}'))


class _FileSink:
    """
    The stream the mcap Writer writes to: unbuffered ``os.write`` with the offset counted.

    ``flush`` also checks that the file still has a name (a removed file is an error, not a
    place to write into). Tests replace ``os_write`` to inject faults.
    """

    def __init__(self, fd: int) -> None:
        """Write to the open descriptor ``fd`` from offset 0."""
        self.fd = fd
        self.offset = 0

    @staticmethod
    def os_write(fd: int, data: memoryview) -> int:
        """Write once, return the bytes written (os.write)."""
        return os.write(fd, data)

    def write(self, data: bytes) -> int:
        """Write all of ``data`` or raise OSError (``offset`` counts what reached the file)."""
        view = memoryview(data)
        while view:
            count = self.os_write(self.fd, view)
            if count <= 0:
                raise OSError(errno.EIO, 'write returned no progress')
            self.offset += count
            view = view[count:]
        return len(data)

    def tell(self) -> int:
        """Return the bytes written so far."""
        return self.offset

    def flush(self) -> None:
        """Raise OSError if the file was removed (its data would vanish on close)."""
        if os.fstat(self.fd).st_nlink == 0:
            raise OSError(errno.ENOENT, 'the file was removed while being written')


@dataclass(frozen=True)
class LogStatus:
    """
    What a McapLog has done: ``ok`` False while writing fails.

    ``written``: records in complete chunks on disk; ``pending``: records accepted but not
    yet flushed; ``lost``: records that will never be written (a write error, the file
    removed); ``errors``: write-error events; ``message``: the last event (error or resume),
    '' when nothing happened; ``files``: every file written, the current one last.
    """

    ok: bool
    path: str
    files: Tuple[str, ...]
    written: int
    pending: int
    lost: int
    errors: int
    message: str

    def describe(self) -> str:
        """Return a one-line account, e.g. for a node's closing log line."""
        state = 'ok' if self.ok else 'ERROR'
        files = ', '.join(self.files)
        text = (f'{state}: {self.written} records written, {self.lost} lost'
                + (f', {self.pending} pending' if self.pending else '') + f'; file(s) {files}')
        return text + (f'; {self.message}' if self.message else '')


class McapLog:
    """
    Append ROS 2 messages to one MCAP file; safe to call from several threads.

    ``flush_every_messages`` (0: never by count) and ``flush_every_s`` (0: never by time)
    bound what a killed process can lose. ``if_exists`` ('fail', 'overwrite', 'rename')
    says what to do with an existing file; ``path`` is the file actually written
    (``requested_path`` the one asked for). ``retry_s``: after a write error, how often to
    try a new file. Use as a context manager or call ``close()``.
    """

    def __init__(self, path: Union[str, Path], *, flush_every_messages: int = 100,
                 flush_every_s: float = 1.0, chunk_size: int = 1024 * 1024,
                 if_exists: str = 'fail', retry_s: float = 1.0,
                 opened: Optional[Tuple[int, Path]] = None) -> None:
        """
        Create ``path`` (see ``open_exclusive``), its parent folders, and start the MCAP.

        ``opened``: (descriptor, path) that ``open_exclusive(path, if_exists)`` returned
        already, e.g. in the process that handed the descriptor to this one; the log owns it.
        """
        if (isinstance(flush_every_messages, bool) or not isinstance(flush_every_messages, int)
                or flush_every_messages < 0):
            raise ValueError('flush_every_messages must be an int >= 0, got '
                             f'{flush_every_messages!r}')
        if not isinstance(flush_every_s, (int, float)) or not 0.0 <= flush_every_s < 1e9:
            raise ValueError(f'flush_every_s must be a number >= 0, got {flush_every_s!r}')
        if not isinstance(retry_s, (int, float)) or not 0.0 <= retry_s < 1e9:
            raise ValueError(f'retry_s must be a number >= 0, got {retry_s!r}')
        self.requested_path = Path(path)
        self._flush_every_messages = flush_every_messages
        self._chunk_size = chunk_size
        self._retry_s = float(retry_s)
        self._lock = threading.Lock()
        self._schemas: Dict[str, int] = {}
        self._encoders: Dict[str, Callable[[Any], bytes]] = {}
        self._channels: Dict[str, Tuple[int, str]] = {}
        self._qos: Dict[str, str] = {}
        self._type_of: Dict[str, str] = {}
        self._metadata: List[Tuple[str, Dict[str, str]]] = [
            ('rosbag2', {'ROS_DISTRO': ROS_DISTRO})]
        self._sequences: Dict[str, int] = {}
        self._files: List[str] = []
        self._written = self._pending = self._lost = self._errors = 0
        self._file_written = 0
        self._committed_offset = 0
        self._message = self._failure = ''
        self._failing = False
        self._next_retry = 0.0
        self._unflushed = 0
        self._closed = False
        self._final: Optional[LogStatus] = None
        if opened is None:
            opened = open_exclusive(self.requested_path, if_exists)
        fd, self.path = opened
        try:
            self._start(fd)
        except OSError:
            os.close(fd)
            raise
        if self.path != self.requested_path:
            self._message = f'{self.requested_path} exists: writing {self.path} instead'
        self._stop = threading.Event()
        self._flusher: Optional[threading.Thread] = None
        if flush_every_s > 0:
            self._flusher = threading.Thread(target=self._flush_periodically,
                                             args=(float(flush_every_s),),
                                             name='mcap-log-flush', daemon=True)
            self._flusher.start()

    def _start(self, fd: int) -> None:
        """Begin an MCAP in the locked file ``fd`` (caller holds the lock or constructs)."""
        self._fd: Optional[int] = fd
        self._sink: Optional[_FileSink] = _FileSink(fd)
        writer = Writer(cast(IO[Any], self._sink), chunk_size=self._chunk_size,
                        compression=CompressionType.ZSTD, enable_data_crcs=True)
        self._writer: Optional[Writer] = writer
        self._files.append(str(self.path))
        self._file_written = 0
        self._committed_offset = 0
        self._channels = {}
        self._schemas = {}
        writer.start(profile='ros2', library=f'cdr_translator msg_tools; {LIBRARY_IDENTIFIER}')
        for name, data in self._metadata:
            writer.add_metadata(name, data)
        for topic, qos in self._qos.items():
            self._register(topic, self._type_of[topic], qos)
        writer.flush()
        self._committed_offset = self._sink.offset

    def __enter__(self) -> 'McapLog':
        """Return self."""
        return self

    def __exit__(self, *exc_info: Any) -> None:
        """Close the file (summary written) whatever happened inside the block."""
        self.close()

    @property
    def closed(self) -> bool:
        """Tell whether ``close()`` has run."""
        return self._closed

    @property
    def message_counts(self) -> Dict[str, int]:
        """Messages accepted so far per topic (written or, after a write error, lost)."""
        with self._lock:
            return dict(self._sequences)

    def status(self) -> LogStatus:
        """Return what has been written and lost so far, and whether writing works."""
        with self._lock:
            return self._status()

    def _status(self) -> LogStatus:
        """Build the status (caller holds the lock)."""
        return LogStatus(ok=not self._failing, path=str(self.path), files=tuple(self._files),
                         written=self._written, pending=self._pending, lost=self._lost,
                         errors=self._errors, message=self._message)

    # writing with failures as events ---------------------------------------------------------
    def _guarded(self, action: Callable[[Writer], Any]) -> bool:
        """
        Run ``action(writer)``; on OSError cut the file back and count the loss.

        Whatever reaches the file ends with complete records; when the file grew, every
        accepted message is in a complete chunk on disk (metadata is written only after a
        flush). Returns whether the action succeeded (caller holds the lock).
        """
        if self._writer is None or self._sink is None:
            return False
        try:
            action(self._writer)
        except OSError as error:
            self._fail(error)
            return False
        if self._sink.offset != self._committed_offset:
            self._written += self._pending
            self._file_written += self._pending
            self._pending = 0
            self._committed_offset = self._sink.offset
        return True

    def _fail(self, error: OSError) -> None:
        """Abandon the current file after ``error`` (caller holds the lock)."""
        lost = self._pending
        removed = getattr(error, 'errno', None) == errno.ENOENT and self._fd is not None \
            and _removed(self._fd)
        if removed:   # what was written into the removed file is gone with it
            lost += self._file_written
            self._written -= self._file_written
        self._lost += lost
        self._pending = 0
        self._errors += 1
        if self._fd is not None:
            if not removed:
                try:
                    os.ftruncate(self._fd, self._committed_offset)
                except OSError:
                    pass
            os.close(self._fd)
        self._fd = self._sink = self._writer = None
        self._failing = True
        self._unflushed = 0
        kept = ('it was removed' if removed else
                f'it is readable up to byte {self._committed_offset}')
        self._failure = (f'writing {self.path} failed: {_error_text(error)}; {lost} records '
                         f'lost ({self._lost} in all); {kept}; trying a new file every '
                         f'{self._retry_s:g} s')
        self._message = self._failure
        self._next_retry = time.monotonic() + self._retry_s

    def _resume(self) -> bool:
        """After a failure, try a new file once ``retry_s`` has passed (caller holds lock)."""
        if self._writer is not None:
            return True
        if self._closed or time.monotonic() < self._next_retry:
            return False
        self._next_retry = time.monotonic() + self._retry_s
        failed = self._failure
        try:
            fd, path = open_exclusive(self.requested_path, 'rename')
        except OSError:
            return False
        previous = self.path
        self.path = path
        try:
            self._start(fd)
        except OSError as error:
            os.close(fd)
            self._fd = self._sink = self._writer = None
            self._files.pop()
            self.path = previous
            try:
                path.unlink()
            except OSError:
                pass
            self._message = f'{failed}; a new file failed too: {_error_text(error)}'
            return False
        self._failing = False
        self._message = (f'resumed in {path} after a write error ({self._lost} records '
                         f'lost so far); earlier: {failed}')
        return True

    # registration ----------------------------------------------------------------------------
    def _check_open(self) -> None:
        """Raise ValueError when the log is closed (caller holds the lock)."""
        if self._closed:
            raise ValueError(f'McapLog {self.path} is closed')

    def _schema_id(self, type_name: str) -> int:
        """Register the schema of ``type_name`` once; return its id (caller holds the lock)."""
        if type_name not in self._schemas:
            assert self._writer is not None
            self._schemas[type_name] = self._writer.register_schema(
                type_name, SchemaEncoding.ROS2, MESSAGE_DEFINITIONS[type_name].encode())
        return self._schemas[type_name]

    def _declare(self, topic: str, type_name: str, qos: str) -> None:
        """Check and remember ``topic`` with its type and QoS (caller holds the lock)."""
        if not isinstance(topic, str) or not topic:
            raise ValueError(f'topic must be a non-empty string, got {topic!r}')
        if type_name not in MESSAGE_DEFINITIONS:
            raise ValueError(f'no message definition for type {type_name!r}; known: '
                             f'{sorted(MESSAGE_DEFINITIONS)}')
        if topic in self._qos:
            if self._type_of[topic] != type_name:
                raise ValueError(f'topic {topic!r} is registered with type '
                                 f'{self._type_of[topic]!r}, not {type_name!r}')
            return
        self._qos[topic] = qos
        self._type_of[topic] = type_name
        self._sequences[topic] = 0

    def _register(self, topic: str, type_name: str, qos: str) -> Optional[int]:
        """Declare ``topic`` and register it in the current file; its channel id or None."""
        self._declare(topic, type_name, qos)
        if self._writer is None:
            return None
        if topic not in self._channels:
            schema_id = self._schema_id(type_name)
            metadata = {'offered_qos_profiles': offered_qos_profiles_yaml(qos),
                        'topic_type_hash': TYPE_HASHES[type_name]}
            self._channels[topic] = (self._writer.register_channel(
                topic, MessageEncoding.CDR, schema_id, metadata), type_name)
        return self._channels[topic][0]

    def register(self, topic: str, type_name: str, qos: str = 'reliable') -> None:
        """
        Declare ``topic`` with its type and offered QoS ('reliable' or 'sensor_data').

        Optional: ``write`` registers unknown topics as 'reliable'. Registering a topic
        again with the same type does nothing; with another type is a ValueError.
        """
        if qos not in QOS_PROFILES:
            raise ValueError(f'qos must be one of {sorted(QOS_PROFILES)}, got {qos!r}')
        with self._lock:
            self._check_open()
            self._resume()
            self._register_guarded(topic, type_name, qos)

    def _register_guarded(self, topic: str, type_name: str, qos: str) -> Optional[int]:
        """``_register`` with a write error (a chunk finished on the way) as an event."""
        try:
            return self._register(topic, type_name, qos)
        except OSError as error:
            self._fail(error)
            return None

    def _encoder(self, type_name: str) -> Callable[[Any], bytes]:
        """Return the CDR encoder of ``type_name`` (built once)."""
        with self._lock:
            if type_name not in self._encoders:
                if type_name not in MESSAGE_DEFINITIONS:
                    raise ValueError(f'no message definition for type {type_name!r}')
                self._encoders[type_name] = serialize_dynamic(
                    type_name, MESSAGE_DEFINITIONS[type_name])[type_name]
            return self._encoders[type_name]

    def write(self, topic: str, type_name: str, message: Mapping[str, Any], log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """Encode a message given as a nested dict (ROS field names) to CDR and append it."""
        try:
            data = self._encoder(type_name)(message)
        except (TypeError, ValueError, KeyError, AttributeError) as error:
            raise ValueError(f'cannot encode a {type_name} for topic {topic!r}: {error}'
                             ) from error
        self.write_serialized(topic, type_name, data, log_time_ns, publish_time_ns)

    def write_serialized(self, topic: str, type_name: str, data: bytes, log_time_ns: int,
                         publish_time_ns: Optional[int] = None) -> None:
        """
        Append an already CDR-serialized message (e.g. rclpy serialize_message output).

        ValueError for a bad call (closed log, bad times, unknown type); a write error is
        not raised but counted (see ``status``).
        """
        log_time = int(log_time_ns)
        publish_time = log_time if publish_time_ns is None else int(publish_time_ns)
        if log_time < 0 or publish_time < 0:
            raise ValueError(f'message times must be >= 0 ns, got {log_time}, {publish_time}')
        with self._lock:
            self._check_open()
            self._resume()
            channel_id = self._register_guarded(topic, type_name, 'reliable')
            self._sequences[topic] += 1
            if channel_id is None:
                self._lost += 1
                return
            sequence = self._sequences[topic] & 0xFFFFFFFF
            self._pending += 1
            if not self._guarded(lambda writer: writer.add_message(
                    channel_id, log_time=log_time, data=bytes(data),
                    publish_time=publish_time, sequence=sequence)):
                return
            self._unflushed += 1
            if self._flush_every_messages and self._unflushed >= self._flush_every_messages:
                self._flush_locked()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record (string keys and values), e.g. how a file was made."""
        record = (name, {str(k): str(v) for k, v in data.items()})
        with self._lock:
            self._check_open()
            self._metadata.append(record)   # repeated in a file started after an error
            self._resume()
            self._flush_locked()   # so that a grown file means the messages are on disk
            self._guarded(lambda writer: writer.add_metadata(*record))

    def _flush_locked(self) -> None:
        """Finish the chunk in progress and push it to the file (caller holds the lock)."""
        self._guarded(lambda writer: writer.flush())
        self._unflushed = 0

    def flush(self) -> None:
        """Write the messages buffered so far to the file as a complete chunk."""
        with self._lock:
            if self._closed:
                return
            if self._resume() and self._unflushed:
                self._flush_locked()

    def _flush_periodically(self, period_s: float) -> None:
        """Background loop: flush buffered messages every ``period_s`` until closed."""
        while not self._stop.wait(period_s):
            try:
                self.flush()
            except Exception as error:  # noqa: B902 - the thread must not die with a traceback
                with self._lock:
                    self._errors += 1
                    self._message = f'flush thread: {_error_text(error)}'

    def close(self) -> LogStatus:
        """
        Write the last chunk, the summary and the footer, close the file; return the status.

        Idempotent; never raises for a write error (the file then ends at its last complete
        chunk and the status counts what was lost).
        """
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join(timeout=10.0)
        with self._lock:
            if self._final is not None:
                return self._final
            self._closed = True
            if self._writer is not None:
                self._flush_locked()
            if self._writer is not None and self._guarded(lambda writer: writer.finish()):
                assert self._fd is not None
                os.close(self._fd)
                self._fd = self._sink = self._writer = None
            self._final = self._status()
            return self._final

    def __repr__(self) -> str:
        """Describe the log."""
        state = 'closed' if self._closed else 'open'
        return f'McapLog({str(self.path)!r}, {state}, {sum(self._sequences.values())} messages)'


def _removed(fd: int) -> bool:
    """Tell whether the open file ``fd`` no longer has a name."""
    try:
        return os.fstat(fd).st_nlink == 0
    except OSError:
        return False


def _error_text(error: BaseException) -> str:
    """Return 'Type: message' of an exception."""
    text = str(error)
    return f'{type(error).__name__}: {text}' if text else type(error).__name__
