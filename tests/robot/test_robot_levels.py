"""The robot on every leg level: agreement with full legs, auto, the atlas and the CLI."""

import json

from cdr_translator.cli import main
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.robot.atlas import load_results, run_atlas
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.samples import AtlasSpec, LEVEL_CODES
import numpy as np
import pytest

GRAVITY_1KG = (0.0, 0.0, -9.81)


@pytest.fixture(scope='module')
def full() -> DeltaRobot:
    """Return a robot with full legs: the reference."""
    return DeltaRobot()


@pytest.fixture(scope='module', params=['cc', 'rod'])
def reduced(request) -> DeltaRobot:
    """Return a robot with reduced legs of each level."""
    return DeltaRobot(fidelity=request.param)


def _unseen_settings(stroke: float) -> list:
    """Slider settings and payloads no other test or the bench uses (a fixed seed)."""
    rng = np.random.default_rng(20261203)
    return [(rng.uniform(-0.6, 0.6, 3) * stroke, rng.uniform([-2, -2, -12], [2, 2, -2]))
            for _ in range(3)]


def test_reduced_levels_agree_with_full_legs_within_their_validated_error(full, reduced):
    """Platform pose within the legs' validated errors of full legs; compliance close too."""
    level = reduced.fidelity
    for sliders, payload in _unseen_settings(full.geometry.slider_stroke):
        expected = full.solve(sliders, payload, warm_start=False, compliance=True)
        result = reduced.solve(sliders, payload, warm_start=False, compliance=True)
        assert result.converged and expected.converged
        assert result.leg_fidelity == (level,) * 3
        bounds = np.array(result.leg_error_bound_m)
        assert np.all(np.isfinite(bounds)) and np.all(bounds > 0.0)
        error = np.linalg.norm(result.platform_position - expected.platform_position)
        assert error <= bounds.max()
        angle = np.degrees(np.linalg.norm(result.platform_rotation_vector
                                          - expected.platform_rotation_vector))
        assert angle <= max(result.leg_error_bound_deg)
        # the platform compliance from the reduced legs' implicit compliances
        scale = np.abs(expected.platform_compliance).max()
        assert np.abs(result.platform_compliance - expected.platform_compliance).max() \
            < 0.1 * scale
        assert result.stable is expected.stable
        assert [leg.fidelity for leg in result.leg_results] == [level] * 3
        data = result.to_dict()
        assert data['leg_fidelity'] == [level] * 3
        assert data['leg_error_bound_position_m'] == pytest.approx(list(bounds))
    assert expected.to_dict()['leg_fidelity'] == ['full'] * 3
    assert expected.to_dict()['leg_error_bound_position_m'] == [None] * 3


def test_warm_solves_equal_cold_ones(reduced):
    """Along a short path the warm solves reach the cold solves' answers."""
    reduced.reset()
    for step in range(4):
        sliders = (0.002 * step, -0.001 * step, 0.0)
        warm = reduced.solve(sliders, GRAVITY_1KG)
        cold = reduced.solve(sliders, GRAVITY_1KG, warm_start=False)
        assert np.allclose(warm.platform_position, cold.platform_position, atol=1e-9)


def test_leg_compliance_equals_finite_differences_of_leg_solves(reduced):
    """A reduced leg's implicit compliance equals differences of its own solves."""
    level = reduced.fidelity
    chain = reduced._reduced.chains[level]
    wrench = np.array([1.5, -0.8, -4.0, 0.02, -0.03, 0.005])
    single = FidelitySolver(reduced.params, level)
    solved = single.solve(wrench[:3], wrench[3:], compliance=True)
    x = solved.unknowns / chain.model.unknown_scale
    _, compliance, _ = chain.leg_linearization(x, wrench)
    reference = solved.compliance.matrix
    assert np.abs(compliance - reference).max() < 1e-4 * np.abs(reference).max()


def test_auto_takes_a_reduced_level_within_the_budget_else_full(full):
    """A 3 mm / 2 deg budget takes reduced legs; a tiny one needs full legs."""
    loose = DeltaRobot(fidelity='auto', max_position_error=3e-3, max_angle_error=2.0)
    result = loose.solve((0.004, 0.0, -0.002), GRAVITY_1KG)
    assert result.converged and result.leg_fidelity[0] in ('cc', 'rod')
    assert max(result.leg_error_bound_m) <= 3e-3
    assert max(result.leg_error_bound_deg) <= 2.0
    tight = DeltaRobot(fidelity='auto', max_position_error=1e-9, max_angle_error=1e-6)
    refined = tight.solve((0.004, 0.0, -0.002), GRAVITY_1KG)
    assert refined.leg_fidelity == ('full',) * 3
    expected = full.solve((0.004, 0.0, -0.002), GRAVITY_1KG, warm_start=False)
    assert np.allclose(refined.platform_position, expected.platform_position, atol=1e-9)


def test_bad_levels_and_budgets_name_the_value():
    """An unknown level or a budget without 'auto' is ValueError naming it."""
    with pytest.raises(ValueError, match='bogus'):
        DeltaRobot(fidelity='bogus')
    with pytest.raises(ValueError, match="'cc'"):
        DeltaRobot(fidelity='cc', max_position_error=1e-3)
    with pytest.raises(ValueError, match='max_angle_error'):
        DeltaRobot(fidelity='auto', max_angle_error=-1.0)


def test_atlas_at_cc_equals_direct_solves(tmp_path):
    """`atlas --fidelity cc` on a 2x2x2 grid equals cold cc solves sample by sample."""
    spec = AtlasSpec.build(2, [GRAVITY_1KG], fidelity='cc')
    out = tmp_path / 'atlas.zarr'
    run_atlas(spec, out, chunk_size=4, workers=1, progress=False)
    loaded, results = load_results(out)
    assert loaded == spec
    robot = DeltaRobot(fidelity='cc')
    for sample in range(spec.size):
        direct = robot.solve(results['sliders'][sample], GRAVITY_1KG, warm_start=False,
                             compliance=True)
        assert direct.converged and results['converged'][sample]
        assert np.allclose(results['platform_position'][sample], direct.platform_position,
                           atol=1e-9)
        assert np.allclose(results['leg_bending'][sample], direct.leg_bending, atol=1e-8)
        translation, _ = direct.compliance_eigenvalues
        assert np.allclose(results['compliance_eigenvalues_translation'][sample], translation,
                           rtol=1e-5)
        assert list(results['leg_fidelity'][sample]) == [LEVEL_CODES['cc']] * 3
        assert np.allclose(results['leg_error_bound_position'][sample],
                           direct.leg_error_bound_m, equal_nan=True)
        assert np.allclose(results['leg_error_bound_angle'][sample], direct.leg_error_bound_deg,
                           equal_nan=True)


def test_cli_fidelity_flags(capsys):
    """The delta / delta-ik --fidelity LEVEL report their legs' level; a bad level is exit 2."""
    assert main(['delta', '--sliders', '0.004', '0', '0', '--payload', '0', '0', '-9.81',
                 '--fidelity', 'cc', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['leg_fidelity'] == ['cc'] * 3 and data['converged'] is True
    target = [str(value) for value in data['platform_position_m']]
    assert main(['delta-ik', '--target', *target, '--payload', '0', '0', '-9.81',
                 '--fidelity', 'cc', '--json']) == 0
    inverse = json.loads(capsys.readouterr().out)
    assert np.allclose(inverse['sliders_m'], [0.004, 0.0, 0.0], atol=1e-6)
    for command in (['delta', '--sliders', '0', '0', '0'], ['delta-ik', '--target', '0', '0',
                                                            '-0.13'],
                    ['atlas', '--grid', '2', '--out', 'unused.zarr']):
        with pytest.raises(SystemExit) as stopped:
            main([*command, '--fidelity', 'bogus'])
        assert stopped.value.code == 2
        assert "'bogus'" in capsys.readouterr().err
    assert main(['delta', '--sliders', '0', '0', '0', '--fidelity', 'rod',
                 '--max-position-error', '0.001']) == 2
    assert "'rod'" in capsys.readouterr().err
