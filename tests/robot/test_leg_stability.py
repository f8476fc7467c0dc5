"""
Each leg held at both ends: its buckling load, its verdict on both sides, the robot's verdict.

The robot's stability verdict condenses the legs into the platform stiffness, valid only if
each leg is stable with both end disks held (cdr_translator/robot/held_leg.py).
"""

import math

from cdr_translator import TranslatorSolver
from cdr_translator._linalg import factorize, solve_lu
from cdr_translator.analysis.stability import pose_twist
from cdr_translator.cli import main
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.held_leg import euler_critical_load, held_reference, held_verdict
from cdr_translator.robot.held_leg import HeldReference
from cdr_translator.robot.linearization import chain_verdict
from cdr_translator.studies.buckling import held_critical_compression
import numpy as np
import pytest

#: Payload (N, along +z: the platform pushed towards the base) that compresses each leg by
#: 234 N, eight times its free-end buckling load.
PAYLOAD_500N = (0.0, 0.0, 500.0)


@pytest.fixture(scope='module')
def held(params):
    """Find the held buckling load and re-solve perturbed on both sides of it."""
    return held_critical_compression(params)


@pytest.fixture(scope='module')
def robot():
    """Build a robot with the shipped parameters; tests reset() it for a cold start."""
    return DeltaRobot()


def straight_leg(params, compression):
    """Return (LU, compliance, wrench) of the straight leg solved under ``compression`` (N)."""
    solver = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False,
                              judge=False)
    result = solver.solve((0.0, 0.0, -compression))
    assert result.converged
    problem = solver.problem
    wrench = np.array([0.0, 0.0, -compression, 0.0, 0.0, 0.0])
    _, jacobian, pose = problem.exact_jacobian(result.unknowns / problem.x_scale, wrench)
    lu = factorize(jacobian)
    compliance = -pose_twist(pose, result.frames['de'][:3, :3]) @ solve_lu(
        lu, problem.wrench_sensitivity)
    return lu, compliance, wrench


def test_held_buckling_load_is_far_above_the_free_one(held, params):
    """J_d is singular there; the clamped-guided estimate agrees; 37 times the free-end load."""
    assert held.smallest_singular_value < 1e-4 * held.unloaded_singular_value
    assert held.critical_load_n == pytest.approx(held.estimate_n, rel=0.01)
    assert held.critical_load_n > 30.0 * euler_critical_load(params)


def test_held_verdict_on_both_sides_of_the_held_buckling_load(held, params):
    """
    Stable 2 % below, flagged 2 % above; the parity alone sees neither side.

    The x and y buckling modes cross together (four-fold symmetry), so sign(det J_d) stays
    as unloaded: the compression against the held buckling load makes the call.
    """
    unloaded = straight_leg(params, 0.0)
    origin = held_reference(unloaded[0], unloaded[1], params.stack_height,
                            held.critical_load_n)
    below = held_verdict(*straight_leg(params, 0.98 * held.critical_load_n), origin)
    above = held_verdict(*straight_leg(params, 1.02 * held.critical_load_n), origin)
    assert below.stable is True and below.margin == pytest.approx(0.02, abs=1e-9)
    assert above.stable is False and above.margin == pytest.approx(-0.02, abs=1e-9)
    assert below.parity_ok and above.parity_ok
    # past the free-end buckling load both legs are unstable under a dead tip load
    assert below.negative_stiffness_directions >= 2


def test_a_leg_in_tension_is_said_to_be_in_tension(params):
    """A tension reads as one in the verdict and the table, never as a negative compression."""
    unloaded = straight_leg(params, 0.0)
    origin = held_reference(unloaded[0], unloaded[1], params.stack_height, 1110.0)
    pulled = held_verdict(*straight_leg(params, -233.6), origin)
    assert pulled.stable is True and pulled.axial_load_n == pytest.approx(-233.6)
    assert 'tension 233.6 N, below the held buckling load 1110 N' in pulled.message
    assert 'compression' not in pulled.message and '-233' not in pulled.message
    pushed = held_verdict(*straight_leg(params, 233.6), origin)
    assert 'compression 233.6 N, below the held buckling load' in pushed.message


def test_delta_table_prints_a_tension_as_one(capsys):
    """`delta` under 500 N pulling the platform away from the base: each leg in tension."""
    assert main(['delta', '--sliders', '0', '0', '0', '--payload', '0', '0', '-500']) == 0
    row = next(line for line in capsys.readouterr().out.splitlines()
               if line.startswith('legs held at both ends'))
    assert row.count('tension') == 3 and 'compression' not in row and '-' not in row
    assert 'N, held buckling load' in row


def test_perturbed_held_solves_confirm_both_sides(held):
    """
    Perturbed along the buckling mode with the end disk held: back below, away above.

    Above, the re-solve ends at a buckled state carrying less compression at the same
    end-disk pose, so of lower energy (dU/d(shortening) is the compression on each branch
    from their common bifurcation point), near the buckling load.
    """
    assert held.below.converged and not held.below.left_straight
    assert held.below.compression_after_n == pytest.approx(held.below.compression_n, rel=1e-9)
    assert held.above.left_straight
    assert held.above.compression_after_n < held.above.compression_n - 10.0
    assert held.above.compression_after_n == pytest.approx(held.critical_load_n, rel=0.01)


def test_a_verdict_that_cannot_be_made_is_unknown(params):
    """A singular leg Jacobian, or no held buckling load, gives None; the chain is unknown."""
    lu, compliance, wrench = straight_leg(params, 10.0)
    origin = HeldReference(1, 1, params.stack_height, None)
    assert held_verdict(lu, compliance, wrench, origin).stable is None
    singular = factorize(np.zeros((4, 4)))
    known = HeldReference(1, 1, params.stack_height, 100.0)
    assert held_verdict(singular, compliance, wrench, known).stable is None
    unknown = held_verdict(lu, compliance, wrench, origin)
    stable = held_verdict(lu, compliance, wrench, known)
    assert stable.stable is True
    assert chain_verdict(True, (stable, unknown, stable)) is None
    assert chain_verdict(False, (stable, unknown, stable)) is False
    assert chain_verdict(True, (stable, stable, stable)) is True


def test_500n_payload_legs_are_stable_held(robot, held):
    """Each leg carries 234 N, past its free-end buckling load, far below its held one."""
    robot.reset()
    result = robot.solve([0.0, 0.0, 0.0], PAYLOAD_500N, compliance=True)
    assert result.converged and result.stable is True and result.stiffness_margin > 0.0
    data = result.to_dict()
    assert len(data['leg_stability']) == 3
    for leg in data['leg_stability']:
        assert leg['stable'] is True
        assert leg['axial_load_n'] == pytest.approx(233.8, abs=0.5)
        assert leg['critical_load_n'] == pytest.approx(held.critical_load_n, rel=1e-6)
        assert leg['margin'] == pytest.approx(1.0 - leg['axial_load_n'] / held.critical_load_n)
        assert leg['negative_stiffness_directions'] == 2  # unstable under a dead tip load
        assert 'below the held buckling load' in leg['message'] and leg['method']


def test_legs_past_their_held_buckling_load_make_the_chain_unstable(robot, held):
    """
    The platform stiffness is positive definite again past the legs' held buckling load.

    The legs' straight state is then a pair of held modes past buckling, which the
    condensed stiffness does not see: the legs' verdicts make the chain unstable. At
    2800 N (each leg 1310 N) the walk from home lands on the straight state; at 2420 N it
    ends on a state whose legs bend 1.5 deg, unstable too, but by its platform stiffness.
    """
    robot.reset()
    payload = 2800.0
    result = robot.solve([0.0, 0.0, 0.0], (0.0, 0.0, payload), compliance=True)
    assert result.converged and result.stiffness_margin > 0.0
    assert np.degrees(result.leg_bending).max() < 0.1
    assert all(leg.axial_load_n > held.critical_load_n for leg in result.leg_stability)
    assert all(leg.stable is False for leg in result.leg_stability)
    assert result.stable is False and 'leg 1: unstable held' in result.message
    assert result.to_dict()['stable'] is False
    assert not math.isnan(result.leg_stability[0].margin)
