"""cdr_node: its message dicts without ROS, then the node over real DDS (own domain)."""

import math
import os
import signal
import sys
import time

from cdr_translator import cdr_messages
from cdr_translator.interface import messages
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.ros.client import isolated_ros_env, NodeProcess
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, WrenchStamped
from mcap.reader import make_reader
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
    named = cdr_messages.sliders_from_joint_state(['slider_3', 'slider_1', 'slider_2'],
                                                  [0.3, 0.1, 0.2])
    assert named.tolist() == [0.1, 0.2, 0.3]
    assert cdr_messages.sliders_from_joint_state([], [1, 2, 3]).tolist() == [1, 2, 3]
    with pytest.raises(ValueError, match='needs 3 positions, got 2'):
        cdr_messages.sliders_from_joint_state([], [0.0, 0.0])
    with pytest.raises(ValueError, match='names must be'):
        cdr_messages.sliders_from_joint_state(['a', 'b', 'c'], [0.0, 0.0, 0.0])


def test_output_messages(solved):
    """Pose, leg angles and wrenches carry the result; the diagnostic says OK."""
    stamp = {'sec': 7, 'nanosec': 9}
    built = {topic: message for topic, _, message in
             cdr_messages.output_messages(solved, stamp, 'world', {'skipped': 0})}
    assert set(built) == {cdr_messages.PLATFORM_POSE_TOPIC, cdr_messages.LEG_ANGLES_TOPIC,
                          cdr_messages.LEG_WRENCHES_TOPIC, cdr_messages.DIAGNOSTICS_TOPIC}
    pose = built[cdr_messages.PLATFORM_POSE_TOPIC]
    assert pose['header'] == {'stamp': stamp, 'frame_id': 'world'}
    assert [pose['pose']['position'][axis] for axis in 'xyz'] == solved.platform_position.tolist()
    angles = built[cdr_messages.LEG_ANGLES_TOPIC]
    by_name = dict(zip(angles['name'], angles['position']))
    assert len(by_name) == 15
    assert by_name['leg2_pj_bending'] == solved.leg_bending[1, 0]
    assert by_name['leg3_dj_bending'] == solved.leg_bending[2, 1]
    wrenches = built[cdr_messages.LEG_WRENCHES_TOPIC]
    assert np.array(wrenches['data']).reshape(3, 6).tolist() == solved.leg_tip_wrenches.tolist()
    status = built[cdr_messages.DIAGNOSTICS_TOPIC]['status'][0]
    assert status['level'] == messages.OK and status['name'] == cdr_messages.DIAGNOSTIC_NAME
    assert {'converged': 'true', 'skipped': '0'}.items() <= {
        pair['key']: pair['value'] for pair in status['values']}.items()


def test_failure_publishes_only_an_error():
    """A result that did not converge: no pose, an ERROR diagnostic with the reason."""
    failed = DeltaRobot(time_limit_s=0.0).solve((0.02, 0.0, 0.0), (0.0, 0.0, 0.0))
    built = cdr_messages.output_messages(failed, {'sec': 1, 'nanosec': 0}, 'world')
    assert [topic for topic, _, _ in built] == [cdr_messages.DIAGNOSTICS_TOPIC]
    status = built[0][2]['status'][0]
    assert status['level'] == messages.ERROR and 'time limit' in status['message']
    rejected = cdr_messages.rejection_messages({'sec': 1, 'nanosec': 0}, 'sliders rejected')
    assert rejected[0][2]['status'][0]['name'] == cdr_messages.DIAGNOSTIC_NAME


class Client:
    """A node of its own context that sends sliders and payloads and records outputs."""

    def __init__(self):
        self.context = Context()
        rclpy.init(args=[], context=self.context)
        self.node = Node('cdr_test_client', context=self.context)
        self.sliders = self.node.create_publisher(JointState, cdr_messages.SLIDERS_TOPIC,
                                                  qos_profile_sensor_data)
        self.wrench = self.node.create_publisher(
            WrenchStamped, cdr_messages.PLATFORM_WRENCH_TOPIC, qos_profile_sensor_data)
        self.received = {}
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        outputs = {cdr_messages.PLATFORM_POSE_TOPIC: PoseStamped,
                   cdr_messages.LEG_ANGLES_TOPIC: JointState,
                   cdr_messages.DIAGNOSTICS_TOPIC: DiagnosticArray}
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

    def send_until_answered(self, publish, timeout_s):
        """Publish (best effort) every 0.25 s until a diagnostic answers; return the stamp."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            stamp = messages.stamp_from_ns(time.time_ns())
            publish(stamp)
            answer_by = time.monotonic() + 0.25
            while time.monotonic() < answer_by:
                self.executor.spin_once(timeout_sec=0.05)
                if self.stamped(cdr_messages.DIAGNOSTICS_TOPIC, stamp):
                    return stamp
        raise AssertionError(f'no answer in {timeout_s} s')

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

    def close(self):
        """Shut the context down."""
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def diagnostic(client, stamp):
    """Return (level, message, values) of the diagnostic answering ``stamp``."""
    status = client.stamped(cdr_messages.DIAGNOSTICS_TOPIC, stamp)[0].status[0]
    return (status.level[0] if isinstance(status.level, bytes) else status.level,
            status.message, {pair.key: pair.value for pair in status.values})


def test_node_round_trip(tmp_path, solved):
    """Sliders then a payload in; the pose equals the library's; bad input; clean SIGINT."""
    env = isolated_ros_env()
    saved = {key: os.environ.get(key) for key in env}
    os.environ.update(env)
    mcap = tmp_path / 'cdr.mcap'
    node = NodeProcess(['-p', f'mcap_path:={mcap}'], env, tmp_path / 'node.log', COMMAND)
    client = None
    try:
        client = Client()
        client.send_until_answered(
            lambda stamp: client.publish_sliders((0.002, 0.01, -0.005), stamp,
                                                 ('slider_3', 'slider_1', 'slider_2')),
            START_TIMEOUT_S)
        stamp = client.send_until_answered(
            lambda stamp: client.publish_wrench((1.0, 0.5, -9.81), stamp), ANSWER_TIMEOUT_S)
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while (not client.stamped(cdr_messages.PLATFORM_POSE_TOPIC, stamp)
               and time.monotonic() < deadline):
            client.executor.spin_once(timeout_sec=0.05)
        pose = client.stamped(cdr_messages.PLATFORM_POSE_TOPIC, stamp)[0]
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
        assert not client.stamped(cdr_messages.PLATFORM_POSE_TOPIC, bad)
        bad = client.send_until_answered(
            lambda stamp: client.publish_wrench((0.0, 0.0, -1.0), stamp, 'elsewhere'),
            ANSWER_TIMEOUT_S)
        level, text, _ = diagnostic(client, bad)
        assert level == messages.ERROR and "'elsewhere' is not the world frame" in text
        assert node.stop(signal.SIGINT) == 0, node.text()
    finally:
        if client is not None:
            client.close()
        node.kill()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    with open(mcap, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    topics = {channel.topic for channel in summary.channels.values()}
    assert {'/sliders', '/platform_wrench', '/platform_pose', '/leg_bending_angles',
            '/leg_tip_wrenches', '/diagnostics'} <= topics
    counts = summary.statistics.channel_message_counts
    by_topic = {summary.channels[channel].topic: count for channel, count in counts.items()}
    assert by_topic['/platform_pose'] >= 2 and by_topic['/sliders'] >= 2
