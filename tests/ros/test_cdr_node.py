"""cdr_node: its message dicts without ROS, then the node over real DDS (own domain)."""

from contextlib import contextmanager
import math
import os
import signal
import sys
import time

from cdr_translator.interface import messages, robot_messages
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.ros.cdr_robot import CdrNode
from cdr_translator.ros.client import isolated_ros_env, NodeProcess
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseStamped, WrenchStamped
from mcap.reader import make_reader
from nodes import send_behind_a_slow_first_solve, stamped_wrenches
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

COMMAND = (sys.executable, '-m', 'cdr_translator.ros.cdr_node')
START_TIMEOUT_S = 120.0
ANSWER_TIMEOUT_S = 60.0


@pytest.fixture(scope='module')
def solved():
    """Solve one off-centre case with the library."""
    return DeltaRobot().solve((0.01, -0.005, 0.002), (1.0, 0.5, -9.81))


def test_sliders_from_joint_state():
    """Named in any order, or three unnamed in leg order; anything else is refused."""
    named = robot_messages.sliders_from_joint_state(['slider_3', 'slider_1', 'slider_2'],
                                                    [0.3, 0.1, 0.2])
    assert named.tolist() == [0.1, 0.2, 0.3]
    assert robot_messages.sliders_from_joint_state([], [1, 2, 3]).tolist() == [1, 2, 3]
    with pytest.raises(ValueError, match='needs 3 positions, got 2'):
        robot_messages.sliders_from_joint_state([], [0.0, 0.0])
    with pytest.raises(ValueError, match='names must be'):
        robot_messages.sliders_from_joint_state(['a', 'b', 'c'], [0.0, 0.0, 0.0])


def test_output_messages(solved):
    """Pose, leg angles and wrenches carry the result; the diagnostic says OK."""
    stamp = {'sec': 7, 'nanosec': 9}
    built = {topic: message for topic, _, message in
             robot_messages.output_messages(solved, stamp, 'world', {'skipped': 0})}
    assert set(built) == {robot_messages.PLATFORM_POSE_TOPIC, robot_messages.LEG_ANGLES_TOPIC,
                          robot_messages.LEG_WRENCHES_TOPIC, robot_messages.DIAGNOSTICS_TOPIC}
    pose = built[robot_messages.PLATFORM_POSE_TOPIC]
    assert pose['header'] == {'stamp': stamp, 'frame_id': 'world'}
    assert [pose['pose']['position'][axis] for axis in 'xyz'] == solved.platform_position.tolist()
    angles = built[robot_messages.LEG_ANGLES_TOPIC]
    by_name = dict(zip(angles['name'], angles['position']))
    assert len(by_name) == 15
    assert by_name['leg2_pj_bending'] == solved.leg_bending[1, 0]
    assert by_name['leg3_dj_bending'] == solved.leg_bending[2, 1]
    wrenches = built[robot_messages.LEG_WRENCHES_TOPIC]
    assert np.array(wrenches['data']).reshape(3, 6).tolist() == solved.leg_tip_wrenches.tolist()
    status = built[robot_messages.DIAGNOSTICS_TOPIC]['status'][0]
    assert status['level'] == messages.OK and status['name'] == robot_messages.DIAGNOSTIC_NAME
    assert {'converged': 'true', 'skipped': '0'}.items() <= {
        pair['key']: pair['value'] for pair in status['values']}.items()


def test_failure_publishes_only_an_error():
    """A result that did not converge: no pose, an ERROR diagnostic with the reason."""
    failed = DeltaRobot(time_limit_s=0.0).solve((0.02, 0.0, 0.0), (0.0, 0.0, 0.0))
    built = robot_messages.output_messages(failed, {'sec': 1, 'nanosec': 0}, 'world')
    assert [topic for topic, _, _ in built] == [robot_messages.DIAGNOSTICS_TOPIC]
    status = built[0][2]['status'][0]
    assert status['level'] == messages.ERROR and 'time limit' in status['message']
    rejected = robot_messages.rejection_messages({'sec': 1, 'nanosec': 0}, 'sliders rejected')
    assert rejected[0][2]['status'][0]['name'] == robot_messages.DIAGNOSTIC_NAME


class Client:
    """A node of its own context that sends sliders and payloads and records outputs."""

    def __init__(self):
        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = Node('cdr_test_client', context=self.context)
        self.sliders = self.node.create_publisher(JointState, robot_messages.SLIDERS_TOPIC,
                                                  qos_profile_sensor_data)
        self.wrench = self.node.create_publisher(
            WrenchStamped, robot_messages.PLATFORM_WRENCH_TOPIC, qos_profile_sensor_data)
        self.target = self.node.create_publisher(PointStamped, robot_messages.TARGET_TOPIC,
                                                 qos_profile_sensor_data)
        self.received = {}
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        outputs = {robot_messages.PLATFORM_POSE_TOPIC: PoseStamped,
                   robot_messages.LEG_ANGLES_TOPIC: JointState,
                   robot_messages.DIAGNOSTICS_TOPIC: DiagnosticArray,
                   robot_messages.SLIDER_COMMAND_TOPIC: JointState,
                   robot_messages.PREDICTED_POSE_TOPIC: PoseStamped}
        for topic, message_class in outputs.items():
            self.node.create_subscription(
                message_class, topic,
                lambda message, topic=topic: self.received.setdefault(topic, []).append(
                    message), reliable)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def stamped(self, topic, stamp):
        """Return the received messages of ``topic`` stamped ``stamp``."""
        return [message for message in self.received.get(topic, [])
                if (message.header.stamp.sec, message.header.stamp.nanosec)
                == (stamp['sec'], stamp['nanosec'])]

    def send_until_answered(self, publish, timeout_s, period_s=0.25, same_stamp=False):
        """
        Publish (best effort) every ``period_s`` until a diagnostic answers; return the stamp.

        Each publication gets a new stamp, or (``same_stamp``, for solves slower than the
        period) they all carry the first one.
        """
        deadline = time.monotonic() + timeout_s
        stamp = messages.stamp_from_ns(time.time_ns())
        while time.monotonic() < deadline:
            if not same_stamp:
                stamp = messages.stamp_from_ns(time.time_ns())
            publish(stamp)
            answer_by = time.monotonic() + period_s
            while time.monotonic() < answer_by:
                self.executor.spin_once(timeout_sec=0.05)
                if self.stamped(robot_messages.DIAGNOSTICS_TOPIC, stamp):
                    return stamp
        raise AssertionError(f'no answer in {timeout_s} s')

    def send_malformed_until_answered(self, publisher, what):
        """Publish bytes that are no message until a diagnostic stamped 0 answers; its stamp."""
        zero = {'sec': 0, 'nanosec': 0}
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while not self.stamped(robot_messages.DIAGNOSTICS_TOPIC, zero):
            assert time.monotonic() < deadline, f'malformed {what} not answered'
            publisher.publish(b'\x00\x01\x00\x00\x07')
            self.executor.spin_once(timeout_sec=0.25)
        return zero

    def publish_sliders(self, positions, stamp, names=('slider_1', 'slider_2', 'slider_3')):
        """Publish a sliders JointState."""
        message = JointState()
        message.header.stamp.sec, message.header.stamp.nanosec = stamp['sec'], stamp['nanosec']
        message.name, message.position = list(names), [float(v) for v in positions]
        self.sliders.publish(message)

    def publish_wrench(self, force, stamp, frame_id=''):
        """Publish a payload WrenchStamped."""
        message = WrenchStamped()
        message.header.stamp.sec, message.header.stamp.nanosec = stamp['sec'], stamp['nanosec']
        message.header.frame_id = frame_id
        message.wrench.force.x, message.wrench.force.y, message.wrench.force.z = force
        self.wrench.publish(message)

    def publish_target(self, target, stamp, frame_id=''):
        """Publish a target_position PointStamped."""
        message = PointStamped()
        message.header.stamp.sec, message.header.stamp.nanosec = stamp['sec'], stamp['nanosec']
        message.header.frame_id = frame_id
        message.point.x, message.point.y, message.point.z = (float(v) for v in target)
        self.target.publish(message)

    def wait_for(self, topic, stamp, timeout_s):
        """Spin until a message of ``topic`` stamped ``stamp`` came; return it."""
        deadline = time.monotonic() + timeout_s
        while not self.stamped(topic, stamp) and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        found = self.stamped(topic, stamp)
        assert found, f'no {topic} stamped {stamp} in {timeout_s} s'
        return found[0]

    def close(self):
        """Shut the context down."""
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@contextmanager
def node_session(tmp_path):
    """
    Start cdr_node (MCAP log in ``tmp_path``) in its own ROS domain and a Client for it.

    Yield (node, client, mcap path); afterwards close the client, kill the node if it still
    runs and restore the environment.
    """
    env = isolated_ros_env()
    saved = {key: os.environ.get(key) for key in env}
    os.environ.update(env)
    mcap = tmp_path / 'cdr.mcap'
    node = NodeProcess(['-p', f'mcap_path:={mcap}'], env, tmp_path / 'node.log', COMMAND)
    client = None
    try:
        client = Client()
        yield node, client, mcap
    finally:
        if client is not None:
            client.close()
        node.kill()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def topic_counts(mcap):
    """Return {topic: message count} of a finalized MCAP file."""
    with open(mcap, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    counts = summary.statistics.channel_message_counts
    return {summary.channels[channel].topic: count for channel, count in counts.items()}


def diagnostic(client, stamp):
    """Return (level, message, values) of the (last) diagnostic answering ``stamp``."""
    status = client.stamped(robot_messages.DIAGNOSTICS_TOPIC, stamp)[-1].status[0]
    return (status.level[0] if isinstance(status.level, bytes) else status.level,
            status.message, {pair.key: pair.value for pair in status.values})


def test_node_round_trip(tmp_path, solved):
    """Sliders then a payload in; the pose equals the library's; bad input; clean SIGINT."""
    with node_session(tmp_path) as (node, client, mcap):
        client.send_until_answered(
            lambda stamp: client.publish_sliders((0.002, 0.01, -0.005), stamp,
                                                 ('slider_3', 'slider_1', 'slider_2')),
            START_TIMEOUT_S)
        stamp = client.send_until_answered(
            lambda stamp: client.publish_wrench((1.0, 0.5, -9.81), stamp), ANSWER_TIMEOUT_S)
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while (not client.stamped(robot_messages.PLATFORM_POSE_TOPIC, stamp)
               and time.monotonic() < deadline):
            client.executor.spin_once(timeout_sec=0.05)
        pose = client.stamped(robot_messages.PLATFORM_POSE_TOPIC, stamp)[0]
        assert pose.header.frame_id == 'cdr_base'
        position = [pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]
        assert np.allclose(position, solved.platform_position, atol=1e-9)
        level, _, values = diagnostic(client, stamp)
        assert level == messages.OK and values['converged'] == 'true'
        assert float(values['equilibrium_residual_norm']) <= 1e-9
        # bad inputs are answered with an ERROR naming the problem, and nothing else
        bad = client.send_until_answered(
            lambda stamp: client.publish_sliders((0.0, math.nan, 0.0), stamp), ANSWER_TIMEOUT_S)
        level, text, _ = diagnostic(client, bad)
        assert level == messages.ERROR and 'slider 2 position is nan' in text
        assert not client.stamped(robot_messages.PLATFORM_POSE_TOPIC, bad)
        bad = client.send_until_answered(
            lambda stamp: client.publish_wrench((0.0, 0.0, -1.0), stamp, 'elsewhere'),
            ANSWER_TIMEOUT_S)
        level, text, _ = diagnostic(client, bad)
        assert level == messages.ERROR and "'elsewhere' is not the world frame" in text
        # malformed bytes: an ERROR (stamp zero), and the node goes on answering
        zero = client.send_malformed_until_answered(client.sliders, 'sliders')
        level, text, _ = diagnostic(client, zero)
        assert level == messages.ERROR and 'sliders rejected: malformed message' in text
        again = client.send_until_answered(
            lambda stamp: client.publish_wrench((1.0, 0.5, -9.81), stamp), ANSWER_TIMEOUT_S)
        assert diagnostic(client, again)[0] == messages.OK
        assert node.stop(signal.SIGINT) == 0, node.text()
    by_topic = topic_counts(mcap)
    assert {'/sliders', '/platform_wrench', '/platform_pose', '/leg_bending_angles',
            '/leg_tip_wrenches', '/diagnostics'} <= set(by_topic)
    assert by_topic['/platform_pose'] >= 2 and by_topic['/sliders'] >= 2


def test_inverse_output_messages():
    """A reached target: command and predicted pose; unreachable: an ERROR only."""
    robot = DeltaRobot()
    target = robot.solve((0.004, -0.002, 0.001), (0.0, 0.0, -9.81)).platform_position
    stamp = {'sec': 3, 'nanosec': 4}
    reached = robot.inverse(target, (0.0, 0.0, -9.81))
    built = {topic: message for topic, _, message in
             robot_messages.inverse_output_messages(reached, stamp, 'world')}
    assert set(built) == {robot_messages.SLIDER_COMMAND_TOPIC, robot_messages.PREDICTED_POSE_TOPIC,
                          robot_messages.DIAGNOSTICS_TOPIC}
    command = built[robot_messages.SLIDER_COMMAND_TOPIC]
    assert command['name'] == list(robot_messages.SLIDER_NAMES)
    assert np.allclose(command['position'], [0.004, -0.002, 0.001], atol=1e-8)
    pose = built[robot_messages.PREDICTED_POSE_TOPIC]['pose']['position']
    assert np.allclose([pose[axis] for axis in 'xyz'], target, atol=1e-9)
    unreachable = robot.inverse((0.0, 0.0, -0.3), (0.0, 0.0, -9.81))
    built = robot_messages.inverse_output_messages(unreachable, stamp, 'world')
    assert [topic for topic, _, _ in built] == [robot_messages.DIAGNOSTICS_TOPIC]
    status = built[0][2]['status'][0]
    assert status['level'] == messages.ERROR and 'unreachable' in status['message']
    assert status['name'] == robot_messages.INVERSE_DIAGNOSTIC_NAME
    point = robot_messages.point_message(target, stamp, 'world')
    parsed, frame_id, parsed_stamp = robot_messages.target_from_point(point)
    assert parsed.tolist() == target.tolist() and frame_id == 'world' and parsed_stamp == stamp


def test_node_inverse_round_trip(tmp_path):
    """
    Inverse statics over DDS: target in, slider command and predicted pose out.

    The commanded sliders, sent back, put the platform at the target (forward(inverse(x))
    = x within 1e-6 m); an unreachable or bad target is an ERROR with no command.
    """
    payload = (0.5, -0.5, -9.81)
    true_sliders = np.array([0.008, -0.004, 0.012])
    target = DeltaRobot().solve(true_sliders, payload).platform_position
    with node_session(tmp_path) as (node, client, mcap):
        client.send_until_answered(lambda stamp: client.publish_wrench(payload, stamp),
                                   START_TIMEOUT_S)
        stamp = client.send_until_answered(
            lambda stamp: client.publish_target(target, stamp, 'cdr_base'), ANSWER_TIMEOUT_S,
            period_s=1.0, same_stamp=True)
        command = client.wait_for(robot_messages.SLIDER_COMMAND_TOPIC, stamp, ANSWER_TIMEOUT_S)
        predicted = client.wait_for(robot_messages.PREDICTED_POSE_TOPIC, stamp, ANSWER_TIMEOUT_S)
        assert list(command.name) == list(robot_messages.SLIDER_NAMES)
        assert np.allclose(command.position, true_sliders, atol=1e-7)
        position = predicted.pose.position
        assert np.allclose([position.x, position.y, position.z], target, atol=1e-9)
        level, _, values = diagnostic(client, stamp)
        assert level == messages.OK and values['reachable'] == 'true'
        # the command, sent back as slider positions, puts the platform at the target
        forward = client.send_until_answered(
            lambda stamp: client.publish_sliders(command.position, stamp), ANSWER_TIMEOUT_S)
        pose = client.wait_for(robot_messages.PLATFORM_POSE_TOPIC, forward, ANSWER_TIMEOUT_S)
        reached = [pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]
        assert np.linalg.norm(np.array(reached) - target) < 1e-6
        # unreachable: an ERROR naming the binding limits, no command
        far = client.send_until_answered(
            lambda stamp: client.publish_target((0.0, 0.0, -0.3), stamp), ANSWER_TIMEOUT_S,
            period_s=5.0, same_stamp=True)
        level, text, values = diagnostic(client, far)
        assert level == messages.ERROR and 'unreachable' in text and 'stroke limit' in text
        assert values['reachable'] == 'false'
        assert not client.stamped(robot_messages.SLIDER_COMMAND_TOPIC, far)
        bad = client.send_until_answered(
            lambda stamp: client.publish_target((0.0, math.nan, -0.1), stamp),
            ANSWER_TIMEOUT_S)
        level, text, _ = diagnostic(client, bad)
        assert level == messages.ERROR and 'target y coordinate is nan' in text
        assert node.stop(signal.SIGINT) == 0, node.text()
    by_topic = topic_counts(mcap)
    assert by_topic['/target_position'] >= 3
    assert by_topic['/slider_command'] >= 1 and by_topic['/predicted_platform_pose'] >= 1


def test_node_rejections_name_their_stage_and_log_at_their_level(tmp_path):
    """
    A rejected input is an ERROR of the stage it was for, logged as an ERROR.

    Targets (wrong frame, unreadable) are the inverse statics', payloads the forward's.
    """
    with node_session(tmp_path) as (node, client, _):
        elsewhere = client.send_until_answered(
            lambda stamp: client.publish_target((0.0, 0.0, -0.13), stamp, 'elsewhere'),
            START_TIMEOUT_S)
        status = client.stamped(robot_messages.DIAGNOSTICS_TOPIC, elsewhere)[-1].status[0]
        assert status.name == robot_messages.INVERSE_DIAGNOSTIC_NAME
        level, text, _ = diagnostic(client, elsewhere)
        assert level == messages.ERROR and "target frame_id 'elsewhere'" in text
        payload = client.send_until_answered(
            lambda stamp: client.publish_wrench((0.0, 0.0, -1.0), stamp, 'elsewhere'),
            ANSWER_TIMEOUT_S)
        status = client.stamped(robot_messages.DIAGNOSTICS_TOPIC, payload)[-1].status[0]
        assert status.name == robot_messages.DIAGNOSTIC_NAME
        zero = client.send_malformed_until_answered(client.target, 'target')
        status = client.stamped(robot_messages.DIAGNOSTICS_TOPIC, zero)[-1].status[0]
        assert status.name == robot_messages.INVERSE_DIAGNOSTIC_NAME
        assert 'target rejected: malformed message' in status.message
        assert node.stop(signal.SIGINT) == 0, node.text()
    lines = [line for line in node.text().splitlines() if 'rejected:' in line]
    wrong_frame = "inverse statics: target rejected: target frame_id 'elsewhere'"
    assert any(line.startswith('[ERROR]') and wrong_frame in line for line in lines), lines
    assert any(line.startswith('[ERROR]') and 'forward statics: payload rejected' in line
               for line in lines), lines
    assert all(line.startswith('[ERROR]') for line in lines), lines


def test_inputs_waiting_at_shutdown_are_answered_or_counted(tmp_path):
    """Payloads waiting behind a slow solve when the node closes: every one is in a count."""
    context = Context()
    rclpy.init(args=[], context=context)
    try:
        node = CdrNode(ros_arguments=['--ros-args', '-p', f'mcap_path:={tmp_path / "run.mcap"}'],
                       context=context)
        solve = node.robot.solve

        def slow(*args, **kwargs):
            time.sleep(0.5)   # the first solve: the next payloads wait in the mailbox meanwhile
            return solve(*args, **kwargs)

        node.robot.solve = slow
        try:
            send_behind_a_slow_first_solve(node, stamped_wrenches(3, 'z', -1.0))
        finally:
            node.close()
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    assert node.received == 3
    assert node.solved + node.failed + node.rejected + node._mailbox.skipped == 3
    assert node.solved == 2   # the first, and the last one waiting at shutdown
