"""The exact (tangent-linear) Jacobian against central differences of the residual."""

from dataclasses import replace

from cdr_translator import TranslatorSolver
from cdr_translator.problem import Problem
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
