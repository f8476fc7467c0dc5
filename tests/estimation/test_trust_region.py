"""
The trust-region damping of a search step: the logarithmic grid's point just above the root.

The damping is defined as the smallest point of a DAMPING_GRID_POINTS logarithmic grid
whose step fits the radius; the search finds it from a Newton root of the secular
equation. Here against the definition: |p| at every grid point.
"""

from cdr_translator.estimation.search import (_boundary_damping, _grid_damping,
                                              DAMPING_GRID_POINTS)
import numpy as np
import pytest


def scanned_damping(weights: np.ndarray, squares: np.ndarray, radius: float) -> float:
    """Return the smallest grid point whose step fits the radius: every point evaluated."""
    top = float(np.linalg.norm(weights)) / radius
    grid = np.geomspace(max(1e-6 * squares[-1], 1e-12 * top), top, DAMPING_GRID_POINTS)
    sizes = np.linalg.norm(weights[None, :] / (squares[None, :] + grid[:, None]), axis=1)
    return float(grid[int(np.argmax(sizes <= radius))])


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
def test_the_damping_is_the_grid_point_the_scan_picks(weights, squares, radius):
    """The same grid point as scanning all of them (to the rounding of the points)."""
    expected = scanned_damping(weights, squares, radius)
    assert _grid_damping(weights, squares, radius) == pytest.approx(expected, rel=1e-13)


@pytest.mark.parametrize('weights, squares, radius', list(problems(100)))
def test_the_root_puts_the_step_on_the_radius(weights, squares, radius):
    """Newton on the secular equation: |p(lambda)| = radius to 1e-10, lambda > 0."""
    damping = _boundary_damping(weights, squares, radius)
    assert damping > 0.0
    assert np.linalg.norm(weights / (squares + damping)) == pytest.approx(radius, rel=1e-9)
