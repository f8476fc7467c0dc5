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

CDR encoding of plain dicts uses ``mcap_ros2``'s dynamic encoder (``serialize_dynamic`` of
mcap-ros2-support 0.6.0, pinned in requirements.txt).
"""

from pathlib import Path
import threading
from typing import Any, Callable, Dict, Mapping, Optional, Tuple, Union

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer
from mcap_ros2._dynamic import serialize_dynamic
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


class McapLog:
    """
    Append ROS 2 messages to one MCAP file; safe to call from several threads.

    ``flush_every_messages`` (0: never by count) and ``flush_every_s`` (0: never by time)
    bound what a killed process can lose. Use as a context manager or call ``close()``.
    """

    def __init__(self, path: Union[str, Path], *, flush_every_messages: int = 100,
                 flush_every_s: float = 1.0, chunk_size: int = 1024 * 1024) -> None:
        """Create (truncate) ``path``, its parent directories, and start the MCAP."""
        if (isinstance(flush_every_messages, bool) or not isinstance(flush_every_messages, int)
                or flush_every_messages < 0):
            raise ValueError('flush_every_messages must be an int >= 0, got '
                             f'{flush_every_messages!r}')
        if not isinstance(flush_every_s, (int, float)) or not 0.0 <= flush_every_s < 1e9:
            raise ValueError(f'flush_every_s must be a number >= 0, got {flush_every_s!r}')
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._flush_every_messages = flush_every_messages
        self._lock = threading.Lock()
        self._stream = open(self.path, 'wb')
        self._writer = Writer(self._stream, chunk_size=chunk_size,
                              compression=CompressionType.ZSTD)
        self._writer.start(profile='ros2', library=f'cdr_translator msg_tools; '
                                                   f'{LIBRARY_IDENTIFIER}')
        self._writer.add_metadata('rosbag2', {'ROS_DISTRO': ROS_DISTRO})
        self._schemas: Dict[str, int] = {}
        self._encoders: Dict[str, Callable[[Any], bytes]] = {}
        self._channels: Dict[str, Tuple[int, str]] = {}
        self._sequences: Dict[str, int] = {}
        self._unflushed = 0
        self._closed = False
        self._stop = threading.Event()
        self._flusher: Optional[threading.Thread] = None
        if flush_every_s > 0:
            self._flusher = threading.Thread(target=self._flush_periodically,
                                             args=(float(flush_every_s),),
                                             name='mcap-log-flush', daemon=True)
            self._flusher.start()

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
        """Messages written so far per topic."""
        with self._lock:
            return dict(self._sequences)

    def _check_open(self) -> None:
        """Raise ValueError when the log is closed (caller holds the lock)."""
        if self._closed:
            raise ValueError(f'McapLog {self.path} is closed')

    def _schema_id(self, type_name: str) -> int:
        """Register the schema of ``type_name`` once; return its id (caller holds the lock)."""
        if type_name not in self._schemas:
            if type_name not in MESSAGE_DEFINITIONS:
                raise ValueError(f'no message definition for type {type_name!r}; known: '
                                 f'{sorted(MESSAGE_DEFINITIONS)}')
            self._schemas[type_name] = self._writer.register_schema(
                type_name, SchemaEncoding.ROS2, MESSAGE_DEFINITIONS[type_name].encode())
        return self._schemas[type_name]

    def _register(self, topic: str, type_name: str, qos: str) -> int:
        """Register ``topic`` once (caller holds the lock); return its channel id."""
        if not isinstance(topic, str) or not topic:
            raise ValueError(f'topic must be a non-empty string, got {topic!r}')
        if topic in self._channels:
            channel_id, registered_type = self._channels[topic]
            if registered_type != type_name:
                raise ValueError(f'topic {topic!r} is registered with type '
                                 f'{registered_type!r}, not {type_name!r}')
            return channel_id
        schema_id = self._schema_id(type_name)
        metadata = {'offered_qos_profiles': offered_qos_profiles_yaml(qos),
                    'topic_type_hash': TYPE_HASHES[type_name]}
        channel_id = self._writer.register_channel(topic, MessageEncoding.CDR, schema_id,
                                                   metadata)
        self._channels[topic] = (channel_id, type_name)
        self._sequences[topic] = 0
        return channel_id

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
            self._register(topic, type_name, qos)

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
        """Append an already CDR-serialized message (e.g. rclpy serialize_message output)."""
        log_time = int(log_time_ns)
        publish_time = log_time if publish_time_ns is None else int(publish_time_ns)
        if log_time < 0 or publish_time < 0:
            raise ValueError(f'message times must be >= 0 ns, got {log_time}, {publish_time}')
        with self._lock:
            self._check_open()
            channel_id = self._register(topic, type_name, 'reliable')
            self._sequences[topic] += 1
            self._writer.add_message(channel_id, log_time=log_time, data=bytes(data),
                                     publish_time=publish_time,
                                     sequence=self._sequences[topic] & 0xFFFFFFFF)
            self._unflushed += 1
            if self._flush_every_messages and self._unflushed >= self._flush_every_messages:
                self._flush_locked()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record (string keys and values), e.g. how a file was made."""
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})

    def _flush_locked(self) -> None:
        """Finish the chunk in progress and push it to the file (caller holds the lock)."""
        self._writer.flush()
        self._unflushed = 0

    def flush(self) -> None:
        """Write the messages buffered so far to the file as a complete chunk."""
        with self._lock:
            if not self._closed and self._unflushed:
                self._flush_locked()

    def _flush_periodically(self, period_s: float) -> None:
        """Background loop: flush buffered messages every ``period_s`` until closed."""
        while not self._stop.wait(period_s):
            self.flush()

    def close(self) -> None:
        """Write the last chunk, the summary and the footer, and close the file; idempotent."""
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join(timeout=10.0)
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._writer.finish()
            finally:
                self._stream.close()

    def __repr__(self) -> str:
        """Describe the log."""
        state = 'closed' if self._closed else 'open'
        return f'McapLog({str(self.path)!r}, {state}, {sum(self._sequences.values())} messages)'
