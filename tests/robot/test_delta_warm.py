"""CDR warm solves: leg results built on access, the Broyden updates, the compiled residual."""

import math

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.robot import coupled_newton, kernels
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.linearization import MAX_SECANTS, Secants
from cdr_translator.robot.result import LegResults, rotation_vector
import numpy as np
import pytest

GRAVITY_1KG = (0.0, 0.0, -9.81)


@pytest.fixture(scope='module')
def robot():
    """Build a robot with the shipped parameters."""
    return DeltaRobot()


def _warm_result(robot):
    """Return a coupled (warm) solve after one from home: its legs are not built yet."""
    robot.reset()
    robot.solve((0.01, -0.004, 0.0), GRAVITY_1KG)
    result = robot.solve((0.011, -0.003, 0.001), (0.5, 0.0, -9.81))
    assert result.converged, result.message
    assert result.leg_solves == 0  # coupled: no full leg solve
    return result


def _leg_solver(robot):
    """Return a leg solver as the robot's: no refinement, no branch following."""
    return TranslatorSolver(robot.params, accuracy=Accuracy(0.0, 0.0),
                            follow_stable_branch=False)


def test_leg_results_built_on_access_match_full_leg_solves(robot):
    """
    Each deferred leg result equals a full leg solve under its tip wrench (1e-9).

    Shape, end-disk frames and unknowns agree with a cold solve of the leg alone; the
    stability verdict and error estimate agree (their margin and the estimate's solution
    part come from the iteration's factorization, so only to its drift: a few %).
    """
    result = _warm_result(robot)
    legs = result.leg_results
    assert isinstance(legs, LegResults) and len(legs) == 3
    assert 'deferred' in repr(legs)
    for k in range(3):
        leg = legs[k]
        assert legs[k] is leg  # built once, kept
        wrench = result.leg_tip_wrenches[k]
        full = _leg_solver(robot).solve(wrench[:3], wrench[3:])
        assert leg.converged and full.converged
        assert leg.message == 'converged'
        for name in ('pe', 'pm', 'dm', 'de'):
            assert np.abs(leg.frames[name] - full.frames[name]).max() <= 1e-9
        assert np.abs(leg.backbones - full.backbones).max() <= 1e-9
        assert np.allclose(leg.unknowns, full.unknowns, rtol=1e-6, atol=1e-9)
        assert leg.stable is full.stable is True
        assert leg.stability_margin == pytest.approx(full.stability_margin, rel=5e-2)
        assert leg.error_estimate_m == pytest.approx(full.error_estimate_m, rel=5e-2)
        assert leg.error_estimate_deg == pytest.approx(full.error_estimate_deg, rel=5e-2)
    assert legs == tuple(legs)  # compares as the tuple of its results
    assert legs[1:] == (legs[1], legs[2])
    assert len(result.to_dict()['leg_bending_deg']) == 3


def test_result_at_is_a_solve_started_there():
    """result_at gives what start_at + solve gives at converged unknowns, warm start kept."""
    params = TranslatorParams.from_yaml()
    solver = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False)
    wrench = np.array([1.5, -0.7, -3.0, 0.02, 0.01, 0.0])
    solved = solver.solve(wrench[:3], wrench[3:])
    xs = solved.unknowns / solver.problem.x_scale
    warm = solver.previous_solution
    at = solver.result_at(xs, wrench)
    assert solver.previous_solution is warm  # the warm start is untouched
    other = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False)
    other.start_at(xs, wrench)
    started = other.solve(wrench[:3], wrench[3:])
    assert at.converged and started.converged and started.iterations == 0
    assert at.iterations == 0 and at.message == started.message == 'converged'
    assert np.array_equal(at.backbones, started.backbones)
    assert np.array_equal(at.frames['de'], started.frames['de'])
    assert at.stable is started.stable is True
    assert at.stability_margin == pytest.approx(started.stability_margin, rel=1e-12)
    assert at.error_estimate_m == pytest.approx(started.error_estimate_m, rel=1e-12)
    # away from the solution it does not iterate: not converged, and says why
    off = solver.result_at(xs * 1.01, wrench)
    assert off.converged is False and 'above the tolerance' in off.message
    assert off.stable is None


def test_secant_update_reproduces_its_step():
    """After an update with step s and H y = c, the updated H maps y to s exactly."""
    rng = np.random.default_rng(3)
    size = 30
    inverse = np.eye(size) + 0.1 * rng.standard_normal((size, size))  # H_0
    secants = Secants(size)
    residual_change = rng.standard_normal(size)
    step = rng.standard_normal(size)
    other = rng.standard_normal(size)
    before = secants.add(step, inverse @ residual_change, inverse @ other)
    assert secants.count == 1

    def applied(vector):
        out = inverse @ vector
        kernels.apply_updates(secants.updates, secants.steps, secants.count, out)
        return out
    assert np.allclose(applied(residual_change), step, rtol=1e-12, atol=1e-12)
    assert np.allclose(before, applied(other), rtol=1e-12, atol=1e-12)
    for _ in range(MAX_SECANTS + 3):  # full: H stays as it is
        secants.add(rng.standard_normal(size), rng.standard_normal(size), other)
    assert secants.count == MAX_SECANTS


def test_compiled_residual_matches_its_formula(robot):
    """
    The compiled CDR residual equals the formula written out here, at a random state.

    Also with an attachment turned by more than 90 degrees from its end disk (the
    rotation vector then comes from the quaternion).
    """
    rng = np.random.default_rng(7)
    robot.reset()
    robot.solve((0.01, 0.0, -0.005), GRAVITY_1KG)
    state = robot._continuation.previous[0]
    inputs = np.concatenate([[0.01, 0.002, -0.005], rng.standard_normal(9)])
    for angle in (0.01, 2.5):
        frames = state.frames.copy()
        turn = rng.standard_normal(3)
        turn *= angle / np.linalg.norm(turn)
        frames[1, :3, :3] = _rotation(turn) @ frames[1, :3, :3]
        trial = type(state)(state.position + 1e-4 * rng.standard_normal(3),
                            _rotation(0.01 * rng.standard_normal(3)) @ state.rotation,
                            state.wrenches + rng.standard_normal((3, 6)), state.unknowns,
                            frames)
        assert np.allclose(robot._chain.residual(trial, inputs), _residual(robot, trial, inputs),
                           rtol=1e-12, atol=1e-12)


def _rotation(vector):
    """Rodrigues' formula."""
    angle = np.linalg.norm(vector)
    x, y, z = vector / angle
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross


def _residual(robot, state, inputs):
    """Return the CDR residual of docs/explanation/robot.md in numpy (the pre-compiled form)."""
    force, moment, offset = inputs[3:6], inputs[6:9], inputs[9:]
    residual = np.empty(24)
    total_force, total_moment = force.copy(), moment + np.cross(state.rotation @ offset, force)
    for k, leg in enumerate(robot.legs):
        arm = state.rotation @ leg.attachment
        target = leg.rotation.T @ (state.position + arm - leg.base(inputs[k]))
        residual[6 * k:6 * k + 3] = state.frames[k, :3, 3] - target
        turned = leg.rotation.T @ state.rotation @ leg.rotation
        residual[6 * k + 3:6 * k + 6] = rotation_vector(state.frames[k, :3, :3] @ turned.T)
        reaction = -leg.rotation @ state.wrenches[k, :3]
        total_force += reaction
        total_moment += np.cross(arm, reaction) - leg.rotation @ state.wrenches[k, 3:]
    residual[18:21], residual[21:] = total_force, total_moment
    return residual


def test_warm_circle_converges_with_few_rebuilds():
    """
    Along a slider circle every warm solve converges coupled, on few Jacobian rebuilds.

    The counts are the algorithm's, not the machine's: no full leg solve, fewer than one
    rebuild (three exact leg Jacobians) every third solve, at most 9 iterations a solve.
    A jump off the path (the quadratic predictor does not apply) converges to the cold
    solution.
    """
    robot = DeltaRobot()
    phases = np.arange(3) * 2.0 * math.pi / 3.0
    results = [robot.solve(0.015 * np.sin(math.radians(2.0 * k) + phases), GRAVITY_1KG)
               for k in range(40)][1:]
    assert all(result.converged for result in results)
    assert sum(result.leg_solves for result in results) == 0
    assert np.mean([result.leg_jacobians for result in results]) / 3 < 0.34
    assert max(result.iterations for result in results) <= 9
    jump = robot.solve((0.002, 0.01, -0.012), (1.0, -2.0, -9.81))
    robot.reset()
    cold = robot.solve((0.002, 0.01, -0.012), (1.0, -2.0, -9.81))
    assert jump.converged and cold.converged
    assert np.allclose(jump.platform_position, cold.platform_position, atol=1e-10)
    assert np.allclose(jump.leg_tip_wrenches, cold.leg_tip_wrenches, atol=1e-6)


def test_unjudged_leg_solves_and_judged_results():
    """
    judge=False: a solve converges and is not judged; result_at judges what is kept.

    The CDR's nested (cold) iteration solves its legs so; the legs it returns are judged
    when read, like a judged solve of the leg (an exact Jacobian at the solution).
    """
    params = TranslatorParams.from_yaml()
    unjudged = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0),
                                follow_stable_branch=False, judge=False)
    judged = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0),
                              follow_stable_branch=False)
    wrench = np.array([2.0, 1.0, -4.0, 0.0, 0.03, 0.0])
    plain = unjudged.solve(wrench[:3], wrench[3:])
    full = judged.solve(wrench[:3], wrench[3:])
    assert plain.converged and plain.stable is None
    assert math.isnan(plain.stability_margin) and math.isnan(plain.error_estimate_m)
    assert not plain.accuracy_met and 'not judged' in plain.message
    assert np.abs(plain.frames['de'] - full.frames['de']).max() <= 1e-9
    kept = unjudged.result_at(plain.unknowns / unjudged.problem.x_scale, wrench)
    assert kept.stable is full.stable is True
    assert kept.stability_margin == pytest.approx(full.stability_margin, rel=1e-2)
    assert kept.error_estimate_m == pytest.approx(full.error_estimate_m, rel=5e-2)
    robot = DeltaRobot()
    cold = robot.solve((0.01, -0.005, 0.002), GRAVITY_1KG)  # from home: nested legs
    assert cold.converged and cold.leg_solves > 0
    assert all(leg.stable is True and leg.error_estimate_m > 0.0 for leg in cold.leg_results)


def _python_loop_only(robot, monkeypatch):
    """Make ``robot``'s Newton run each coupled iteration in Python (the FAR hand-off)."""
    def hand_back(state, residual, step, inputs, factorization, fresh, chord_steps, chord_log,
                  allowed):
        return coupled_newton.CoupledRun(kernels.FAR, 0, state, residual, step, fresh,
                                         chord_steps, chord_log)
    monkeypatch.setattr(robot._newton, 'coupled_iterations', hand_back)


def test_compiled_coupled_iterations_take_the_python_loops_steps(monkeypatch):
    """
    kernels.coupled_iterations does what CoupledNewton.correct's Python loop does, step for step.

    Along warm solves on a slider path (some rebuild their factorization, some do not) the
    same iterations, leg shots and leg Jacobians, and the platform within 1e-12 m, as the
    loop run in Python (every iteration handed back to it as the compiled one hands back a
    rotation error of 90 degrees).
    """
    path = [(0.002 * k, -0.0015 * k, 0.0005 * k) for k in range(4)]  # rebuilds
    path += [(0.006 + 0.0002 * k, -0.0045 - 0.0001 * k, 0.0015) for k in range(1, 5)]
    compiled, python = DeltaRobot(), DeltaRobot()
    _python_loop_only(python, monkeypatch)
    rebuilt = set()
    for sliders in path:
        fast = compiled.solve(sliders, GRAVITY_1KG)
        slow = python.solve(sliders, GRAVITY_1KG)
        assert fast.converged and slow.converged, (fast.message, slow.message)
        for name in ('iterations', 'leg_shots', 'leg_jacobians', 'leg_solves'):
            assert getattr(fast, name) == getattr(slow, name), (sliders, name)
        assert np.abs(np.asarray(fast.platform_position)
                      - np.asarray(slow.platform_position)).max() <= 1e-12
        rebuilt.add(fast.leg_jacobians > 0)
    assert rebuilt == {True, False}  # both kinds of warm solve were compared


def test_leg_bending_without_the_leg_results_equals_theirs(robot):
    """The bending angles read before the legs' results are built equal the built ones'."""
    result = _warm_result(robot)
    assert isinstance(result.leg_results, LegResults)
    unbuilt = result.leg_bending
    assert 'deferred' in repr(result.leg_results)  # reading the angles built no result
    built = np.array([[leg.pj_bending[0], leg.dj_bending[0]] for leg in result.leg_results])
    assert np.array_equal(unbuilt, built)
    assert np.array_equal(result.leg_bending, built)
