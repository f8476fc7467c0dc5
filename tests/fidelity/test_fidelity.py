"""Fidelity levels (cdr_translator.fidelity): physics of the reduced models and the budget."""

import json
import math

from cdr_translator import TranslatorSolver
from cdr_translator.cli import EXIT_BAD_INPUT, EXIT_CONVERGED, main
from cdr_translator.fidelity import FidelitySolver, pose_errors, reference_solver, Validation
from cdr_translator.fidelity import validation
import numpy as np
import pytest
import yaml

PAPER_12N = np.array([12.0, 0.0, 0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope='module')
def full(params):
    """Full model at the shipped discretization."""
    return TranslatorSolver(params)


@pytest.fixture(scope='module')
def reference(params):
    """Return the reference the validated errors were measured against."""
    return reference_solver(params)


@pytest.fixture(scope='module')
def stored(params):
    """Return the shipped validation data (they must match the shipped parameters)."""
    data = Validation.load()
    assert data is not None and data.matches(params, FidelitySolver(params).rod_steps), \
        'config/fidelity_validation.yaml is missing or stale: run make bench'
    return data


def solve(solver, wrench, cold=True):
    """Solve a 6-vector wrench; every test result must converge."""
    if cold:
        solver.reset()
    result = solver.solve(wrench[:3], wrench[3:])
    assert result.converged, result.message
    return result


@pytest.fixture(scope='module', params=['cc', 'rod'])
def reduced(request, params):
    """Each reduced model, fixed."""
    return FidelitySolver(params, fidelity=request.param)


def test_zero_load_is_straight(reduced, params):
    """No load: every frame on the axis, unrotated; the end disk at 2 L + L_m."""
    result = solve(reduced, np.zeros(6))
    assert result.fidelity == reduced.fidelity
    assert np.allclose(result.end_disk_position, [0.0, 0.0, params.stack_height], atol=1e-15)
    for frame in result.frames.values():
        assert np.allclose(frame[:3, :3], np.eye(3), atol=1e-15)
    assert result.backbones.shape[0] == 5


def test_paper_cases_close_to_full_model(reduced, full):
    """Both reduced models reproduce the S-shape of the paper's cases to a few per cent."""
    for force in (12.0, 20.0):
        wrench = np.array([force, 0, 0, 0, 0, 0])
        expected = solve(full, wrench)
        result = solve(reduced, wrench)
        position, angle = pose_errors(result, expected)
        # measured: cc 0.81 / 1.8 mm, rod 0.28 / 0.81 mm of 60 / 87 mm deflection
        assert position < 0.03 * expected.end_disk_position[0]
        assert math.degrees(angle) < 0.03 * math.degrees(expected.pj_bending[0])
        # the PJ bends toward +x, the DJ back toward -x: the end disk stays nearly level
        assert abs(result.pj_bending[1]) < 1e-9
        assert abs(abs(result.dj_bending[1]) - math.pi) < 1e-9
        assert result.end_disk_rotation < 0.05 * result.pj_bending[0]


@pytest.mark.parametrize('wrench, position_tolerance, rotation_tolerance', [
    # a pure moment: the joints hardly bend, the secondaries' stretch carries it (relative)
    ((0.0, 0.0, 0.0, 1.0, 0.0, 0.0), 1e-5, 1e-5),
    # torsion: guided-beam secondaries between the disks; neither reduced model has the
    # 1.5 um shortening of the twisted secondaries (absolute position tolerance, m)
    ((0.0, 0.0, 0.0, 0.0, 0.0, 0.5), 2e-6, 2e-2),
    # axial: the primary and the secondaries in parallel (relative; no rotation, 1e-9 rad)
    ((0.0, 0.0, -20.0, 0.0, 0.0, 0.0), 1e-4, 1.0),
])
def test_constraint_directions_match_full_model(reduced, full, wrench, position_tolerance,
                                                rotation_tolerance):
    """Where the joints hardly bend, the reduced models' stiffness theory is the full one's."""
    wrench = np.array(wrench)
    expected = solve(full, wrench)
    result = solve(reduced, wrench)
    moved = np.linalg.norm(expected.end_disk_position
                           - np.array([0.0, 0.0, full.params.stack_height]))
    if wrench[5] != 0.0:
        moved = 1.0  # torsion: the tolerance is absolute
    assert np.linalg.norm(result.end_disk_position - expected.end_disk_position) \
        <= position_tolerance * moved
    rotation = expected.end_disk_rotation
    assert abs(result.end_disk_rotation - rotation) <= rotation_tolerance * max(rotation, 1e-9)


def test_mirror_and_quarter_turn_symmetry(reduced):
    """-x mirrors +x; a force along y is the force along x turned by 90 deg about z."""
    along_x = solve(reduced, np.array([12.0, 0, 0, 0, 0, 0])).end_disk_position
    mirrored = solve(reduced, np.array([-12.0, 0, 0, 0, 0, 0])).end_disk_position
    along_y = solve(reduced, np.array([0, 12.0, 0, 0, 0, 0])).end_disk_position
    assert np.allclose(mirrored, along_x * [-1.0, 1.0, 1.0], atol=1e-12)
    assert np.allclose(along_y, [-along_x[1], along_x[0], along_x[2]], atol=1e-12)


def test_warm_and_cold_agree(reduced):
    """A warm-started reduced solve lands where a cold one does."""
    target = np.array([15.0, -8.0, -5.0, 0.3, 0.2, 0.2])
    solve(reduced, 0.5 * target)
    warm = solve(reduced, target, cold=False)
    cold = solve(reduced, target)
    assert np.allclose(warm.end_disk_position, cold.end_disk_position, atol=1e-10)


def test_reduced_compliance_close_to_full(reduced, full):
    """C of a reduced level (differences of its own solves) near the full model's C."""
    wrench = PAPER_12N
    full.reset()
    expected = full.solve(wrench[:3], wrench[3:], compliance=True).compliance.matrix
    reduced.reset()
    result = reduced.solve(wrench[:3], wrench[3:], compliance=True)
    translation = result.compliance.matrix[:3, :3]
    assert np.allclose(translation, expected[:3, :3], rtol=0.1, atol=0.02 * expected[0, 0])
    assert result.to_dict()['fidelity'] == reduced.fidelity


def test_rod_model_converges_under_refinement(params):
    """RK4 in the equivalent rod: the change from 4 to 8 steps is ~16x below that of 2 to 4."""
    positions = [solve(FidelitySolver(params, fidelity='rod', rod_steps=steps),
                       np.array([20.0, 0, 0, 0, 0, 0])).end_disk_position
                 for steps in (2, 4, 8)]
    coarse = np.linalg.norm(positions[1] - positions[0])
    fine = np.linalg.norm(positions[2] - positions[1])
    assert 8.0 < coarse / fine < 32.0


def test_linear_level_is_first_order(params, full):
    """Linear: its C is the full C at the cached point and its error shrinks as offset^2."""
    solver = FidelitySolver(params, fidelity='linear')
    solver.cache_full_solution(PAPER_12N)
    direction = np.array([1.0, -0.6, 0.4, 0.02, 0.01, -0.015])
    errors = []
    for size in (1.0, 0.5):
        wrench = PAPER_12N + size * direction
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
        assert result.fidelity == 'linear'
        errors.append(pose_errors(result, solve(full, wrench)))
    for coarse, fine in zip(*errors):
        assert 3.0 < coarse / fine < 5.0
    full.reset()
    cached = full.solve(PAPER_12N[:3], compliance=True).compliance.matrix
    # two independent implicit computations at the same solution (refined to 1e-6)
    assert np.allclose(result.compliance.matrix, cached, rtol=1e-6,
                       atol=1e-7 * np.abs(cached).max())


def test_tight_budget_picks_full(params, stored):
    """A budget below every reduced level's validated error uses the full model."""
    solver = FidelitySolver(params, max_position_error=1e-9, max_angle_error_deg=1e-7)
    result = solver.solve([5.0, 1.0, 0.0])
    assert result.fidelity == 'full' and result.converged
    assert result.to_dict()['fidelity'] == 'full'
    assert FidelitySolver(params).solve([5.0, 1.0, 0.0]).fidelity == 'full'  # no budget


def _unseen(scale, count, seed):
    """Wrenches inside the box of ``scale`` that the validation did not sample."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (count, 6)) * scale * validation.box_half_widths()


def _judged_here(solver, reference, wrench):
    """Give ``solver`` the full model's verdict at ``wrench``, as a full answer there would."""
    solver.reset()
    full = solve(reference, wrench)
    solver.auto.note_full_answer(wrench, full.stable, full.stability_margin)


def test_loose_budget_picks_the_cheapest_level_within_its_measured_error(
        params, reference, stored):
    """
    The cheapest admissible level is chosen and stays inside its measured error.

    With no full solution near, the answer is full: it carries its own verdict.
    """
    cc = stored.levels['cc']
    budget = (cc.max_position_error_m[-1], cc.max_angle_error_deg[-1])
    solver = FidelitySolver(params, max_position_error=budget[0], max_angle_error_deg=budget[1])
    for wrench in _unseen(1.0, 6, seed=2024):
        solver.reset()
        alone = solver.solve(wrench[:3], wrench[3:])
        assert alone.fidelity == 'full' and alone.stable is not None, alone.message
        _judged_here(solver, reference, wrench)
        result = solver.solve(wrench[:3], wrench[3:])
        assert result.fidelity == 'cc', result.message
        assert result.stable is True and "full model's verdict" in result.message
        position, angle = pose_errors(result, solve(reference, wrench))
        assert position <= budget[0] and math.degrees(angle) <= budget[1]


def test_middle_budget_picks_rod_where_cc_is_too_coarse(params, reference, stored):
    """Between the two reduced levels' errors, 'rod' is used where 'cc' misses the budget."""
    cc, rod = stored.levels['cc'], stored.levels['rod']
    index = next(i for i in range(len(rod.scales))
                 if rod.max_position_error_m[i] < cc.max_position_error_m[i]
                 and rod.max_angle_error_deg[i] < cc.max_angle_error_deg[i] and i > 0)
    budget = (rod.max_position_error_m[index], rod.max_angle_error_deg[index])
    solver = FidelitySolver(params, max_position_error=budget[0], max_angle_error_deg=budget[1])
    inner, outer = rod.scales[index - 1], rod.scales[index]
    rng = np.random.default_rng(77)
    checked = 0
    for _ in range(40):
        wrench = rng.uniform(-1.0, 1.0, 6) * outer * validation.box_half_widths()
        scale = validation.box_scale(wrench)
        if not inner < scale <= outer or cc.within(scale, *budget):
            continue
        _judged_here(solver, reference, wrench)
        result = solver.solve(wrench[:3], wrench[3:])
        assert result.fidelity == 'rod', result.message
        position, angle = pose_errors(result, solve(reference, wrench))
        assert position <= budget[0] and math.degrees(angle) <= budget[1]
        checked += 1
        if checked == 4:
            break
    assert checked == 4


def test_auto_uses_linear_near_a_cached_solution(params, reference, stored):
    """Small steps after a full solve expand about it, inside the linear level's error."""
    linear = stored.levels['linear']
    budget = (linear.max_position_error_m[-1], linear.max_angle_error_deg[-1])
    solver = FidelitySolver(params, max_position_error=budget[0], max_angle_error_deg=budget[1])
    base = np.array([14.0, 3.0, -2.0, 0.1, -0.05, 0.08])
    step = 0.01 * linear.scales[-1] * validation.box_half_widths()
    levels = []
    for k in range(6):
        wrench = base + k * step
        result = solver.solve(wrench[:3], wrench[3:])
        levels.append(result.fidelity)
        if result.fidelity == 'linear':
            position, angle = pose_errors(result, solve(reference, wrench))
            assert position <= budget[0] and math.degrees(angle) <= budget[1]
    # 'cc' and 'rod' miss this budget at these loads, so the first solves are full; once
    # the wrench moves slowly, the full solution is expanded and reused
    assert levels[0] == 'full' and 'linear' in levels


def test_outside_the_validated_range_falls_back_to_full(params, reference, stored):
    """Past the largest validated box every budget gives the full model."""
    solver = FidelitySolver(params, max_position_error=1.0, max_angle_error_deg=180.0)
    _judged_here(solver, reference, np.array([10.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    inside = solver.solve([10.0, 0.0, 0.0])
    outside = solver.solve([1.5 * validation.BOX_FORCE_N[0], 0.0, 0.0])
    assert inside.fidelity in ('cc', 'rod', 'linear')
    assert outside.fidelity == 'full' and 'outside the validated range' in outside.message


def test_other_parameters_are_not_validated(params, stored):
    """Validation data of other parameters are ignored: the budget then uses 'full'."""
    other = params.with_changes(tube_length=0.1)
    solver = FidelitySolver(other, max_position_error=1.0, max_angle_error_deg=180.0)
    assert solver.validation is None
    assert solver.solve([10.0, 0.0, 0.0]).fidelity == 'full'
    # the full model's discretization does not change the reduced levels' errors
    finer = FidelitySolver(params.with_changes(steps_per_segment=16))
    assert finer.validation is not None


def test_validation_round_trip(tmp_path, stored):
    """Saving and loading give back the same data."""
    path = tmp_path / 'validation.yaml'
    stored.save(path, 'header line')
    assert path.read_text().startswith('# header line\n')
    assert Validation.load(path) == stored
    assert Validation.load(tmp_path / 'missing.yaml') is None


@pytest.mark.parametrize('options, message', [
    ({'fidelity': 'exact'}, 'fidelity must be one of'),
    ({'max_position_error': -1.0}, 'max_position_error'),
    ({'max_angle_error_deg': math.nan}, 'max_angle_error_deg'),
    ({'fidelity': 'cc', 'max_position_error': 1e-3}, "needs fidelity 'auto'"),
    ({'rod_steps': 0}, 'rod steps'),
])
def test_bad_options_are_value_errors(params, options, message):
    """Bad settings raise ValueError naming them."""
    with pytest.raises(ValueError, match=message):
        FidelitySolver(params, **options)


def test_drop_in_for_translator_solver(params):
    """The attributes edges use (params, time_limit_s, reset, solve) behave the same."""
    solver = FidelitySolver(params, fidelity='full')
    solver.time_limit_s = 0.0
    assert solver.full.time_limit_s == 0.0
    result = solver.solve([12.0, 0.0, 0.0])
    assert not result.converged and 'time limit' in result.message
    solver.time_limit_s = 10.0
    solver.reset()
    assert solver.solve([12.0, 0.0, 0.0]).converged and solver.params == params


def test_non_finite_wrench_is_rejected(params):
    """NaN/Inf wrench: ValueError, as with the full solver."""
    with pytest.raises(ValueError, match='force x'):
        FidelitySolver(params, fidelity='cc').solve([math.nan, 0.0, 0.0])


def test_params_file_budget(tmp_path, params):
    """from_params_file reads fidelity, max_position_error (m), max_angle_error (deg)."""
    values = dict(params.to_dict(), fidelity='auto', max_position_error=2e-3,
                  max_angle_error=0.7)
    path = tmp_path / 'translator.yaml'
    path.write_text(yaml.safe_dump({'translator_node': {'ros__parameters': values}}))
    solver = FidelitySolver.from_params_file(path)
    assert (solver.fidelity, solver.max_position_error, solver.max_angle_error_deg) == \
        ('auto', 2e-3, 0.7)
    fixed = FidelitySolver.from_params_file(path, fidelity='full', max_position_error=0.0,
                                            max_angle_error_deg=0.0)
    assert fixed.solve([1.0, 0.0, 0.0]).fidelity == 'full'


def test_cli_fidelity(capsys):
    """The CLI's --fidelity picks the level; the JSON says which; misuse exits with 2."""
    assert main(['solve', '--force', '12', '0', '0', '--fidelity', 'cc', '--json']) \
        == EXIT_CONVERGED
    data = json.loads(capsys.readouterr().out)
    assert data['fidelity'] == 'cc' and data['converged']
    assert main(['solve', '--force', '5', '0', '0', '--fidelity', 'auto',
                 '--max-position-error', '1e-9', '--max-angle-error', '1e-6']) == EXIT_CONVERGED
    assert 'fidelity' in capsys.readouterr().out
    assert main(['solve', '--force', '5', '0', '0', '--fidelity', 'rod', '--verify']) \
        == EXIT_BAD_INPUT
    assert '--fidelity full only' in capsys.readouterr().err
