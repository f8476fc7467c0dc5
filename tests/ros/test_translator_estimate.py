"""
translator_node's wrench estimate over real DDS: wrench -> pose -> estimated wrench.

The node runs as a child process in this module's own ROS_DOMAIN_ID (localhost discovery);
every wait is bounded. The measured poses are the library's forward solves of known
wrenches, so the estimate must give the wrench back.
"""

import math
import time

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.interface import messages, pose_estimation
from cdr_translator.ros.client import diagnostic_values
from geometry_msgs.msg import PoseStamped
from mcap_ros2.reader import read_ros2_messages
from nodes import ANSWER_TIMEOUT_S, Running
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

ESTIMATE = pose_estimation.ESTIMATED_WRENCH_TOPIC
COVARIANCE = pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC
ESTIMATE_STATUS = pose_estimation.ESTIMATE_STATUS_TOPIC
TOPICS = (ESTIMATE, COVARIANCE, ESTIMATE_STATUS)
#: Pose covariance: 10 um and 0.01 deg standard deviations (a good optical tracker).
POSE_COVARIANCE = np.diag([1e-10] * 3 + [math.radians(0.01) ** 2] * 3)
pytestmark = pytest.mark.usefixtures('ros_env')


def _estimate_status(run, stamp):
    """Wait for the estimate's DiagnosticStatus stamped ``stamp``; return it."""
    assert run.client.wait_for(lambda: any(
        message.status[0].name == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME
        for message in run.client.messages_stamped(ESTIMATE_STATUS, stamp)), ANSWER_TIMEOUT_S), \
        (stamp, run.node.text())
    return next(message for message in run.client.messages_stamped(ESTIMATE_STATUS, stamp)
                if message.status[0].name == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME)


def _first_pose_answered(run, position, quaternion):
    """
    Send the pose (a new stamp each time) until one is answered; return the answered stamp.

    The pose subscriptions match apart from the wrench one that the handshake waited for:
    the first best-effort samples may be lost.
    """
    deadline = time.monotonic() + ANSWER_TIMEOUT_S
    sent = []
    while time.monotonic() < deadline:
        sent.append(run.client.publish_pose(position, quaternion))
        if run.client.wait_for(lambda: any(run.client.messages_stamped(ESTIMATE, stamp)
                                           for stamp in sent), 1.0):
            return next(stamp for stamp in sent if run.client.messages_stamped(ESTIMATE, stamp))
    raise AssertionError(run.node.text())


def test_round_trip_bad_input_and_log(tmp_path, ros_env):
    """
    Wrench -> pose -> estimated wrench equals the wrench; bad poses are rejected; all logged.

    The covariance published is the library's for the same pose; the diagnostic reports the
    residual, the conditioning and the stability verdict.
    """
    forward = TranslatorSolver(TranslatorParams.from_yaml())
    library = TranslatorSolver(TranslatorParams.from_yaml())
    wrenches = [((3.0, 1.0, 0.5), (0.01, 0.0, 0.005)),
                ((-2.0, 4.0, -1.0), (0.0, -0.02, 0.01))]
    exact = ['-p', 'estimate_pose_position_sd:=0.0', '-p', 'estimate_pose_orientation_sd:=0.0']
    with Running(tmp_path, ros_env, ros_args=exact, topics=TOPICS) as run:
        solved = forward.solve(*wrenches[0])
        stamp = _first_pose_answered(run, solved.end_disk_position,
                                     solved.end_disk_quaternion_xyzw)
        estimate = run.client.messages_stamped(ESTIMATE, stamp)[0]
        assert estimate.header.frame_id == 'translator_base'
        found = estimate.wrench
        np.testing.assert_allclose([found.force.x, found.force.y, found.force.z],
                                   wrenches[0][0], rtol=0, atol=1e-5)
        np.testing.assert_allclose([found.torque.x, found.torque.y, found.torque.z],
                                   wrenches[0][1], rtol=0, atol=1e-7)
        status = _estimate_status(run, stamp).status[0]
        assert status.level == bytes([messages.OK]), status.message
        values = diagnostic_values(_estimate_status(run, stamp))
        assert values['converged'] == 'true' and values['stable'] == 'true'
        assert values['accuracy_met'] == 'not assessed' and values['flags'] == 'none'
        assert float(values['residual_m']) < 1e-9
        assert 'axial force' in values['poorly_observable']
        assert float(values['condition_number']) > 100.0

        # with a covariance: the wrench and its covariance, as the library gives them
        solved = forward.solve(*wrenches[1])
        expected = library.estimate_wrench(solved.end_disk_position,
                                           solved.end_disk_quaternion_xyzw,
                                           pose_covariance=POSE_COVARIANCE)
        stamp = run.client.publish_pose(solved.end_disk_position,
                                        solved.end_disk_quaternion_xyzw,
                                        covariance=POSE_COVARIANCE.ravel())
        found = run.answer(ESTIMATE, stamp).wrench
        # the maximum-a-posteriori estimate: the library's, the axial force near the prior's
        # zero; both converge to a hundredth of a posterior standard deviation
        np.testing.assert_allclose(
            [found.force.x, found.force.y, found.force.z, found.torque.x, found.torque.y,
             found.torque.z], expected.wrench, rtol=0,
            atol=0.05 * expected.standard_deviation.max())
        np.testing.assert_allclose([found.force.x, found.force.y], wrenches[1][0][:2], rtol=0,
                                   atol=0.1)
        status = _estimate_status(run, stamp).status[0]
        assert status.level == bytes([messages.WARN]), status.message  # fz uninformative
        values = diagnostic_values(_estimate_status(run, stamp))
        assert values['accuracy_met'] == 'false' and 'uninformative' in values['flags']
        assert run.client.wait_for(lambda: run.client.received[COVARIANCE], ANSWER_TIMEOUT_S)
        covariance = run.client.received[COVARIANCE][-1][0]
        assert [(dim.label, dim.size, dim.stride) for dim in covariance.layout.dim] == [
            ('rows', 6, 36), ('cols', 6, 6)]
        np.testing.assert_allclose(np.reshape(covariance.data, (6, 6)), expected.covariance,
                                   rtol=1e-2, atol=1e-6 * np.abs(expected.covariance).max())

        bad = [((math.nan, 0.0, 0.06), (0.0, 0.0, 0.0, 1.0), '', 'position x component is nan'),
               ((0.0, 0.0, 0.06), (0.0, 0.0, 0.0, 0.5), '', 'unit quaternion'),
               ((0.0, 0.0, 0.06), (0.0, 0.0, 0.0, 1.0), 'world', "unknown frame_id 'world'")]
        for position, quaternion, frame, reason in bad:
            stamp = run.client.publish_pose(position, quaternion, frame)
            status = _estimate_status(run, stamp).status[0]
            assert status.level == bytes([messages.ERROR])
            assert reason in status.message
            assert not run.client.messages_stamped(ESTIMATE, stamp)
        stamp = run.client.publish_pose(solved.end_disk_position,
                                        solved.end_disk_quaternion_xyzw)
        run.answer(ESTIMATE, stamp)
        values = diagnostic_values(_estimate_status(run, stamp))
        assert int(values['rejected']) == len(bad)
        assert run.node.process.poll() is None
        assert run.node.stop() == 0, run.node.text()
    assert 'measured poses:' in run.node.text()
    logged = {}
    for item in read_ros2_messages(str(run.mcap)):
        logged.setdefault(item.channel.topic, item.schema.name)
    assert logged['/' + pose_estimation.MEASURED_POSE_TOPIC] == messages.POSE_TYPE
    assert logged['/' + pose_estimation.MEASURED_POSE_COV_TOPIC] == messages.POSE_COV_TYPE
    assert logged['/' + ESTIMATE] == messages.WRENCH_TYPE
    assert logged['/' + ESTIMATE_STATUS] == messages.DIAGNOSTIC_ARRAY_TYPE
    assert logged['/' + COVARIANCE] == messages.FLOAT64_MULTI_ARRAY_TYPE


def test_a_burst_of_poses_is_accounted_for(node):
    """
    Poses faster than the estimates: the newest answered, the rest counted as skipped.

    The in-process node's pose callback gets 30 poses and a malformed message back to back;
    once idle, every received pose is estimated, rejected or skipped, and the last (the
    malformed one, newest in the mailbox) is rejected.
    """
    forward = TranslatorSolver(TranslatorParams.from_yaml())
    receive = node._estimates.subscriptions[0].callback
    for index in range(30):
        solved = forward.solve((2.0 + 0.1 * index, 1.0, 0.0))
        message = PoseStamped()
        message.header.stamp.sec = index + 1
        message.pose.position.x, message.pose.position.y, message.pose.position.z = (
            solved.end_disk_position.tolist())
        orientation = message.pose.orientation
        orientation.x, orientation.y, orientation.z, orientation.w = (
            solved.end_disk_quaternion_xyzw.tolist())
        receive(serialize_message(message))
    receive(b'\x00\x01\x00\x00\x07')
    counts = node.estimator.counts
    deadline = time.monotonic() + ANSWER_TIMEOUT_S
    while (counts['solved'] + counts['rejected'] + counts['not_converged']
           + node._estimates._mailbox.skipped < 31 and time.monotonic() < deadline):
        time.sleep(0.01)
    skipped = node._estimates._mailbox.skipped
    assert counts['received'] == 31
    assert counts['solved'] + counts['rejected'] + counts['not_converged'] + skipped == 31
    assert counts['rejected'] == 1 and counts['not_converged'] == 0
    assert skipped > 0 and counts['solved'] >= 1


def test_estimate_parameters_change_at_run_time(node):
    """
    The estimate's parameters are declared, changeable at run time, and checked.

    The prior covariance (an empty double array by default) takes 36 doubles; a bad value
    is refused with the reason naming it; the next pose is estimated with the new values.
    """
    assert node.get_parameter('estimate_components').value == ''
    declared = node.get_parameter('estimate_prior_covariance')  # initialized: ros2 param dump
    assert declared.type_ == Parameter.Type.DOUBLE_ARRAY and list(declared.value) == []
    assert node.get_parameter('estimate_pose_position_sd').value == 0.0002
    prior = np.diag([9.0, 9.0, 1.0, 0.04, 0.04, 0.04]).ravel().tolist()
    results = node.set_parameters([Parameter('estimate_prior_covariance', value=prior),
                                   Parameter('estimate_components', value='lateral'),
                                   Parameter('estimate_held_force', value=[0.0, 0.0, 0.5])])
    assert all(result.successful for result in results), results
    assert node.estimator.settings.estimate_prior_covariance == tuple(prior)
    refused = node.set_parameters([Parameter('estimate_components', value='fx fq')])[0]
    assert not refused.successful and 'estimate_components' in refused.reason
    refused = node.set_parameters([Parameter('estimate_prior_covariance',
                                             value=[1.0] * 35)])[0]
    assert not refused.successful and 'estimate_prior_covariance' in refused.reason
    solved = TranslatorSolver(TranslatorParams.from_yaml()).solve((2.0, 1.0, 0.5))
    message = PoseStamped()
    message.pose.position.x, message.pose.position.y, message.pose.position.z = (
        solved.end_disk_position.tolist())
    orientation = message.pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = (
        solved.end_disk_quaternion_xyzw.tolist())
    estimate = node.estimator.process(message).estimate
    assert estimate.components == ('fx', 'fy') and estimate.force[2] == 0.5
    np.testing.assert_allclose(estimate.force[:2], (2.0, 1.0), rtol=0,
                               atol=3.0 * estimate.standard_deviation[:2].max())
    assert estimate.accuracy_met is True
