"""Compiled kernels of the reduced and linear levels: exact Jacobians, sequences, poses."""

import math

from bench.speed_vs_error import wrench_sequence
from cdr_translator.fidelity import cc, equivalent_rod, FidelitySolver, level_kernels, newton
from cdr_translator.fidelity.cc_derivatives import cc_system
from cdr_translator.fidelity.equivalent_rod_jacobian import rod_system
from cdr_translator.fidelity.reduced import ReducedModel
import numpy as np
import pytest

WRENCH = np.array([10.0, -5.0, 3.0, 0.2, -0.1, 0.3])


def _central_differences(system, x, data, step=1e-6):
    """Jacobian of ``system``'s residual by central differences."""
    size = len(x)
    result = np.empty((size, size))
    plus, minus = np.empty(size), np.empty(size)
    for column in range(size):
        probe = x.copy()
        probe[column] += step
        system(probe, data, plus, np.empty((0, 0)), False)
        probe[column] -= 2.0 * step
        system(probe, data, minus, np.empty((0, 0)), False)
        result[:, column] = (plus - minus) / (2.0 * step)
    return result


@pytest.mark.parametrize('system, data_of, size', [
    (cc_system, cc.model_data, cc.SIZE),
    (rod_system, lambda params: equivalent_rod.model_data(params, 2), equivalent_rod.SIZE)])
@pytest.mark.parametrize('spread', [0.3, 1e-3])
def test_jacobian_equals_finite_differences(params, system, data_of, size, spread):
    """The closed-form ('cc') and forward-mode ('rod') Jacobians match central differences."""
    data = data_of(params)
    data[:6] = WRENCH
    x = np.random.default_rng(7).normal(size=size) * spread
    residual, jacobian = np.empty(size), np.empty((size, size))
    system(x, data, residual, jacobian, True)
    expected = _central_differences(system, x, data)
    assert np.abs(jacobian - expected).max() <= 1e-6 * np.abs(expected).max()
    alone = np.empty(size)
    system(x, data, alone, np.empty((0, 0)), False)
    assert np.allclose(alone, residual, rtol=0.0, atol=1e-14)


@pytest.fixture(scope='module', params=['cc', 'rod'])
def model(request, params):
    """Each reduced model."""
    if request.param == 'cc':
        return ReducedModel.constant_curvature(params)
    return ReducedModel.equivalent_rod(params)


def test_sequence_equals_one_by_one(model):
    """The compiled sequence equals solve_row called row by row with the same warm state."""
    wrenches = wrench_sequence(60)
    unknowns, norms, status, iterations = model.solve_sequence(wrenches)
    assert np.all(status == newton.CONVERGED) and np.all(norms < 1e-8)
    lu = np.empty((model.size, model.size))
    pivots = np.zeros(model.size + 1, dtype=np.int64)
    x, origin = np.zeros(model.size), np.zeros(6)
    data = model._data.copy()
    for row, wrench in enumerate(wrenches):
        answer, norm, count, code = level_kernels.solve_row(
            model.code, x, data, origin, wrench, model.tolerance, model.max_iterations, lu,
            pivots)
        assert code == status[row] and count == iterations[row]
        assert np.abs(answer - unknowns[row]).max() <= 1e-12
        x, origin = answer, wrench


def test_sequence_matches_the_solver_and_its_poses(model):
    """Rows agree with ReducedModel.solve (cold, each) and poses with SolveResult's."""
    wrenches = wrench_sequence(40)[::8]
    unknowns, _, status, _ = model.solve_sequence(wrenches)
    pose, bending = model.poses(wrenches, unknowns)
    assert np.all(status == newton.CONVERGED)
    for row, wrench in enumerate(wrenches):
        outcome = model.solve(wrench, None, math.inf)
        frames = model.frames(outcome.x, wrench)
        assert np.abs(frames[3][:3, 3] - pose[row, :3]).max() < 1e-9
    solver = FidelitySolver(fidelity=model.name)
    result = solver.solve(wrenches[-1][:3], wrenches[-1][3:])
    assert np.allclose(pose[-1, :3], result.end_disk_position, atol=1e-9)
    assert np.allclose(pose[-1, 3:], result.end_disk_quaternion_xyzw, atol=1e-9)
    assert np.allclose(bending[-1], result.pj_bending + result.dj_bending, atol=1e-9)


@pytest.mark.parametrize('bad', [np.nan, np.inf, 'past the range'])
def test_failing_row_is_flagged_and_later_rows_solve(model, bad):
    """A row past the level's range, or not finite, is flagged; the rows after it solve."""
    wrenches = wrench_sequence(20)
    broken = wrenches.copy()
    if bad == 'past the range':
        if model.name == 'cc':
            pytest.skip("Newton on 'cc' converged for every finite wrench tried (to 1e6)")
        broken[7] = [0.0, 0.0, 0.0, 1e3, 0.0, 0.0]
    else:
        broken[7, 2] = bad
    unknowns, _, status, _ = model.solve_sequence(broken)
    assert status[7] != newton.CONVERGED
    assert np.all(np.delete(status, 7) == newton.CONVERGED)
    expected, _, _, _ = model.solve_sequence(wrenches)
    assert np.abs(unknowns[8:] - expected[8:]).max() < 1e-8


def test_linear_poses_equal_prediction(params):
    """The compiled linear poses equal TangentModel.predict's frames, row by row."""
    solver = FidelitySolver(params, fidelity='linear')
    wrenches = wrench_sequence(30)
    solver.cache_full_solution(wrenches[0])
    pose, bending = solver.tangent.poses(wrenches)
    for row in (0, 11, 29):
        result = solver.solve(wrenches[row][:3], wrenches[row][3:])
        assert result.fidelity == 'linear'
        assert np.allclose(pose[row, :3], result.end_disk_position, atol=1e-14)
        assert np.allclose(pose[row, 3:], result.end_disk_quaternion_xyzw, atol=1e-12)
        assert np.allclose(bending[row], result.pj_bending + result.dj_bending, atol=1e-12)
