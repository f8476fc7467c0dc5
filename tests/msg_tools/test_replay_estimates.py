"""Replay of measured end-disk poses: the node's wrench estimates, offline."""

import math

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.interface import messages, pose_estimation
from cdr_wire.mcap_log import McapLog
from mcap_ros2.reader import read_ros2_messages
from msg_tools.replay import replay
import numpy as np

WRENCHES = [((3.0, 1.0, 0.5), (0.01, 0.0, 0.005)), ((3.5, 1.0, 0.5), (0.01, 0.0, 0.005))]
POSE_COVARIANCE = np.diag([1e-10] * 3 + [math.radians(0.01) ** 2] * 3)
POSE_TOPIC = '/' + pose_estimation.MEASURED_POSE_TOPIC
POSE_COV_TOPIC = '/' + pose_estimation.MEASURED_POSE_COV_TOPIC
ESTIMATE_TOPIC = '/' + pose_estimation.ESTIMATED_WRENCH_TOPIC
COVARIANCE_TOPIC = '/' + pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC


def _pose(result, stamp, covariance=None, frame_id=''):
    pose = {'position': dict(zip('xyz', result.end_disk_position.tolist())),
            'orientation': dict(zip('xyzw', result.end_disk_quaternion_xyzw.tolist()))}
    if covariance is not None:
        pose = {'pose': pose, 'covariance': covariance.ravel().tolist()}
    return {'header': messages.header(stamp, frame_id), 'pose': pose}


def _recording(path):
    """Write wrenches and, after each, its pose measured (plain, then with a covariance)."""
    solver = TranslatorSolver(TranslatorParams.from_yaml())
    with McapLog(path, flush_every_messages=0, flush_every_s=0.0,
                 if_exists='overwrite') as log:
        for topic, type_name in (('/wrench', messages.WRENCH_TYPE),
                                 (POSE_TOPIC, messages.POSE_TYPE),
                                 (POSE_COV_TOPIC, messages.POSE_COV_TYPE)):
            log.register(topic, type_name, qos='sensor_data')
        for index, (force, moment) in enumerate(WRENCHES):
            time_ns = 1_000_000_000 + 10_000_000 * index
            stamp = messages.stamp_from_ns(time_ns)
            log.write('/wrench', messages.WRENCH_TYPE,
                      messages.wrench_message(force, moment, '', stamp), log_time_ns=time_ns)
            result = solver.solve(force, moment)
            log.write(POSE_TOPIC, messages.POSE_TYPE, _pose(result, stamp),
                      log_time_ns=time_ns + 1)
            log.write(POSE_COV_TOPIC, messages.POSE_COV_TYPE,
                      _pose(result, stamp, POSE_COVARIANCE), log_time_ns=time_ns + 2)
        # a pose in an unknown frame: rejected, logged, no estimate
        log.write(POSE_TOPIC, messages.POSE_TYPE, _pose(result, {'sec': 9, 'nanosec': 0},
                                                        frame_id='camera'),
                  log_time_ns=2_000_000_000)


def _read(path):
    found = {}
    for item in read_ros2_messages(str(path)):
        found.setdefault(item.channel.topic, []).append((item.schema.name, item.ros_msg))
    return found


def test_replay_estimates_the_wrench_of_each_measured_pose(tmp_path):
    """Each pose gives the wrench back, with its covariance when measured with one."""
    source, output = tmp_path / 'in.mcap', tmp_path / 'out.mcap'
    _recording(source)
    summary = replay(source, output)
    assert summary.topics == ['/wrench']
    assert (summary.poses, summary.estimated, summary.solved) == (5, 4, 2)
    assert 'measured poses' in summary.table()
    found = _read(output)
    assert {name for name, _ in found[POSE_TOPIC]} == {messages.POSE_TYPE}
    assert len(found[POSE_TOPIC]) == 3 and len(found[POSE_COV_TOPIC]) == 2
    estimates = found[ESTIMATE_TOPIC]
    assert len(estimates) == 4
    for (_, message), (force, moment) in zip(estimates, np.repeat(WRENCHES, 2, axis=0)):
        assert message.header.frame_id == 'translator_base'
        wrench = message.wrench
        np.testing.assert_allclose([wrench.force.x, wrench.force.y, wrench.force.z], force,
                                   rtol=0, atol=1e-5)
        np.testing.assert_allclose([wrench.torque.x, wrench.torque.y, wrench.torque.z],
                                   moment, rtol=0, atol=1e-7)
    assert len(found[COVARIANCE_TOPIC]) == 2
    assert all(len(message.data) == 36 for _, message in found[COVARIANCE_TOPIC])
    statuses = [message.status[0] for _, message in found['/diagnostics']
                if message.status[0].name == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME]
    assert len(statuses) == 5
    assert statuses[-1].level == messages.ERROR
    assert "unknown frame_id 'camera'" in statuses[-1].message
    # both pose topics of one namespace share one warm-started stream, as in the node
    assert {pair.key: pair.value for pair in statuses[-1].values}['received'] == '5'


def test_a_chosen_wrench_topic_leaves_the_poses_out(tmp_path):
    """--topic /wrench replays the wrenches only; naming a pose topic adds it."""
    source = tmp_path / 'in.mcap'
    _recording(source)
    summary = replay(source, tmp_path / 'wrench.mcap', topics=['/wrench'])
    assert summary.poses == 0 and not summary.warnings
    assert ESTIMATE_TOPIC not in _read(tmp_path / 'wrench.mcap')
    summary = replay(source, tmp_path / 'both.mcap', topics=['/wrench', POSE_COV_TOPIC])
    assert (summary.poses, summary.estimated) == (2, 2) and not summary.warnings
