"""
Drive a translator_node from outside: start it as a process, send wrenches, collect outputs.

Used by ``make demo`` (scripts/demo.py), the node tests and the latency measurement. Every
wait is bounded; ``NodeProcess`` kills what it started when left.
"""

import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import rclpy
from rclpy.context import Context
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy

from .estimate_stream import TRANSLATOR_ESTIMATE_INPUTS, TRANSLATOR_ESTIMATE_OUTPUTS
from .topics import fill_message, OUTPUTS
from ..interface import messages, pose_estimation

#: What a client listens to unless told otherwise.
DEFAULT_TOPICS = (messages.END_DISK_POSE_TOPIC, messages.BENDING_ANGLES_TOPIC,
                  messages.SOLVE_STATUS_TOPIC, messages.DIAGNOSTICS_TOPIC)


#: The node run as a module of this interpreter, and as the installed console script.
MODULE_COMMAND = (sys.executable, '-m', 'cdr_translator.ros.translator_node')
#: Domains an isolated run picks from (both ends included): the range ROS 2 recommends on
#: Linux is 0-101 (above it the participants' ports run into the ephemeral port range), and
#: 0 is everyone's default domain.
ISOLATED_DOMAINS = (1, 101)
SCRIPT_COMMAND = (str(Path(sys.executable).parent / 'translator_node'),)


def isolated_ros_env(domain_id: Optional[int] = None) -> Dict[str, str]:
    """
    Return os.environ with its own ROS_DOMAIN_ID and localhost discovery.

    The domain is ``domain_id`` or random in ISOLATED_DOMAINS. Set it in os.environ before
    ``rclpy.init`` and pass it to child processes so that runs on one machine never see
    each other.
    """
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(random.randint(*ISOLATED_DOMAINS) if domain_id is None
                               else domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    return env


class NodeProcess:
    """translator_node as a child process (``python -m cdr_translator.ros.translator_node``)."""

    def __init__(self, ros_args: Sequence[str], env: Mapping[str, str], output: Path,
                 command: Sequence[str] = MODULE_COMMAND, cwd: Optional[Path] = None) -> None:
        """
        Start ``command --ros-args ros_args`` in ``cwd``; stdout and stderr go to ``output``.

        ``python -m`` imports from its working directory first: to run another checkout's
        node, ``cwd`` must be that checkout (else this one's code runs).
        """
        self.output = Path(output)
        self._file = open(self.output, 'wb')
        self.process = subprocess.Popen([*command, '--ros-args', *ros_args], env=dict(env),
                                        stdout=self._file, stderr=subprocess.STDOUT, cwd=cwd)

    def text(self) -> str:
        """Return what the node has printed so far."""
        return self.output.read_text(errors='replace')

    def stop(self, number: int = signal.SIGINT, timeout_s: float = 20.0) -> Optional[int]:
        """Send a signal and wait for the exit code (None, after a kill, if it did not exit)."""
        if self.process.poll() is None:
            self.process.send_signal(number)
        try:
            return self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.kill()
            return None

    def kill(self) -> None:
        """Kill the process if it still runs and close its output file."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(10.0)
        self._file.close()

    def __enter__(self) -> 'NodeProcess':
        """Return self."""
        return self

    def __exit__(self, *exc_info: Any) -> None:
        """Kill the node if still running."""
        self.kill()


class TranslatorClient:
    """
    A second node in its own rclpy context: sends inputs, records the node's outputs.

    It publishes wrenches and measured poses; ``received[topic]`` lists (message, receive
    time in ns) in arrival order; an executor thread spins the node until ``close()``.
    """

    def __init__(self, topics: Sequence[str] = DEFAULT_TOPICS, name: str = 'translator_client',
                 depth: int = 1000) -> None:
        """
        Subscribe ``topics`` (reliable, ``depth`` deep) and advertise ``wrench``.

        ``solve_status`` is always subscribed too: ``handshake`` waits for it.
        """
        if messages.SOLVE_STATUS_TOPIC not in topics:
            topics = (*topics, messages.SOLVE_STATUS_TOPIC)
        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = Node(name, context=self.context)
        self.publisher = self.node.create_publisher(WrenchStamped, messages.WRENCH_TOPIC,
                                                    qos_profile_sensor_data)
        self.pose_publishers = {
            topic: self.node.create_publisher(message_class, topic, qos_profile_sensor_data)
            for topic, message_class in TRANSLATOR_ESTIMATE_INPUTS.items()}
        outputs = {**OUTPUTS, **TRANSLATOR_ESTIMATE_OUTPUTS}
        self.received: Dict[str, List[Tuple[Any, int]]] = {topic: [] for topic in topics}
        self.handshake_stamps: List[dict] = []
        self._condition = threading.Condition()
        reliable = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
        self.subscriptions = [
            self.node.create_subscription(outputs[topic], topic, self._recorder(topic),
                                          reliable)
            for topic in topics]
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name='client_spin', daemon=True)
        self._thread.start()

    def _recorder(self, topic: str) -> Callable[[Any], None]:
        def record(message: Any) -> None:
            with self._condition:
                self.received[topic].append((message, time.time_ns()))
                self._condition.notify_all()
        return record

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Wait until ``predicate()`` holds (re-checked on every message); False on timeout."""
        deadline = time.monotonic() + timeout_s
        with self._condition:
            while not predicate():
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return False
                self._condition.wait(min(remaining, 0.05))
        return True

    def wait_connected(self, timeout_s: float) -> bool:
        """Wait until the node subscribes to ``wrench`` and publishes every listened topic."""
        return self.wait_for(lambda: self.publisher.get_subscription_count() > 0 and all(
            self.node.count_publishers(subscription.topic_name) > 0
            for subscription in self.subscriptions), timeout_s)

    def handshake(self, timeout_s: float, period_s: float = 0.25) -> bool:
        """
        Send zero wrenches until one is answered on ``solve_status``; False on timeout.

        Matching is not symmetric: the publisher may see the node's subscription before the
        node's reader accepts its samples, so the first best-effort wrenches can be lost.
        A slow node may also answer late, after a second one was sent: ``handshake_stamps``
        lists every wrench sent, so that callers can account for the node's counts.
        """
        deadline = time.monotonic() + timeout_s
        if not self.wait_connected(timeout_s):
            return False
        sent = self.handshake_stamps
        while time.monotonic() < deadline:
            sent.append(self.publish((0.0, 0.0, 0.0)))
            if self.wait_for(lambda: any(self.messages_stamped(messages.SOLVE_STATUS_TOPIC,
                                                               stamp)
                                         for stamp in sent), period_s):
                return True
        return False

    def publish(self, force: Sequence[float], moment: Sequence[float] = (0.0, 0.0, 0.0),
                frame_id: str = '', stamp_ns: Optional[int] = None) -> dict:
        """Publish one wrench stamped now (or ``stamp_ns``); return its stamp dict."""
        stamp = messages.stamp_from_ns(time.time_ns() if stamp_ns is None else stamp_ns)
        self.publisher.publish(fill_message(WrenchStamped(), messages.wrench_message(
            force, moment, frame_id, stamp)))
        return stamp

    def publish_pose(self, position: Sequence[float], quaternion_xyzw: Sequence[float],
                     frame_id: str = '', covariance: Optional[Sequence[float]] = None,
                     stamp_ns: Optional[int] = None) -> dict:
        """
        Publish a measured end-disk pose stamped now (or ``stamp_ns``); return its stamp.

        With ``covariance`` (36 values, row-major) on ``measured_end_disk_pose_cov``, else on
        ``measured_end_disk_pose``.
        """
        stamp = messages.stamp_from_ns(time.time_ns() if stamp_ns is None else stamp_ns)
        pose: Dict[str, Any] = {'position': dict(zip('xyz', map(float, position))),
                                'orientation': dict(zip('xyzw', map(float, quaternion_xyzw)))}
        topic = pose_estimation.MEASURED_POSE_TOPIC
        if covariance is not None:
            topic = pose_estimation.MEASURED_POSE_COV_TOPIC
            pose = {'pose': pose, 'covariance': [float(value) for value in covariance]}
        publisher = self.pose_publishers[topic]
        publisher.publish(fill_message(TRANSLATOR_ESTIMATE_INPUTS[topic](), {
            'header': messages.header(stamp, frame_id), 'pose': pose}))
        return stamp

    def messages_stamped(self, topic: str, stamp: Mapping[str, int]) -> List[Any]:
        """Return the received messages of ``topic`` whose header stamp is ``stamp``."""
        with self._condition:
            return [message for message, _ in self.received[topic]
                    if message.header.stamp.sec == stamp['sec']
                    and message.header.stamp.nanosec == stamp['nanosec']]

    def diagnostics_after(self, stamp: Mapping[str, int], timeout_s: float,
                          topic: str = messages.SOLVE_STATUS_TOPIC) -> Optional[Any]:
        """
        Wait for the first /diagnostics array stamped after the status of ``stamp`` arrived.

        Its counts include that input (the node counts an input before it publishes its
        status on ``topic``). Both /diagnostics and ``topic`` must be subscribed. None on
        timeout.
        """
        deadline = time.monotonic() + timeout_s
        wanted = messages.stamp_to_ns(stamp)
        if not self.wait_for(lambda: bool(self.messages_stamped(topic, stamp)), timeout_s):
            return None
        with self._condition:
            arrived = min(received for message, received in self.received[topic]
                          if messages.stamp_to_ns(message.header.stamp) == wanted)

        def later() -> List[Any]:
            return [message for message, _ in self.received[messages.DIAGNOSTICS_TOPIC]
                    if messages.stamp_to_ns(message.header.stamp) > arrived]
        if not self.wait_for(lambda: bool(later()), max(deadline - time.monotonic(), 0.0)):
            return None
        with self._condition:
            return later()[0]

    def close(self) -> None:
        """Stop spinning and shut the context down."""
        self._stop.set()
        self._thread.join(5.0)
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def diagnostic_values(message: DiagnosticArray) -> Dict[str, str]:
    """Return the key/values of the first status of a DiagnosticArray."""
    return {pair.key: pair.value for pair in message.status[0].values}
