"""DeltaRobot.estimate_payload: the payload back from the platform pose it gives."""

import json
import math

from cdr_translator.robot import DeltaRobot, PayloadEstimate
import numpy as np
import pytest

SLIDERS = np.array([0.006, -0.004, 0.002])


@pytest.fixture(scope='module')
def robots():
    """Two robots: one solves the payloads, the other estimates them (warm along its own)."""
    return DeltaRobot(), DeltaRobot()


def test_payload_estimate_of_a_solved_pose_is_its_payload(robots):
    """
    Platform pose -> payload to 1e-6 (relative), with its covariance and verdict.

    The covariance (0.1 nm, 1e-10 rad) makes the pose all but exact: the three legs hold
    the platform so stiffly that at 1 um the 25 N prior still sets the payload force.
    """
    forward, estimator = robots
    length = forward.params.stack_height
    scale = np.repeat([1.0, length], 3)
    for payload in ([0.8, -0.5, -9.81, 0.02, -0.01, 0.01], [1.5, 0.4, -6.0, -0.03, 0.0, 0.02]):
        payload = np.array(payload)
        solved = forward.solve(SLIDERS, payload[:3], payload[3:])
        assert solved.converged, solved.message
        estimate = estimator.estimate_payload(solved.platform_position, SLIDERS,
                                              solved.platform_quaternion_xyzw,
                                              covariance=np.diag(np.repeat([1e-20, 1e-20], 3)))
        assert isinstance(estimate, PayloadEstimate)
        assert estimate.converged and estimate.accuracy_met and estimate.stable, \
            estimate.message
        error = np.linalg.norm((estimate.wrench - payload) / scale)
        assert error < 1e-6 * np.linalg.norm(payload / scale), (estimate.wrench, payload)
        assert estimate.covariance.shape == (6, 6) and np.all(np.diag(estimate.covariance) > 0)
        np.testing.assert_array_equal(estimate.sliders, SLIDERS)
        data = json.loads(json.dumps(estimate.to_dict()))
        assert data['sliders'] == SLIDERS.tolist() and data['estimated'] == 'wrench'


def test_platform_position_gives_the_payload_force(robots):
    """A platform position alone gives the force (no moment), the moment staying zero."""
    forward, estimator = robots
    force = np.array([-0.7, 1.1, -8.0])
    solved = forward.solve(SLIDERS, force)
    estimate = estimator.estimate_payload(solved.platform_position, SLIDERS,
                                          covariance=np.eye(3) * 1e-20)
    assert estimate.converged and estimate.estimated == 'force', estimate.message
    np.testing.assert_allclose(estimate.force, force, rtol=0, atol=1e-6 * np.linalg.norm(force))
    assert not estimate.moment.any() and math.isnan(estimate.residual_deg)
    assert not estimate.covariance[3:].any()


def test_payload_estimate_bad_input_is_a_value_error(robots):
    """Sliders out of the stroke, a bad quaternion or covariance: ValueError naming it."""
    estimator = robots[1]
    with pytest.raises(ValueError, match='slider 1'):
        estimator.estimate_payload([0.0, 0.0, -0.15], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match='platform_quaternion_xyzw'):
        estimator.estimate_payload([0.0, 0.0, -0.15], SLIDERS, [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match='covariance must be 6x6'):
        estimator.estimate_payload([0.0, 0.0, -0.15], SLIDERS, [0.0, 0.0, 0.0, 1.0],
                                   covariance=np.eye(3))
    with pytest.raises(ValueError, match='max_force must be'):
        estimator.estimate_payload([0.0, 0.0, -0.15], SLIDERS, max_force=-1.0)


def test_a_pose_only_a_payload_past_the_limits_matches_is_unmatched(robots):
    """
    A platform 1 cm off its solved place (a tracker frame off by that much): unmatched.

    Without limits the search matches it with about 500 N; with cdr_node's 100 N it tries
    no larger payload and says which limit it met.
    """
    forward, estimator = robots
    solved = forward.solve(SLIDERS, [0.0, 0.0, -9.81])
    position = solved.platform_position + np.array([0.01, 0.0, 0.0])
    covariance = np.eye(3) * 0.2e-3 ** 2
    unbounded = DeltaRobot().estimate_payload(position, SLIDERS, covariance=covariance)
    assert np.linalg.norm(unbounded.force) > 100.0
    estimate = DeltaRobot().estimate_payload(position, SLIDERS, covariance=covariance,
                                             max_force=100.0, max_moment=10.0)
    assert not estimate.converged and not estimate.accuracy_met
    assert estimate.flags[0] == ('no nearby wrench lowers the pose residual: no equilibrium '
                                 'matches the measured pose within |f| <= 100 N (max_force)')
    assert np.linalg.norm(estimate.force) <= 100.0
