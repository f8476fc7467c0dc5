"""
cdr_node: slider positions and a platform payload in, the Continuum Delta Robot's pose out.

Subscribes ``sliders`` (sensor_msgs/JointState: positions in m, named slider_1..3 or
unnamed in leg order) and ``platform_wrench`` (geometry_msgs/WrenchStamped: the payload on
the platform origin, in the world frame), both with sensor-data QoS, and publishes,
reliable with depth 10, ``platform_pose``, ``leg_bending_angles``, ``leg_tip_wrenches``
and ``/diagnostics`` (robot_messages defines their content). Every accepted input triggers a
solve with the latest value of the other (sliders at home and no payload until the first
message of each). Inverse statics: ``target_position`` (geometry_msgs/PointStamped, world
frame, sensor-data QoS) is solved under the latest payload and answered on
``slider_command`` (sensor_msgs/JointState) and ``predicted_platform_pose``, warm-started
along the path of targets; an unreachable target is an ERROR diagnostic (no command).
Force sensing: ``measured_platform_pose`` (geometry_msgs/PoseStamped) or
``measured_platform_pose_cov`` (PoseWithCovarianceStamped), world frame, gives
``estimated_payload`` (WrenchStamped) and ``estimated_payload_covariance``
(Float64MultiArray) at the sliders last received, through a mailbox, thread and robot of
their own (estimate_stream.EstimateStream, interface.payload_estimation).
The translator node's parts do the rest: the latest-wins mailbox and
solver thread pattern (latest_mailbox.py), message filling (topics.py), MCAP log process
(node_log.py), parameter checks (parameter_checks.py) and ``run`` loop (spin.py); the
parameters are CdrSettings' (cdr_translator.interface.settings).
"""

import sys
import threading
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
from geometry_msgs.msg import WrenchStamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from . import node_help, serialization
from .estimate_stream import count_line, EstimateStream, SKIPPED_INPUT
from .latest_mailbox import LatestMailbox
from .node_log import LOG_CHECK_PERIOD_S, log_health, log_lost, LogWatch, node_diagnostic_log
from .node_log import open_log
from .parameter_checks import check_parameters
from .parameters import descriptor, ros_parameter_sources
from .spin import run, SHUTDOWN_JOIN_S
from .topics import fill_message, OUTPUTS, sensor_qos, type_name
from .._jit import timed_warm_up
from ..interface import messages, payload_estimation, robot_messages
from ..interface.payload_estimation import PayloadProcessor
from ..interface.settings import CDR_SPECS, CdrSettings
from ..interface.wrench_processing import check_magnitude
from ..params.translator_params import DEFAULT_PARAMS_PATH
from ..robot.delta import DeltaRobot
from ..robot.inverse import check_target
from ..robot.params import CDR_NODE_NAME, check_sliders
from ..solve.solver import check_wrench

#: Output topics and their message classes (the translator node's classes, by type).
CDR_OUTPUTS = {
    robot_messages.PLATFORM_POSE_TOPIC: OUTPUTS[messages.END_DISK_POSE_TOPIC],
    robot_messages.LEG_ANGLES_TOPIC: OUTPUTS[messages.BENDING_ANGLES_TOPIC],
    robot_messages.LEG_WRENCHES_TOPIC: OUTPUTS[messages.COMPLIANCE_TOPIC],
    robot_messages.DIAGNOSTICS_TOPIC: OUTPUTS[messages.DIAGNOSTICS_TOPIC],
    robot_messages.SLIDER_COMMAND_TOPIC: OUTPUTS[messages.BENDING_ANGLES_TOPIC],
    robot_messages.PREDICTED_POSE_TOPIC: OUTPUTS[messages.END_DISK_POSE_TOPIC],
    payload_estimation.ESTIMATED_PAYLOAD_TOPIC: WrenchStamped,
    payload_estimation.ESTIMATED_PAYLOAD_COVARIANCE_TOPIC: OUTPUTS[messages.COMPLIANCE_TOPIC],
}

#: The measured-pose inputs of the payload estimate, and their message classes.
CDR_ESTIMATE_INPUTS = {payload_estimation.MEASURED_PLATFORM_POSE_TOPIC: PoseStamped,
                       payload_estimation.MEASURED_PLATFORM_POSE_COV_TOPIC:
                       PoseWithCovarianceStamped}

#: Input topics and their message classes.
CDR_INPUTS = {robot_messages.PLATFORM_WRENCH_TOPIC: WrenchStamped,
              robot_messages.SLIDERS_TOPIC: JointState,
              robot_messages.TARGET_TOPIC: PointStamped, **CDR_ESTIMATE_INPUTS}

#: Mailbox item kinds: a forward solve (sliders) or an inverse one (target position).
FORWARD, INVERSE = 'forward', 'inverse'


class CdrNode(Node):
    """The CDR forward statics as a ROS 2 node; ``close()`` stops it and finalizes its log."""

    def __init__(self, params_path: str = str(DEFAULT_PARAMS_PATH),
                 ros_arguments: Sequence[str] = (), **kwargs: Any) -> None:
        """
        Declare parameters, warm up, then subscribe.

        The values are CdrSettings' reading of ``params_path`` (the shipped defaults) and of
        the ``--params-file``/``-p`` of ``ros_arguments``, for this node's fully qualified
        name: the rules the CLI applies to the same files.
        """
        super().__init__(CDR_NODE_NAME, **kwargs)
        self.add_on_set_parameters_callback(self._check_parameters)
        settings = CdrSettings.from_params_files(
            ros_parameter_sources(ros_arguments), namespace=self.get_namespace(),
            defaults_path=params_path, node_name=self.get_name())
        values = {name: self.declare_parameter(name, value,
                                               descriptor(CDR_SPECS[name], value)).value
                  for name, value in settings.values().items()}
        self._settings = CdrSettings.from_values(values)
        self.robot = DeltaRobot(self._settings.params, self._settings.geometry,
                                time_limit_s=self._settings.solve_time_limit_s)
        self.estimator = PayloadProcessor(self._settings, self._latest_sliders)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.received = self.rejected = self.solved = self.failed = 0
        self._sliders = np.zeros(3)
        self._payload = (np.zeros(3), np.zeros(3))
        self._inputs_lock = threading.Lock()
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self._publishers_by_topic = {topic: self.create_publisher(message_class, topic,
                                                                  reliable)
                                     for topic, message_class in CDR_OUTPUTS.items()}
        self._mailbox = LatestMailbox()
        self._diagnostic_log = node_diagnostic_log(self.get_logger(), CDR_NODE_NAME)
        timed_warm_up(self._warm_up, self.get_logger().info)
        topics = [(self.resolve_topic_name(topic), type_name(message_class), 'sensor_data')
                  for topic, message_class in CDR_INPUTS.items()]
        topics += [(publisher.topic_name, type_name(CDR_OUTPUTS[topic]), 'reliable')
                   for topic, publisher in self._publishers_by_topic.items()]
        self._log, self.mcap_path = open_log(self._settings, 'cdr', topics)
        self._log_watch = LogWatch(self._log) if self._log is not None else None
        self._log_timer = (self.create_timer(LOG_CHECK_PERIOD_S, self._check_log)
                           if self._log is not None else None)
        self._worker = threading.Thread(target=self._work, name='solver', daemon=True)
        self._worker.start()
        # the readers of the input types, built now (reading a layout takes about 17 ms)
        self._decoders = {message_class: serialization.decoder(message_class)
                          for message_class in CDR_INPUTS.values()}
        sensor = sensor_qos(self._settings.input_queue_depth)
        self._subscriptions = [
            self.create_subscription(WrenchStamped, robot_messages.PLATFORM_WRENCH_TOPIC,
                                     self._on_wrench, sensor, raw=True),
            self.create_subscription(JointState, robot_messages.SLIDERS_TOPIC, self._on_sliders,
                                     sensor, raw=True),
            self.create_subscription(PointStamped, robot_messages.TARGET_TOPIC, self._on_target,
                                     sensor, raw=True)]
        self._estimates = EstimateStream(self, CDR_ESTIMATE_INPUTS, self.estimator,
                                         self._publish, self._log,
                                         self._settings.input_queue_depth,
                                         turn=self._mailbox.idle_turn)
        self.get_logger().info(
            f'ready: {", ".join(s.topic_name for s in self._subscriptions)}, '
            f'{", ".join(s.topic_name for s in self._estimates.subscriptions)} -> '
            f'{", ".join(p.topic_name for p in self._publishers_by_topic.values())}; '
            f'MCAP log {self.mcap_path or "off"}')

    # parameters ------------------------------------------------------------------------------
    def _check_parameters(self, parameters: List[Parameter]) -> SetParametersResult:
        """Reject a change with the reason (descriptors have checked read-only and ranges)."""
        return check_parameters(self, CDR_SPECS, parameters)

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Take accepted run-time values into a new settings snapshot."""
        self._settings = self._settings.with_values(
            **{parameter.name: parameter.value for parameter in parameters})
        self.robot.time_limit_s = self._settings.solve_time_limit_s
        self.estimator.settings = self._settings
        self.estimator.robot.time_limit_s = self._settings.solve_time_limit_s

    def _check_log(self) -> None:
        """Timer: publish an ERROR diagnostic while the MCAP log fails (WARN once resumed)."""
        self._publish(log_health(self._log_watch, CDR_NODE_NAME, self._counts()))

    # input -----------------------------------------------------------------------------------
    def _warm_up(self) -> None:
        """Solve once at home (loads the kernels, the compliance's too), estimate its payload."""
        result = self.robot.solve(self._sliders, (0.0, 0.0, -1.0), compliance=True)
        self.estimator.process(robot_messages.platform_pose_message(
            result, {'sec': 0, 'nanosec': 0}, ''))
        self.robot.reset()
        self.estimator.robot.reset()
        self.estimator.counts.update(dict.fromkeys(self.estimator.counts, 0))

    def _latest_sliders(self) -> np.ndarray:
        """Return the slider positions last received (the payload estimate's)."""
        with self._inputs_lock:
            return self._sliders

    def _log_input(self, index: int, data: bytes) -> None:
        """Count and log an input as received (the EventsExecutor gives no message info)."""
        self.received += 1
        if self._log is not None:
            subscription = self._subscriptions[index]
            self._log.submit(subscription.topic_name, type_name(subscription.msg_type), data,
                             time.time_ns())

    def _on_wrench(self, data: bytes) -> None:
        """Log the payload as received; reject it with a diagnostic or solve with it."""
        self._log_input(0, data)
        message = self._decoded(data, robot_messages.PLATFORM_WRENCH_TOPIC, WrenchStamped,
                                'payload')
        if message is None:
            return
        force, moment, frame_id, stamp = messages.wrench_from_message(message)
        settings = self._settings
        try:
            if frame_id not in ('', settings.world_frame):
                raise ValueError(f'payload frame_id {frame_id!r} is not the world frame '
                                 f'{settings.world_frame!r} (no tf here)')
            check_wrench(force, moment)
            check_magnitude(force, moment, settings.max_force, settings.max_moment)
        except ValueError as error:
            self._reject(stamp, robot_messages.PLATFORM_WRENCH_TOPIC, 'payload', error)
            return
        with self._inputs_lock:
            self._payload = (force, moment)
            self._mailbox.put((FORWARD, stamp, self._sliders, force, moment))

    def _on_sliders(self, data: bytes) -> None:
        """Log the slider positions as received; reject them with a diagnostic or solve."""
        self._log_input(1, data)
        message = self._decoded(data, robot_messages.SLIDERS_TOPIC, JointState, 'sliders')
        if message is None:
            return
        stamp = dict(message['header']['stamp'])
        try:
            sliders = check_sliders(
                robot_messages.sliders_from_joint_state(message['name'], message['position']),
                self.robot.geometry.slider_stroke)
        except ValueError as error:
            self._reject(stamp, robot_messages.SLIDERS_TOPIC, 'sliders', error)
            return
        with self._inputs_lock:
            self._sliders = sliders
            self._mailbox.put((FORWARD, stamp, sliders, *self._payload))

    def _on_target(self, data: bytes) -> None:
        """Log the target as received; reject it with a diagnostic or solve the inverse."""
        self._log_input(2, data)
        message = self._decoded(data, robot_messages.TARGET_TOPIC, PointStamped, 'target')
        if message is None:
            return
        target, frame_id, stamp = robot_messages.target_from_point(message)
        world = self._settings.world_frame
        try:
            if frame_id not in ('', world):
                raise ValueError(f'target frame_id {frame_id!r} is not the world frame '
                                 f'{world!r} (no tf here)')
            check_target(target)
        except ValueError as error:
            self._reject(stamp, robot_messages.TARGET_TOPIC, 'target', error)
            return
        with self._inputs_lock:
            self._mailbox.put((INVERSE, stamp, target, *self._payload))

    def _decoded(self, data: bytes, topic: str, message_class: type, what: str
                 ) -> Optional[dict]:
        """
        Return the message in ``data`` as a dict; None, rejected with a diagnostic, if malformed.

        serialization.decoder reads it in microseconds, where rclpy's deserialize_message took
        0.15-0.3 ms in this (executor) thread.
        """
        try:
            return self._decoders[message_class](data)
        except ValueError as error:  # cdr's readers raise nothing else on bad bytes
            self._reject({'sec': 0, 'nanosec': 0}, topic, what,
                         ValueError(f'malformed message: {error}'))
            return None

    def _reject(self, stamp: dict, topic: str, what: str, error: Exception) -> None:
        """Count an input of ``topic`` not used; an ERROR of the stage it was for says why."""
        self.rejected += 1
        self._publish(robot_messages.rejection_messages(
            stamp, f'{what} rejected: {error}', self._counts(),
            name=robot_messages.INPUT_DIAGNOSTIC_NAMES[topic]))

    # solving ---------------------------------------------------------------------------------
    def _work(self) -> None:
        """Solver thread: solve the newest inputs, publish and log what it gives."""
        while True:
            item = self._mailbox.take()
            if item is None:
                return
            try:
                self._answer(*item)
            finally:
                self._mailbox.done()   # a payload estimate may take its turn

    def _answer(self, kind: str, stamp: dict, inputs: np.ndarray, force: np.ndarray,
                moment: np.ndarray) -> None:
        """Solve one input (forward sliders or an inverse target); publish what it gives."""
        try:
            if kind == INVERSE:
                self._answer_target(stamp, inputs, force, moment)
                return
            result = self.robot.solve(inputs, force, moment)
        except Exception as error:  # noqa: B902 - a bug must not silence the node
            self.failed += 1
            self._publish(robot_messages.rejection_messages(
                stamp, f'internal error: {error!r}', self._counts(),
                name=(robot_messages.INVERSE_DIAGNOSTIC_NAME if kind == INVERSE
                      else robot_messages.DIAGNOSTIC_NAME)))
            return
        if result.converged:
            self.solved += 1
        else:
            self.failed += 1
        self._publish(robot_messages.output_messages(
            result, stamp, self._settings.world_frame, self._counts()))

    def _answer_target(self, stamp: dict, target: np.ndarray, force: np.ndarray,
                       moment: np.ndarray) -> None:
        """Solve the inverse statics for ``target`` and publish the command or the reason."""
        result = self.robot.inverse(target, force, moment)
        if result.converged and result.reachable:
            self.solved += 1
        else:
            self.failed += 1
        self._publish(robot_messages.inverse_output_messages(
            result, stamp, self._settings.world_frame, self._counts()))

    # output ----------------------------------------------------------------------------------
    def _counts(self) -> Dict[str, int]:
        """Return the running message counts reported with every diagnostic."""
        return {'received': self.received, 'rejected': self.rejected, 'solved': self.solved,
                'not_converged': self.failed, 'skipped': self._mailbox.skipped,
                **log_lost(getattr(self, '_log', None))}

    def _publish(self, built: Sequence[Tuple[str, str, dict]]) -> None:
        """
        Fill, publish and queue for the MCAP log the (topic, type, dict) of robot_messages.

        Every diagnostic is logged here at its level (DiagnosticLog), and nowhere else.
        """
        for topic, name, values in self._diagnostic_log.logged(built):
            message = fill_message(CDR_OUTPUTS[topic](), values)
            publisher = self._publishers_by_topic[topic]
            publisher.publish(message)
            if self._log is not None:
                self._log.submit(publisher.topic_name, name, message, time.time_ns())

    # shutdown --------------------------------------------------------------------------------
    def close(self) -> None:
        """
        Stop taking inputs, answer those waiting, finalize the MCAP file.

        As translator_node does: the requests waiting are solved within ``SHUTDOWN_JOIN_S``,
        any still waiting then count as skipped, so the closing counts account for every
        received input.
        """
        for subscription in self._subscriptions:
            self.destroy_subscription(subscription)
        self._mailbox.close(drain=True)
        self._worker.join(SHUTDOWN_JOIN_S)
        self._mailbox.discard()
        counts = self._counts()
        self.get_logger().info(count_line('inputs', counts, 'solved', SKIPPED_INPUT))
        self.get_logger().info(count_line('measured platform poses', self._estimates.close(self)))
        if self._log_timer is not None:
            self.destroy_timer(self._log_timer)
        if self._log is not None:
            self._log.close()
            complete, line = self._log.closing_line()
            if complete:
                self.get_logger().info(line)
            else:
                self.get_logger().error(line)


def help_text() -> str:
    """Return cdr_node's ``--help``: its parameters, topics and exit codes."""
    return node_help.help_text(
        CDR_NODE_NAME, __doc__.strip().splitlines()[0], CDR_SPECS,
        CdrSettings.from_params_file().values(),
        {topic: type_name(message_class) for topic, message_class in CDR_INPUTS.items()},
        {topic: type_name(message_class) for topic, message_class in CDR_OUTPUTS.items()})


def main(args: Optional[Sequence[str]] = None) -> int:
    """Run cdr_node until SIGINT or SIGTERM; return the process exit code."""
    return run(CdrNode, CDR_NODE_NAME, args, help_text)


if __name__ == '__main__':
    sys.exit(main())
