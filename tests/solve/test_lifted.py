"""Multiple shooting by the lifted Newton method (multiple_shooting and its node kernels)."""

from cdr_translator import TranslatorSolver
from cdr_translator.bvp.problem import Problem
from cdr_translator.solve import continuation, multiple_shooting
import numpy as np
import pytest


@pytest.fixture(scope='module')
def spaced(params):
    """Return a solver with 3 spacer disks per joint and its solution at 10 N lateral."""
    solver = TranslatorSolver(params.with_changes(spacers_per_joint=3))
    result = solver.solve([10.0, 0.0, 0.0])
    assert result.converged
    return solver, result.unknowns / solver.problem.x_scale


def _lifted_equations(problem: Problem, xs: np.ndarray, nodes: np.ndarray,
                      wrench: np.ndarray) -> np.ndarray:
    """Residuals and defects of multiple shooting as one nondimensional vector."""
    rs, ds = problem.lifted_residual(xs, nodes, wrench)
    return np.concatenate([rs, ds.ravel()])


def test_recorded_nodes_reproduce_single_shooting(spaced):
    """Shot from the nodes single shooting carries, the residual is its own, defects zero."""
    solver, xs = spaced
    problem = solver.problem
    wrench = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    nodes = problem.node_states(xs, wrench)
    assert nodes.shape == (problem.node_count, problem.node_scale.size)
    rs, ds = problem.lifted_residual(xs, nodes, wrench)
    np.testing.assert_array_equal(rs, problem.residual(xs, wrench))
    assert np.abs(ds).max() == 0.0


def test_lifted_step_equals_newton_step_at_zero_defects(spaced):
    """At consistent nodes the condensed Jacobian and step are single shooting's."""
    solver, xs = spaced
    problem = solver.problem
    wrench = np.array([11.0, 0.5, 0.0, 0.0, 0.0, 0.1])  # off the solution: rs != 0
    nodes = problem.node_states(xs, wrench)
    rs, ds, jac, column = problem.lifted_jacobian(xs, nodes, wrench)
    plain_rs, plain_jac, _ = problem.exact_jacobian(xs, wrench)
    np.testing.assert_allclose(rs, plain_rs, rtol=0.0, atol=1e-14)
    # (the tangent shot's own primal arithmetic differs from the plain shot's in rounding)
    assert np.abs(ds).max() <= 1e-14 and np.abs(column).max() <= 1e-14
    step = np.linalg.solve(jac, -(rs + column))
    plain = np.linalg.solve(plain_jac, -plain_rs)
    assert np.abs(step - plain).max() <= 1e-10 * np.abs(plain).max()


def test_lifted_step_solves_the_linearized_multiple_shooting_system(spaced):
    """
    With defects, (dx, dz) from condensing zeroes the lifted equations to first order.

    The directional derivative of residuals and defects along (dx, dz), by central
    differences, must cancel them: this checks the lifted column, the node tangents and
    the node update together against the nonlinear shot with nodes.
    """
    solver, xs = spaced
    problem = solver.problem
    wrench = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    rng = np.random.default_rng(4)
    nodes = problem.node_states(xs, wrench)
    nodes += 1e-4 * problem.node_scale * rng.standard_normal(nodes.shape)  # defects
    rs, ds, jac, column = problem.lifted_jacobian(xs, nodes, wrench)
    assert np.abs(ds).max() > 1e-5 and np.abs(column).max() > 1e-5
    dx = np.linalg.solve(jac, -(rs + column))
    dz = problem.advance_nodes(nodes, dx) - nodes  # small: no rotation is projected
    equations = _lifted_equations(problem, xs, nodes, wrench)
    h = 1e-3
    derivative = (_lifted_equations(problem, xs + h * dx, nodes + h * dz, wrench)
                  - _lifted_equations(problem, xs - h * dx, nodes - h * dz, wrench)) / (2 * h)
    assert np.abs(equations + derivative).max() <= 1e-6 * np.abs(equations).max()


def test_lifted_newton_converges_quadratically_where_single_shooting_diverges(params):
    """
    Nine spacer disks: one exact Newton step from the 1.0 N solution to 1.1 N.

    Single shooting's step raises the residual a hundredfold; the lifted iteration from
    the same state converges in a few steps to the single-shooting solution.
    """
    solver = TranslatorSolver(params.with_changes(spacers_per_joint=9), time_limit_s=60.0)
    assert solver.solve([1.0, 0.0, 0.0]).converged
    problem = solver.problem
    xs = solver.previous_solution[0]
    wrench = np.array([1.1, 0.0, 0.0, 0.0, 0.0, 0.0])
    rs, jac, _ = problem.exact_jacobian(xs, wrench)
    single = problem.residual(xs - np.linalg.solve(jac, rs), wrench)
    assert np.abs(single).max() > 10.0 * np.abs(rs).max()
    outcome = multiple_shooting.newton(problem, xs, problem.node_states(xs, wrench), wrench,
                                       1e-10, 8, np.inf)
    assert outcome.converged and outcome.iterations <= 5, outcome
    assert np.abs(problem.residual(outcome.xs, wrench)).max() <= 1e-10


def test_nine_spacer_disks_cold_solve_converges_and_verifies(params):
    """The cold 2 N solve at nine spacer disks per joint: converged and verified."""
    solver = TranslatorSolver(params.with_changes(spacers_per_joint=9), time_limit_s=60.0)
    result = solver.solve([2.0, 0.0, 0.0], warm_start=False, verify=True)
    assert result.converged and result.verified, result.message
    assert result.stable
    # single shooting needed 421 iterations (99 Jacobians) for this solve
    assert result.iterations <= 20


def test_lifting_applies_to_cold_solves_with_spacer_disks(params):
    """Cold continuations lift from LIFT_FROM_SPACERS spacer disks on; both paths agree."""
    chosen = params.with_changes(spacers_per_joint=2)
    lifted_solver = TranslatorSolver(chosen)
    assert continuation.LIFT_FROM_SPACERS == 2 and lifted_solver.engine.lifting
    single_solver = TranslatorSolver(chosen)
    single_solver.lift_from_spacers = None
    assert not single_solver.engine.lifting
    assert not TranslatorSolver(chosen, jacobian='fd').engine.lifting
    assert not TranslatorSolver(params.with_changes(spacers_per_joint=1)).engine.lifting
    results = [solver.solve([15.0, -5.0, 0.0], [0.0, 0.0, 0.2], warm_start=False)
               for solver in (lifted_solver, single_solver)]
    assert all(result.converged for result in results)
    assert results[0].iterations < results[1].iterations
    np.testing.assert_allclose(results[0].frames['de'], results[1].frames['de'], atol=1e-9)
