"""The path predictor of warm solves with reduced legs (robot/chain_path.py)."""

import math

from cdr_translator.robot.chain_path import DEGREE, extrapolate, point_width, push
from cdr_translator.robot.delta import DeltaRobot
import numpy as np
from scipy.spatial.transform import Rotation

SIZE = 8  # a 'cc' leg's reduced unknowns


def _state(t: float) -> tuple:
    """Return the state at t on a path cubic in t (the rotation: by an angle linear in t)."""
    position = np.array([1.0, -2.0, 0.5]) * t + np.array([0.3, 0.0, -1.0]) * t ** 3
    rotation = Rotation.from_rotvec(np.array([0.1, 0.2, -0.05]) * t).as_matrix()
    wrenches = np.arange(18.0).reshape(3, 6) * t ** 2
    leg_x = np.linspace(-1.0, 1.0, 3 * SIZE).reshape(3, SIZE) * (t - 0.5 * t ** 3)
    return position, rotation, wrenches, leg_x


def _path(times: list) -> tuple:
    points = np.zeros((DEGREE + 1, point_width(SIZE)))
    seen = np.zeros((DEGREE + 1, 12))
    count = np.zeros(1, dtype=np.int64)
    for t in times:
        inputs = np.zeros(12)
        inputs[:3] = t
        push(points, seen, count, *_state(t), np.zeros((3, 4, 4)), inputs)
    return points, seen, count


def test_predictor_is_exact_on_a_cubic_path_and_declines_a_jump():
    """Steady inputs: the cubic through the last four points; a jump: no prediction."""
    step = 0.05
    points, seen, count = _path([step * k for k in range(6)])  # keeps the last four
    assert count[0] == DEGREE + 1
    state = [np.empty(3), np.empty((3, 3)), np.empty((3, 6)), np.empty((3, SIZE))]
    inputs = np.zeros(12)
    inputs[:3] = 6 * step
    assert extrapolate(points, seen, count, inputs, np.ones(12), *state)
    expected = _state(6 * step)
    for made, wanted in zip(state[::2], expected[::2]):
        np.testing.assert_allclose(made, wanted, atol=1e-12)
    np.testing.assert_allclose(state[3], expected[3], atol=1e-12)
    # the rotation, extrapolated by entries, is orthonormal and within the path's order
    np.testing.assert_allclose(state[1] @ state[1].T, np.eye(3), atol=1e-12)
    assert np.abs(state[1] - expected[1]).max() < 1e-5
    inputs[:3] = 1.0  # far off the path: the rest exceeds the change's half
    inputs[5] = 1.0
    assert not extrapolate(points, seen, count, inputs, np.ones(12), *state)


def test_warm_solves_along_a_circle_equal_cold_ones():
    """Warm solves started by the predictor reach the cold answers, compliance and verdicts."""
    robot = DeltaRobot(fidelity='cc')
    cold = DeltaRobot(fidelity='cc')
    for step in range(10):
        angle = math.radians(3.0 * step)
        sliders = [0.01 * math.sin(angle + 2.0 * math.pi * k / 3) for k in range(3)]
        compliance = step % 4 == 3
        warm = robot.solve(sliders, (0.0, 0.0, -9.81), compliance=compliance)
        reference = cold.solve(sliders, (0.0, 0.0, -9.81), warm_start=False,
                               compliance=compliance)
        assert warm.converged and reference.converged
        np.testing.assert_allclose(warm.platform_position, reference.platform_position,
                                   atol=1e-9)
        np.testing.assert_allclose(warm.leg_tip_wrenches, reference.leg_tip_wrenches,
                                   atol=1e-6)
        if compliance:
            np.testing.assert_allclose(warm.platform_compliance,
                                       reference.platform_compliance, rtol=1e-6, atol=1e-12)
            assert warm.stable is reference.stable
            assert [verdict.stable for verdict in warm.leg_stability] \
                == [verdict.stable for verdict in reference.leg_stability]
