"""The exact (tangent-linear) Jacobian against central differences of the residual."""

from dataclasses import replace

from cdr_translator import TranslatorSolver
from cdr_translator._jit import interpreted_kernels
from cdr_translator.bvp import rod
from cdr_translator.bvp.problem import Problem
import numpy as np
import pytest

#: (force, moment) loads whose solutions the random states scatter around: small, large
#: bends (100 N lateral: about 60 deg per joint), torsion, compression
LOADS = [((5.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
         ((100.0, -40.0, 10.0), (0.0, 0.0, 0.0)),
         ((30.0, 10.0, -5.0), (0.5, -0.3, 2.0)),
         ((0.0, 0.0, -20.0), (1.0, 1.0, 0.0))]


def _central(problem: Problem, xs: np.ndarray, wrench: np.ndarray, step: float) -> np.ndarray:
    """Central-difference Jacobian with nondimensional ``step``."""
    jacobian = np.empty((problem.size, problem.size))
    for column in range(problem.size):
        probe = np.zeros(problem.size)
        probe[column] = step
        jacobian[:, column] = (problem.residual(xs + probe, wrench)
                               - problem.residual(xs - probe, wrench)) / (2.0 * step)
    return jacobian


def _richardson(problem: Problem, xs: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """
    Central differences with their h^2 truncation error extrapolated away (Richardson).

    Off a solution at 100 N lateral plain central differences are off by up to 2e-4
    relative at a 1e-5 step, the error falling exactly as h^2 down to 1e-6 (so the exact
    Jacobian is their limit); extrapolating two steps leaves O(h^4) and rounding, ~1e-8.
    """
    coarse = _central(problem, xs, wrench, 2e-5)
    fine = _central(problem, xs, wrench, 1e-5)
    return (4.0 * fine - coarse) / 3.0


def _column_error(exact: np.ndarray, reference: np.ndarray) -> float:
    """Largest difference in any column relative to that column's largest entry."""
    scale = np.maximum(np.abs(reference).max(axis=0), 1e-12)
    return float((np.abs(exact - reference).max(axis=0) / scale).max())


@pytest.mark.parametrize('spacers', [1, 2])
def test_exact_jacobian_equals_central_differences(params, solver, spacers):
    """At random states near loaded solutions, incl. large bends, to <= 1e-6 relative."""
    chosen = replace(params, spacers_per_joint=spacers)
    problem = Problem(chosen)
    if spacers != params.spacers_per_joint:
        solver = TranslatorSolver(chosen)
    rng = np.random.default_rng(13 + spacers)
    for force, moment in LOADS:
        wrench = np.concatenate([force, moment])
        solver.reset()
        result = solver.solve(force, moment)
        assert result.converged, result.message
        xs = result.unknowns / problem.x_scale
        xs = xs + 0.02 * rng.standard_normal(problem.size)  # off the solution: any state
        rs, exact, pose = problem.exact_jacobian(xs, wrench)
        np.testing.assert_allclose(rs, problem.residual(xs, wrench), rtol=0, atol=1e-13)
        assert _column_error(exact, _richardson(problem, xs, wrench)) <= 1e-6
        # the end-disk pose derivative, against central differences of the frame
        step = 1e-6
        for column in rng.choice(problem.size, 6, replace=False):
            probe = np.zeros(problem.size)
            probe[column] = step
            plus = problem.residual_and_end_frame(xs + probe, wrench)[1]
            minus = problem.residual_and_end_frame(xs - probe, wrench)[1]
            central = np.concatenate([(plus[:3, 3] - minus[:3, 3]),
                                      (plus[:3, :3] - minus[:3, :3]).ravel()]) / (2 * step)
            assert np.abs(pose[:, column] - central).max() <= 1e-6 * max(
                np.abs(central).max(), 1e-3)


def test_fd_jacobian_stays_selectable(params):
    """jacobian='fd' gives forward-difference Jacobians (residual, pose), near the exact."""
    exact, fd = Problem(params), Problem(params, jacobian='fd')
    wrench = np.array([12.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    xs = exact.straight_guess(wrench)
    rs = exact.residual(xs, wrench)
    assert _column_error(fd.jacobian(xs, wrench, rs), exact.jacobian(xs, wrench, rs)) < 1e-4
    assert np.abs(fd.pose_jacobian - exact.pose_jacobian).max() < 1e-4 * np.abs(
        exact.pose_jacobian).max()
    with pytest.raises(ValueError, match='jacobian'):
        Problem(params, jacobian='central')


#: A segment state off the rotation group (R(0) is not orthogonal, as RK4 leaves it): the
#: local derivative is along all 9 entries of R(0), not along rotations only.
SEGMENT_ROT = np.array([[0.96, -0.2, 0.15], [0.22, 0.97, -0.05], [-0.14, 0.08, 0.99]])
SEGMENT_N = np.array([30.0, -12.0, 8.0])
SEGMENT_M = np.array([0.2, -0.35, 0.05])
SEGMENT_LENGTH = 0.03


def _segment_end(rot, n, m, length):
    """(p_end - p_start, R_end row-major, m_end) of one integrate_segment call, 15 values."""
    inv_kse, inv_kbt = rod.inverse_stiffness(88.4e9, 33.2e9, 1.2e-3)
    p, rot, m = np.array([0.01, -0.02, 0.005]), rot.copy(), m.copy()
    start = p.copy()
    rod.integrate_segment(p, rot, n.copy(), m, length, 8, inv_kse, inv_kbt, np.empty((0, 3)), 0,
                          np.empty(rod.SEGMENT_SCRATCH))
    return np.concatenate([p - start, rot.ravel(), m])


def _segment_tangent(kernels, active):
    """End state (15 values) and local derivative of integrate_segment_tangent in ``kernels``."""
    inv_kse, inv_kbt = rod.inverse_stiffness(88.4e9, 33.2e9, 1.2e-3)
    p, rot, m = np.array([0.01, -0.02, 0.005]), SEGMENT_ROT.copy(), SEGMENT_M.copy()
    start = p.copy()
    local = np.full((kernels.LOCAL_OUTPUTS, kernels.LOCAL_DIRECTIONS), np.nan)
    kernels.integrate_segment_tangent(p, rot, SEGMENT_N.copy(), m, SEGMENT_LENGTH, 8, inv_kse,
                                      inv_kbt, active, local)
    return np.concatenate([p - start, rot.ravel(), m]), local


def test_segment_tangent_equals_central_differences():
    """
    rod.integrate_segment_tangent gives integrate_segment's end state and its derivative.

    Per direction, against central differences (Richardson-extrapolated), to 1e-9 of the
    column; a subset of active directions gives the same columns and zeros elsewhere; the
    interpreted source (method='paper' imports it) gives the same numbers.
    """
    every = np.ones(rod.LOCAL_DIRECTIONS, dtype=np.bool_)
    end, local = _segment_tangent(rod, every)
    inputs = (SEGMENT_ROT, SEGMENT_N, SEGMENT_M, SEGMENT_LENGTH)
    np.testing.assert_allclose(end, _segment_end(*inputs), rtol=0, atol=1e-13)
    scales = [1e-3] * 9 + [1e-2] * 3 + [1e-4] * 3 + [1e-5]

    def moved(j, step):
        rot, n, m, length = (np.array(value, dtype=float) for value in inputs)
        if j < rod.LOCAL_N:
            rot[(j - rod.LOCAL_ROT) // 3, (j - rod.LOCAL_ROT) % 3] += step
        elif j < rod.LOCAL_M:
            n[j - rod.LOCAL_N] += step
        elif j < rod.LOCAL_LENGTH:
            m[j - rod.LOCAL_M] += step
        else:
            length = length + step
        return _segment_end(rot, n, m, float(length))

    for j, scale in enumerate(scales):
        central = [(moved(j, h) - moved(j, -h)) / (2.0 * h) for h in (2.0 * scale, scale)]
        reference = (4.0 * central[1] - central[0]) / 3.0
        assert np.abs(local[:, j] - reference).max() <= 1e-9 * np.abs(reference).max(), j
    some = np.zeros(rod.LOCAL_DIRECTIONS, dtype=np.bool_)
    some[[rod.LOCAL_ROT + 4, rod.LOCAL_N + 1, rod.LOCAL_M, rod.LOCAL_LENGTH]] = True
    partial_end, partial = _segment_tangent(rod, some)
    np.testing.assert_allclose(partial_end, end, rtol=0, atol=1e-13)
    np.testing.assert_allclose(partial[:, some], local[:, some], rtol=1e-12,
                               atol=1e-12 * np.abs(local).max())
    assert not partial[:, ~some].any()
    interpreted_end, interpreted = _segment_tangent(interpreted_kernels()['rod'], every)
    np.testing.assert_allclose(interpreted_end, end, rtol=0, atol=1e-13)
    np.testing.assert_allclose(interpreted, local, rtol=1e-12, atol=1e-12 * np.abs(local).max())
