"""The nodes' load estimates without ROS: pose messages in, estimate messages out."""

from dataclasses import replace
import math

from cdr_translator import TranslatorSolver
from cdr_translator.interface import messages, payload_estimation, pose_estimation
from cdr_translator.interface import robot_messages
from cdr_translator.interface.payload_estimation import PayloadProcessor
from cdr_translator.interface.pose_estimation import pose_from_message, PoseProcessor
from cdr_translator.interface.settings import CdrSettings, TranslatorSettings
from cdr_translator.robot.delta import DeltaRobot
import numpy as np
import pytest

STAMP = {'sec': 12, 'nanosec': 345}
WRENCH = ((2.5, -1.5, 0.8), (0.02, 0.01, -0.004))
#: Pose covariance: 10 um and 0.01 deg standard deviations.
POSE_COVARIANCE = np.diag([1e-10] * 3 + [math.radians(0.01) ** 2] * 3)


def _pose(position, quaternion, frame_id='', covariance=None, stamp=STAMP):
    """Return a PoseStamped dict, or a PoseWithCovarianceStamped one with ``covariance``."""
    pose = {'position': dict(zip('xyz', map(float, position))),
            'orientation': dict(zip('xyzw', map(float, quaternion)))}
    if covariance is not None:
        pose = {'pose': pose, 'covariance': [float(value) for value in np.ravel(covariance)]}
    return {'header': messages.header(stamp, frame_id), 'pose': pose}


@pytest.fixture(scope='module')
def settings():
    """Return the shipped node settings."""
    return TranslatorSettings.from_params_file()


@pytest.fixture(scope='module')
def measured(settings):
    """Return the end-disk pose under ``WRENCH`` (the library's forward solve)."""
    result = TranslatorSolver(settings.params).solve(*WRENCH)
    assert result.converged
    return result.end_disk_position, result.end_disk_quaternion_xyzw


def _by_topic(outputs):
    found = {}
    for topic, type_name, values in outputs:
        found.setdefault(topic, []).append((type_name, values))
    return found


def test_pose_messages_are_read_with_and_without_covariance(measured):
    """A PoseStamped gives no covariance; a PoseWithCovarianceStamped its 6x6, row-major."""
    position, quaternion = measured
    plain = pose_from_message(_pose(position, quaternion, 'translator_base'))
    assert plain.covariance is None and plain.frame_id == 'translator_base'
    assert plain.stamp == STAMP
    np.testing.assert_array_equal(plain.position, position)
    np.testing.assert_array_equal(plain.quaternion_xyzw, quaternion)
    asymmetric = np.arange(36.0).reshape(6, 6)
    carried = pose_from_message(_pose(position, quaternion, covariance=asymmetric))
    np.testing.assert_array_equal(carried.covariance, asymmetric)  # row-major, as given
    np.testing.assert_array_equal(carried.position, position)


def test_round_trip_gives_the_wrench_and_its_covariance(settings, measured):
    """
    Wrench -> pose -> estimate, with a pose covariance: the MAP estimate and its spread.

    The lateral force comes back tightly; the axial force, which the pose hardly sees, is
    pulled toward the prior's zero mean, and the posterior covers the truth there too.
    Such an estimate is flagged (the axial spread is larger than the force reported and the
    target): a WARN naming why, counted as solved and flagged.
    """
    processor = PoseProcessor(settings.params, settings)
    position, quaternion = measured
    outcome = processor.process(_pose(position, quaternion, covariance=POSE_COVARIANCE))
    found = _by_topic(outcome.outputs)
    assert set(found) == {pose_estimation.ESTIMATED_WRENCH_TOPIC,
                          pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC,
                          pose_estimation.ESTIMATE_STATUS_TOPIC}
    type_name, wrench = found[pose_estimation.ESTIMATED_WRENCH_TOPIC][0]
    assert type_name == messages.WRENCH_TYPE
    assert wrench['header'] == messages.header(STAMP, settings.base_frame)
    force, moment, _, _ = messages.wrench_from_message(wrench)
    truth = np.concatenate(WRENCH)
    error = np.concatenate([force, moment]) - truth
    sd = outcome.estimate.standard_deviation
    assert np.all(np.abs(error) <= 3.0 * sd), (error, sd)  # the posterior covers the truth
    assert np.all(np.abs(error[:2]) < 0.1)  # lateral force: tight
    assert abs(force[2]) < 0.5 * abs(truth[2])  # axial force: pulled toward the prior's 0
    assert sd[2] > 5.0 * sd[0]  # ... with about the prior's spread
    _, covariance = found[pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC][0]
    assert covariance['layout']['dim'] == [{'label': 'rows', 'size': 6, 'stride': 36},
                                           {'label': 'cols', 'size': 6, 'stride': 6}]
    matrix = np.reshape(covariance['data'], (6, 6))
    np.testing.assert_array_equal(matrix, outcome.estimate.covariance)
    np.testing.assert_allclose(np.sqrt(np.diag(matrix)), sd)
    status = found[pose_estimation.ESTIMATE_STATUS_TOPIC][0][1]['status'][0]
    assert status['name'] == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME
    assert status['level'] == messages.WARN, status['message']
    values = {pair['key']: pair['value'] for pair in status['values']}
    assert values['converged'] == 'true' and values['stable'] == 'true'
    assert values['accuracy_met'] == 'false'
    assert 'uninformative' in values['flags'] and 'fz' in values['flags']
    assert values['components'] == 'fx fy fz mx my mz'
    assert len(values['standard_deviation'].split()) == 6
    assert 0.0 <= float(values['chi_square_p']) <= 1.0
    assert float(values['chi_square']) >= 0.0
    assert 'axial force' in values['poorly_observable']
    assert (values['received'], values['solved'], values['flagged'], values['estimated']) == (
        '1', '1', '1', '0')


def test_exact_pose_gives_the_wrench_back_accuracy_not_assessed(settings, measured):
    """
    A PoseStamped with both assumed sds 0 is exact: the wrench back, no covariance, OK.

    Its accuracy is not assessed ('not assessed', never 'false'); warm from the last
    estimate.
    """
    exact = settings.with_values(estimate_pose_position_sd=0.0,
                                 estimate_pose_orientation_sd=0.0)
    processor = PoseProcessor(exact.params, exact)
    position, quaternion = measured
    for _ in range(2):
        outcome = processor.process(_pose(position, quaternion))
    assert pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC not in _by_topic(outcome.outputs)
    assert outcome.estimate.converged and outcome.estimate.iterations <= 1
    assert outcome.estimate.accuracy_met is None
    np.testing.assert_allclose(outcome.estimate.force, WRENCH[0], rtol=0, atol=1e-5)
    np.testing.assert_allclose(outcome.estimate.moment, WRENCH[1], rtol=0, atol=1e-7)
    status = outcome.outputs[-1][2]['status'][0]
    values = {pair['key']: pair['value'] for pair in status['values']}
    assert status['level'] == messages.OK, status['message']
    assert values['accuracy_met'] == 'not assessed' and values['flags'] == 'none'
    assert float(values['residual_m']) < 1e-9
    assert (values['solved'], values['estimated'], values['flagged']) == ('2', '2', '0')


def test_a_pose_stamped_gets_the_assumed_noise(settings, measured):
    """
    A PoseStamped is estimated with the parameters' pose noise: a covariance published.

    Lateral-only (axial force and moment held at their true values): the lateral force
    back within its posterior spread, the target met, OK; the held components as given.
    """
    lateral = settings.with_values(estimate_components='lateral',
                                   estimate_held_force=[0.0, 0.0, WRENCH[0][2]],
                                   estimate_held_moment=list(WRENCH[1]))
    processor = PoseProcessor(lateral.params, lateral)
    outcome = processor.process(_pose(*measured))
    estimate = outcome.estimate
    assert pose_estimation.ESTIMATED_WRENCH_COVARIANCE_TOPIC in _by_topic(outcome.outputs)
    assert estimate.components == ('fx', 'fy') and not estimate.flags
    assert estimate.accuracy_met is True
    np.testing.assert_allclose(estimate.force[:2], WRENCH[0][:2], rtol=0,
                               atol=3.0 * estimate.standard_deviation[:2].max())
    assert estimate.standard_deviation[0] < lateral.estimate_target_force_sd
    assert (estimate.force[2], *estimate.moment) == (WRENCH[0][2], *WRENCH[1])
    assert outcome.outputs[-1][2]['status'][0]['level'] == messages.OK


def test_estimate_level_warns_for_a_flagged_estimate(settings, measured):
    """A converged estimate with a flag (or accuracy not met) is WARN; not converged ERROR."""
    estimate = PoseProcessor(settings.params, settings.with_values(
        estimate_pose_position_sd=0.0, estimate_pose_orientation_sd=0.0)).estimate(
        pose_from_message(_pose(*measured)))
    assert estimate.converged and not estimate.flags and estimate.accuracy_met is None
    assert pose_estimation.estimate_level(estimate) == messages.OK
    assert pose_estimation.estimate_level(
        replace(estimate, flags=['past buckling'])) == messages.WARN
    assert pose_estimation.estimate_level(replace(estimate, accuracy_met=False)) == \
        messages.WARN
    assert pose_estimation.estimate_level(replace(estimate, accuracy_met=True)) == messages.OK
    assert pose_estimation.estimate_level(replace(estimate, converged=False)) == \
        messages.ERROR


@pytest.mark.parametrize('position, quaternion, frame_id, covariance, reason', [
    ((math.nan, 0.0, 0.06), (0, 0, 0, 1), '', None, 'position x component is nan'),
    ((0.0, 0.0, 0.06), (0, 0, 0, 0.5), '', None, 'must be a unit quaternion'),
    ((0.0, 0.0, 0.06), (0, 0, 0, 1), 'world', None, "unknown frame_id 'world'"),
    ((0.0, 0.0, 0.06), (0, 0, 0, 1), '', -np.eye(6), 'pose_covariance'),
    ((0.0, 0.0, 0.06), (0, 0, 0, 1), '', np.zeros(35), 'malformed message'),
])
def test_bad_poses_are_rejected_with_the_reason(settings, position, quaternion, frame_id,
                                                covariance, reason):
    """NaN, a non-unit quaternion, another frame, a bad covariance: ERROR, no wrench."""
    processor = PoseProcessor(settings.params, settings)
    outcome = processor.process(_pose(position, quaternion, frame_id, covariance))
    assert outcome.estimate is None
    assert [topic for topic, _, _ in outcome.outputs] == [pose_estimation.ESTIMATE_STATUS_TOPIC]
    status = outcome.outputs[0][2]['status'][0]
    assert status['level'] == messages.ERROR
    assert status['name'] == pose_estimation.ESTIMATE_DIAGNOSTIC_NAME
    assert reason in status['message'], status['message']
    assert processor.counts['rejected'] == 1 and processor.counts['received'] == 1


def test_unreachable_pose_is_an_error_without_a_wrench(settings):
    """A pose beyond the translator's reach: ERROR naming it, no estimated wrench."""
    processor = PoseProcessor(settings.params, settings)
    outcome = processor.process(_pose((0.0, 0.0, 1.0), (0, 0, 0, 1)))
    assert [topic for topic, _, _ in outcome.outputs] == [pose_estimation.ESTIMATE_STATUS_TOPIC]
    status = outcome.outputs[0][2]['status'][0]
    assert status['level'] == messages.ERROR and 'unreachable' in status['message']
    assert processor.counts['not_converged'] == 1


def test_payload_round_trip_at_the_latest_sliders():
    """cdr_node's processor: platform pose at some sliders -> the payload back, in {w}."""
    settings = CdrSettings.from_params_file()
    sliders, force = np.array([0.01, -0.005, 0.002]), (1.0, 0.5, -9.81)
    solved = DeltaRobot(settings.params, settings.geometry).solve(sliders, force)
    processor = PayloadProcessor(settings, lambda: sliders)
    outcome = processor.process(robot_messages.platform_pose_message(
        solved, STAMP, settings.world_frame))
    found = _by_topic(outcome.outputs)
    assert set(found) == {payload_estimation.ESTIMATED_PAYLOAD_TOPIC, messages.DIAGNOSTICS_TOPIC}
    payload = found[payload_estimation.ESTIMATED_PAYLOAD_TOPIC][0][1]
    assert payload['header'] == messages.header(STAMP, settings.world_frame)
    estimated_force, estimated_moment, _, _ = messages.wrench_from_message(payload)
    np.testing.assert_allclose(estimated_force, force, rtol=0, atol=1e-4)
    np.testing.assert_allclose(estimated_moment, 0.0, rtol=0, atol=1e-5)
    status = found[messages.DIAGNOSTICS_TOPIC][0][1]['status'][0]
    assert status['name'] == payload_estimation.PAYLOAD_DIAGNOSTIC_NAME
    assert status['level'] == messages.OK, status['message']
    rejected = processor.process(robot_messages.platform_pose_message(solved, STAMP, 'tool'))
    assert rejected.estimate is None
    assert "unknown frame_id 'tool'" in rejected.outputs[0][2]['status'][0]['message']
