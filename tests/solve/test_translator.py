"""The translator model against the paper (Table II), symmetry, statics and refinement."""

import math

from cdr_translator import TranslatorSolver
from cdr_translator.params.paper import TABLE_II, TABLE_II_TOLERANCE_DEG
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.solve import continuation
import numpy as np
import pytest

MIRROR_X = np.diag([-1.0, 1.0, 1.0])
QUARTER_TURN = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def cold(solver, force, moment=(0.0, 0.0, 0.0)):
    """Solve from the unloaded state."""
    solver.reset()
    result = solver.solve(force, moment)
    assert result.converged, result.message
    return result


def test_zero_load_is_straight(solver, params):
    """No load: straight stack, end disk on the axis at 4 D + L_m, no rotation."""
    result = cold(solver, (0.0, 0.0, 0.0))
    assert result.iterations == 0
    height = 2 * (params.spacers_per_joint + 1) * params.disk_spacing + params.tube_length
    assert np.allclose(result.end_disk_position, [0.0, 0.0, height], atol=1e-14)
    assert np.allclose(result.frames['de'][:3, :3], np.eye(3), atol=1e-14)
    assert result.pj_bending[0] == 0.0 and result.dj_bending[0] == 0.0
    # straight backbones are lines, not small circles of a rank-deficient fit
    assert max(result.max_arc_deviation.values()) < 1e-12


@pytest.mark.parametrize('case', TABLE_II, ids=lambda case: f'F={case.force[0]:g}N')
def test_table_ii(solver, case):
    """Paper Table II: bending angles within 0.5 deg, end-disk rotation within 0.2 deg."""
    result = cold(solver, case.force)
    pj, pj_direction = result.pj_bending
    dj, dj_direction = result.dj_bending
    tolerance = TABLE_II_TOLERANCE_DEG
    assert abs(math.degrees(pj) - case.pj_bending_deg) < tolerance['bending']
    assert abs(math.degrees(dj) - case.dj_bending_deg) < tolerance['bending']
    assert abs(math.degrees(result.end_disk_rotation)
               - case.end_disk_rotation_deg) < tolerance['rotation']
    # a +x force bends the PJ toward +x and the DJ back toward -x
    assert abs(pj_direction) < 1e-9 and abs(abs(dj_direction) - math.pi) < 1e-9
    # the planar end-disk rotation is the difference of the bending angles (Table II)
    assert abs(result.end_disk_rotation - (pj - dj)) < 1e-9
    # arc deviations of the paper's order (0.016 mm, 0.012 mm)
    for deviation in result.max_arc_deviation.values():
        assert 0.25 * case.max_arc_deviation_mm < 1e3 * deviation \
            < 4.0 * case.max_arc_deviation_mm


def test_residuals_far_below_paper_tolerances(solver):
    """The converged residual is many orders below 2e-4 m, 1e-4 rad, 1e-4 N, 1e-4 N m."""
    result = cold(solver, (20.0, 0.0, 0.0))
    assert result.residual_by_type['position_m'] < 1e-11
    assert result.residual_by_type['orientation_rad'] < 1e-9
    assert result.residual_by_type['force_n'] < 1e-9
    assert result.residual_by_type['moment_nm'] < 1e-9


def base_reaction(result, params):
    """Total force and moment (about the base origin) the five rods carry at the base."""
    values = result.unknowns[:30].reshape(5, 6)
    positions = np.zeros((5, 3))
    for i in range(4):
        angle = 0.5 * math.pi * i
        positions[i + 1] = params.pitch_radius * np.array([math.cos(angle), math.sin(angle), 0])
    force = values[:, :3].sum(axis=0)
    moment = (values[:, 3:] + np.cross(positions, values[:, :3])).sum(axis=0)
    return force, moment


@pytest.mark.parametrize('force, moment', [((12.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                                           ((3.0, -7.0, -4.0), (0.05, 0.1, -0.08))])
def test_global_equilibrium(solver, params, force, moment):
    """Base reactions balance the applied wrench (moments about the base) to 1e-9."""
    result = cold(solver, force, moment)
    base_force, base_moment = base_reaction(result, params)
    expected_moment = np.array(moment) + np.cross(result.end_disk_position, force)
    assert np.allclose(base_force, force, atol=1e-9, rtol=0)
    assert np.allclose(base_moment, expected_moment, atol=1e-9, rtol=0)


def test_mirror_symmetry(solver):
    """A force mirrored in the yz plane gives the mirrored deflection."""
    plus = cold(solver, (9.0, 0.0, 2.0))
    minus = cold(solver, (-9.0, 0.0, 2.0))
    assert np.allclose(minus.end_disk_position, MIRROR_X @ plus.end_disk_position, atol=1e-12)
    assert math.isclose(plus.pj_bending[0], minus.pj_bending[0], abs_tol=1e-12)
    # the solves stop at residuals <= 1e-10 rad, so agreement to 1e-12 would be luck
    assert math.isclose(plus.end_disk_rotation, minus.end_disk_rotation, abs_tol=1e-10)


def test_quarter_turn_symmetry(solver):
    """The four secondaries make the structure symmetric under a 90 deg turn about z."""
    force = np.array([5.0, 2.0, -3.0])
    moment = np.array([0.05, -0.02, 0.03])
    first = cold(solver, force, moment)
    turned = cold(solver, QUARTER_TURN @ force, QUARTER_TURN @ moment)
    assert np.allclose(turned.end_disk_position, QUARTER_TURN @ first.end_disk_position,
                       atol=1e-12)
    expected = QUARTER_TURN @ first.frames['de'][:3, :3] @ QUARTER_TURN.T
    assert np.allclose(turned.frames['de'][:3, :3], expected, atol=1e-10)


def test_warm_start_agrees_with_cold(params):
    """A warm-started sequence ends where a cold solve of its last wrench does."""
    solver = TranslatorSolver(params)
    for fx in np.linspace(0.0, 15.0, 7):
        warm = solver.solve((fx, 0.5 * fx, 0.0))
        assert warm.converged, warm.message
    reference = TranslatorSolver(params).solve((15.0, 7.5, 0.0))
    assert np.allclose(warm.end_disk_position, reference.end_disk_position, atol=1e-12)


def test_convergence_under_refinement(params):
    """End-disk position converges at RK4's fourth order as the rods are refined."""
    force = (12.0, 4.0, 0.0)
    moment = (0.0, 0.0, 0.05)

    def tip(steps):
        result = TranslatorSolver(params.with_changes(steps_per_segment=steps),
                                  accuracy=Accuracy(0.0, 0.0)).solve(force, moment)
        assert result.converged, result.message
        return result.end_disk_position

    reference = tip(64)
    errors = [np.linalg.norm(tip(steps) - reference) for steps in (2, 4, 8)]
    orders = [math.log2(errors[k] / errors[k + 1]) for k in range(2)]
    print(f'end-disk error (m) at 2/4/8 steps: {errors}; observed orders {orders}')
    assert all(3.5 < order < 4.6 for order in orders), orders
    assert errors[2] < 1e-6  # the default discretization (8 steps) is sub-micrometre


def test_more_spacer_disks(params):
    """Three spacer disks per joint: converges, stays straight unloaded, bends alike."""
    solver = TranslatorSolver(params.with_changes(spacers_per_joint=3, tube_length=0.0983))
    straight = solver.solve((0.0, 0.0, 0.0))
    assert np.allclose(straight.end_disk_position, [0, 0, 2 * 0.04 + 0.0983], atol=1e-14)
    result = solver.solve((12.0, 0.0, 0.0))
    assert result.converged, result.message
    assert abs(result.end_disk_rotation - (result.pj_bending[0] - result.dj_bending[0])) < 1e-9


@pytest.mark.parametrize('bad', [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0),
                                 (0.0, 0.0, -math.inf)])
def test_non_finite_wrench_is_rejected(solver, bad):
    """Reject NaN or Inf in a wrench with a ValueError naming the component."""
    with pytest.raises(ValueError, match='force . component is'):
        solver.solve(bad)
    with pytest.raises(ValueError, match='moment . component is'):
        solver.solve((0.0, 0.0, 0.0), bad)


@pytest.mark.parametrize('options, fragment', [
    ({'params': {'youngs_modulus': 1.0}}, 'params must be a TranslatorParams, got dict'),
    ({'params': 'config/translator.yaml'}, 'params must be a TranslatorParams, got str'),
    ({'max_iterations': '5'}, 'max_iterations must be an integer'),
    ({'max_iterations': 1.5}, 'max_iterations must be an integer'),
    ({'max_iterations': math.nan}, 'max_iterations must be an integer'),
    ({'max_iterations': 0}, 'max_iterations must be an integer >= 1'),
    ({'time_limit_s': None}, 'time_limit_s must be a number'),
    ({'time_limit_s': -1.0}, 'time_limit_s must be >= 0'),
    ({'tolerance': 'x'}, 'tolerance must be a number'),
    ({'tolerance': 0.0}, 'tolerance must be positive'),
    ({'accuracy': (1e-3, 1e-3)}, 'accuracy must be an Accuracy'),
])
def test_bad_solver_options_are_value_errors_naming_them(options, fragment):
    """At construction, not as a TypeError or AttributeError halfway through a solve."""
    with pytest.raises(ValueError) as raised:
        TranslatorSolver(**options)
    assert fragment in str(raised.value).replace(' (TranslatorParams.from_yaml reads a '
                                                 'params file)', ''), raised.value


def test_unknown_parameter_change_is_named(params):
    """with_changes refuses a key no TranslatorParams has: a ParameterError, not a TypeError."""
    with pytest.raises(ValueError, match='unknown parameter.s. bogus'):
        params.with_changes(bogus=1.0)


def test_wrong_wrench_shape_is_rejected(solver):
    """A force needs exactly three components."""
    with pytest.raises(ValueError, match='3 components'):
        solver.solve((1.0, 2.0))


def test_non_convergence_is_a_result(params):
    """Running out of time gives converged=False with a message, not an exception."""
    result = TranslatorSolver(params, time_limit_s=0.0).solve((20.0, 0.0, 0.0))
    assert not result.converged
    assert 'time limit' in result.message


def test_a_solve_takes_its_own_time_limit(params):
    """``time_limit_s=`` caps one solve and its message names it; the solver's stays."""
    solver = TranslatorSolver(params)
    assert not solver.has_warm_start
    capped = solver.solve((12.0, 0.0, 0.0), time_limit_s=1e-4)
    assert not capped.converged and 'time limit of 0.0001 s reached' in capped.message
    assert solver.time_limit_s == 10.0
    result = solver.solve((12.0, 0.0, 0.0), warm_start=False)
    assert result.converged and solver.has_warm_start, result.message
    solver.reset()
    assert not solver.has_warm_start
    with pytest.raises(ValueError, match='time_limit_s'):
        solver.solve((12.0, 0.0, 0.0), time_limit_s=-1.0)


def test_paper_method_agrees_at_its_tolerances(params):
    """The interpreted Levenberg-Marquardt baseline lands on the same equilibrium."""
    coarse = params.with_changes(steps_per_segment=2)
    baseline = TranslatorSolver(coarse, method='paper').solve((4.0, 0.0, 0.0))
    fast = TranslatorSolver(coarse).solve((4.0, 0.0, 0.0))
    assert baseline.converged, baseline.message
    assert np.allclose(baseline.end_disk_position, fast.end_disk_position, atol=2e-4)
    assert abs(baseline.pj_bending[0] - fast.pj_bending[0]) < 1e-3


def test_a_warm_sequence_extrapolates_and_ends_where_cold_solves_do(params, monkeypatch):
    """Along a smooth sequence the extrapolating predictor needs fewer iterations, same answers."""
    wrenches = [np.array([10.0 + 0.05 * k, 6.0 - 0.03 * k, -0.02 * k * k, 0.0, 0.01, 0.0])
                for k in range(8)]

    def sequence():
        solver = TranslatorSolver(params)
        return [solver.solve(w[:3], w[3:]) for w in wrenches]

    extrapolated = sequence()
    monkeypatch.setattr(continuation, 'EXTRAPOLATION_MISS', -1.0)  # never extrapolate
    linear = sequence()
    assert sum(r.iterations for r in extrapolated[3:]) < sum(r.iterations for r in linear[3:])
    for result, other in zip(extrapolated, linear):
        assert result.converged and result.stable and result.accuracy_met, result.message
        cold_result = cold(TranslatorSolver(params), result.force, result.moment)
        for candidate in (result, other):
            assert np.allclose(candidate.end_disk_position, cold_result.end_disk_position,
                               rtol=0, atol=1e-11)
