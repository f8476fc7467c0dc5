"""The chain's predictors along an atlas grid: exact on the paths whose order they match."""

from cdr_translator.robot.chain import ChainState, difference
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.grid_predictor import GridPredictor
import numpy as np

GRAVITY_1KG = (0.0, 0.0, -9.81)
LEG_UNKNOWNS = 5
#: Flat scale of the platform unknowns (position, rotation, wrenches) in these paths.
X_SCALE = np.concatenate([np.full(3, 0.1), np.ones(3), np.full(18, 2.0)])


def _state(flat: np.ndarray) -> ChainState:
    """Return a chain state at flat unknowns (platform times X_SCALE, then legs), not turned."""
    platform = flat[:24] * X_SCALE
    return ChainState(platform[:3].copy(), np.eye(3), platform[6:24].reshape(3, 6).copy(),
                      flat[24:].reshape(3, LEG_UNKNOWNS).copy())


def _reached(state: ChainState, step: np.ndarray) -> np.ndarray:
    """Return the flat unknowns of ``state`` moved by a predicted ``step``."""
    return difference(state.moved(step, X_SCALE), _state(np.zeros(24 + 3 * LEG_UNKNOWNS)),
                      X_SCALE)


def _unturned(coefficients: np.ndarray) -> np.ndarray:
    """Coefficients with no platform rotation (the predictors' steps then add exactly)."""
    coefficients = coefficients.copy()
    coefficients[..., 3:6] = 0.0
    return coefficients


def test_hermite_along_a_line_is_exact_for_a_cubic_path():
    """Equal steps along a cubic path: the third point follows from two and their tangents."""
    rng = np.random.default_rng(3)
    a, b, c, d = _unturned(rng.normal(size=(4, 24 + 3 * LEG_UNKNOWNS)))

    def point(s):
        return a + b * s + c * s ** 2 + d * s ** 3

    def tangent(s):  # per input step
        return b + 2.0 * c * s + 3.0 * d * s ** 2
    step = np.zeros(12)
    step[0] = 0.01
    predictor = GridPredictor(X_SCALE)
    first = _state(point(0.0))
    assert predictor.predict(first, np.zeros(12), step, tangent(0.0)) is None
    second = _state(point(1.0))
    predictor.reached(second)
    predicted = predictor.predict(second, step, step, tangent(1.0))
    assert predicted is not None
    assert np.allclose(_reached(second, predicted), point(2.0), rtol=0.0, atol=1e-12)
    # a different step is not the same line: no Hermite, and no curvature that far
    predictor.reached(_state(point(2.0)))
    assert predictor.predict(_state(point(2.0)), 2.0 * step, 3.0 * step, tangent(2.0)) is None


def test_curvature_of_a_nearby_step_is_exact_for_a_quadratic_path():
    """A turn: the curvature of the parallel step one line back predicts a quadratic path."""
    rng = np.random.default_rng(5)
    a, b, c, g = _unturned(rng.normal(size=(4, 24 + 3 * LEG_UNKNOWNS)))

    def point(u, v):  # quadratic along slider 1, linear along slider 2
        return a + b * u + c * u ** 2 + g * v

    step = np.zeros(12)
    step[0] = 0.01
    aside = np.zeros(12)
    aside[1] = 0.01
    predictor = GridPredictor(X_SCALE)
    start = _state(point(0.0, 0.0))
    # taken backwards (-step), from u = 1 to u = 0: its curvature is the same
    back = _state(point(1.0, 0.0))
    predictor.predict(back, step, -step, -(b + 2.0 * c))
    predictor.reached(start)
    turned = _state(point(0.0, 1.0))
    predictor.predict(start, np.zeros(12), aside, g)  # the turn, no curvature for it
    predictor.reached(turned)
    predicted = predictor.predict(turned, aside, step, b)
    assert predicted is not None
    assert np.allclose(_reached(turned, predicted), point(1.0, 1.0), rtol=0.0, atol=1e-12)


def test_solves_along_a_line_equal_cold_solves():
    """Compliance solves along equal slider steps (the predictors' case) equal cold solves."""
    robot = DeltaRobot()
    cold = DeltaRobot()
    for slider in (0.0, 0.01, 0.02, 0.03):
        sliders = (slider, -0.01, 0.005)
        warm = robot.solve(sliders, GRAVITY_1KG, compliance=True)
        direct = cold.solve(sliders, GRAVITY_1KG, warm_start=False, compliance=True)
        assert warm.converged and direct.converged
        assert np.allclose(warm.platform_position, direct.platform_position, atol=1e-9)
        assert np.allclose(warm.platform_compliance, direct.platform_compliance,
                           rtol=1e-6, atol=1e-6 * np.abs(direct.platform_compliance).max())
        assert warm.stable is direct.stable
