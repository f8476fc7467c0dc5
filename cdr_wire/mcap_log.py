"""
McapLog: a thread-safe ROS 2 MCAP writer that rosbag2, Foxglove and mcap_ros2 read as their own.

The file follows the MCAP ``ros2`` profile the way rosbag2 (Jazzy) writes it: schemas with
encoding ``ros2msg`` holding the complete message definition (``msgdefs``), channels with
message encoding ``cdr`` and the channel metadata ``offered_qos_profiles`` (the YAML list
rosbag2 stores) and ``topic_type_hash`` (RIHS01), zstd-compressed chunks, and a ``rosbag2``
metadata record with ``ROS_DISTRO`` (``cdr_wire.rosbag2_metadata``). Completed chunks are
flushed to the file every N messages and every T seconds (a background thread), so a writer
killed with SIGKILL loses at most the messages of that window; everything before stays
readable (see ``cdr_wire.reader`` for the salvage of such a file). ``close()`` writes the
summary and index and is idempotent.

One writer per file: the file is created exclusively and held with an exclusive ``flock``
while open (``cdr_wire.file_lock``). Write errors (disk full, I/O error, the file removed)
never raise from ``write``/``flush``/``close``: the file is cut back to its last complete
chunk, the records not written are counted, ``status()`` (a ``LogStatus``) says what
happened, and writing resumes in a new file (``<stem>_<n><suffix>``) once that works again.
See docs/reference/files.md.

Plain dicts are encoded to CDR by the compiled encoders of ``cdr_wire.cdr_codecs`` (the
bytes ``mcap_ros2`` writes).
"""

import errno
import os
from pathlib import Path
import struct
import threading
import time
from typing import Any, Callable, cast, Dict, IO, List, Mapping, Optional, Tuple, Union

from cdr_wire.cdr_codecs import encoder
from cdr_wire.errors import error_text
from cdr_wire.file_lock import open_exclusive
from cdr_wire.log_status import LogStatus
from cdr_wire.msgdefs import MESSAGE_DEFINITIONS, TYPE_HASHES
from cdr_wire.rosbag2_metadata import offered_qos_profiles_yaml, QOS_PROFILES, ROS_DISTRO
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer


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
        writer.start(profile='ros2', library=f'cdr_translator cdr_wire; {LIBRARY_IDENTIFIER}')
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

    @property
    def ok(self) -> bool:
        """Whether writing works: ``status().ok`` without building the status."""
        return not self._failing

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
    def _guarded(self, method: str, *arguments: Any) -> bool:
        """
        Call the writer's ``method`` with ``arguments``; on OSError cut the file back.

        The records lost are counted. Whatever reaches the file ends with complete records;
        when the file grew, every accepted message is in a complete chunk on disk (metadata
        is written only after a flush). Returns whether the call succeeded (caller holds
        the lock).
        """
        if self._writer is None or self._sink is None:
            return False
        try:
            getattr(self._writer, method)(*arguments)
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
        self._failure = (f'writing {self.path} failed: {error_text(error)}; {lost} records '
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
        except OSError as error:
            self._message = (f'{failed}; a new file cannot be created either: '
                             f'{error_text(error)}')
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
            self._message = f'{failed}; a new file failed too: {error_text(error)}'
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
                self._encoders[type_name] = encoder(type_name)
            return self._encoders[type_name]

    def write(self, topic: str, type_name: str, message: Mapping[str, Any], log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """Encode a message given as a nested dict (ROS field names) to CDR and append it."""
        try:
            data = self._encoder(type_name)(message)
        except (TypeError, ValueError, KeyError, AttributeError, struct.error) as error:
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
            channel = (self._channels.get(topic)   # a registered topic: no checks again
                       if self._writer is not None else None)
            channel_id = (channel[0] if channel is not None and channel[1] == type_name
                          else self._register_guarded(topic, type_name, 'reliable'))
            self._sequences[topic] += 1
            if channel_id is None:
                self._lost += 1
                return
            self._pending += 1
            if not self._guarded('add_message', channel_id, log_time, bytes(data),
                                 publish_time, self._sequences[topic] & 0xFFFFFFFF):
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
            self._guarded('add_metadata', *record)

    def _flush_locked(self) -> None:
        """Finish the chunk in progress and push it to the file (caller holds the lock)."""
        self._guarded('flush')
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
                    self._message = f'flush thread: {error_text(error)}'

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
            if self._writer is not None and self._guarded('finish'):
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
