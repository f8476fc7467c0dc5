"""Continuum Delta Robot forward statics: symmetry, equilibrium, kinematics, bad input."""

import itertools
import json
import math

from cdr_translator import geometry, ParameterError, TranslatorParams
from cdr_translator.cli import main
from cdr_translator.interface.settings import CdrSettings
from cdr_translator.params.translator_params import DEFAULT_PARAMS_PATH
from cdr_translator.robot.chain import Chain, ChainState
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.params import CDR_NODE_NAME, DeltaParams
import numpy as np
import pytest
from scipy.optimize import fsolve
import yaml

GRAVITY_1KG = (0.0, 0.0, -9.81)
JSON_KEYS = {'converged', 'message', 'platform_position_m', 'platform_rotation_deg',
             'leg_bending_deg', 'leg_tip_wrench', 'equilibrium_residual_norm'}


@pytest.fixture(scope='module')
def robot():
    """Build a robot with the shipped parameters; tests reset() it for a cold start."""
    return DeltaRobot()


class Layout:
    """
    The CDR layout rebuilt from the raw YAML numbers and docs/reference/conventions.md.

    Written apart from delta_params.legs() so that the tests check that code too: leg i
    leaves its base point R_b (cos a_i, sin a_i, 0) - q_i z_w along the straight line to
    its platform point R_p (cos a_i, sin a_i, 0) + p; its frame has z along that line, y
    tangential (counter-clockwise) and x = y cross z.
    """

    def __init__(self):
        document = yaml.safe_load(DEFAULT_PARAMS_PATH.read_text())
        cdr = document[CDR_NODE_NAME]['ros__parameters']
        leg = TranslatorParams.from_yaml()
        self.joint = (leg.spacers_per_joint + 1) * leg.disk_spacing
        self.tube = leg.tube_length
        self.height = 2.0 * self.joint + self.tube
        self.base_radius = cdr['base_radius']
        self.platform_radius = cdr['platform_radius']
        azimuths = np.radians(cdr['leg_azimuths_deg'])
        self.radial = np.stack([np.cos(azimuths), np.sin(azimuths), np.zeros(3)], axis=1)
        drop = math.sqrt(self.height ** 2 - (self.base_radius - self.platform_radius) ** 2)
        self.home = np.array([0.0, 0.0, -drop])
        self.frames = []
        for radial in self.radial:
            z_axis = ((self.platform_radius - self.base_radius) * radial + self.home) / self.height
            y_axis = np.cross([0.0, 0.0, 1.0], radial)
            self.frames.append(np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis]))

    def base(self, leg, slider):
        """Base-disk centre of a leg (sliders parallel to the robot axis, + towards -z)."""
        return self.base_radius * self.radial[leg] - np.array([0.0, 0.0, slider])

    def arc(self, theta):
        """
        Constant-curvature translator: (lateral, axial) end-disk offset at bending theta.

        Both joints bend by theta in opposite senses (the end disk stays parallel), each
        an arc of length `joint`, joined by the straight tube.
        """
        if abs(theta) < 1e-9:
            return (self.joint + self.tube) * theta, self.height
        lateral = 2.0 * self.joint * (1.0 - math.cos(theta)) / theta + self.tube * math.sin(theta)
        axial = 2.0 * self.joint * math.sin(theta) / theta + self.tube * math.cos(theta)
        return lateral, axial

    def constant_curvature(self, sliders):
        """Platform position and leg bending angles of the purely kinematic model."""
        def equations(unknowns):
            position, thetas = unknowns[:3], unknowns[3:]
            out = []
            for leg in range(3):
                offset = (position + self.platform_radius * self.radial[leg]
                          - self.base(leg, sliders[leg]))
                axis = self.frames[leg][:, 2]
                axial = offset @ axis
                lateral = np.linalg.norm(offset - axial * axis)
                want_lateral, want_axial = self.arc(thetas[leg])
                out += [lateral - want_lateral, axial - want_axial]
            return out
        guess = np.concatenate([self.home - [0.0, 0.0, np.mean(sliders)], np.full(3, 0.05)])
        solution, info, flag, message = fsolve(equations, guess, full_output=True, xtol=1e-13)
        assert flag == 1, message
        return solution[:3], solution[3:]


@pytest.fixture(scope='module')
def layout():
    """Rebuild the layout independently of delta_params."""
    return Layout()


def converged(robot, sliders, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0),
              offset=(0.0, 0.0, 0.0)):
    """Solve and insist on convergence and a small equilibrium residual."""
    result = robot.solve(sliders, force, moment, offset)
    assert result.converged, result.message
    assert result.equilibrium_residual_norm <= 1e-9
    return result


def test_home_is_exact(robot, layout):
    """Sliders at home, no payload: straight legs, platform at home, nothing loaded."""
    robot.reset()
    result = converged(robot, (0.0, 0.0, 0.0))
    assert result.iterations == 0
    assert np.allclose(result.platform_position, layout.home, atol=1e-15)
    assert np.allclose(result.platform_rotation, np.eye(3), atol=1e-15)
    assert np.all(result.leg_tip_wrenches == 0.0)
    assert np.all(result.leg_bending == 0.0)


@pytest.mark.parametrize('slider', [0.0, 0.012, -0.02])
def test_equal_sliders_centred_payload(robot, layout, slider):
    """Equal sliders, centred vertical payload: on the axis, no rotation, equal legs."""
    result = converged(robot, (slider,) * 3, GRAVITY_1KG)
    position = result.platform_position
    assert np.hypot(position[0], position[1]) < 1e-12
    # the platform follows the sliders rigidly; the legs only stretch (micrometres)
    assert abs(position[2] - (layout.home[2] - slider)) < 1e-5
    assert result.platform_rotation_angle < 1e-10
    wrenches = result.leg_tip_wrenches
    assert np.abs(wrenches - wrenches[0]).max() < 1e-10
    # each leg carries a third of the weight, along its axis (tension)
    axial = wrenches[0, 2]
    cosine = -layout.frames[0][2, 2]
    assert abs(axial - 9.81 / (3.0 * cosine)) < 1e-3 * axial
    assert np.abs(wrenches[0, :2]).max() < 1e-3 * axial  # the leg stays nearly straight
    assert np.degrees(result.leg_bending).max() < 1e-3


def test_cyclic_and_mirror_symmetry(robot):
    """Legs at 120 deg: permuting sliders turns the answer; mirroring y flips it."""
    sliders = np.array([0.012, -0.004, 0.006])
    force = np.array([1.0, -2.0, -5.0])
    turn = np.array([[-0.5, -math.sqrt(0.75), 0.0], [math.sqrt(0.75), -0.5, 0.0],
                     [0.0, 0.0, 1.0]])
    reference = converged(robot, sliders, force)
    turned = converged(robot, np.roll(sliders, 1), turn @ force)
    assert np.allclose(turned.platform_position, turn @ reference.platform_position,
                       atol=1e-9)
    assert np.allclose(turned.platform_rotation_vector,
                       turn @ reference.platform_rotation_vector, atol=1e-9)
    assert np.allclose(turned.leg_tip_wrenches, np.roll(reference.leg_tip_wrenches, 1, axis=0),
                       atol=1e-7)
    mirror = np.diag([1.0, -1.0, 1.0])
    mirrored = converged(robot, sliders[[0, 2, 1]], mirror @ force)
    assert np.allclose(mirrored.platform_position, mirror @ reference.platform_position,
                       atol=1e-9)
    assert abs(mirrored.platform_rotation_angle - reference.platform_rotation_angle) < 1e-9


@pytest.mark.parametrize('sliders', [(0.01, 0.0, 0.0), (0.02, -0.01, 0.0),
                                     (0.015, -0.015, 0.015), (-0.03, 0.03, -0.03)])
def test_zero_payload_matches_constant_curvature(robot, layout, sliders):
    """
    No payload: the platform goes where the constant-curvature kinematics puts it.

    The Cosserat legs deviate from arcs and their DJ bends a little less than the PJ (the
    platform is not perfectly parallel), so agreement is to about 1 % of the motion.
    """
    result = converged(robot, sliders)
    position, thetas = layout.constant_curvature(np.array(sliders))
    motion = np.linalg.norm(position - layout.home)
    assert np.linalg.norm(result.platform_position - position) < 0.015 * motion
    mean_bending = result.leg_bending.mean(axis=1)
    assert np.allclose(mean_bending, thetas, rtol=0.05)
    assert np.all(result.leg_bending[:, 1] < result.leg_bending[:, 0])
    # the kinematic model's platform only translates; the Cosserat one nearly so
    assert math.degrees(result.platform_rotation_angle) < 0.04 * np.degrees(thetas).max()


@pytest.mark.parametrize('sliders', [(0.0, 0.0, 0.0), (0.01, -0.005, 0.002)])
def test_payload_sweep_mostly_translates(robot, sliders):
    """
    A 1 kg payload in 26 directions: the platform moves < 0.05 mm and turns < 0.1 deg.

    (Measured: 0.037-0.039 mm and 0.063-0.065 deg; docs/explanation/robot.md.)
    """
    unloaded = converged(robot, sliders)
    directions = [np.array(d, float) / np.linalg.norm(d)
                  for d in itertools.product((-1, 0, 1), repeat=3) if any(d)]
    for direction in directions:
        result = converged(robot, sliders, 9.81 * direction)
        moved = np.linalg.norm(result.platform_position - unloaded.platform_position)
        turned = geometry.rotation_angle(result.platform_rotation
                                         @ unloaded.platform_rotation.T)
        assert moved < 5e-5
        assert math.degrees(turned) < 0.1


def test_equilibrium_and_compatibility_recomputed(robot, layout):
    """
    Off-centre payload with a moment: the legs' own results balance it.

    The balance is recomputed here from each leg's solved end-disk pose (not the platform's
    attachment points the solver uses), and each end disk sits on the platform.
    """
    sliders = np.array([0.015, -0.01, 0.004])
    force, moment, offset = (np.array([2.0, -1.0, -9.81]), np.array([0.05, 0.02, -0.03]),
                             np.array([0.01, -0.02, -0.03]))
    result = converged(robot, sliders, force, moment, offset)
    rotation = result.platform_rotation
    total_force = force.copy()
    total_moment = moment + np.cross(rotation @ offset, force)
    for leg, solved in enumerate(result.leg_results):
        frame = layout.frames[leg]
        end = layout.base(leg, sliders[leg]) + frame @ solved.end_disk_position
        wrench = result.leg_tip_wrenches[leg]
        assert np.allclose(wrench, np.concatenate([solved.force, solved.moment]))
        reaction = -frame @ wrench[:3]
        total_force += reaction
        total_moment += np.cross(end - result.platform_position, reaction) - frame @ wrench[3:]
        attachment = (result.platform_position
                      + rotation @ (layout.platform_radius * layout.radial[leg]))
        assert np.linalg.norm(end - attachment) < 1e-9
        # the end disk keeps its home orientation relative to the platform
        relative = (frame @ solved.frames['de'][:3, :3]).T @ rotation @ frame
        assert geometry.rotation_angle(relative) < 1e-9
    assert np.linalg.norm(total_force) < 1e-9
    assert np.linalg.norm(total_moment) < 1e-9


def test_warm_and_cold_solves_agree(robot):
    """A warm-started solve lands where a cold one does."""
    robot.reset()
    converged(robot, (0.01, 0.0, -0.01), (0.0, 3.0, -9.81))
    warm = converged(robot, (0.012, 0.002, -0.008), (1.0, 2.0, -9.81))
    robot.reset()
    cold = converged(robot, (0.012, 0.002, -0.008), (1.0, 2.0, -9.81))
    assert np.allclose(warm.platform_position, cold.platform_position, atol=1e-10)
    assert np.allclose(warm.leg_tip_wrenches, cold.leg_tip_wrenches, atol=1e-6)


@pytest.mark.parametrize('fidelity', ['full', 'cc'])
def test_cold_solves_under_upward_payloads_across_the_node_force_range(fidelity):
    """
    Every slider corner, edge and centre under upward payloads up to cdr_node's max_force.

    An upward payload compresses the legs past their free-end buckling load (29.6 N each
    near 90 N; 29.4 N for a 'cc' leg), where a leg solved under its wrench alone has
    strongly bent shapes besides the chain's, and its Jacobian alone is singular at that
    load: each solve must still converge, stable (held at both ends the legs buckle only
    near 1100 N), with the legs in compression. Cold: the continuation from home.
    """
    settings = CdrSettings.from_params_file(DEFAULT_PARAMS_PATH)
    robot = DeltaRobot(settings.params, settings.geometry, time_limit_s=5.0, fidelity=fidelity)
    stroke = robot.geometry.slider_stroke
    failed = []
    for sliders in itertools.product((-stroke, 0.0, stroke), repeat=3):
        for share in (0.25, 0.5, 0.75, 1.0):
            payload = (0.0, 0.0, share * settings.max_force)
            result = robot.solve(sliders, payload, warm_start=False, compliance=True)
            if not (result.converged and result.stable is True):
                failed.append((sliders, payload, result.message))
            elif share == 1.0:
                assert np.all(result.leg_tip_wrenches[:, 2] < 0.0)  # compression
    assert not failed, failed


def test_cli_delta_upward_payload_past_the_free_end_buckling_load(capsys):
    """The sliders that converge at 0, +30 and -90 N converge at +90 N too, exit 0."""
    assert main(['delta', '--sliders', '0.02', '-0.01', '0', '--payload', '0', '0', '90',
                 '--time-limit', '5', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['converged'] is True and data['stable'] is True
    assert data['message'] == 'converged'
    assert max(max(leg) for leg in data['leg_bending_deg']) < 15.0  # not a far branch


def test_a_diverged_leg_frame_is_an_arithmetic_error(robot):
    """
    A leg shot whose end-disk frame is no rotation fails the Newton step that made it.

    An ArithmeticError, which the continuation answers by a shorter step, not scipy's
    ValueError out of ``solve`` (seen on a coupled walk from home to 1000 N).
    """
    chain = Chain(robot.legs, robot.params)
    state = ChainState(robot.home_position.copy(), np.eye(3), np.zeros((3, 6)),
                       np.zeros((3, 1)), frames=np.tile(np.eye(4), (3, 1, 1)))
    state.frames[1, :3, :3] = np.diag([-1e10, -3e9, -2e9])  # improper, far from a rotation
    with pytest.raises(ArithmeticError, match='end-disk frame of leg 2 is no rotation'):
        chain.residual(state, np.zeros(12))


@pytest.mark.parametrize('kwargs, fragment', [
    ({'sliders': (0.0, float('nan'), 0.0)}, 'slider 2 position is nan'),
    ({'sliders': (0.0, 0.0)}, 'sliders must have 3 positions'),
    ({'sliders': (0.0, 0.0, 0.031)}, 'slider 3 position 0.031 m is outside the stroke'),
    ({'payload_force': (0.0, float('inf'), 0.0)}, 'force y component is inf'),
    ({'payload_force': (0.0, 0.0)}, 'force must have 3 components'),
    ({'payload_moment': (float('nan'), 0.0, 0.0)}, 'moment x component is nan'),
    ({'payload_offset': (0.0, 0.0)}, 'payload offset must be 3 finite coordinates'),
])
def test_bad_input_raises(robot, kwargs, fragment):
    """Bad input is a ValueError naming the value."""
    arguments = {'sliders': (0.0, 0.0, 0.0), 'payload_force': (0.0, 0.0, 0.0)}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=fragment):
        robot.solve(**arguments)


def test_non_convergence_is_a_result():
    """Out of time: converged False, a message, the last good state, no exception."""
    robot = DeltaRobot(time_limit_s=0.0)
    result = robot.solve((0.02, 0.0, 0.0), GRAVITY_1KG)
    assert result.converged is False
    assert 'time limit' in result.message
    assert len(result.leg_results) == 3
    assert np.isfinite(result.equilibrium_residual_norm)
    assert result.equilibrium_residual_norm > 1.0  # the payload is not carried yet


def shipped_geometry(**changes):
    """Return the shipped cdr_node values with some changed (None deletes a key)."""
    values = yaml.safe_load(DEFAULT_PARAMS_PATH.read_text())[CDR_NODE_NAME]['ros__parameters']
    for key, value in changes.items():
        if value is None:
            values.pop(key)
        else:
            values[key] = value
    return values


@pytest.mark.parametrize('key, value, fragment', [
    ('base_radius', -0.1, 'base_radius must be positive'),
    ('platform_radius', 'wide', 'platform_radius must be a number'),
    ('slider_stroke', float('nan'), 'slider_stroke must be finite'),
    ('slider_inclination_deg', 90.0, 'slider_inclination_deg must lie in'),
    ('leg_azimuths_deg', [0.0, 120.0], 'leg_azimuths_deg must be three finite numbers'),
    ('leg_azimuths_deg', [0.0, 360.0, 120.0], 'two legs share a radial plane'),
    ('base_radius', None, 'missing cdr_node parameter.*base_radius'),
    ('leg_count', 3, 'unknown cdr_node parameter.*leg_count'),
])
def test_bad_geometry_names_the_key(key, value, fragment):
    """Bad geometry values raise ParameterError naming the key."""
    with pytest.raises(ParameterError, match=fragment):
        DeltaParams.from_mapping(shipped_geometry(**{key: value}))


def test_geometry_file_errors(tmp_path):
    """A params file with nothing for the robot, or no file, is a ParameterError."""
    path = tmp_path / 'params.yaml'
    path.write_text('some_node:\n  ros__parameters: {}\n')
    with pytest.raises(ParameterError, match='has no section for cdr_node or translator_node'):
        DeltaParams.from_yaml(path)
    with pytest.raises(ParameterError, match='cannot read parameter file'):
        DeltaParams.from_yaml(tmp_path / 'missing.yaml')


def test_unreachable_platform_rejected():
    """Radii further apart than a leg is long cannot hold straight legs at home."""
    geometry_params = DeltaParams.from_mapping(shipped_geometry(base_radius=0.5))
    with pytest.raises(ParameterError, match='straight legs cannot reach the platform'):
        DeltaRobot(TranslatorParams.from_yaml(), geometry_params)


def test_inclined_sliders():
    """Sliders along the legs: equal strokes push each leg along its own axis."""
    leg_params = TranslatorParams.from_yaml()
    shipped = DeltaParams.from_yaml()
    beta = math.degrees(shipped.leg_inclination(leg_params.stack_height))
    inclined = DeltaParams.from_mapping(shipped_geometry(slider_inclination_deg=beta))
    robot = DeltaRobot(leg_params, inclined)
    for leg in robot.legs:
        assert np.allclose(leg.slider_axis, leg.rotation[:, 2])
    result = converged(robot, (0.005, 0.005, 0.005))
    assert np.hypot(*result.platform_position[:2]) < 1e-12
    assert result.platform_rotation_angle < 1e-10
    # the base disks close in on the axis, so the legs S-bend and the platform drops further
    assert result.platform_displacement[2] < -0.005 * math.cos(math.radians(beta))
    assert np.degrees(result.leg_bending).min() > 0.5


def test_cli_delta_json(capsys):
    """`delta --sliders 0 0 0 --payload 0 0 -9.81 --json`: the contract keys, symmetric."""
    assert main(['delta', '--sliders', '0', '0', '0', '--payload', '0', '0', '-9.81',
                 '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert JSON_KEYS <= set(data)
    assert data['converged'] is True
    assert np.hypot(*data['platform_position_m'][:2]) < 1e-12
    assert data['platform_rotation_deg'] < 1e-8
    assert np.array(data['leg_bending_deg']).shape == (3, 2)
    wrenches = np.array(data['leg_tip_wrench'])
    assert wrenches.shape == (3, 6) and np.ptp(wrenches, axis=0).max() < 1e-10
    assert data['equilibrium_residual_norm'] <= 1e-9


def test_cli_delta_table_and_exit_codes(capsys):
    """A readable table; exit 2 for bad input, 3 when not converged (JSON still printed)."""
    assert main(['delta', '--sliders', '0.01', '0', '-0.005', '--payload', '1', '0', '-5']) == 0
    assert 'leg 3 PJ / DJ bending' in capsys.readouterr().out
    assert main(['delta', '--sliders', '0', 'nan', '0']) == 2
    assert 'slider 2 position is nan' in capsys.readouterr().err
    assert main(['delta', '--sliders', '0.01', '0', '0', '--time-limit', '0', '--json']) == 3
    data = json.loads(capsys.readouterr().out)
    assert data['converged'] is False and 'time limit' in data['message']
