"""
The runtime both nodes share: mailbox, message filling, MCAP log thread, start and spin.

The latest-wins mailbox, message filling and the MCAP log thread can each be tested without
DDS; ``run`` starts a node, spins it until SIGINT/SIGTERM and closes it cleanly. The input
checks and the solve of one wrench are cdr_translator.interface.processing's, shared with
the offline replay.
"""

import datetime
from functools import lru_cache
import importlib
import os
from pathlib import Path
import queue
import signal
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from msg_tools.mcap_log import LogStatus, McapLog
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from .parameters import check_value
from ..interface import messages
from ..params import ParameterError

#: The node's output topics (relative names except /diagnostics) and their message classes.
OUTPUTS = {
    messages.END_DISK_POSE_TOPIC: PoseStamped,
    messages.BENDING_ANGLES_TOPIC: JointState,
    messages.COMPLIANCE_EIGENVALUES_TOPIC: Float64MultiArray,
    messages.COMPLIANCE_TOPIC: Float64MultiArray,
    messages.BACKBONES_TOPIC: MarkerArray,
    messages.DIAGNOSTICS_TOPIC: DiagnosticArray,
}

#: How long main() waits for the solver thread to finish its solve at shutdown.
SHUTDOWN_JOIN_S = 5.0

#: Records the MCAP log thread may hold before a producer waits (never dropped, never
#: unbounded): at 1 kHz input with five outputs per solve, several seconds of backlog.
LOG_QUEUE_CAPACITY = 20000

#: How often a node checks its MCAP log (an ERROR diagnostic while writing fails).
LOG_CHECK_PERIOD_S = 1.0

#: While the solver works, the log thread holds its records back (they would take the GIL
#: from the solve) at most this long, then writes what is queued ...
LOG_HOLD_S = 0.1
#: ... or as soon as this many records are queued (checked every LOG_HOLD_CHECK_S).
LOG_HOLD_RECORDS = 1000
LOG_HOLD_CHECK_S = 0.02


def sensor_qos(depth: int) -> QoSProfile:
    """Return the sensor-data QoS (best effort, volatile, keep last) ``depth`` deep."""
    return QoSProfile(depth=depth, reliability=qos_profile_sensor_data.reliability,
                      durability=qos_profile_sensor_data.durability,
                      history=qos_profile_sensor_data.history)


class LatestMailbox:
    """
    One-slot, thread-safe mailbox: ``put`` replaces an untaken item (counted as skipped).

    The consumer always gets the newest item; nothing ever queues up behind it. ``idle`` is
    set while the consumer waits with nothing to take (and once closed): the time a node's
    log thread writes in.
    """

    def __init__(self) -> None:
        """Start empty and open."""
        self._condition = threading.Condition()
        self._item: Any = None
        self._full = False
        self._closed = False
        self.skipped = 0
        self.idle = threading.Event()

    def put(self, item: Any) -> bool:
        """Leave ``item``; return True if it replaced one nobody had taken yet."""
        with self._condition:
            replaced = self._full
            if replaced:
                self.skipped += 1
            self._item, self._full = item, True
            self.idle.clear()
            self._condition.notify()
            return replaced

    def take(self, timeout: Optional[float] = None) -> Any:
        """Wait for an item and return it; None once closed (or after ``timeout`` s)."""
        with self._condition:
            if not self._full:
                self.idle.set()
            self._condition.wait_for(lambda: self._full or self._closed, timeout)
            if self._closed or not self._full:
                return None
            item, self._item, self._full = self._item, None, False
            self.idle.clear()
            return item

    def close(self) -> None:
        """Wake the consumer for good; an untaken item is dropped."""
        with self._condition:
            self._closed = True
            self.idle.set()
            self._condition.notify_all()


#: Field name -> rosidl type, per generated message class (filled on first use).
_FIELD_TYPES: Dict[Any, Dict[str, Any]] = {}


def _field_types(message_class: Any) -> Dict[str, Any]:
    """Map field name -> rosidl type of a generated message class."""
    types = _FIELD_TYPES.get(message_class)
    if types is None:
        types = dict(zip(message_class.get_fields_and_field_types(), message_class.SLOT_TYPES))
        _FIELD_TYPES[message_class] = types
    return types


@lru_cache(maxsize=None)
def _message_class(namespaces: tuple, name: str) -> type:
    """Import a generated message class, e.g. (('geometry_msgs', 'msg'), 'Point')."""
    return getattr(importlib.import_module('.'.join(namespaces)), name)


def fill_message(message: Any, values: Mapping[str, Any]) -> Any:
    """
    Set the fields of a generated ROS message from a nested plain dict; return the message.

    Nested messages are dicts, sequences of messages lists of dicts, an int for a ``byte``
    field becomes that one byte, everything else is assigned as it is (the message's own
    setters check the types). KeyError names a field the message does not have.
    """
    types = _field_types(type(message))
    for name, value in values.items():
        if name not in types:
            raise KeyError(f'{type(message).__name__} has no field {name!r}')
        if isinstance(value, Mapping):
            fill_message(getattr(message, name), value)
        elif isinstance(value, (list, tuple)) and value and isinstance(value[0], Mapping):
            element = types[name].value_type
            element_class = _message_class(tuple(element.namespaces), element.name)
            setattr(message, name, [fill_message(element_class(), item) for item in value])
        elif isinstance(value, int) and isinstance(getattr(message, name), bytes):
            setattr(message, name, bytes([value]))  # a .msg 'byte' field, e.g. a level
        else:
            setattr(message, name, value)
    return message


def type_name(message_class: Any) -> str:
    """Return the ROS 2 type name of a generated message class, e.g. 'std_msgs/msg/String'."""
    package = message_class.__module__.split('.')[0]
    return f'{package}/msg/{message_class.__name__}'


class LogThread:
    """
    Serialize and write log records to an McapLog on a thread of its own.

    Producers (the subscription callback, the solver thread) only enqueue: a record is the
    already-serialized bytes of a received message or a published message object, which
    this thread serializes. The queue is bounded (``capacity``); when it is full a producer
    waits rather than drop a record. The McapLog itself flushes completed chunks every N
    messages and T seconds. ``enqueue_wait_s`` and ``write_time_s`` measure whether logging
    ever holds up the solver.

    With ``idle`` (the solver's LatestMailbox.idle), records are written while the solver
    waits for input: a write holds the GIL for tens of microseconds, and a solver waiting
    for it can lose up to Python's switch interval (5 ms) each time. While the solver
    works, records wait at most ``hold_s`` (then what is queued is written) or until
    ``hold_records`` are queued.

    Log times never go back on a channel (what MCAP readers and ``mcap doctor`` expect): a
    record whose log time is earlier than the previous one of its topic (two producer
    threads, or rmw receive stamps out of step) is written with that previous time and
    counted in ``reordered``. Write errors do not stop the thread: the McapLog counts what
    it could not write (``status()``), ``errors`` counts records that could not even be
    serialized.
    """

    def __init__(self, log: Any, capacity: int = LOG_QUEUE_CAPACITY,
                 idle: Optional[threading.Event] = None, hold_s: float = LOG_HOLD_S,
                 hold_records: int = LOG_HOLD_RECORDS) -> None:
        """Start writing to ``log`` (an McapLog, closed by ``close()``), while ``idle`` is set."""
        self._log = log
        self._idle = idle
        self._hold_s = hold_s
        self._hold_records = hold_records
        self.held = 0
        self._queue: queue.Queue = queue.Queue(maxsize=capacity)
        self.submitted = 0
        self.written = 0
        self.errors = 0
        self.reordered = 0
        self.last_error = ''
        self.max_depth = 0
        self.enqueue_wait_s = 0.0
        self.max_enqueue_wait_s = 0.0
        self.write_time_s = 0.0
        self._last_log_time: Dict[str, int] = {}
        self._closed = False
        self._final: Optional[LogStatus] = None
        self._thread = threading.Thread(target=self._run, name='mcap_log', daemon=True)
        self._thread.start()

    @property
    def path(self) -> str:
        """Return the file being written (a new one after a write error)."""
        return str(self._log.path)

    def submit(self, topic: str, type_name: str, message: Any, log_time_ns: int,
               publish_time_ns: Optional[int] = None) -> None:
        """Queue one record; ``message`` is CDR bytes or a generated message object."""
        started = time.perf_counter()
        self._queue.put((topic, type_name, message, log_time_ns, publish_time_ns))
        waited = time.perf_counter() - started
        self.submitted += 1
        self.enqueue_wait_s += waited
        self.max_enqueue_wait_s = max(self.max_enqueue_wait_s, waited)
        self.max_depth = max(self.max_depth, self._queue.qsize())

    def _run(self) -> None:
        """Write queued records until the ``None`` that close() queues."""
        ungated = 0  # records to write without waiting (queued when a hold ran out)
        while True:
            record = self._queue.get()
            if record is None:
                return
            if ungated > 0:
                ungated -= 1
            elif self._idle is not None and not self._idle.is_set():
                self.held += 1
                ungated = self._hold(self._idle)
            topic, name, message, log_time_ns, publish_time_ns = record
            started = time.perf_counter()
            previous = self._last_log_time.get(topic, 0)
            if log_time_ns < previous:
                log_time_ns = previous
                self.reordered += 1
            self._last_log_time[topic] = log_time_ns
            try:
                data = message if isinstance(message, bytes) else serialize_message(message)
                self._log.write_serialized(topic, name, data, log_time_ns, publish_time_ns)
                self.written += 1
            except Exception as error:  # noqa: B902 - a bad record must not end the log
                self.errors += 1
                self.last_error = f'{topic}: {error}'
            self.write_time_s += time.perf_counter() - started

    def _hold(self, idle: threading.Event) -> int:
        """
        Wait until ``idle``, at most hold_s or until hold_records are queued.

        Return 0 when the solver waits for input now, else the number of records queued,
        to be written without waiting again.
        """
        deadline = time.monotonic() + self._hold_s
        while self._queue.qsize() < self._hold_records:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                break
            if idle.wait(min(remaining, LOG_HOLD_CHECK_S)):
                return 0
        return self._queue.qsize()

    def status(self) -> LogStatus:
        """Return the McapLog's status: records written and lost, the last error."""
        return self._final if self._final is not None else self._log.status()

    def close(self, timeout_s: float = 10.0) -> LogStatus:
        """Write what is queued, close the McapLog (summary written); idempotent, no raise."""
        if self._final is not None:
            return self._final
        self._closed = True
        self._queue.put(None)
        self._thread.join(timeout_s)
        self._final = self._log.close()
        return self._final

    def closing_line(self) -> Tuple[bool, str]:
        """Return (all written, the node's closing log line) after ``close()``."""
        status = self.status()
        lost = status.lost + self.errors
        text = (f'MCAP log closed: {status.written} records written, {lost} lost '
                f'({status.lost} not written, {self.errors} not serializable) in '
                f'{", ".join(status.files)}')
        if status.message:
            text += f'; {status.message}'
        return lost == 0, text


class LogWatch:
    """
    The MCAP log's health as diagnostics: ERROR while writing fails, WARN once it resumed.

    ``check()`` (called about once a second) returns (level, message, values) to publish,
    or None when there is nothing to say: nothing is published while the log is fine.
    """

    def __init__(self, log: LogThread) -> None:
        """Watch ``log``."""
        self.log = log
        self._reported_lost = 0
        self._reported_errors = 0
        self._failing = False

    def check(self) -> Optional[Tuple[int, str, Dict[str, Any]]]:
        """Return the diagnostic to publish now, if any (an error between two checks too)."""
        status = self.log.status()
        lost = status.lost + self.log.errors
        values: Dict[str, Any] = {'mcap_file': status.path, 'records_written': status.written,
                                  'records_lost': lost, 'write_errors': status.errors}
        if not status.ok or status.errors > self._reported_errors:
            self._failing = True
            self._reported_lost = lost
            self._reported_errors = status.errors
            return messages.ERROR, f'MCAP log: {status.message}', values
        if self._failing or lost > self._reported_lost:
            self._failing = False
            self._reported_lost = lost
            text = status.message or self.log.last_error
            return messages.WARN, f'MCAP log: {lost} records lost so far; {text}', values
        return None


def log_health(watch: Optional[LogWatch], logger: Any, node_name: str,
               counts: Mapping[str, Any]) -> List[Tuple[str, str, dict]]:
    """
    Check the MCAP log (a node's timer work); return the diagnostic to publish, if any.

    The status is named '<node_name>: mcap_log'; ERROR is also logged (throttled), WARN
    once. ``counts`` (the node's running counts) are added to its values.
    """
    found = watch.check() if watch is not None else None
    if found is None:
        return []
    level, text, values = found
    if level == messages.ERROR:
        logger.error(text, throttle_duration_sec=10.0)
    else:
        logger.warning(text)
    return [(messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
             messages.diagnostics_message(messages.stamp_from_ns(time.time_ns()), level, text,
                                          {**values, **counts},
                                          name=f'{node_name}: mcap_log'))]


def log_lost(log: Optional[LogThread]) -> Dict[str, int]:
    """Return ``{'log_records_lost': N}`` for a node's diagnostics ({} without a log)."""
    if log is None:
        return {}
    return {'log_records_lost': log.status().lost + log.errors}


def check_parameters(node: Any, specs: Mapping[str, Any], parameters: Sequence[Any],
                     check: Callable[[str, Any, Mapping[str, Any]], Optional[str]] = check_value
                     ) -> SetParametersResult:
    """
    Judge a parameter change of ``node`` (an on-set-parameters callback's work).

    ``check(name, value, others)`` gives the reason to reject a value (None: accept), with
    the others as they would be after the change; descriptors have already checked
    read-only and ranges.
    """
    values = {name: node.get_parameter(name).value for name in specs
              if node.has_parameter(name)}
    values.update({parameter.name: parameter.value for parameter in parameters})
    for parameter in parameters:
        reason = check(parameter.name, parameter.value, values)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
    return SetParametersResult(successful=True)


def open_log(settings: Any, prefix: str, topics: Sequence[Tuple[str, str, str]],
             idle: Optional[threading.Event] = None) -> Tuple[Optional[LogThread], str]:
    """
    Open a node's MCAP log and its writer thread; (None, '') when logging is off.

    ``settings`` has log_to_mcap, mcap_path, log_dir, mcap_flush_messages and mcap_flush_s;
    an empty mcap_path names the file <log_dir>/<prefix>_<UTC time>_<pid>.mcap (another
    free name if that exists). A given mcap_path is created exclusively: an existing file
    (an earlier run's log) or one another writer holds is an OSError naming it (and the
    holder's PID), which ``run`` turns into exit code 2. ``topics`` are (resolved name, type
    name, 'sensor_data' or 'reliable') to register up front; ``idle``: when the log thread
    writes (LogThread). The path returned is the file actually written.
    """
    if not settings.log_to_mcap:
        return None, ''
    path = Path(settings.mcap_path) if settings.mcap_path else (
        Path(settings.log_dir) / datetime.datetime.now(datetime.timezone.utc).strftime(
            f'{prefix}_%Y-%m-%d_%H-%M-%S_{os.getpid()}.mcap'))
    log = McapLog(path, flush_every_messages=settings.mcap_flush_messages,
                  flush_every_s=settings.mcap_flush_s,
                  if_exists='fail' if settings.mcap_path else 'rename')
    for topic, name, qos in topics:
        log.register(topic, name, qos=qos)
    return LogThread(log, idle=idle), str(log.path)


def run(factory: Callable[..., Node], name: str, args: Optional[Sequence[str]] = None) -> int:
    """
    Run the node ``factory(ros_arguments=...)`` builds until SIGINT or SIGTERM.

    ``ros_arguments`` is the command line (``args``, or sys.argv), from which the node reads
    its ``--params-file`` and ``-p`` values. The exit code is 2 when it cannot start (bad
    parameters, unwritable log), else 0 after its ``close()`` (which must stop its threads
    and finalize its log) and a clean shutdown.
    """
    rclpy.init(args=None if args is None else list(args),
               signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda *_: stop.set())
    try:
        node: Any = factory(ros_arguments=list(sys.argv if args is None else args))
    except (ParameterError, InvalidParameterTypeException, InvalidParameterValueException,
            OSError) as error:
        print(f'{name}: {error}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
