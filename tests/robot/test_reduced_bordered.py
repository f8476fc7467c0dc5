"""The chain's Newton with 'cc' legs held in the system (robot/reduced_bordered.py)."""

from cdr_translator.fidelity.newton import ROD
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.reduced_bordered import (bordered_newton, bordered_system,
                                                   BorderedState, PLATFORM, SOLVED)
from cdr_translator.robot.reduced_kernels import move_platform
import numpy as np
import pytest

SLIDERS = (0.03, 0.0, -0.03)
UPWARD = (0.0, 0.0, 75.0)  # compresses the legs past a 'cc' leg's free-end buckling load


@pytest.fixture(scope='module')
def solved():
    """Return a converged 'cc' chain under an upward payload, its state and inputs."""
    robot = DeltaRobot(fidelity='cc', time_limit_s=5.0)
    result = robot.solve(SLIDERS, UPWARD, warm_start=False)
    assert result.converged, result.message
    chain = robot._reduced.chains['cc']
    state, inputs = chain.previous
    return chain, state, inputs


def test_bordered_jacobian_matches_central_differences(solved):
    """Every column of the bordered Jacobian is the residual's derivative (scaled unknowns)."""
    chain, state, inputs = solved
    x_scale = chain.chain.platform[5]
    data = chain.data.copy()
    held = BorderedState(state.position, state.rotation, state.wrenches, state.leg_x)
    base, matrix, _, _ = bordered_system(chain.model.code, data, held, inputs,
                                         chain.chain.platform, True)
    assert np.all(np.isfinite(matrix))
    legs, size = held.leg_x.shape
    step = 1e-6
    for column in range(PLATFORM + legs * size):
        sides = []
        for sign in (1.0, -1.0):
            moved = BorderedState(held.position, held.rotation, held.wrenches, held.leg_x)
            if column < PLATFORM:
                unit = np.zeros(PLATFORM)
                unit[column] = sign * step
                move_platform(held.position, held.rotation, held.wrenches, unit, 1.0, x_scale,
                              moved.position, moved.rotation, moved.wrenches)
            else:
                moved.leg_x.ravel()[column - PLATFORM] += sign * step
            sides.append(bordered_system(chain.model.code, data, moved, inputs,
                                         chain.chain.platform, False)[0])
        difference = (sides[0] - sides[1]) / (2.0 * step)
        assert np.allclose(matrix[:, column], difference, rtol=1e-5, atol=1e-6), column
    assert np.abs(base).max() < 1e-8  # at the solution


def test_bordered_newton_returns_to_the_solution(solved):
    """From a perturbed state the damped bordered Newton converges back to the solution."""
    chain, state, inputs = solved
    x_scale = chain.chain.platform[5]
    rng = np.random.default_rng(3)
    held = BorderedState(state.position, state.rotation, state.wrenches, state.leg_x)
    move_platform(state.position, state.rotation, state.wrenches,
                  1e-3 * rng.normal(size=PLATFORM), 1.0, x_scale, held.position, held.rotation,
                  held.wrenches)
    held.leg_x = held.leg_x + 1e-3 * rng.normal(size=held.leg_x.shape)
    tolerances = np.array([1e-10, 1e-10, 1e-9])
    code, iterations, residual, _ = bordered_newton(
        chain.model.code, chain.data.copy(), chain.model.tolerance, held, inputs,
        chain.chain.platform, tolerances, 12)
    assert code == SOLVED and iterations > 0
    assert np.allclose(held.position, state.position, atol=1e-9)
    assert np.allclose(held.wrenches, state.wrenches, atol=1e-6)
    assert np.abs(residual[18:]).max() <= 1e-10


def test_only_cc_legs(solved):
    """Rod legs have no closed-form wrench derivative: a ValueError names the model."""
    chain, state, inputs = solved
    held = BorderedState(state.position, state.rotation, state.wrenches, state.leg_x)
    with pytest.raises(ValueError, match='model'):
        bordered_newton(ROD, chain.data.copy(), 1e-9, held, inputs, chain.chain.platform,
                        np.array([1e-10, 1e-10, 1e-9]), 12)
