"""Stability verdict on every solve (cdr_translator.analysis.stability, docs/explanation)."""

import json

from cdr_translator import _linalg, cli, TranslatorSolver
from cdr_translator.analysis import stability
from cdr_translator.solve import branch
import numpy as np
import pytest
from scipy.linalg import lu_factor


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
    monkeypatch.setattr(branch, 'BRANCH_ATTEMPTS', 0)
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


def _exact_jacobians(monkeypatch, solver):
    """Count the solver's exact Jacobians; return the list that grows by one per Jacobian."""
    made = []
    original = solver.problem.exact_jacobian

    def counted(*args):
        made.append(1)
        return original(*args)
    monkeypatch.setattr(solver.problem, 'exact_jacobian', counted)
    return made


def test_sensor_noise_at_rest_keeps_the_verdict(params, monkeypatch):
    """0.05 N of noise around no load: the verdict is reused, not rebuilt every solve."""
    solver = TranslatorSolver(params)
    rng = np.random.default_rng(5)
    solver.solve(rng.normal(scale=0.05, size=3))
    made = _exact_jacobians(monkeypatch, solver)
    for _ in range(100):
        result = solver.solve(rng.normal(scale=0.05, size=3), rng.normal(scale=1e-3, size=3))
        assert result.converged and result.stable
        assert result.stability_margin == pytest.approx(1.0, abs=0.01)
    assert len(made) <= 10  # drift measured against |w| alone: one Jacobian per solve


def test_reused_verdicts_stay_within_half_the_margin_of_fresh_ones(params):
    """Warm compression from no load to 90 % of the buckling load: the rule's promise."""
    warm = TranslatorSolver(params)
    problem = warm.problem
    for force in np.linspace(0.0, 26.5, 120)[1:]:
        wrench = np.array([0.02 * force, 0.0, -force, 0.0, 0.0, 0.0])
        result = warm.solve(wrench[:3])
        _, jacobian, pose = problem.exact_jacobian(result.unknowns / problem.x_scale, wrench)
        truth = stability.assess(lu_factor(jacobian), pose, result.frames['de'][:3, :3],
                                 problem.wrench_sensitivity, warm.unloaded_reference())
        assert result.stable and truth.stable
        assert abs(result.stability_margin - truth.margin) <= 0.5 * truth.margin


def test_a_solve_after_an_exact_compliance_keeps_the_verdict_made_with_it(params):
    """
    The exact compliance's factorization carries its verdict to the warm solves after it.

    Along a sensor-noise walk with compliance=True, each answer whose verdict was kept is
    judged by the exact compliance of the answer before it (the factorization the solve
    stepped on), not by a stale one assessed again.
    """
    solver = TranslatorSolver(params)
    reference = solver.unloaded_reference()
    rng = np.random.default_rng(11)
    force = np.array([3.0, -2.0, -1.0])
    before = solver.solve(force, compliance=True)
    kept = 0
    for _ in range(40):
        force = force + rng.normal(scale=0.02, size=3)
        after = solver.solve(force, compliance=True)
        assert after.converged and after.stable
        previous = stability.margin(before.compliance.matrix, reference)
        kept += after.stability_margin == previous
        assert after.stability_margin == pytest.approx(previous, rel=0.05)
        before = after
    assert kept >= 30  # a sensor-noise step keeps the verdict: most answers


def test_factorize_equals_scipy_lu_factor_and_flags_a_singular_matrix():
    """LAPACK getrf directly gives lu_factor's factors; an exactly singular J has sign 0."""
    rng = np.random.default_rng(5)
    matrix = rng.standard_normal((90, 90))
    lu, pivots = _linalg.factorize(matrix)
    expected_lu, expected_pivots = lu_factor(matrix)
    assert np.array_equal(pivots, expected_pivots)
    assert np.allclose(lu, expected_lu, rtol=0.0, atol=1e-12)
    assert stability.determinant_sign((lu, pivots)) == np.sign(np.linalg.det(matrix))
    singular = matrix.copy()
    singular[:, 3] = 0.0  # a zero pivot
    assert stability.determinant_sign(_linalg.factorize(singular)) == 0


def test_pose_twist_is_the_spatial_angular_velocity():
    """A frame turning as R(t) = exp(t [w]) R moving at v gives the twist [v; w]."""
    rng = np.random.default_rng(6)
    rotation = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    twists = rng.standard_normal((6, 4))
    changes = np.empty((12, 4))
    for column, (velocity, spin) in enumerate(zip(twists[:3].T, twists[3:].T)):
        skew = np.array([[0.0, -spin[2], spin[1]], [spin[2], 0.0, -spin[0]],
                         [-spin[1], spin[0], 0.0]])
        changes[:3, column] = velocity
        changes[3:, column] = (skew @ rotation).ravel()  # dR/dt at t = 0, row-major
    assert np.allclose(stability.pose_twist(changes, rotation), twists, atol=1e-14)
    assert np.allclose(stability.pose_twist(changes[:, 2], rotation), twists[:, 2],
                       atol=1e-14)
