"""
The trust-region step of a search: the Gauss-Newton step when it fits, else on the radius.

A step on the radius, not inside it: the radius grows only after a step that reached it
(search.search), so a step held inside would keep a search creeping at one length.
"""

from cdr_translator.estimation.search import _boundary_damping, _trust_region_step
import numpy as np
import pytest


def problems(count: int):
    """Yield (weights, squares, radius): 2-6 singular values over 7 decades, radius inside."""
    rng = np.random.default_rng(11)
    for _ in range(count):
        size = rng.integers(2, 7)
        values = np.sort(10.0 ** rng.uniform(-3.0, 4.0, size))[::-1]
        weights = values * rng.normal(0.0, 1.0, size) * 10.0 ** rng.uniform(-2.0, 3.0)
        squares = values ** 2
        newton = float(np.linalg.norm(weights / squares))
        yield weights, squares, newton * 10.0 ** rng.uniform(-6.0, -1e-3)


@pytest.mark.parametrize('weights, squares, radius', list(problems(100)))
def test_the_root_puts_the_step_on_the_radius(weights, squares, radius):
    """Newton on the secular equation: |p(lambda)| = radius to 1e-10, lambda > 0."""
    damping = _boundary_damping(weights, squares, radius)
    assert damping > 0.0
    assert np.linalg.norm(weights / (squares + damping)) == pytest.approx(radius, rel=1e-9)


@pytest.mark.parametrize('weights, squares, radius', list(problems(30)))
def test_a_step_that_does_not_fit_is_the_constrained_minimum_on_the_radius(
        weights, squares, radius):
    """
    On the radius, and no point of the ball models a lower cost.

    The model cost |r + J p|^2 (U^T r = projected, rotated by a random V) against 2000
    random points within the radius: none is lower (Nocedal & Wright, Theorem 4.1).
    """
    rng = np.random.default_rng(3)
    values = np.sqrt(squares)
    projected = weights / values
    right = np.linalg.qr(rng.normal(size=(len(values), len(values))))[0]
    step = _trust_region_step(values, right, projected, radius)
    assert np.linalg.norm(step) == pytest.approx(radius, rel=1e-9)

    def model(points: np.ndarray) -> np.ndarray:
        return np.sum((projected + values * (points @ right.T)) ** 2, axis=-1)
    directions = rng.normal(size=(2000, len(values)))
    points = (directions / np.linalg.norm(directions, axis=1)[:, None]
              * radius * rng.uniform(0.0, 1.0, (2000, 1)) ** (1.0 / len(values)))
    assert model(step) <= model(points).min() * (1.0 + 1e-12) + 1e-300


def test_the_gauss_newton_step_is_taken_when_it_fits():
    """Within the radius: the undamped step, which zeroes the model residual."""
    values, projected = np.array([3.0, 0.5]), np.array([1.5, -0.25])
    right = np.eye(2)
    step = _trust_region_step(values, right, projected, 10.0)
    np.testing.assert_allclose(projected + values * (right @ step), 0.0, atol=1e-15)
