"""Independent verification (cdr_translator.solve.verify): good results pass, bad ones fail."""

import copy
import dataclasses
import json

from cdr_translator import TranslatorSolver
from cdr_translator.cli import main
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.solve.result import PAPER_TOLERANCES
from cdr_translator.solve.verify import Tolerances, verify
import numpy as np
import pytest

GLOBAL_CHECKS = ('global_force_n', 'global_moment_nm')


@pytest.fixture(scope='module')
def table_ii(params):
    """Solve the 12 N Table II case."""
    result = TranslatorSolver(params).solve((12.0, 0.0, 0.0))
    assert result.converged
    return result


def test_default_tolerances_are_the_papers():
    """Verification holds results to the paper's own convergence tolerances (SI)."""
    assert dataclasses.asdict(Tolerances()) == PAPER_TOLERANCES


def test_table_ii_result_verifies(params, table_ii):
    """A converged paper case passes with every check far inside its limit."""
    verification = verify(table_ii, params)
    assert verification.passed, verification.message
    assert set(verification.checks) == set(verification.limits)
    for name, value in verification.checks.items():
        assert 0.0 <= value < 0.05 * verification.limits[name], name
    # the discrete solution's own statics hold to the solver's tolerance
    assert verification.checks['global_force_n'] < 1e-8
    assert verification.checks['global_moment_nm'] < 1e-9


def test_unloaded_state_reshoots_straight(params):
    """With no load the re-shot stack is straight at 4 D + L_m, clamps exact."""
    result = TranslatorSolver(params).solve((0.0, 0.0, 0.0))
    verification = verify(result, params)
    assert verification.passed
    assert max(verification.checks.values()) < 1e-12


def corrupted(result, **changes):
    """Deep copy of ``result`` with some fields replaced."""
    copied = copy.deepcopy(result)
    for name, value in changes.items():
        setattr(copied, name, value)
    return copied


def test_wrong_spacer_reaction_is_caught(params, table_ii):
    """A 0.01 N error in one spacer-disk reaction breaks the clamps of the re-shoot."""
    unknowns = table_ii.unknowns.copy()
    unknowns[30 + 1] += 0.01  # secondary 1, first PJ spacer disk, in-plane force x
    verification = verify(corrupted(table_ii, unknowns=unknowns), params)
    assert not verification.passed
    assert verification.checks['end_clamp_rotation_rad'] > PAPER_TOLERANCES['orientation_rad']
    # the base reactions still balance the load: only the transfer is wrong
    assert all(verification.checks[name] < 1e-8 for name in GLOBAL_CHECKS)


def test_wrong_base_reaction_breaks_global_equilibrium(params, table_ii):
    """A 1 mN error in the primary's base force shows in the global force balance."""
    unknowns = table_ii.unknowns.copy()
    unknowns[0] += 1e-3
    verification = verify(corrupted(table_ii, unknowns=unknowns), params)
    assert not verification.passed
    assert verification.checks['global_force_n'] == pytest.approx(1e-3, rel=1e-6)


def test_wrong_reported_pose_is_caught(params, table_ii):
    """An end-disk frame 1 mm off from the re-shot one fails the frame check."""
    frames = {name: frame.copy() for name, frame in table_ii.frames.items()}
    frames['de'][0, 3] += 1e-3
    verification = verify(corrupted(table_ii, frames=frames), params)
    assert not verification.passed
    assert verification.checks['frame_de_position_m'] == pytest.approx(1e-3, rel=1e-3)
    assert 'frame_de_position_m' in verification.message


def test_discretization_error_is_measured_with_rk4_order(params):
    """At 60 N the default 8 RK4 steps miss the tolerance; 16 steps cut the error ~16x."""
    errors = []
    for steps in (8, 16):
        refined = params.with_changes(steps_per_segment=steps)
        result = TranslatorSolver(refined, accuracy=Accuracy(0.0, 0.0)).solve((60.0, 0.0, 0.0))
        verification = verify(result, refined)
        assert all(verification.checks[name] < 1e-8 for name in GLOBAL_CHECKS)
        errors.append(verification.checks['tangent_tilt_rad'])
        assert verification.passed == (steps == 16), verification.message
    order = np.log2(errors[0] / errors[1])
    assert 3.5 < order < 4.5


def test_non_converged_result_never_passes(params):
    """Out of time: the checks still run and say how far off it is, but it does not pass."""
    result = TranslatorSolver(params, time_limit_s=0.0).solve((20.0, 0.0, 0.0))
    verification = verify(result, params)
    assert not result.converged and not verification.passed
    assert verification.message.startswith('not converged')
    assert verification.checks


def test_non_finite_unknowns_do_not_pass(params, table_ii):
    """Report a NaN in the unknowns instead of integrating it."""
    unknowns = table_ii.unknowns.copy()
    unknowns[5] = np.nan
    verification = verify(corrupted(table_ii, unknowns=unknowns), params)
    assert not verification.passed and 'non-finite' in verification.message


def test_solve_with_verify_fills_the_result(params):
    """solve(verify=True): result.verified, result.verification and their JSON keys."""
    solver = TranslatorSolver(params)
    result = solver.solve((5.0, -3.0, 1.0), (0.02, 0.0, 0.01), verify=True)
    assert result.verified is True and result.verification.passed
    data = result.to_dict()
    assert data['verified'] is True and data['verification_message'] == 'verified'
    assert set(data['verification_checks']) == set(data['verification_limits'])
    assert solver.solve((5.0, 0.0, 0.0)).verified is None


def test_cli_verify_flag(capsys):
    """`solve --verify --json` adds the verification keys; 60 N is refined until it verifies."""
    assert main(['solve', '--force', '12', '0', '0', '--verify', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['verified'] is True and data['verification_message'] == 'verified'
    assert main(['solve', '--force', '60', '0', '0', '--verify']) == 0
    table = capsys.readouterr().out
    assert 'True (verified)' in table and 'refined to' in table
