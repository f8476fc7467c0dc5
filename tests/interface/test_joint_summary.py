"""Joint angle summaries: ranges, and circular statistics for the bending directions."""

import math

from cdr_translator.interface import messages
from cdr_translator.interface.joint_summary import CIRCULAR_JOINT_NAMES, JointSummary
import numpy as np
from scipy import stats

DIRECTIONS = [messages.JOINT_NAMES.index(name) for name in CIRCULAR_JOINT_NAMES]


def test_running_sums_equal_scipy_circmean_and_circstd():
    """Added one by one or as rows: scipy's circmean / circstd (high=π, low=-π), and ranges."""
    rng = np.random.default_rng(3)
    joints = rng.uniform(-math.pi, math.pi, size=(200, len(messages.JOINT_NAMES)))
    joints[:, DIRECTIONS] = np.angle(np.exp(1j * rng.normal(3.0, 0.4, size=(200, 2))))
    one_by_one, at_once = JointSummary(), JointSummary()
    for row in joints:
        one_by_one.add(list(row))
    at_once.add(joints)
    for summary in (one_by_one, at_once):
        assert summary.count == 200
        assert np.allclose(summary.circular_mean(),
                           stats.circmean(joints, high=math.pi, low=-math.pi, axis=0))
        assert np.allclose(summary.circular_std(),
                           stats.circstd(joints, high=math.pi, low=-math.pi, axis=0))
        assert np.array_equal(summary.low, joints.min(axis=0))
        assert np.array_equal(summary.high, joints.max(axis=0))


def test_rows_give_directions_by_circular_mean_and_std():
    """Two loads in one direction, either side of ±180°: mean ±180, spread ~0; the rest ranges."""
    summary = JointSummary()
    summary.add([0.1, math.pi - 1e-7, 0.2, -1e-7, 0.01])
    summary.add([0.3, -math.pi + 1e-7, 0.4, 1e-7, 0.02])
    rows = dict(summary.rows())
    assert rows['pj_direction deg'] in ('circular mean 180.000, circular std 0.000',
                                        'circular mean -180.000, circular std 0.000')
    assert rows['dj_direction deg'] == 'circular mean 0.000, circular std 0.000'
    assert rows['pj_bending deg min..max'] == f'{math.degrees(0.1):.3f} .. {math.degrees(0.3):.3f}'
    assert 'pj_direction deg min..max' not in rows and len(rows) == 5
    assert JointSummary().rows() == []


def test_directions_that_cancel_have_no_mean():
    """Opposite directions: no mean direction, the spread is infinite."""
    summary = JointSummary()
    summary.add([0.0, 0.5 * math.pi, 0.0, 0.0, 0.0])
    summary.add([0.0, -0.5 * math.pi, 0.0, 0.0, 0.0])
    assert math.isnan(summary.circular_mean()[1]) and summary.circular_std()[1] == math.inf
    assert dict(summary.rows())['pj_direction deg'] == (
        'circular mean none (the directions cancel), circular std inf')
