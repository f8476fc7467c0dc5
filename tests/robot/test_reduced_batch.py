"""Reduced legs: the coupled warm solve and the atlas's compiled loop over samples."""

from cdr_translator.analysis.stability import determinant_sign
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.reduced_coupled_kernels import refresh_leg
from cdr_translator.robot.samples import empty_results, store
import numpy as np
import pytest

GRAVITY_1KG = (0.0, 0.0, -9.81)


def _samples(stroke: float) -> tuple:
    """Return a path of slider settings with steps of a coarse atlas grid, and payloads."""
    sliders = np.array([[-0.5, -0.5, 0.0], [0.0, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.0, 0.2],
                        [0.0, 0.0, 0.2], [-0.5, 0.0, 0.2], [-0.5, 0.5, -0.4]]) * stroke
    payloads = np.array([GRAVITY_1KG, GRAVITY_1KG, (1.0, 0.0, -15.0), (1.0, 0.0, -15.0),
                         (0.0, -2.0, -5.0), (0.0, -2.0, -5.0), GRAVITY_1KG])
    return sliders, payloads


def test_columns_equal_solves_sample_by_sample():
    """Each row of the compiled loop equals a compliance solve made after the row before."""
    level = 'cc'
    batch = DeltaRobot(fidelity=level)
    sliders, payloads = _samples(batch.geometry.slider_stroke)
    columns = empty_results(len(sliders))
    assert batch.solve_columns(sliders, payloads, columns, store)
    direct = DeltaRobot(fidelity=level)
    expected = empty_results(len(sliders))
    for row, (setting, payload) in enumerate(zip(sliders, payloads)):
        store(expected, row, direct.solve(setting, payload, compliance=True))
    assert np.all(columns['converged']) and np.all(expected['converged'])
    assert list(columns['message']) == list(expected['message'])
    assert np.array_equal(columns['stable'], expected['stable'])
    for name in ('platform_position', 'platform_rotation_vector', 'parasitic_rotation',
                 'leg_bending', 'leg_axial_force'):
        assert np.allclose(columns[name], expected[name], rtol=0.0, atol=1e-8), name
    for name in ('compliance_eigenvalues_translation', 'compliance_eigenvalues_rotation',
                 'slider_jacobian', 'stiffness_margin'):
        scale = np.abs(expected[name]).max()
        assert np.allclose(columns[name], expected[name], rtol=1e-6, atol=1e-9 * scale), name
    for name in ('leg_error_bound_position', 'leg_error_bound_angle'):
        assert np.array_equal(columns[name], expected[name], equal_nan=True), name


@pytest.mark.parametrize('level', ['full', 'rod'])
def test_other_levels_have_no_compiled_loop(level):
    """solve_columns is for 'cc' legs only: other levels leave the columns untouched."""
    robot = DeltaRobot(fidelity=level)
    columns = empty_results(1)
    assert not robot.solve_columns(np.zeros((1, 3)), np.array([GRAVITY_1KG]), columns, store)
    assert not columns['converged'][0]


def test_warm_solves_take_the_coupled_newton_and_equal_cold_ones():
    """Along a slider circle warm 'cc' solves converge in a few coupled iterates, as cold ones."""
    level = 'cc'
    robot = DeltaRobot(fidelity=level)
    cold = DeltaRobot(fidelity=level)
    for step in range(6):
        angle = np.radians(2.0 * step)
        sliders = [0.015 * np.sin(angle + 2.0 * np.pi * k / 3) for k in range(3)]
        warm = robot.solve(sliders, GRAVITY_1KG)
        assert warm.converged and warm.message == 'converged'
        if step == 0:
            continue  # the first solve walks from home
        assert warm.iterations <= 5
        kept_factorization = robot._reduced.chains[level].kept[5]
        assert kept_factorization[-1] == 1  # made and kept by the coupled Newton
        reference = cold.solve(sliders, GRAVITY_1KG, warm_start=False)
        assert np.allclose(warm.platform_position, reference.platform_position, atol=1e-9)
        assert np.allclose(warm.leg_tip_wrenches, reference.leg_tip_wrenches, atol=1e-7)


def test_closed_form_cc_linearization_equals_the_implicit_differences():
    """The coupled Newton's 'cc' leg compliance (twist Jacobian in closed form) is exact."""
    robot = DeltaRobot(fidelity='cc')
    chain = robot._reduced.chains['cc']
    wrench = np.array([1.5, -0.8, -4.0, 0.02, -0.03, 0.005])
    single = FidelitySolver(robot.params, 'cc')
    x = single.solve(wrench[:3], wrench[3:]).unknowns / chain.model.unknown_scale
    size = chain.model.size
    lu, pivots = np.zeros((size, size)), np.zeros(size + 1, dtype=np.int64)
    sensitivity, compliance = np.zeros((size, 6)), np.zeros((6, 6))
    sign = refresh_leg(chain.model.code, x, chain.data, wrench, lu, pivots, sensitivity,
                       compliance)
    _, reference, reference_lu = chain.leg_linearization(x, wrench)
    assert sign == determinant_sign(reference_lu) and pivots[-1] == 1
    assert np.abs(compliance - reference).max() < 1e-9 * np.abs(reference).max()
