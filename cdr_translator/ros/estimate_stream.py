"""
A node's measured-pose inputs: subscriptions, a mailbox and a thread of their own.

Both nodes estimate a load from a measured pose (translator_node the end-disk wrench,
cdr_node the payload) beside their forward solves: the poses get their own latest-wins
mailbox and worker thread, so that a stream of poses neither pushes wrenches out of the
solver's mailbox nor waits behind them, and each estimate warm-starts from the one before
it. As for wrenches, the callback only counts and logs the bytes as received; the worker
decodes them (serialization.decoder), hands the message to the processor (the ROS-free
check, estimate and messages of cdr_translator.interface) and publishes what it returns.
Nothing is lost silently: a malformed message, a rejected pose, a failed estimate and an
internal error each give an ERROR status (the processor's ``status_topic``) and count in the
aggregated /diagnostics, and the poses a newer one pushed out of the
mailbox are counted as ``skipped``.
"""

from contextlib import contextmanager
import threading
import time
from typing import (Callable, ContextManager, Dict, Iterator, List, Mapping, Optional,
                    Tuple)

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, WrenchStamped
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from . import serialization
from .latest_mailbox import LatestMailbox
from .node_log import NodeLog
from .spin import SHUTDOWN_JOIN_S
from .topics import sensor_qos, type_name
from ..interface import pose_estimation
from ..interface.pose_estimation import MeasuredPoseProcessor

__all__ = ['count_line', 'SKIPPED_INPUT', 'EstimateStream', 'TRANSLATOR_ESTIMATE_INPUTS',
           'TRANSLATOR_ESTIMATE_OUTPUTS']

Built = List[Tuple[str, str, dict]]

#: translator_node's measured-pose inputs and estimate outputs, and their message classes.
TRANSLATOR_ESTIMATE_INPUTS: Dict[str, type] = {
    pose_estimation.MEASURED_POSE_TOPIC: PoseStamped,
    pose_estimation.MEASURED_POSE_COV_TOPIC: PoseWithCovarianceStamped}
TRANSLATOR_ESTIMATE_OUTPUTS: Dict[str, type] = {
    pose_estimation.ESTIMATED_WRENCH_TOPIC: WrenchStamped,
    pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC: Float64MultiArray,
    pose_estimation.ESTIMATE_STATUS_TOPIC: DiagnosticArray}


class EstimateStream:
    """The subscriptions of ``inputs`` (topic -> message class) on ``node`` and their worker."""

    def __init__(self, node: Node, inputs: Mapping[str, type],
                 processor: MeasuredPoseProcessor,
                 publish: Callable[[Built], None], log: Optional[NodeLog], queue_depth: int,
                 capacity: int = 1,
                 turn: Optional[Callable[[], ContextManager[None]]] = None) -> None:
        """
        Subscribe (sensor-data QoS, ``queue_depth`` deep) and start the worker.

        ``publish`` publishes (and logs) the built messages; ``log`` (None: off) receives
        every input as received; ``capacity`` poses may wait for the worker. ``turn`` (the
        node's own inputs' LatestMailbox.idle_turn; None: estimate at once) gives each
        estimate its turn between the node's own inputs, which come first: the two never
        share the interpreter, and the poses that arrive meanwhile wait, the newest
        winning, and are counted as skipped when pushed out.
        """
        self.processor = processor
        self._turn = turn if turn is not None else _at_once
        self._publish = publish
        self._log = log
        self._decoders = {topic: serialization.decoder(message_class)
                          for topic, message_class in inputs.items()}
        self._type_names = {topic: type_name(message_class)
                            for topic, message_class in inputs.items()}
        self._mailbox = LatestMailbox(capacity)
        self._worker = threading.Thread(target=self._work, name='estimator', daemon=True)
        self._worker.start()
        sensor = sensor_qos(queue_depth)
        self.subscriptions = [
            node.create_subscription(message_class, topic, self._receiver(topic), sensor,
                                     raw=True)
            for topic, message_class in inputs.items()]
        self._type_names = {topic: type_name(message_class)
                            for topic, message_class in inputs.items()}

    def _receiver(self, topic: str) -> Callable[[bytes], None]:
        """Return the raw callback of ``topic``."""
        index = list(self._decoders).index(topic)

        def receive(data: bytes) -> None:
            """Count and log the pose as received; leave its bytes for the worker."""
            self.processor.counts['received'] += 1
            if self._log is not None:
                self._log.submit(self.subscriptions[index].topic_name, self._type_names[topic],
                                 data, time.time_ns())
            self._mailbox.put((topic, data))
        return receive

    def _work(self) -> None:
        """Worker: at each turn, estimate the newest pose (older ones count as skipped)."""
        while self._mailbox.wait_for_item():
            with self._turn():
                item = self._mailbox.take_newest()
                if item is not None:
                    self._estimate(*item)

    def _estimate(self, topic: str, data: bytes) -> None:
        """Decode and process one pose, publish what it gives."""
        counts = self.processor.counts
        counts['skipped'] = self._mailbox.skipped
        try:
            try:
                message = self._decoders[topic](data)
            except ValueError as error:  # cdr's readers raise nothing else on bad bytes
                self._publish(self.processor.reject({'sec': 0, 'nanosec': 0},
                                                    f'malformed message: {error}').outputs)
                return
            self._publish(self.processor.process(message, count_received=False).outputs)
        except Exception as error:  # noqa: B902 - a bug must not silence the node
            self._publish(self.processor.internal_error({'sec': 0, 'nanosec': 0},
                                                        f'internal error: {error!r}'))

    def close(self, node: Node) -> Dict[str, int]:
        """
        Stop taking poses, estimate those waiting (within ``SHUTDOWN_JOIN_S``); return counts.

        Poses still waiting then count as skipped, so the counts account for every pose.
        """
        for subscription in self.subscriptions:
            node.destroy_subscription(subscription)
        self._mailbox.close(drain=True)
        self._worker.join(SHUTDOWN_JOIN_S)
        self._mailbox.discard()
        self.processor.counts['skipped'] = self._mailbox.skipped
        return dict(self.processor.counts)


@contextmanager
def _at_once() -> Iterator[None]:
    """Give the turn at once: there is no other input to give way to."""
    yield


def count_line(what: str, counts: Mapping[str, int], solved: str = 'estimated',
               skipped: str = '') -> str:
    """
    Return the closing log line of an input stream's counts.

    ``solved`` names what became of the inputs answered (those of them flagged, not to be
    acted on, in brackets when the counts have ``flagged``); ``skipped`` explains the
    skipped.
    """
    flagged = f' ({counts["flagged"]} flagged)' if 'flagged' in counts else ''
    return (f'{what}: {counts["received"]} received, {counts["solved"]} {solved}{flagged}, '
            f'{counts["rejected"]} rejected, {counts["not_converged"]} not converged, '
            f'{counts["skipped"]} skipped{skipped}')


#: Why a node's own input (a wrench, sliders, a target) is skipped.
SKIPPED_INPUT = ' (a newer one arrived, or still waiting at shutdown)'
