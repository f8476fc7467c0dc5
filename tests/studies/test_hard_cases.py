"""
The quick hard cases (cdr_translator.studies.hard_cases): outcomes, physics and failure handling.

The whole suite, with refinement, runs in `make hard-cases` (bench/hard_cases.py).
"""

import math

from cdr_translator import TranslatorSolver
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.solve import continuation, correctors
from cdr_translator.studies import hard_cases
from cdr_translator.studies.buckling import critical_compression
from cdr_translator.studies.hard_case_report import markdown_report
from cdr_translator.studies.hard_cases import DISCRETIZATION_FREE_CHECKS
import numpy as np
import pytest

MIRROR_X = np.diag([-1.0, 1.0, 1.0])


@pytest.fixture(scope='module')
def reports(params):
    """Run every quick case once; by name (about 10 s)."""
    return {report.case.name: report for report in hard_cases.run_suite(params, quick_only=True)}


@pytest.fixture(scope='module')
def buckling(params):
    """Analyse the axial buckling of the shipped translator."""
    return critical_compression(params)


def test_the_suite_covers_every_kind_of_hard_case(reports):
    """The quick subset spans all groups; the full suite has more cases than it."""
    groups = {report.case.group for report in reports.values()}
    assert groups == {'lateral', 'compression', 'torsion', 'combined', 'reversal', 'tiny',
                      'jumps', 'parameters'}
    assert len(hard_cases.cases()) > len(reports)


def test_every_quick_solve_converges(reports):
    """Convergence rate of the quick subset: every solve."""
    failed = [(name, outcome.message) for name, report in reports.items()
              for outcome in report.loads if not outcome.converged]
    assert not failed


def test_every_converged_solve_is_verified_or_flagged(reports):
    """
    Never a silent wrong answer.

    Every converged solve either verifies or fails only checks that a finer
    discretization cures: its global equilibrium always holds.
    """
    for name, report in reports.items():
        for outcome in report.loads:
            checks, limits = outcome.verification.checks, outcome.verification.limits
            for check in DISCRETIZATION_FREE_CHECKS:
                assert checks[check] <= limits[check], (name, check)
            if not outcome.verification.passed:
                assert outcome.verified_steps is None
                assert report.outcome.startswith('converged, not verified: '), name


def test_paper_range_cases_verify_at_the_default_discretization(reports):
    """Table II, moderate combined loads, tiny loads and stiff parameters verify as they are."""
    for name in ('lateral 12 N (Table II)', 'reversal +40 N -> -40 N lateral',
                 'reversal of a combined wrench', 'zero load', '1e-9 N lateral',
                 'jumps between opposite corners, 20 N + 0.2 N m',
                 'stiff material (E 210 GPa), 20 N', 'short tube (20 mm), 12 N and 60 N'):
        assert reports[name].outcome == 'verified', (name, reports[name].outcome)
    for name, report in reports.items():
        if report.case.group == 'combined':
            assert report.outcome == 'verified', name


def test_pj_bending_past_90_degrees(reports):
    """100 N out and 100 N down bend the PJ past 90 deg; 8 RK4 steps are too coarse there."""
    report = reports['PJ past 90 deg: 100 N out, 100 N down']
    assert report.converged
    assert math.degrees(report.final.pj_bending[0]) > 95.0
    assert not report.verified
    assert 'tangent_tilt_rad' in report.loads[-1].verification.message


def test_refinement_verifies_a_coarse_state(params):
    """A 60 N state that fails at 8 steps verifies after a warm-started finer re-solve."""
    case = hard_cases.HardCase('lateral 60 N', 'lateral', (hard_cases.load(60.0),))
    report = hard_cases.run_case(case, params, refine=True)
    assert report.verified
    assert report.verified_steps > params.steps_per_segment
    assert report.outcome.startswith('verified at')


def test_buckling_load_matches_euler(buckling):
    """The Jacobian turns singular within 2 % of the closed-form Euler load of the S-mode."""
    assert buckling.critical_load_n == pytest.approx(buckling.euler_estimate_n, rel=0.02)
    assert buckling.smallest_singular_value < 1e-4 * buckling.unloaded_singular_value
    assert buckling.stable_below is True and buckling.stable_above is False


def test_compression_stability(reports, buckling):
    """Half the buckling load is stable; the straight state past it is an unstable equilibrium."""
    below = reports['compression 15 N (half the buckling load)']
    above = reports['compression 44 N, perfect (straight past buckling)']
    assert 15.0 < buckling.critical_load_n < 44.0
    assert below.stable is True and below.verified
    assert above.stable is False and above.verified
    assert above.final.pj_bending[0] < 1e-12


def test_post_buckled_state_settles_on_the_diagonal(reports):
    """
    Past buckling the stable equilibrium bends between two secondaries.

    Buckled toward a secondary it is a saddle (the azimuthal direction is unstable); from a
    17 deg imperfection the structure rolls to 45 deg, where it is stable.
    """
    toward = reports['post-buckled 44 N toward a secondary (2 N along x, compress, release)']
    rolled = reports['post-buckled 44 N from a 17 deg imperfection (ends on the diagonal)']
    assert toward.converged and rolled.converged
    assert toward.stable is False and rolled.stable is True
    assert abs(toward.final.pj_bending[1]) < 1e-6
    assert math.degrees(rolled.final.pj_bending[1]) == pytest.approx(45.0, abs=1e-4)
    assert math.degrees(rolled.final.pj_bending[0]) > 60.0


def test_load_reversal_is_the_mirror_image(params, reports):
    """+40 N then -40 N, warm-started: the mirror of the +40 N state, as a cold solve gives."""
    report = reports['reversal +40 N -> -40 N lateral']
    solver = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0))  # the suite's 8 steps
    plus = solver.solve((40.0, 0.0, 0.0), warm_start=False)
    assert np.allclose(report.final.end_disk_position, MIRROR_X @ plus.end_disk_position,
                       atol=1e-9, rtol=0.0)
    cold = solver.solve((-40.0, 0.0, 0.0), warm_start=False)
    assert np.allclose(report.final.end_disk_position, cold.end_disk_position, atol=1e-9,
                       rtol=0.0)


def test_tiny_loads_respond_linearly(params, reports):
    """Zero load takes no iteration; 1e-9 N moves the end disk by C(0) times 1e-9 N."""
    zero = reports['zero load']
    assert zero.iterations == 0 and zero.residual == 0.0
    tiny = reports['1e-9 N lateral'].final
    compliance = TranslatorSolver(params).solve((0.0, 0.0, 0.0), compliance=True).compliance
    height = params.stack_height
    displacement = tiny.end_disk_position - np.array([0.0, 0.0, height])
    expected = compliance.matrix[:3, 0] * 1e-9
    # 5.7e-12 m, resolved to the rounding of a 0.18 m position (a few 1e-17 m)
    assert np.allclose(displacement, expected, rtol=0.0, atol=1e-15)


def test_jumps_end_where_a_cold_solve_does(params, reports):
    """After a sequence of jumps the warm-started state equals a cold solve of the last load."""
    for name in ('jumps between opposite corners, 20 N + 0.2 N m', 'zero after 100 N (warm)'):
        report = reports[name]
        force, moment = report.case.loads[-1]
        cold = TranslatorSolver(params).solve(force, moment)
        assert np.allclose(report.final.end_disk_position, cold.end_disk_position, atol=1e-9,
                           rtol=0.0), name


def test_extreme_parameters_converge(reports):
    """Short tube, long tube, soft and stiff material, thin backbones, more spacer disks."""
    for name, report in reports.items():
        if report.case.group == 'parameters':
            assert report.converged, name
            assert report.stable is True, (name, report.stability)


def test_failure_is_a_result_with_the_best_residual_at_the_requested_wrench(params):
    """
    One Newton iteration per step cannot reach 500 N: converged False, honest residual.

    (Without the fallback continuation, which does reach it.)
    """
    solver = TranslatorSolver(params, max_iterations=1, fallback=False)
    result = solver.solve((500.0, 0.0, 0.0))
    assert not result.converged
    assert result.message.startswith('continuation stalled at')
    assert result.force.tolist() == [500.0, 0.0, 0.0]
    wrench = np.array([500.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    residual = solver.problem.residual(result.unknowns / solver.problem.x_scale, wrench)
    assert math.isfinite(result.residual_norm)
    assert result.residual_norm == pytest.approx(float(np.linalg.norm(residual)), rel=1e-12)


def test_non_finite_trial_states_are_survived(params, monkeypatch):
    """At 500 N full-load predictions overflow; those steps are halved, not fatal."""
    solver = TranslatorSolver(params)
    # try the whole load first, as it once did
    monkeypatch.setattr(continuation, 'first_step', lambda predicted: 1.0)
    messages = []
    newton = correctors.newton

    def recording(*args):
        outcome = newton(*args)
        messages.append(outcome.message)
        return outcome

    monkeypatch.setattr(correctors, 'newton', recording)
    result = solver.solve((500.0, 0.0, 0.0))
    assert 'residual became non-finite during the iteration' in messages
    assert result.converged and np.all(np.isfinite(result.unknowns))


def test_time_cap_ends_a_hard_solve_with_a_message(params):
    """A case that needs many steps stops at a tiny cap and says it was the time limit."""
    result = TranslatorSolver(params, time_limit_s=1e-3).solve((500.0, 0.0, 0.0))
    assert not result.converged
    assert 'time limit of 0.001 s' in result.message


@pytest.mark.parametrize('force, moment, text', [
    ((math.nan, 0.0, 0.0), (0.0, 0.0, 0.0), 'force x component is nan'),
    ((0.0, 0.0, 0.0), (0.0, math.inf, 0.0), 'moment y component is inf'),
    ((0.0, 0.0, -math.inf), (0.0, 0.0, 0.0), 'force z component is -inf'),
])
def test_non_finite_wrench_is_a_value_error(solver, force, moment, text):
    """NaN/Inf input raises ValueError naming the component."""
    with pytest.raises(ValueError, match=text):
        solver.solve(force, moment)


@pytest.mark.parametrize('keyword, value', [('time_limit_s', -1.0), ('time_limit_s', math.nan),
                                            ('tolerance', 0.0), ('tolerance', math.inf)])
def test_bad_solver_settings_are_value_errors(params, keyword, value):
    """Negative or non-finite caps and tolerances are rejected by name."""
    with pytest.raises(ValueError, match=keyword):
        TranslatorSolver(params, **{keyword: value})


def test_report_lists_rates_and_buckling(reports, buckling):
    """The markdown report has one row per case, the convergence rate and the buckling load."""
    text = markdown_report(list(reports.values()), buckling)
    rows = [line for line in text.splitlines() if line.startswith('| ') and 'case |' not in line]
    assert len(rows) == len(reports)
    assert 'Convergence rate:' in text and 'Axial buckling load:' in text
    assert 'Euler estimate' in text


@pytest.mark.parametrize('name', ['torsion 40 N m', 'PJ past 100 deg: 200 N out, 400 N down'])
def test_former_stalls_converge_verify_and_are_judged(params, name):
    """
    Two of the three former stalls converge, verify and are judged stable.

    The fallback continuation converges them, refinement (re-solved by tracking) verifies
    them. About 10 s each, most of it the fine grids (400-550 steps per interval) they need.
    """
    case = next(case for case in hard_cases.cases() if case.name == name)
    report = hard_cases.run_case(case, params, refine=True)
    assert report.converged, report.outcome
    assert report.verified, report.outcome
    assert report.verified_steps is not None and report.verified_steps > params.steps_per_segment
    assert 'fallback continuation' in report.loads[0].message
    assert report.stable is True, report.stability
