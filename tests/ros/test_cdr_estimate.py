"""
cdr_node's payload estimate over real DDS: sliders and a payload -> pose -> the payload back.

The node runs as a child process in its own ROS_DOMAIN_ID (localhost discovery); every wait
is bounded.
"""

import signal

from cdr_translator.interface import payload_estimation, robot_messages
from cdr_translator.interface.messages import ERROR, OK
from cdr_translator.robot.delta import DeltaRobot
from geometry_msgs.msg import PoseStamped, WrenchStamped
import numpy as np
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from test_cdr_node import ANSWER_TIMEOUT_S, diagnostic, node_session, START_TIMEOUT_S
from test_cdr_node import topic_counts

SLIDERS = (0.01, -0.005, 0.002)
PAYLOAD = (1.0, 0.5, -9.81)
ESTIMATE = payload_estimation.ESTIMATED_PAYLOAD_TOPIC


def test_payload_estimate_round_trip(tmp_path):
    """The measured platform pose at the sliders sent gives the payload; bad frames rejected."""
    solved = DeltaRobot().solve(SLIDERS, PAYLOAD)
    with node_session(tmp_path) as (node, client, mcap):
        client.node.create_subscription(
            WrenchStamped, ESTIMATE,
            lambda message: client.received.setdefault(ESTIMATE, []).append(message),
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
        poses = client.node.create_publisher(
            PoseStamped, payload_estimation.MEASURED_PLATFORM_POSE_TOPIC,
            qos_profile_sensor_data)

        def publish_pose(stamp, frame_id=''):
            message = PoseStamped()
            message.header.stamp.sec, message.header.stamp.nanosec = (stamp['sec'],
                                                                      stamp['nanosec'])
            message.header.frame_id = frame_id
            position, orientation = message.pose.position, message.pose.orientation
            position.x, position.y, position.z = solved.platform_position.tolist()
            quaternion = robot_messages.platform_pose_message(solved, stamp, '')['pose'][
                'orientation']
            orientation.x, orientation.y = quaternion['x'], quaternion['y']
            orientation.z, orientation.w = quaternion['z'], quaternion['w']
            poses.publish(message)

        client.send_until_answered(
            lambda stamp: client.publish_sliders(SLIDERS, stamp), START_TIMEOUT_S)
        stamp = client.send_until_answered(publish_pose, ANSWER_TIMEOUT_S, period_s=2.0)
        found = client.wait_for(ESTIMATE, stamp, ANSWER_TIMEOUT_S)
        assert found.header.frame_id == 'cdr_base'
        wrench = found.wrench
        np.testing.assert_allclose([wrench.force.x, wrench.force.y, wrench.force.z], PAYLOAD,
                                   rtol=0, atol=1e-4)
        level, text, values = diagnostic(client, stamp)
        assert level == OK, text
        assert values['converged'] == 'true' and 'residual_m' in values
        bad = client.send_until_answered(lambda stamp: publish_pose(stamp, 'camera'),
                                         ANSWER_TIMEOUT_S)
        level, text, _ = diagnostic(client, bad)
        assert level == ERROR and "unknown frame_id 'camera'" in text
        assert not client.stamped(ESTIMATE, bad)
        assert node.stop(signal.SIGINT) == 0, node.text()
    assert 'measured platform poses:' in node.text()
    by_topic = topic_counts(mcap)
    assert by_topic['/' + payload_estimation.MEASURED_PLATFORM_POSE_TOPIC] >= 2
    assert by_topic['/' + ESTIMATE] >= 1
