"""Inverse statics of the Continuum Delta Robot, and the platform compliance / stability."""

import json
import re

from cdr_translator.cli import main
from cdr_translator.robot.delta import DeltaRobot
import numpy as np
import pytest

GRAVITY_1KG = (0.0, 0.0, -9.81)


@pytest.fixture(scope='module')
def robot():
    """Build the shipped robot, used for inverse solves."""
    return DeltaRobot()


@pytest.fixture(scope='module')
def checker():
    """Build a second robot for forward checks (no warm start shared with ``robot``)."""
    return DeltaRobot()


def test_round_trip_on_random_reachable_targets(robot, checker):
    """forward(inverse(x)) = x within 1e-6 m on targets made from random slider settings."""
    rng = np.random.default_rng(16)
    stroke = robot.geometry.slider_stroke
    for sliders in rng.uniform(-0.9 * stroke, 0.9 * stroke, size=(4, 3)):
        payload = rng.normal(0.0, 3.0, 3) + np.array(GRAVITY_1KG)
        target = checker.solve(sliders, payload, warm_start=False).platform_position
        result = robot.inverse(target, payload, warm_start=False)
        assert result.converged and result.reachable, result.message
        assert np.all(np.abs(result.sliders) <= stroke)
        assert result.binding == ()
        check = checker.solve(result.sliders, payload, warm_start=False)
        assert check.converged
        assert np.linalg.norm(check.platform_position - target) < 1e-6
        # the map is one-to-one here: the sliders that made the target come back
        assert np.allclose(result.sliders, sliders, atol=1e-7)
        assert result.platform_rotation_angle == pytest.approx(check.platform_rotation_angle,
                                                               abs=1e-9)


def test_warm_start_along_a_path(robot):
    """Along a 1 mm-step path each solve needs at most two Newton iterations."""
    robot.inverse((0.0, 0.0, -0.13), GRAVITY_1KG, warm_start=False)
    for step in range(1, 4):
        result = robot.inverse((0.001 * step, 0.0005 * step, -0.13), GRAVITY_1KG)
        assert result.converged and result.reachable, result.message
        assert result.iterations <= 2
        assert result.position_error <= 1e-9


@pytest.mark.parametrize('target, binding', [
    ((0.0, 0.0, -0.25), ('slider 1 upper', 'slider 2 upper', 'slider 3 upper')),
    ((0.05, 0.0, -0.13), ('slider 1 lower', 'slider 2 upper', 'slider 3 upper')),
])
def test_unreachable_target_is_a_result(robot, checker, target, binding):
    """Beyond the stroke: the nearest reachable point, the binding limits, no exception."""
    result = robot.inverse(target, GRAVITY_1KG, warm_start=False)
    assert result.converged is True and result.reachable is False
    assert 'unreachable' in result.message and 'stroke limit' in result.message
    assert result.binding == binding
    stroke = robot.geometry.slider_stroke
    assert np.all(np.abs(result.sliders) <= stroke)
    assert result.position_error > 1e-3
    # the reported nearest point is where the sliders put the platform
    check = checker.solve(result.sliders, GRAVITY_1KG, warm_start=False)
    assert np.allclose(check.platform_position, result.platform_position, atol=1e-9)
    # and no neighbouring admissible slider setting is nearer to the target
    for axis in range(3):
        for sign in (-1.0, 1.0):
            moved = result.sliders.copy()
            moved[axis] = np.clip(moved[axis] + sign * 1e-3, -stroke, stroke)
            if np.array_equal(moved, result.sliders):
                continue
            near = checker.solve(moved, GRAVITY_1KG).platform_position
            assert np.linalg.norm(near - target) >= result.position_error - 1e-9


@pytest.mark.parametrize('kwargs, fragment', [
    ({'platform_position': (0.0, float('nan'), -0.13)}, 'target y coordinate is nan'),
    ({'platform_position': (0.0, -0.13)}, 'target must have 3 coordinates'),
    ({'payload_force': (0.0, 0.0, float('inf'))}, 'force z component is inf'),
])
def test_bad_input_raises(robot, kwargs, fragment):
    """Bad input is a ValueError naming the value."""
    arguments = {'platform_position': (0.0, 0.0, -0.13)}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=fragment):
        robot.inverse(**arguments)


def test_platform_compliance_matches_finite_differences(checker):
    """C from the assembled Jacobian equals central differences of loaded solves."""
    sliders, payload = np.array([0.01, -0.005, 0.002]), np.array([1.0, -2.0, -9.81])
    result = checker.solve(sliders, payload, compliance=True)
    assert result.stable is True and result.stiffness_margin > 0.0
    compliance = result.platform_compliance
    step = 1e-2
    for column in (0, 2, 4):
        extra = np.zeros(6)
        extra[column] = step
        poses = []
        for sign in (1.0, -1.0):
            moved = checker.solve(sliders, payload + sign * extra[:3], sign * extra[3:])
            rotation = moved.platform_rotation @ result.platform_rotation.T
            poses.append(np.concatenate([moved.platform_position,
                                         _rotation_vector(rotation)]))
        difference = (poses[0] - poses[1]) / (2.0 * step)
        assert np.allclose(difference, compliance[:, column],
                           atol=1e-4 * np.abs(compliance[:, column]).max())
    translation, rotation = result.compliance_eigenvalues
    assert np.all(translation > 0.0) and np.all(rotation > 0.0)
    sensitivity = result.input_sensitivity
    moved = checker.solve(sliders + [1e-6, 0.0, 0.0], payload)
    assert np.allclose((moved.platform_position - result.platform_position) / 1e-6,
                       sensitivity[:3, 0], atol=1e-4)


def _rotation_vector(rotation):
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(rotation).as_rotvec()


def test_cli_delta_ik_json_and_exit_codes(capsys):
    """`delta-ik --json`: the contract keys; 0 reached, 3 unreachable, 2 bad input."""
    assert main(['delta-ik', '--target', '0.01', '0', '-0.13', '--payload', '0', '0',
                 '-9.81', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert {'converged', 'reachable', 'message', 'sliders_m', 'platform_position_m',
            'platform_rotation_deg', 'solve_time_s', 'stable'} <= set(data)
    assert data['converged'] is True and data['reachable'] is True
    assert np.allclose(data['platform_position_m'], [0.01, 0.0, -0.13], atol=1e-9)
    assert main(['delta-ik', '--target', '0', '0', '-0.3', '--json']) == 3
    data = json.loads(capsys.readouterr().out)
    assert data['reachable'] is False and 'unreachable' in data['message']
    assert main(['delta-ik', '--target', '0', 'nan', '-0.1']) == 2
    assert 'target y coordinate is nan' in capsys.readouterr().err


def test_cli_delta_ik_table_says_what_happened(capsys):
    """The table of an unreachable target names the outcome; it never says 'converged True'."""
    assert main(['delta-ik', '--target', '10', '0', '-130']) == 3   # mm typed as m
    out = capsys.readouterr().out
    first, second = out.splitlines()[:2]
    assert first.split(None, 1)[0] == 'result'
    assert first.split(None, 1)[1].startswith(
        'nearest reachable point found, target unreachable: [10000.000, 0.000, -130000.000] mm')
    assert 'stroke limit' in first and second.split() == ['reachable', 'False']
    assert 'converged' not in out
    assert main(['delta-ik', '--target', '0.01', '0', '-0.13']) == 0
    assert capsys.readouterr().out.splitlines()[0].split(None, 1)[1].startswith(
        'target reached')


def test_cli_delta_ik_table_is_in_mm_and_counts_in_words(capsys):
    """Every length of the table in mm, the position error too; '1 iteration', 'forward solve'."""
    assert main(['delta-ik', '--target', '0.001', '0', '-0.127']) == 0
    rows = dict(re.split(r'\s{2,}', line, maxsplit=1)
                for line in capsys.readouterr().out.splitlines())
    error = rows['position error']
    assert error.endswith(' mm') and float(error[:-3]) < 1e-3
    assert '(1 iteration, 2 forward solves)' in rows['solve time']
    assert main(['delta-ik', '--target', '0', '0', '-0.12714']) == 0
    assert '(0 iterations, 1 forward solve)' in capsys.readouterr().out


def test_cli_delta_has_stability(capsys):
    """`delta --json` now carries the platform compliance and the stability verdict."""
    assert main(['delta', '--sliders', '0.01', '0', '0', '--payload', '0', '0', '-9.81',
                 '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['stable'] is True
    assert np.array(data['platform_compliance']).shape == (6, 6)
    assert len(data['platform_compliance_eigenvalues']['translation_m_per_n']) == 3
