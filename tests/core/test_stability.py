"""Stability verdict on every solve (cdr_translator.stability, docs/stability.md)."""

import json

from cdr_translator import cli, solver as solver_module, TranslatorSolver
import numpy as np
import pytest


def test_unloaded_margin_is_one_and_lateral_load_is_stable(solver):
    """Margin 1 at (almost) no load; a Table II load is stable with a positive margin."""
    solver.reset()
    small = solver.solve([1e-6, 0.0, 0.0])
    assert small.stable and small.stability_margin == pytest.approx(1.0, abs=1e-3)
    solver.reset()
    result = solver.solve([12.0, 0.0, 0.0])
    assert result.converged and result.stable and result.stability_margin > 0.0
    data = result.to_dict()
    assert data['stable'] is True and data['stability_margin'] == result.stability_margin


def test_moderate_compression_stays_straight_and_stable(solver):
    """Below the 29.3 N buckling load the straight shape is the stable answer."""
    solver.reset()
    result = solver.solve([0.0, 0.0, -20.0])
    assert result.stable and 0.0 < result.stability_margin < 1.0
    assert np.linalg.norm(result.end_disk_position[:2]) < 1e-9


def test_compression_past_buckling_is_never_a_silent_straight_success(params):
    """-40 N: the stable buckled shape (it verifies), or converged with stable False."""
    result = TranslatorSolver(params).solve([0.0, 0.0, -40.0], verify=True)
    assert result.converged
    lateral = np.linalg.norm(result.end_disk_position[:2])
    if result.stable:
        assert lateral > 0.01, 'straight and "stable" past the buckling load'
        assert result.stability_margin > 0.0 and result.verified
        assert 'stable branch' in result.message
    else:
        assert 'unstable' in result.message


def test_unstable_answer_is_flagged_and_exits_4(monkeypatch, capsys):
    """Without branch following the straight -40 N answer says unstable; the CLI exits 4."""
    monkeypatch.setattr(solver_module, 'BRANCH_ATTEMPTS', 0)
    code = cli.main(['solve', '--force', '0', '0', '-40', '--json'])
    data = json.loads(capsys.readouterr().out)
    assert code == cli.EXIT_UNSTABLE == 4
    assert data['converged'] is True and data['stable'] is False
    assert data['stability_margin'] < 0.0 and 'unstable' in data['message']


def test_fd_jacobian_solver_gives_the_same_verdict(params):
    """jacobian='fd' solves too; its verdict comes from a tangent shot at the solution."""
    fd = TranslatorSolver(params, jacobian='fd')
    result = fd.solve([12.0, 0.0, 0.0])
    assert result.converged and result.stable
    with pytest.raises(ValueError, match='jacobian'):
        TranslatorSolver(params, jacobian='complex-step')


def test_warm_compression_ramp_buckles_onto_the_stable_branch(params):
    """
    Warm steps across the 29.3 N load: the margin falls as 1 - F / F_cr, then buckles.

    The stale factorizations of chord steps must not hide the crossing: the straight state
    is never reported stable past the buckling load.
    """
    solver = TranslatorSolver(params)
    margins = []
    for load in (10.0, 20.0, 27.0, 29.5, 33.0):
        result = solver.solve((0.0, 0.0, -load))
        assert result.converged and result.stable, result.message
        lateral = np.linalg.norm(result.end_disk_position[:2])
        margins.append(result.stability_margin)
        if load > 29.3:
            assert lateral > 5e-3, f'straight and stable at {load} N'
        else:
            assert lateral < 1e-9
    assert margins[0] == pytest.approx(1.0 - 10.0 / 29.3, abs=0.02)
    assert margins[1] == pytest.approx(1.0 - 20.0 / 29.3, abs=0.02)
