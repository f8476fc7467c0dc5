"""Inverse statics along a path: secant slopes, extrapolated sliders, the cold start's work."""

from bench.delta_inverse import exact_slope_inverse
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.slider_path import SliderPath
from cdr_translator.robot.straight_legs import straight_leg_sliders
import numpy as np
import pytest

GRAVITY_1KG = (0.0, 0.0, -9.81)
START = np.array([0.002, -0.003, -0.13])
DIRECTION = np.array([0.6, 0.0, 0.8])


@pytest.fixture(scope='module')
def robots():
    """Build two shipped robots: inverse solves; forward checks and the exact-slope Newton."""
    return DeltaRobot(), DeltaRobot()


@pytest.fixture(scope='module')
def reference(robots):
    """Return the robot of the forward checks (no warm start shared with the inverse's)."""
    return robots[1]


@pytest.fixture(scope='module')
def path(robots):
    """Solve a cold start, then 12 steps of 1 mm along a line: the results."""
    robot = robots[0]
    results = [robot.inverse(START, GRAVITY_1KG, warm_start=False)]
    for step in range(1, 13):
        results.append(robot.inverse(START + 0.001 * step * DIRECTION, GRAVITY_1KG))
    return results


def test_every_step_reaches_its_target(path):
    """Each answer is within the tolerance, inside the stroke, on no limit."""
    for result in path:
        assert result.converged and result.reachable, result.message
        assert result.position_error <= result.tolerance == 1e-9
        assert result.binding == ()


def test_a_settled_path_step_needs_one_forward_solve(path):
    """
    Once the extrapolation has its points, a 1 mm step is one forward solve, no exact slope.

    The forward solve is warm and coupled (no full leg solve); its chain rebuilds its own
    factorization at most once (three leg Jacobians).
    """
    for result in path[6:]:
        assert result.forward_solves == 1
        assert result.iterations == 0
        assert result.exact_slopes == 0
        assert result.leg_solves == 0
        assert result.leg_jacobians <= 3


def test_every_path_step_needs_at_most_three_forward_solves(path):
    """The first steps (first-order prediction with the secant slope) correct once or twice."""
    for result in path[1:]:
        assert result.forward_solves <= 3
        assert result.exact_slopes == 0
    assert sum(result.forward_solves for result in path[1:]) <= 2 * (len(path) - 1)


def test_cold_start_is_one_cold_forward_solve_and_two_corrections(path, reference):
    """From the straight-leg guess: one cold forward solve with its slope, two warm ones."""
    cold = path[0]
    assert cold.exact_slopes == 1
    assert cold.forward_solves <= 3
    check = reference.solve(cold.sliders, GRAVITY_1KG, warm_start=False)
    # the legs are solved in full only by the cold forward solve
    assert cold.leg_solves <= check.leg_solves


def test_answers_equal_the_exact_slope_newtons(path, reference):
    """The exact-slope Newton (a forward solve with compliance per iterate) agrees."""
    sliders, slope, _ = exact_slope_inverse(reference, path[0].target, GRAVITY_1KG,
                                            warm_start=False)
    for previous, result in zip(path, path[1:]):
        assert np.abs(sliders - previous.sliders).max() < 1e-8
        guess = sliders + np.linalg.solve(slope, result.target - previous.target)
        sliders, slope, _ = exact_slope_inverse(reference, result.target, GRAVITY_1KG,
                                                sliders=guess)
    assert np.abs(sliders - path[-1].sliders).max() < 1e-8


def test_compliance_made_on_first_read_equals_the_eager_one(reference):
    """``forward`` adds the compliance when first read: that of a solve with compliance."""
    robot = DeltaRobot()
    result = robot.inverse(START, GRAVITY_1KG, warm_start=False)
    result = robot.inverse(START + 0.001 * DIRECTION, GRAVITY_1KG)
    assert result.solution is not None and result.solution.platform_compliance is None
    robot.inverse(START + 0.002 * DIRECTION, GRAVITY_1KG)  # the robot moves on
    forward = result.forward
    assert forward is result.solution and forward.platform_compliance is not None
    eager = reference.solve(result.sliders, GRAVITY_1KG, warm_start=False, compliance=True)
    assert forward.stable is eager.stable is True
    assert np.allclose(forward.platform_compliance, eager.platform_compliance,
                       rtol=1e-6, atol=1e-6 * np.abs(eager.platform_compliance).max())
    assert np.allclose(forward.input_sensitivity, eager.input_sensitivity,
                       rtol=1e-6, atol=1e-9)
    assert forward.stiffness_margin == pytest.approx(eager.stiffness_margin, rel=1e-6)
    data = result.to_dict()
    assert data['stable'] is True and len(data['platform_compliance']) == 6


def test_straight_leg_guess_is_near_the_sliders(reference):
    """The rigid-link inverse is exact at home and within a millimetre over 60 % stroke."""
    height = reference.params.stack_height
    home = straight_leg_sliders(reference.legs, height, reference.home_position)
    assert np.abs(home).max() < 1e-12
    rng = np.random.default_rng(5)
    stroke = reference.geometry.slider_stroke
    for sliders in rng.uniform(-0.6 * stroke, 0.6 * stroke, size=(4, 3)):
        position = reference.solve(sliders, GRAVITY_1KG, warm_start=False).platform_position
        guess = straight_leg_sliders(reference.legs, height, position)
        assert np.abs(guess - sliders).max() < 1e-3
        for leg, slider in zip(reference.legs, guess):
            length = np.linalg.norm(position + leg.attachment - leg.base(slider))
            assert length == pytest.approx(height, rel=1e-12)


def test_secant_update_reproduces_the_observed_step():
    """Broyden's update makes B exact along the step just taken, unchanged across it."""
    path = SliderPath()
    slope = np.diag([1.0, 2.0, 3.0])
    path.restart(slope, np.zeros(3), np.zeros(3))
    step, change = np.array([1e-3, 0.0, 0.0]), np.array([1.1e-3, 1e-4, 0.0])
    path.observe(step, change)
    assert path.slope is not None
    assert np.allclose(path.slope @ step, change, rtol=0, atol=1e-15)
    assert np.allclose(path.slope @ [0.0, 1.0, 1.0], slope @ [0.0, 1.0, 1.0])
    path.observe(step + 1e-9, change)  # shorter than SECANT_MIN_STEP: no update
    assert np.allclose(path.slope @ step, change, rtol=0, atol=1e-15)


def test_extrapolation_follows_a_polynomial_path_exactly():
    """Sliders cubic along equally spaced targets on a line: degree 3 and up are exact."""
    path = SliderPath()
    path.restart(np.eye(3) * 0.7, np.zeros(3), np.zeros(3))  # any slope: the rest is 0
    load = np.zeros(9)

    def sliders(t):
        return np.array([t, 0.5 * t ** 2, 2.0 * t ** 3 - t])

    for k in range(5):
        path.record(np.array([0.001 * k, 0.0, 0.0]), sliders(0.01 * k), np.zeros(3), load)
    predicted = path.predict(np.array([0.005, 0.0, 0.0]), load)
    assert np.allclose(predicted, sliders(0.05), rtol=0, atol=1e-15)
    # another load: the first-order prediction from the last solve
    other = path.predict(np.array([0.005, 0.0, 0.0]), np.ones(9))
    assert np.allclose(other, sliders(0.04) + np.array([0.001, 0.0, 0.0]) / 0.7)
