"""The output message dicts of a result: pose, angles, markers, diagnostics, compliance."""

import math

from cdr_translator import TranslatorSolver
from cdr_translator.interface import messages
import numpy as np
import pytest

STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


def test_pose_and_joint_state_follow_the_result(solved):
    """Pose = end-disk centre and quaternion; JointState = bending angles in radians."""
    pose = messages.pose_message(solved, STAMP, 'base')
    assert pose['header'] == {'stamp': STAMP, 'frame_id': 'base'}
    assert [pose['pose']['position'][a] for a in 'xyz'] == solved.end_disk_position.tolist()
    assert [pose['pose']['orientation'][a] for a in 'xyzw'] == (
        solved.end_disk_quaternion_xyzw.tolist())
    joints = messages.joint_state_message(solved, STAMP, 'base')
    assert joints['name'] == list(messages.JOINT_NAMES)
    table = solved.to_dict()
    expected = [table['pj_bending_deg'], table['pj_direction_deg'], table['dj_bending_deg'],
                table['dj_direction_deg'], table['end_disk_rotation_deg']]
    assert np.allclose(np.degrees(joints['position']), expected, rtol=0, atol=1e-12)
    assert 22.0 < math.degrees(joints['position'][0]) < 22.6   # Table II: 22.448 deg


def test_backbone_markers_draw_the_solved_shape(solved, params):
    """Five line strips through the backbones, four disks at the frames, the rigid tube."""
    markers = messages.backbones_message(solved, params, STAMP, 'base')['markers']
    strips = [m for m in markers if m['ns'] == 'backbones']
    assert [m['type'] for m in strips] == [messages.MARKER_LINE_STRIP] * 5
    for strip, rod in zip(strips, solved.backbones):
        assert np.array_equal([[p['x'], p['y'], p['z']] for p in strip['points']], rod)
    disks = [m for m in markers if m['ns'] == 'disks']
    for disk, name in zip(disks, ('pe', 'pm', 'dm', 'de')):
        assert np.allclose([disk['pose']['position'][a] for a in 'xyz'],
                           solved.frames[name][:3, 3], atol=1e-15)
    (tube,) = [m for m in markers if m['ns'] == 'tube']
    assert tube['scale']['z'] == pytest.approx(params.tube_length, abs=1e-9)
    assert all(m['header']['frame_id'] == 'base' for m in markers)


def test_wrench_dict_round_trip():
    """wrench_message and wrench_from_message are inverse, for dicts and for objects."""
    message = messages.wrench_message([1.0, -2.0, 3.5], [0.1, 0.0, -0.2], 'base', STAMP)
    force, moment, frame_id, stamp = messages.wrench_from_message(message)
    assert force.tolist() == [1.0, -2.0, 3.5] and moment.tolist() == [0.1, 0.0, -0.2]
    assert (frame_id, stamp) == ('base', STAMP)
    assert messages.stamp_to_ns(stamp) == 1_700_000_000_123_456_789
    assert messages.stamp_from_ns(1_700_000_000_123_456_789) == STAMP


def test_diagnostics_and_output_messages(solved, params):
    """Converged: pose, angles, markers and an OK status; not converged: ERROR status only."""
    outputs = messages.output_messages(solved, STAMP, 'base', backbones_params=params,
                                       extra_values={'follower_solves': 3})
    topics = [topic for topic, _, _ in outputs]
    assert topics[:2] == [messages.END_DISK_POSE_TOPIC, messages.BENDING_ANGLES_TOPIC]
    assert topics[-2:] == [messages.BACKBONES_TOPIC, messages.SOLVE_STATUS_TOPIC]
    for topic, type_name, _ in outputs:
        assert messages.TOPIC_TYPES[topic] == type_name
    status = outputs[-1][2]['status'][0]
    values = {kv['key']: kv['value'] for kv in status['values']}
    assert status['level'] == messages.OK and values['converged'] == 'true'
    # the solver bounds the largest residual by 1e-10, so the norm of 90 by sqrt(90) times it
    assert values['follower_solves'] == '3' and float(values['residual_norm']) <= 1e-9
    failing = TranslatorSolver(params, time_limit_s=0.0).solve([20.0, 5.0, 0.0])
    assert not failing.converged
    outputs = messages.output_messages(failing, STAMP, 'base')
    assert [(topic, msg['status'][0]['level']) for topic, _, msg in outputs] == [
        (messages.SOLVE_STATUS_TOPIC, messages.ERROR)]
    assert outputs[0][2]['status'][0]['message'] == failing.message
    with pytest.raises(ValueError, match='level'):
        messages.diagnostics_message(STAMP, 7, 'x', {})
    with pytest.raises(ValueError, match='compliance'):
        messages.compliance_message(failing if getattr(failing, 'compliance', None) is None
                                    else solved)


def test_compliance_arrays_are_row_major_with_layout(params):
    """6x6 compliance: dims rows/cols, element (i, j) at 6 i + j; eigenvalues (6)."""
    solver = TranslatorSolver(params)
    result = solver.solve([12.0, 0.0, 0.0], compliance=True)
    matrix = messages.compliance_message(result)
    assert [(d['label'], d['size'], d['stride']) for d in matrix['layout']['dim']] == [
        ('rows', 6, 36), ('cols', 6, 6)]
    stored = np.array(matrix['data']).reshape(6, 6)
    assert np.array_equal(stored, result.compliance.matrix)
    eigen = messages.compliance_eigenvalues_message(result)
    assert eigen['data'] == [float(v) for v in result.compliance.eigenvalues]
    topics = [t for t, _, _ in messages.output_messages(result, STAMP, 'base')]
    assert messages.COMPLIANCE_TOPIC in topics and messages.COMPLIANCE_EIGENVALUES_TOPIC in topics
