"""
translator_node: wrenches in, the translator's loaded shape out, every run logged to MCAP.

Subscribes ``wrench`` (geometry_msgs/WrenchStamped, sensor-data QoS) and publishes, reliable
with depth 10, ``end_disk_pose``, ``bending_angles``, ``compliance_eigenvalues``,
``compliance``, ``backbones`` and every wrench's status, ``solve_status``
(cdr_translator.interface.messages defines their content); and every
``diagnostics_period_s`` (1 s) one aggregated DiagnosticArray on ``/diagnostics`` (REP 107:
the wrenches', the estimates' and the MCAP log's status over the period, with counts, rates,
worst residual and the last fault; interface.diagnostics_period). The subscription callback
only counts and logs a wrench and hands its bytes to a solver thread through a mailbox where
``pending_wrenches`` (2) may wait: when one more arrives, the oldest waiting one is skipped
(counted), so two wrenches arriving within one solve are both answered and, when they keep
arriving faster than the solver, the newest wins. The solver thread decodes
(serialization.decoder) and checks the wrench it takes with the offline replay's code (a
cdr_translator.interface.wrench_processing.WrenchProcessor: the same checks, frames,
follower-load solve and counts). The subscription's queue is ``wrench_queue_depth`` deep and
an EventsExecutor (rclpy.experimental, spin.run) spins it. Outputs are built only for topics
someone subscribes to (all of them while logging), one by one with the pose first (it is
published before the others are built), encoded straight to CDR from their dicts
(serialization.encode), published only where someone subscribes, and the same bytes logged:
every received wrench and every output goes to an MCAP file written by a child process
(node_log.NodeLog), so that the writing takes no time from the solve. Measured end-disk
poses (``measured_end_disk_pose``, ``measured_end_disk_pose_cov``) give ``estimated_wrench``
and ``estimated_wrench_covariance``, each pose its status on ``estimate_status``, through
a mailbox and thread of their own (estimate_stream.EstimateStream,
interface.pose_estimation), logged alike. Only cdr_translator.ros imports rclpy or ROS
message classes.
"""

from pathlib import Path
import sys
import threading
import time
from typing import Any, Dict, FrozenSet, Iterable, Iterator, List, Optional, Sequence, Tuple

from geometry_msgs.msg import WrenchStamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy

from . import node_help, serialization
from .estimate_stream import count_line, EstimateStream, SKIPPED_INPUT
from .estimate_stream import TRANSLATOR_ESTIMATE_INPUTS, TRANSLATOR_ESTIMATE_OUTPUTS
from .latest_mailbox import LatestMailbox
from .node_log import log_lost, log_status, LogWatch, node_diagnostic_log, NodeLog, open_log
from .parameter_checks import check_parameters
from .parameters import declare, ros_parameter_sources, SPECS
from .spin import run, SHUTDOWN_JOIN_S
from .topics import OUTPUTS, sensor_qos, SubscriberCounts, type_name
from .._jit import timed_warm_up
from ..interface import messages
from ..interface.diagnostics_period import diagnostics_array
from ..interface.pose_estimation import PoseProcessor
from ..interface.settings import TranslatorSettings
from ..interface.wrench_processing import WrenchProcessor
from ..params.translator_params import DEFAULT_PARAMS_PATH, NODE_NAME


#: Forces (N, along x) of the warm-up solves: a path long enough for the usual warm solve.
WARM_UP_FORCES = (1.0, 1.5, 2.0, 2.5)

#: Wrenches kept beyond ``pending_wrenches`` while a pose estimate has its turn (and until
#: the solver has caught up with them): at 1 kHz, an estimate of up to 50 ms loses none.
ESTIMATE_TURN_ROOM = 50

#: Every topic the node publishes, and its message class.
NODE_OUTPUTS = {**OUTPUTS, **TRANSLATOR_ESTIMATE_OUTPUTS}


class TranslatorNode(Node):
    """The translator as a ROS 2 node; ``close()`` stops it and finalizes the MCAP log."""

    def __init__(self, params_path: Path = DEFAULT_PARAMS_PATH,
                 ros_arguments: Sequence[str] = (), **kwargs: Any) -> None:
        """
        Declare parameters, warm up, then subscribe.

        The values are TranslatorSettings' reading of ``params_path`` (the shipped defaults)
        and of the ``--params-file``/``-p`` of ``ros_arguments`` (the command line), for this
        node's fully qualified name: the rules the CLI and replay apply to the same files.
        """
        super().__init__(NODE_NAME, **kwargs)
        self.add_on_set_parameters_callback(self._check_parameters)
        settings = TranslatorSettings.from_params_files(
            ros_parameter_sources(ros_arguments), namespace=self.get_namespace(),
            defaults_path=params_path, node_name=self.get_name())
        values = {name: declare(self, SPECS[name], value)
                  for name, value in settings.values().items()}
        self._settings = TranslatorSettings.from_values(values)
        self._mailbox = LatestMailbox(self._settings.pending_wrenches, ESTIMATE_TURN_ROOM)
        self.processor = WrenchProcessor(
            self._settings.params, self._settings,
            extra_counts=lambda: {'skipped': self._mailbox.skipped,
                                  **log_lost(getattr(self, '_log', None))})
        self.estimator = PoseProcessor(self._settings.params, self._settings)
        self.add_post_set_parameters_callback(self._apply_parameters)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self._publishers_by_topic = {topic: self.create_publisher(message_class, topic,
                                                                  reliable)
                                     for topic, message_class in NODE_OUTPUTS.items()}
        self._subscribers = SubscriberCounts(self._publishers_by_topic)
        self._encoders = {topic: serialization.encoder(message_class)
                          for topic, message_class in NODE_OUTPUTS.items()}
        # built now: reading the layout takes about 17 ms, which the first wrench would wait
        self._decode_wrench = serialization.decoder(WrenchStamped)
        self._type_names = {topic: type_name(message_class)
                            for topic, message_class in NODE_OUTPUTS.items()}
        # resolved once: the log names every record, and a name costs a call into rcl
        self._resolved = {topic: publisher.topic_name
                          for topic, publisher in self._publishers_by_topic.items()}
        self._diagnostic_log = node_diagnostic_log(self.get_logger(), NODE_NAME)
        timed_warm_up(self._warm_up, self.get_logger().info)
        self._log, self.mcap_path = self._open_log()
        self._log_watch = LogWatch(self._log) if self._log is not None else None
        started_s = time.monotonic()
        self.processor.diagnostics.begin(started_s)
        self.estimator.diagnostics.begin(started_s)
        self._diagnostics_timer = self.create_timer(self._settings.diagnostics_period_s,
                                                    self._publish_diagnostics)
        self._worker = threading.Thread(target=self._work, name='solver', daemon=True)
        self._worker.start()
        self._estimates = EstimateStream(
            self, TRANSLATOR_ESTIMATE_INPUTS, self.estimator,
            lambda built: self._publish_all(self._serialized(built)), self._log,
            self._settings.wrench_queue_depth, self._settings.pending_wrenches,
            turn=self._mailbox.idle_turn)
        self._wrench_topic = self.resolve_topic_name(messages.WRENCH_TOPIC)  # as logged
        self._subscription = self.create_subscription(
            WrenchStamped, messages.WRENCH_TOPIC, self._on_wrench,
            sensor_qos(self._settings.wrench_queue_depth), raw=True)
        self.get_logger().info(
            f'ready: {self._subscription.topic_name}, '
            f'{", ".join(sub.topic_name for sub in self._estimates.subscriptions)} -> '
            f'{", ".join(pub.topic_name for pub in self._publishers_by_topic.values())}; '
            f'MCAP log {self.mcap_path or "off"}')

    # parameters ------------------------------------------------------------------------------
    def _check_parameters(self, parameters: List[Parameter]) -> SetParametersResult:
        """Reject a change with the reason (descriptors have checked read-only and ranges)."""
        return check_parameters(self, SPECS, parameters)

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Take accepted run-time values into a new settings snapshot."""
        self._settings = self._settings.with_values(
            **{parameter.name: parameter.value for parameter in parameters})
        self.processor.apply_settings(self._settings)
        self.estimator.settings = self._settings
        self.estimator.solver.time_limit_s = self._settings.solve_time_limit_s

    # start-up --------------------------------------------------------------------------------
    def _warm_up(self) -> None:
        """
        Solve along a short path and build every output (compiles or loads the kernels).

        Four solves: the fourth is the usual warm solve of a stream (warm_fast_path.py), whose
        kernel would otherwise load while a wrench waits; then a wrench estimate from the
        last pose. Then the solvers forget them.
        """
        solver = self.processor.solver
        for force in WARM_UP_FORCES[:-1]:
            solver.solve([force, 0.0, 0.0])
        result = solver.solve([WARM_UP_FORCES[-1], 0.0, 0.0], compliance=True)
        for topic, _, values in messages.output_messages(
                result, {'sec': 0, 'nanosec': 0}, self._settings.base_frame,
                backbones_params=solver.params):
            self._encoders[topic](values)
        pose = messages.pose_message(result, {'sec': 0, 'nanosec': 0}, '')
        pose['pose'] = {'pose': pose['pose'], 'covariance': [0.0] * 36}
        for topic, _, values in self.estimator.process(pose).outputs:
            self._encoders[topic](values)
        solver.reset()
        self.estimator.solver.reset()
        self.estimator.counts.update(dict.fromkeys(self.estimator.counts, 0))
        self.estimator.diagnostics.discard_notes()

    def _open_log(self) -> Tuple[Optional[NodeLog], str]:
        """Open the MCAP log (unless disabled) and register the wrench and output topics."""
        inputs = {messages.WRENCH_TOPIC: WrenchStamped, **TRANSLATOR_ESTIMATE_INPUTS}
        topics = [(self.resolve_topic_name(topic), type_name(message_class), 'sensor_data')
                  for topic, message_class in inputs.items()]
        topics += [(publisher.topic_name, type_name(NODE_OUTPUTS[topic]), 'reliable')
                   for topic, publisher in self._publishers_by_topic.items()]
        return open_log(self._settings, 'translator', topics)

    def _publish_diagnostics(self) -> None:
        """
        Timer: publish (and log) the period's aggregated DiagnosticArray on /diagnostics.

        Its statuses: the wrenches', the measured poses' and, while logging, the MCAP log's
        (an ERROR while writing fails, WARN once it resumed). Each is logged at its level.
        """
        # stamped before the counts are read: an input whose status went out before the
        # stamp is in them
        stamp = messages.stamp_from_ns(time.time_ns())
        now_s = time.monotonic()
        statuses = [self.processor.diagnostics_status(now_s),
                    self.estimator.diagnostics_status(now_s)]
        if self._log_watch is not None:
            statuses.append(log_status(self._log_watch, NODE_NAME))
        array = diagnostics_array(stamp, statuses)
        built = [(messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE, array)]
        self._publish_all(self._serialized(self._diagnostic_log.logged(built)))

    # input -----------------------------------------------------------------------------------
    def _on_wrench(self, data: bytes) -> None:
        """
        Count and log the wrench as received, and leave its bytes for the solver thread.

        Nothing more happens here: decoding and checking wait until the solver takes the
        wrench, so one that a newer wrench replaces first (latest wins) costs no more. The
        EventsExecutor passes no message info: the log time is taken here, and the MCAP
        publish time equals it (it was the DDS source timestamp before).
        """
        received_ns = time.time_ns()
        self.processor.receive()
        if self._log is not None:
            self._log.submit(self._wrench_topic, messages.WRENCH_TYPE, data, received_ns)
        self._mailbox.put(data)

    # solving ---------------------------------------------------------------------------------
    def _work(self) -> None:
        """Solver thread: check the newest wrench, then solve it, publish and log the outputs."""
        while True:
            data = self._mailbox.take()
            if data is None:
                return
            stamp = {'sec': 0, 'nanosec': 0}
            try:
                try:
                    wrench = self._decode_wrench(data)
                except ValueError as error:  # cdr's readers raise nothing else on bad bytes
                    self._reject(stamp, f'malformed message: {error}')
                    continue
                force, moment, frame_id, stamp = messages.wrench_from_message(wrench)
                self._process(stamp, force, moment, frame_id)
            except Exception as error:  # noqa: B902 - a bug must not silence the node
                self._publish_all(self._serialized(self.processor.internal_error(
                    stamp, f'internal error: {error!r}')))
            finally:
                self._mailbox.done()   # a pose estimate may take its turn

    def _reject(self, stamp: dict, reason: str) -> None:
        """Count a rejected wrench and publish (and so log) its ERROR status."""
        self._publish_all(self._serialized(self.processor.reject(stamp, reason)))

    def _process(self, stamp: dict, force: np.ndarray, moment: np.ndarray,
                 frame_id: str) -> None:
        """
        Check and solve one wrench (WrenchProcessor.answer); publish and log what it gives.

        The compliance and the backbones are computed only while someone subscribes to
        them or they are logged; the outputs are built one by one, the pose published first.
        """
        subscribed = self._subscribers.subscribed()
        want_compliance = self._settings.log_compliance or bool(
            subscribed & {messages.COMPLIANCE_TOPIC, messages.COMPLIANCE_EIGENVALUES_TOPIC})
        want_backbones = (self._settings.log_backbones
                          or messages.BACKBONES_TOPIC in subscribed)
        answer = self.processor.answer(force, moment, frame_id, stamp,
                                       compliance=want_compliance, backbones=want_backbones)
        self._publish_all(self._serialized(answer.outputs, subscribed), subscribed)

    # output ----------------------------------------------------------------------------------
    @property
    def received(self) -> int:
        """Count the wrenches received."""
        return self.processor.counts['received']

    @property
    def rejected(self) -> int:
        """Count the wrenches rejected: malformed, not finite, too large, unknown frame."""
        return self.processor.counts['rejected']

    @property
    def solved(self) -> int:
        """Count the wrenches solved: converged."""
        return self.processor.counts['solved']

    @property
    def failed(self) -> int:
        """Count the wrenches not converged, or left unanswered by an internal error."""
        return self.processor.counts['not_converged']

    def _counts(self) -> Dict[str, Any]:
        """Return the running message counts the aggregated diagnostics report."""
        return self.processor.report_counts()

    def _serialized(self, built: Iterable[Tuple[str, str, dict]],
                    subscribed: Optional[FrozenSet[str]] = None) -> Iterator[Tuple[str, bytes]]:
        """
        CDR-encode the wanted outputs among (topic, type, dict) triples, as (topic, bytes).

        Wanted: logged, or someone subscribes to the topic (serialization.encode writes the bytes
        straight from the dict, no rclpy message in between). ``subscribed``: the topics
        with subscribers, if the caller has just counted them.
        """
        logged = self._log is not None
        if subscribed is None:
            subscribed = self._subscribers.subscribed()
        return ((topic, self._encoders[topic](values)) for topic, _, values in built
                if logged or topic in subscribed)

    def _publish_all(self, topic_data: Iterable[Tuple[str, bytes]],
                     subscribed: Optional[FrozenSet[str]] = None) -> None:
        """Publish each serialized output that someone subscribes to; log all of them."""
        if subscribed is None:
            subscribed = self._subscribers.subscribed()
        records = []
        for topic, data in topic_data:
            if topic in subscribed:
                self._publishers_by_topic[topic].publish(data)
            if self._log is not None:
                records.append((self._resolved[topic], self._type_names[topic], data,
                                time.time_ns(), None))
        if records:
            assert self._log is not None
            self._log.submit_many(records)

    # shutdown --------------------------------------------------------------------------------
    def close(self) -> None:
        """
        Stop taking wrenches, answer those waiting, finalize the MCAP file.

        The wrenches received and waiting are solved (each gets its outputs and
        diagnostic, as at any time) within ``SHUTDOWN_JOIN_S``; any still waiting then
        count as skipped, so the closing counts account for every received wrench.
        """
        self.destroy_subscription(self._subscription)
        self._mailbox.close(drain=True)
        self._worker.join(SHUTDOWN_JOIN_S)
        self._mailbox.discard()
        counts = self._counts()
        self.get_logger().info(count_line('wrenches', counts, 'solved', SKIPPED_INPUT))
        self.get_logger().info(count_line('measured poses', self._estimates.close(self)))
        self.destroy_timer(self._diagnostics_timer)
        self._publish_diagnostics()  # the last period: the closing counts, in the log too
        if self._log is not None:
            log = self._log
            log.close()
            complete, line = log.closing_line()
            text = (f'{line}; handing a record to the log process took '
                    f'{1e6 * log.enqueue_wait_s / max(log.submitted, 1):.1f} us on average, '
                    f'{1e3 * log.max_enqueue_wait_s:.3f} ms at most; writing '
                    f'{1e6 * log.write_time_s / max(log.written, 1):.1f} us per record; '
                    f'{log.reordered} log times held back to keep each channel in order')
            if complete:
                self.get_logger().info(text)
            else:
                self.get_logger().error(text)


def help_text() -> str:
    """Return translator_node's ``--help``: its parameters, topics and exit codes."""
    return node_help.help_text(
        NODE_NAME, __doc__.strip().splitlines()[0], SPECS,
        TranslatorSettings.from_params_file().values(),
        {messages.WRENCH_TOPIC: type_name(WrenchStamped),
         **{topic: type_name(message_class)
            for topic, message_class in TRANSLATOR_ESTIMATE_INPUTS.items()}},
        {topic: type_name(message_class) for topic, message_class in NODE_OUTPUTS.items()})


def main(args: Optional[Sequence[str]] = None) -> int:
    """Run translator_node until SIGINT or SIGTERM; return the process exit code."""
    return run(TranslatorNode, NODE_NAME, args, help_text)


if __name__ == '__main__':
    sys.exit(main())
