"""The compiled Newton-Broyden loop (cdr_translator/bvp/chord.py) against plain linear algebra."""

import gc
import math
import tracemalloc
import warnings

from cdr_translator import _linalg
from cdr_translator.bvp import chord
import numpy as np
import pytest
from scipy.linalg import lu_factor, lu_solve


@pytest.fixture
def factorized():
    """Return a random well-conditioned 40x40 matrix and scipy's LU factors of it."""
    rng = np.random.default_rng(7)
    matrix = rng.normal(size=(40, 40)) + 8.0 * np.eye(40)
    return matrix, lu_factor(matrix)


@pytest.mark.parametrize('order', ['F', 'C'])
def test_lu_solve_matches_lapack(factorized, order):
    """The compiled substitutions give LAPACK's solution (pivoting included), either layout."""
    matrix, (lu, pivots) = factorized
    assert lu.flags.f_contiguous  # lu_factor's layout: the column sweeps
    rhs = np.random.default_rng(8).normal(size=40)
    out = np.empty(40)
    _linalg.lu_solve(np.asarray(lu, order=order), pivots, rhs, out)
    assert np.allclose(out, lu_solve((lu, pivots), rhs), rtol=0, atol=1e-12)
    assert np.allclose(matrix @ out, rhs, atol=1e-10)


def test_broyden_updates_meet_the_secant_condition(factorized):
    """After the update from (s, y), H y = s: the defining property of Broyden's formula."""
    _, (lu, pivots) = factorized
    rng = np.random.default_rng(9)
    updates = np.empty((4, 40))
    steps = np.empty((4, 40))
    for count in range(3):
        step, change = rng.normal(size=40), rng.normal(size=40)
        mapped = np.empty(40)
        chord.broyden_apply(lu, pivots, updates, steps, count, change, mapped)
        updates[count] = (step - mapped) / (step @ mapped)
        steps[count] = step
        after = np.empty(40)
        chord.broyden_apply(lu, pivots, updates, steps, count + 1, change, after)
        assert np.allclose(after, step, atol=1e-10)


def test_chord_iterations_converge_on_the_translator(solver):
    """From a perturbed solution, on the factorization at the solution, chord steps converge."""
    problem = solver.problem
    wrench = np.array([12.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    solution = solver.solve(wrench[:3]).unknowns / problem.x_scale
    factorization = lu_factor(problem.exact_jacobian(solution, wrench)[1])
    xs = solution * (1.0 + 1e-4 * np.random.default_rng(3).normal(size=problem.size))
    rs = problem.residual_and_shape(xs, wrench)
    status, iterations, norm, slot = problem.chord_newton(
        xs, rs, wrench, factorization, False, 1e-10, 40, 0.9, 0)
    assert status == chord.CONVERGED, status
    assert 0 < iterations <= 40
    assert np.abs(rs).max() <= 1e-10 and norm == pytest.approx(np.linalg.norm(rs))
    assert np.allclose(xs, solution, atol=1e-7)
    points, frames = problem.recorded_shape(slot)
    expected_points, expected_frames = problem.shape(xs, wrench)
    assert np.allclose(frames, expected_frames, atol=1e-14)
    assert np.allclose(points, expected_points, atol=1e-14)


def test_a_stale_factorization_asks_for_a_new_one(solver):
    """Chord steps on a factorization from another load that shrink the residual too little."""
    problem = solver.problem
    nearby = solver.solve([10.0, 0.0, 0.0]).unknowns / problem.x_scale
    stale = lu_factor(problem.exact_jacobian(nearby, np.array([10.0, 0, 0, 0, 0, 0]))[1])
    wrench = np.array([12.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    solution = solver.solve(wrench[:3]).unknowns / problem.x_scale
    xs = solution * (1.0 + 1e-4 * np.random.default_rng(3).normal(size=problem.size))
    rs = problem.residual_and_shape(xs, wrench)
    start = np.linalg.norm(rs)
    status, iterations, norm, _ = problem.chord_newton(
        xs, rs, wrench, stale, False, 1e-10, 40, 0.9, 0)
    assert status == chord.REFACTOR
    assert iterations >= 1 and norm < start  # the steps it took were accepted descents


def test_extrapolation_is_exact_on_a_quadratic_path(factorized):
    """Unknowns quadratic in the length of a straight wrench path: extrapolated exactly."""
    _, (lu, pivots) = factorized
    rng = np.random.default_rng(11)
    a, b, c = rng.normal(size=(3, 40))
    start, direction = rng.normal(size=6), rng.normal(size=6)
    scale = np.array([2.0, 2.0, 2.0, 0.5, 0.5, 0.5])
    direction /= np.linalg.norm(direction / scale)  # unit path length per unit t
    times = np.array([-0.7, -0.3, 0.0])  # unequal steps; the new wrench at t = 0.5
    path_xs = np.array([a + b * t + c * t * t for t in times])
    path_wrenches = np.array([start + t * direction for t in times])
    out = np.empty(40)
    assert chord.extrapolate(path_xs, path_wrenches, 3, start + 0.5 * direction, scale,
                             np.ones(6), np.arange(34, 40), lu, pivots, np.empty((1, 40)),
                             np.empty((1, 40)), 0, 0.5, out)
    assert np.allclose(out, a + 0.5 * b + 0.25 * c, rtol=0, atol=1e-12)


def test_five_solutions_extrapolate_a_quartic_path_exactly(factorized):
    """A straight path lands every degree on the wrench: the highest (4) is used, exact."""
    _, (lu, pivots) = factorized
    rng = np.random.default_rng(12)
    coefficients = rng.normal(size=(5, 40))
    start, direction = rng.normal(size=6), rng.normal(size=6)
    scale = np.array([2.0, 2.0, 2.0, 0.5, 0.5, 0.5])
    direction /= np.linalg.norm(direction / scale)
    times = np.array([-1.3, -0.9, -0.7, -0.3, 0.0])
    path_xs = np.array([sum(c * t ** power for power, c in enumerate(coefficients))
                        for t in times])
    path_wrenches = np.array([start + t * direction for t in times])
    out = np.empty(40)
    assert chord.extrapolate(path_xs, path_wrenches, 5, start + 0.4 * direction, scale,
                             np.ones(6), np.arange(34, 40), lu, pivots, np.empty((1, 40)),
                             np.empty((1, 40)), 0, 0.5, out)
    expected = sum(c * 0.4 ** power for power, c in enumerate(coefficients))
    assert np.allclose(out, expected, rtol=0, atol=1e-10)


def test_scattered_older_wrenches_fall_back_to_a_lower_degree(factorized):
    """Older solutions off the path miss the wrench: the quadratic of the last three is used."""
    _, (lu, pivots) = factorized
    rng = np.random.default_rng(13)
    a, b, c = rng.normal(size=(3, 40))
    direction = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    times = np.array([-1.2, -0.9, -0.6, -0.3, 0.0])
    path_wrenches = np.array([t * direction for t in times])
    path_wrenches[0, 1], path_wrenches[1, 1] = 0.2, -0.15  # the two oldest off the line
    path_xs = np.array([a + b * t + c * t * t for t in times])
    path_xs[:2] += 5.0  # and their unknowns: using them would show
    out = np.empty(40)
    assert chord.extrapolate(path_xs, path_wrenches, 5, 0.3 * direction, np.ones(6),
                             np.zeros(6), np.arange(34, 40), lu, pivots, np.empty((1, 40)),
                             np.empty((1, 40)), 0, 10.0, out)
    assert np.allclose(out, a + 0.3 * b + 0.09 * c, rtol=0, atol=1e-12)


def test_a_wrench_off_the_path_is_not_extrapolated(factorized):
    """A wrench that turns away from the path (or lies far ahead) gets no extrapolation."""
    _, (lu, pivots) = factorized
    path_xs = np.zeros((3, 40))
    path_wrenches = np.array([[0.0] * 6, [1.0] + [0.0] * 5, [2.0] + [0.0] * 5])
    out = np.empty(40)
    arguments = (np.ones(6), np.ones(6), np.arange(34, 40), lu, pivots, np.empty((1, 40)),
                 np.empty((1, 40)), 0, 0.5, out)
    assert chord.extrapolate(path_xs, path_wrenches, 3, np.array([3.0] + [0.0] * 5),
                             *arguments)
    assert not chord.extrapolate(path_xs, path_wrenches, 3, np.array([2.0, 1.0, 0, 0, 0, 0]),
                                 *arguments)  # turned by 90 degrees: misses by the step
    assert not chord.extrapolate(path_xs, path_wrenches, 3, np.array([7.0] + [0.0] * 5),
                                 *arguments)  # more than twice the path's length ahead


def test_chord_calls_leave_nothing_for_the_garbage_collector(solver):
    """
    Calls into the compiled loop allocate nothing that outlives them.

    With the collector off, 300 calls leave under 5 kB (a twenty-argument kernel left 400
    bytes per call, freed only at the next collection).
    """
    problem = solver.problem
    wrench = np.array([3.0, 1.0, 0.0, 0.0, 0.0, 0.05])
    solution = solver.solve(wrench[:3], wrench[3:]).unknowns / problem.x_scale
    factorization = lu_factor(problem.exact_jacobian(solution, wrench)[1])

    def calls(count, shoot):
        for _ in range(count):
            xs = solution * 1.0001
            rs = np.empty(problem.size) if shoot else problem.residual(xs, wrench)
            status = problem.chord_newton(xs, rs, wrench, factorization, True, 1e-12, 10, 0.5,
                                          0, shoot)[0]
            assert status == chord.CONVERGED

    calls(5, True)
    gc.collect()
    gc.disable()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        calls(150, True)
        calls(150, False)
        left = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
        gc.enable()
    assert left < 5_000, left


def test_norm_matches_numpy_and_overflows_quietly():
    """_linalg.norm is the Euclidean norm; huge entries give inf and NaN stays NaN, no warning."""
    values = np.random.default_rng(3).standard_normal(90)
    assert _linalg.norm(values) == pytest.approx(np.linalg.norm(values), rel=1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert _linalg.norm(np.full(90, 1e200)) == math.inf
        assert math.isnan(_linalg.norm(np.array([math.nan, 1.0])))
