"""Replay of measured end-disk poses: the node's wrench estimates, offline."""

import math
from pathlib import Path
import subprocess
import sys

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.interface import messages, pose_estimation
from cdr_wire.mcap_log import McapLog
from mcap_ros2.reader import read_ros2_messages
from msg_tools.replay import replay
import numpy as np
import pytest

WRENCHES = [((3.0, 1.0, 0.5), (0.01, 0.0, 0.005)), ((3.5, 1.0, 0.5), (0.01, 0.0, 0.005))]
POSE_COVARIANCE = np.diag([1e-10] * 3 + [math.radians(0.01) ** 2] * 3)
POSE_TOPIC = '/' + pose_estimation.MEASURED_POSE_TOPIC
POSE_COV_TOPIC = '/' + pose_estimation.MEASURED_POSE_COV_TOPIC
ESTIMATE_TOPIC = '/' + pose_estimation.ESTIMATED_WRENCH_TOPIC
COVARIANCE_TOPIC = '/' + pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC
#: A PoseStamped taken as exact: the estimate matches it (accuracy not assessed).
EXACT = {'estimate_pose_position_sd': 0.0, 'estimate_pose_orientation_sd': 0.0}
#: Seconds a replay of the test recordings may take, at most.
REPLAY_TIMEOUT_S = 600
ROOT = Path(__file__).resolve().parents[2]


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
    summary = replay(source, output, parameters=EXACT)
    assert summary.topics == ['/wrench']
    assert (summary.poses, summary.solved) == (5, 2)
    # the PoseStamped ones exact (accuracy not assessed, no flag), those with the tight
    # covariance flagged (the axial force's spread is the prior's)
    assert (summary.estimated, summary.flagged, summary.failed, summary.rejected_poses) == (
        2, 2, 0, 1)
    assert summary.pose_counts() == '5: 2 estimated, 2 flagged, 0 failed, 1 rejected'
    assert summary.pose_counts() in summary.table()
    # why: each flagged estimate under every kind of reason it gives, values left out
    assert summary.pose_reasons == {'uninformative': 2, 'accuracy target missed': 2}
    assert '2 accuracy target missed, 2 uninformative' in summary.table()
    assert summary.estimate_times.count == 4
    found = _read(output)
    assert {name for name, _ in found[POSE_TOPIC]} == {messages.POSE_TYPE}
    assert len(found[POSE_TOPIC]) == 3 and len(found[POSE_COV_TOPIC]) == 2
    estimates = found[ESTIMATE_TOPIC]
    assert len(estimates) == 4
    for (_, message), (force, moment) in zip(estimates[::2], WRENCHES):  # the exact poses
        assert message.header.frame_id == 'translator_base'
        wrench = message.wrench
        np.testing.assert_allclose([wrench.force.x, wrench.force.y, wrench.force.z], force,
                                   rtol=0, atol=1e-5)
        np.testing.assert_allclose([wrench.torque.x, wrench.torque.y, wrench.torque.z],
                                   moment, rtol=0, atol=1e-7)
    assert len(found[COVARIANCE_TOPIC]) == 2
    assert all(len(message.data) == 36 for _, message in found[COVARIANCE_TOPIC])
    statuses = [message.status[0] for _, message in found['/estimate_status']
                if message.status[0].name == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME]
    assert len(statuses) == 5
    assert statuses[-1].level == messages.ERROR
    assert "unknown frame_id 'camera'" in statuses[-1].message
    # both pose topics of one namespace share one warm-started stream, as in the node
    assert {pair.key: pair.value for pair in statuses[-1].values}['received'] == '5'
    # the closing aggregated array: the wrenches' and the estimates' counts side by side
    closing = {status.name: {pair.key: pair.value for pair in status.values}
               for status in found['/diagnostics'][-1][1].status}
    assert closing[messages.DIAGNOSTIC_NAME]['solved'] == '2'
    estimates = closing[pose_estimation.ESTIMATE_DIAGNOSTIC_NAME]
    assert (estimates['received'], estimates['estimated'], estimates['flagged'],
            estimates['rejected']) == ('5', '2', '2', '1')


def test_a_chosen_wrench_topic_leaves_the_poses_out(tmp_path):
    """--topic /wrench replays the wrenches only; naming a pose topic adds it."""
    source = tmp_path / 'in.mcap'
    _recording(source)
    summary = replay(source, tmp_path / 'wrench.mcap', topics=['/wrench'])
    assert summary.poses == 0 and not summary.warnings
    assert ESTIMATE_TOPIC not in _read(tmp_path / 'wrench.mcap')
    summary = replay(source, tmp_path / 'both.mcap', topics=['/wrench', POSE_COV_TOPIC])
    assert (summary.poses, summary.estimated + summary.flagged) == (2, 2)
    assert not summary.warnings


def _msg_tools(*args):
    """Run ``python -m msg_tools`` with ``args``; return the finished process."""
    return subprocess.run([sys.executable, '-m', 'msg_tools', *map(str, args)],
                          capture_output=True, text=True, timeout=REPLAY_TIMEOUT_S, cwd=ROOT)


def test_a_noisy_tracker_stream_lateral_estimates(tmp_path):
    """
    A realistic noisy recording (0.2 mm, 0.1 deg): every pose counted; lateral estimates.

    synth's random walk moves every force component within the peak's magnitude (the axial
    force too, here within 1 N) and no moment: ``--estimate lateral`` holds the axial force
    and the moment at zero, which biases the lateral force by under 0.02 N (the axial force
    changes the lateral stiffness by its ratio to the 29 N buckling load). Each pose comes
    twice (PoseStamped: the assumed noise; PoseWithCovarianceStamped: its own); the lateral
    force comes back within its posterior spread, 0.1 N rms.
    """
    source, output = tmp_path / 'noisy.mcap', tmp_path / 'out.mcap'
    made = _msg_tools('synth', source, '--profile', 'random-walk', '--count', 50, '--force',
                      1.0, 0.0, 0.0, '--measured-pose-noise', 0.0002, 0.1)
    assert made.returncode == 0, made.stderr
    replayed = _msg_tools('replay', source, '--out', output, '--no-compliance', '--estimate',
                          'lateral', '--held-force', 0, 0, 0, '--held-moment', 0, 0, 0,
                          '--pose-sd', 0.0002, math.radians(0.1))
    assert replayed.returncode == 0, replayed.stderr
    line = next(line for line in replayed.stdout.splitlines()
                if line.startswith('measured poses'))
    counts = [int(word) for word in line.replace(':', ' ').replace(',', ' ').split()
              if word.isdigit()]
    assert counts[0] == 100 and sum(counts[1:]) == 100, line
    assert 'estimate time ms p50/p95/max' in replayed.stdout
    truth = {(message.header.stamp.sec, message.header.stamp.nanosec): message.wrench
             for message in (item.ros_msg for item in read_ros2_messages(str(source))
                             if item.channel.topic == '/wrench')}
    found = _read(output)
    estimates = [message for _, message in found[ESTIMATE_TOPIC]]
    spreads = [np.sqrt(np.diag(np.reshape(message.data, (6, 6))))
               for _, message in found[COVARIANCE_TOPIC]]
    assert len(estimates) == len(spreads) == 100  # every pose has a covariance now
    errors, limits = [], []
    for estimate, spread in zip(estimates, spreads):
        true = truth[(estimate.header.stamp.sec, estimate.header.stamp.nanosec)]
        wrench = estimate.wrench
        assert (wrench.force.z, wrench.torque.x, wrench.torque.y, wrench.torque.z) == (
            0.0, 0.0, 0.0, 0.0)  # held
        errors.append([wrench.force.x - true.force.x, wrench.force.y - true.force.y])
        limits.append(4.0 * spread[:2] + 0.02)
    errors = np.array(errors)
    assert np.all(np.abs(errors) <= np.array(limits)), np.abs(errors).max(axis=0)
    assert np.sqrt(np.mean(errors ** 2)) < 0.1
    assert np.abs(errors).max() < 0.2


@pytest.mark.parametrize('flags, reason', [
    (['--estimate', 'fx fq'], '--estimate: estimate_components: estimate must be one of'),
    (['--prior-force-sd', '0'], '--prior-force-sd: estimate_prior_force_sd must lie in'),
    (['--target-moment-sd', '-1'], '--target-moment-sd: estimate_target_moment_sd must lie'),
    (['--pose-sd', '-1', '0'], '--pose-sd: estimate_pose_position_sd must lie in'),
    (['--held-force', '0', 'nan', '0'], '--held-force: estimate_held_force[1]'),
])
def test_bad_estimate_flags_are_named(tmp_path, flags, reason):
    """A bad estimate flag stops replay before reading, exit code 2, naming the flag."""
    source = tmp_path / 'in.mcap'
    _recording(source)
    replayed = _msg_tools('replay', source, '--out', tmp_path / 'out.mcap', *flags)
    assert replayed.returncode == 2, replayed.stdout + replayed.stderr
    assert reason in replayed.stderr
    assert not (tmp_path / 'out.mcap').exists()


def test_estimate_flags_override_the_params_file(tmp_path):
    """--estimate and the held values reach the estimator over --params' values."""
    source = tmp_path / 'in.mcap'
    _recording(source)
    params = tmp_path / 'params.yaml'
    params.write_text('translator_node:\n  ros__parameters:\n'
                      "    estimate_components: 'moment'\n")
    summary = replay(source, tmp_path / 'out.mcap', topics=['/wrench', POSE_TOPIC],
                     params_path=params, parameters={**EXACT, 'estimate_components': 'fx fy',
                                                     'estimate_held_force': [0.0, 0.0, 0.5],
                                                     'estimate_held_moment': [0.01, 0.0,
                                                                              0.005]})
    assert summary.poses == 3 and summary.rejected_poses == 1
    statuses = [message.status[0]
                for _, message in _read(tmp_path / 'out.mcap')['/estimate_status']
                if message.status[0].name == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME]
    values = {pair.key: pair.value for pair in statuses[0].values}
    assert values['components'] == 'fx fy' and values['accuracy_met'] == 'not assessed'
    wrench = _read(tmp_path / 'out.mcap')[ESTIMATE_TOPIC][0][1].wrench
    # the first pose's held values are its true ones: the lateral force back exactly
    np.testing.assert_allclose([wrench.force.x, wrench.force.y], WRENCHES[0][0][:2], atol=1e-5)
    assert (wrench.force.z, wrench.torque.x, wrench.torque.z) == (0.5, 0.01, 0.005)
