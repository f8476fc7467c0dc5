"""
The runtime both nodes share: mailbox, message filling, MCAP log process, start and spin.

The latest-wins mailbox, message filling and the MCAP log process can each be tested without
DDS; ``run`` starts a node, spins it until SIGINT/SIGTERM and closes it cleanly. The input
checks and the solve of one wrench are cdr_translator.interface.wrench_processing's, shared
with the offline replay.
"""

from collections import deque
import datetime
from functools import lru_cache
import gc
import importlib
import math
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Any, Callable, Deque, Dict, FrozenSet, List, Mapping, Optional, Sequence
from typing import Tuple

from cdr_wire.log_process import LogProcess
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.exceptions import ParameterUninitializedException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as rclpy_extension
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from .diagnostic_log import DiagnosticLog
from .node_help import EXIT_CANNOT_START, wants_help
from .parameters import check_command_line, check_value
from ..console import run_command
from ..interface import messages
from ..params.translator_params import ParameterError

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

#: How often a node checks its MCAP log (an ERROR diagnostic while writing fails).
LOG_CHECK_PERIOD_S = 1.0

#: Least time between two log lines of the MCAP log's status (s).
LOG_ERROR_THROTTLE_S = 10.0

#: How long a node trusts its count of an output topic's subscribers before counting again
#: (s): a count costs 10-15 us, and a node publishes several outputs per input at 1 kHz.
SUBSCRIBERS_REFRESH_S = 0.05

#: How long a thread that wants the GIL waits before the running one is asked to drop it
#: (CPython's default is 5 ms): the executor's wrench callback behind a busy solver thread.
GIL_SWITCH_INTERVAL_S = 0.0005


class SubscriberCounts:
    """
    Which output topics have subscribers, counted again at most every ``refresh_s``.

    A node builds and publishes an output only for a topic someone subscribes to (or when
    it logs it): a subscriber that appears is served from the next count on.
    """

    def __init__(self, publishers: Mapping[str, Any], refresh_s: float = SUBSCRIBERS_REFRESH_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Watch ``publishers`` (topic -> rclpy Publisher)."""
        self._publishers = dict(publishers)
        self._refresh_s = refresh_s
        self._clock = clock
        self._next = -math.inf
        self._subscribed: FrozenSet[str] = frozenset()

    def subscribed(self) -> FrozenSet[str]:
        """Return the topics with at least one subscriber (as last counted)."""
        now = self._clock()
        if now >= self._next:
            self._subscribed = frozenset(
                topic for topic, publisher in self._publishers.items()
                if publisher.get_subscription_count() > 0)
            self._next = now + self._refresh_s
        return self._subscribed


def sensor_qos(depth: int) -> QoSProfile:
    """Return the sensor-data QoS (best effort, volatile, keep last) ``depth`` deep."""
    return QoSProfile(depth=depth, reliability=qos_profile_sensor_data.reliability,
                      durability=qos_profile_sensor_data.durability,
                      history=qos_profile_sensor_data.history)


class LatestMailbox:
    """
    Bounded, thread-safe mailbox, first in first out: beyond ``capacity`` the oldest goes.

    ``put`` adds an item; when more than ``capacity`` items wait, the oldest waiting one is
    dropped (counted as skipped), so the newest item always waits and at most
    ``capacity - 1`` older ones before it. Capacity 1: the consumer always gets the newest
    (latest wins); 2 also keeps an item that arrived while the one before it was taken and
    being worked on, so two items arriving within one piece of work are both taken.
    """

    def __init__(self, capacity: int = 1) -> None:
        """Start empty and open; ``capacity`` >= 1 items may wait."""
        if capacity < 1:
            raise ValueError(f'a mailbox holds at least 1 item, got capacity {capacity}')
        self._condition = threading.Condition()
        self._items: Deque[Any] = deque()
        self.capacity = capacity
        self._closed = False
        self.skipped = 0

    def put(self, item: Any) -> bool:
        """Leave ``item``; return True if it pushed out an older one nobody had taken yet."""
        with self._condition:
            self._items.append(item)
            dropped = len(self._items) > self.capacity
            if dropped:
                self._items.popleft()
                self.skipped += 1
            self._condition.notify()
            return dropped

    def take(self, timeout: Optional[float] = None) -> Any:
        """
        Wait for an item and return the oldest; None after ``timeout`` s, or once closed.

        Closed with ``drain``, the items waiting then are still handed out first.
        """
        with self._condition:
            self._condition.wait_for(lambda: bool(self._items) or self._closed, timeout)
            if not self._items:
                return None
            return self._items.popleft()

    def close(self, drain: bool = False) -> None:
        """Wake the consumer for good; untaken items are dropped unless ``drain``."""
        with self._condition:
            self._closed = True
            if not drain:
                self._items.clear()
            self._condition.notify_all()

    def discard(self) -> int:
        """Drop the items still waiting, count them as skipped; return how many."""
        with self._condition:
            count = len(self._items)
            self.skipped += count
            self._items.clear()
            return count


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


class NodeLog(LogProcess):
    """
    A node's MCAP log: an McapLog in a child process (cdr_wire.log_process).

    The node's threads only hand records over (one pickled send per batch); the writing
    runs beside them instead of taking the GIL from the solve. Records may be CDR bytes or
    generated message objects, which are serialized here.
    """

    def submit_many(self, records: Sequence[Tuple[str, str, Any, int, Optional[int]]]
                    ) -> None:
        """Hand records over; message objects are serialized first."""
        super().submit_many([
            record if isinstance(record[2], bytes) else
            (record[0], record[1], serialize_message(record[2]), record[3], record[4])
            for record in records])


class LogWatch:
    """
    The MCAP log's health as diagnostics: ERROR while writing fails, WARN once it resumed.

    ``check()`` (called about once a second) returns (level, message, values) to publish,
    or None when there is nothing to say: nothing is published while the log is fine.
    """

    def __init__(self, log: NodeLog) -> None:
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


def log_status_name(node_name: str) -> str:
    """Return the DiagnosticStatus name of a node's MCAP log health."""
    return f'{node_name}: mcap_log'


def node_diagnostic_log(logger: Any, node_name: str) -> DiagnosticLog:
    """
    Return the DiagnosticLog of a node: each status one line a second at most.

    The MCAP log's status gets one line in ``LOG_ERROR_THROTTLE_S``: while writing fails
    it is an ERROR at every check.
    """
    return DiagnosticLog(logger, throttle_s_by_name={
        log_status_name(node_name): LOG_ERROR_THROTTLE_S})


def log_health(watch: Optional[LogWatch], node_name: str, counts: Mapping[str, Any]
               ) -> List[Tuple[str, str, dict]]:
    """
    Check the MCAP log (a node's timer work); return the diagnostic to publish, if any.

    The status is named ``log_status_name(node_name)``; ``counts`` (the node's running
    counts) are added to its values. The node logs it as it publishes it (DiagnosticLog).
    """
    found = watch.check() if watch is not None else None
    if found is None:
        return []
    level, text, values = found
    return [(messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
             messages.diagnostics_message(messages.stamp_from_ns(time.time_ns()), level, text,
                                          {**values, **counts},
                                          name=log_status_name(node_name)))]


def log_lost(log: Optional[NodeLog]) -> Dict[str, int]:
    """Return ``{'log_records_lost': N}`` for a node's diagnostics ({} without a log)."""
    if log is None:
        return {}
    return {'log_records_lost': log.status().lost + log.errors}


def _current_value(node: Any, name: str) -> Any:
    """Return a parameter's value; None while declared by type only (parameters.declare)."""
    try:
        return node.get_parameter(name).value
    except ParameterUninitializedException:
        return None


def check_parameters(node: Any, specs: Mapping[str, Any], parameters: Sequence[Any],
                     check: Callable[[str, Any, Mapping[str, Any]], Optional[str]] = check_value
                     ) -> SetParametersResult:
    """
    Judge a parameter change of ``node`` (an on-set-parameters callback's work).

    ``check(name, value, others)`` gives the reason to reject a value (None: accept), with
    the others as they would be after the change; descriptors have already checked
    read-only and ranges.
    """
    values = {name: _current_value(node, name) for name in specs if node.has_parameter(name)}
    values.update({parameter.name: parameter.value for parameter in parameters})
    for parameter in parameters:
        reason = check(parameter.name, parameter.value, values)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
    return SetParametersResult(successful=True)


def open_log(settings: Any, prefix: str, topics: Sequence[Tuple[str, str, str]]
             ) -> Tuple[Optional[NodeLog], str]:
    """
    Open a node's MCAP log and its writer process; (None, '') when logging is off.

    ``settings`` has log_to_mcap, mcap_path, log_dir, mcap_flush_messages and mcap_flush_s;
    an empty mcap_path names the file <log_dir>/<prefix>_<UTC time>_<pid>.mcap (another
    free name if that exists). A given mcap_path is created exclusively: an existing file
    (an earlier run's log) or one another writer holds is an OSError naming it (and the
    holder's PID), which ``run`` turns into exit code 2. ``topics`` are (resolved name, type
    name, 'sensor_data' or 'reliable') to register up front. The path returned is the file
    actually written.
    """
    if not settings.log_to_mcap:
        return None, ''
    path = Path(settings.mcap_path) if settings.mcap_path else (
        Path(settings.log_dir) / datetime.datetime.now(datetime.timezone.utc).strftime(
            f'{prefix}_%Y-%m-%d_%H-%M-%S_{os.getpid()}.mcap'))
    log = NodeLog(path, topics=topics, flush_every_messages=settings.mcap_flush_messages,
                  flush_every_s=settings.mcap_flush_s,
                  if_exists='fail' if settings.mcap_path else 'rename')
    return log, log.path


def freeze_heap() -> int:
    """
    Collect, then move every object alive now out of the cyclic garbage collector's reach.

    A started node holds about 150 000 long-lived objects (numba, scipy, rclpy, the
    solver); a full collection traverses them all, 130 ms measured, and the collector runs
    one every so often under the allocations of a 1 kHz wrench stream: the ~200 ms
    latency spikes of bench/results/node_rate.md. Frozen (``gc.freeze``), they are skipped;
    what is allocated afterwards is collected as before. Returns the number frozen.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def run(factory: Callable[..., Node], name: str, args: Optional[Sequence[str]] = None,
        help_text: Optional[Callable[[], str]] = None) -> int:
    """
    Run the node ``factory(ros_arguments=...)`` builds until SIGINT or SIGTERM.

    ``ros_arguments`` is the command line (``args``, or sys.argv), from which the node reads
    its ``--params-file`` and ``-p`` values. ``-h``/``--help`` (outside ``--ros-args``)
    prints ``help_text()`` and returns 0 before anything starts. The exit code is
    EXIT_CANNOT_START (2, one line on stderr) when it cannot start (a missing or
    unparsable params file, a bad ``-p``, bad parameters, an unwritable log),
    EXIT_INTERRUPTED (130) after a Ctrl-C during start-up (console.run_command), else 0
    after its ``close()`` (which must stop its threads and finalize its log) and a clean
    shutdown. What the started node holds is frozen (``freeze_heap``) before it spins.
    """
    arguments = list(sys.argv if args is None else args)
    return run_command(lambda: _start(factory, name, arguments, help_text))


def _cannot_start(name: str, error: BaseException) -> int:
    """Print why node ``name`` cannot start, on one line; return EXIT_CANNOT_START."""
    print(f'{name}: {" ".join(str(error).split())}', file=sys.stderr)
    return EXIT_CANNOT_START


def _start(factory: Callable[..., Node], name: str, arguments: List[str],
           help_text: Optional[Callable[[], str]]) -> int:
    """Answer ``--help``, check the parameter sources, then initialize rclpy and spin."""
    if help_text is not None and wants_help(arguments):
        print(help_text())
        return 0
    try:
        # rcl would refuse these with a traceback: the CLI's checks name the file or -p
        check_command_line(arguments)
        rclpy.init(args=arguments, signal_handler_options=SignalHandlerOptions.NO)
    except (ParameterError, rclpy_extension.RCLError) as error:
        return _cannot_start(name, error)
    try:
        return _spin(factory, name, arguments)
    finally:
        rclpy.try_shutdown()


def _spin(factory: Callable[..., Node], name: str, arguments: List[str]) -> int:
    """
    Build the node and spin it until SIGINT or SIGTERM; return the exit code.

    SIGTERM during start-up stops the node once built; SIGINT is a KeyboardInterrupt until
    the node is built (Ctrl-C need not wait for the warm-up), then a stop request.
    """
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        node: Any = factory(ros_arguments=arguments)
    except (ParameterError, InvalidParameterTypeException, InvalidParameterValueException,
            OSError) as error:
        return _cannot_start(name, error)
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    freeze_heap()
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
    return 0
