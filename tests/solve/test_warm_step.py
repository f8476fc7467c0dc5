"""The one-call warm solve (cdr_translator/solve/warm_fast_path.py) against its parts."""

from cdr_translator import TranslatorSolver
from cdr_translator.analysis.accuracy import estimate
from cdr_translator.bvp import chord
from cdr_translator.solve.warm_fast_path import _warm_step, settings_array, TOO_FAR, warm_step
import numpy as np
import pytest
from scipy.linalg import lu_factor

#: A straight wrench path (N, N m) and the next wrench along it.
PATH = [np.array([10.0 + 0.2 * k, 1.0 - 0.1 * k, -2.0, 0.05, 0.0, 0.02 * k]) for k in range(4)]


@pytest.fixture(scope='module')
def along_a_path(params):
    """Solutions of PATH[:3] and the factorization at the last one (problem, path, lu, pose)."""
    solver = TranslatorSolver(params)
    problem = solver.problem
    xs = np.array([solver.solve(wrench[:3], wrench[3:]).unknowns / problem.x_scale
                   for wrench in PATH[:3]])
    _, jacobian, pose = problem.exact_jacobian(xs[-1], PATH[2])
    path_xs = np.zeros((chord.PATH_LENGTH, problem.size))
    path_wrenches = np.zeros((chord.PATH_LENGTH, 6))
    path_xs[:3], path_wrenches[:3] = xs, PATH[:3]
    return problem, (path_xs, path_wrenches, 3), lu_factor(jacobian), pose.copy()


def _settings(reach=0.3, max_iterations=12, estimate=True):
    return settings_array(1e-10, max_iterations, 0.5, 0.5, reach, estimate)


def test_converges_with_the_estimate_and_residuals_of_the_parts(along_a_path):
    """The solution meets the tolerance; its estimate is accuracy.estimate's at that point."""
    problem, path, lu, pose = along_a_path
    step, xs, rs = warm_step(problem, (path[0][2], PATH[2]), path, PATH[3], lu, pose,
                             _settings())
    assert step.status == chord.CONVERGED and step.iterations >= 1
    residual = problem.residual(xs, PATH[3])
    assert np.allclose(rs, residual, rtol=0, atol=1e-14)
    assert np.abs(residual).max() <= 1e-10
    assert step.residual_by_kind == pytest.approx(problem.residual_by_kind(rs), rel=1e-12)
    frames = problem.recorded_shape(step.slot)[1]
    assert np.allclose(frames, problem.shape(xs, PATH[3])[1], rtol=0, atol=1e-15)
    parts = estimate(problem, xs, PATH[3], rs, frames, lu, pose)
    assert step.estimate == parts


@pytest.mark.parametrize('count', [3, 0])
def test_predicts_to_first_order_off_the_path(along_a_path, count):
    """A wrench off the path's line (or no path): first order, the guess of the solver's."""
    problem, path, lu, pose = along_a_path
    problem.keep_secant_count(lu, 0)  # the exact factorization alone, no Broyden updates
    off = PATH[2] + np.array([0.0, 0.3, -0.2, 0.0, 0.0, 0.0])
    step, xs, _ = warm_step(problem, (path[0][2], PATH[2]), (path[0], path[1], count), off,
                            lu, pose, _settings(max_iterations=0))
    assert step.status == chord.OUT_OF_ITERATIONS and step.iterations == 0  # the guess
    first_order = path[0][2] - problem.wrench_response(lu, off - PATH[2])
    assert np.allclose(xs, first_order, rtol=0, atol=1e-13)
    step, xs, _ = warm_step(problem, (path[0][2], PATH[2]), (path[0], path[1], count), off,
                            lu, pose, _settings())
    assert step.status == chord.CONVERGED
    assert np.abs(problem.residual(xs, off)).max() <= 1e-10


def test_says_too_far_beyond_the_reach(along_a_path):
    """A prediction moving an unknown further than the reach: no whole step is tried."""
    problem, path, lu, pose = along_a_path
    step, xs, _ = warm_step(problem, (path[0][2], PATH[2]), path, PATH[3], lu, pose,
                            _settings(1e-9))
    assert step.status == TOO_FAR and step.iterations == 0
    assert np.array_equal(xs, path[0][2])


@pytest.mark.parametrize('noise', [0.0, 0.05])
def test_solver_results_match_the_general_path(params, noise):
    """Along a smooth (or noisy: N) sequence the one-call solves agree with the general path."""
    fused, general = TranslatorSolver(params), TranslatorSolver(params)
    calls = []
    general.engine.warm_step = lambda wrench, deadline, newton: (None, 0)
    general.engine.usual_solve = lambda wrench, started: (None, None)
    fused_step, fused_usual = fused.engine.warm_step, fused.engine.usual_solve

    def counted(wrench, deadline, newton):
        outcome, spent = fused_step(wrench, deadline, newton)
        calls.append(outcome is not None)
        return outcome, spent

    def counted_usual(wrench, started):
        result, undo = fused_usual(wrench, started)
        calls.append(result is not None)
        return result, undo
    fused.engine.warm_step, fused.engine.usual_solve = counted, counted_usual
    rng = np.random.default_rng(11)
    for t in np.linspace(0.0, 1.0, 40):
        wrench = np.array([10.0 + 4.0 * np.sin(3 * t), 3.0 * t, -2.0, 0.1 * t, 0.0, 0.05])
        wrench[:3] += rng.normal(scale=noise, size=3) if noise else 0.0
        one, other = fused.solve(wrench[:3], wrench[3:]), general.solve(wrench[:3], wrench[3:])
        assert one.converged and other.converged and one.stable and other.stable
        assert one.accuracy_met and other.accuracy_met
        assert np.allclose(one.frames['de'], other.frames['de'], rtol=0, atol=1e-9)
        assert one.error_estimate_m == pytest.approx(other.error_estimate_m, rel=0.3)
    assert sum(calls) >= 30  # the usual case: the one call solved it


def test_the_one_call_runs_without_the_gil():
    """Its kernel releases the GIL (jit_releasing_gil); the short kernels keep it."""
    assert _warm_step.targetoptions['nogil'] is True
    assert chord.chord_iterations.targetoptions['nogil'] is False


def test_no_estimate_when_not_asked(along_a_path):
    """Settings without the estimate (a solver that does not judge): converged, no estimate."""
    problem, path, lu, pose = along_a_path
    problem.keep_secant_count(lu, 0)  # the exact factorization alone, no Broyden updates
    step, xs, _ = warm_step(problem, (path[0][2], PATH[2]), path, PATH[3], lu, pose,
                            _settings(estimate=False))
    assert step.status == chord.CONVERGED
    assert step.estimate is None and step.residual_by_kind is None
    assert np.abs(problem.residual(xs, PATH[3])).max() <= 1e-10
