"""The 'auto' fidelity (cdr_translator.fidelity.auto): checks, escalation and the budget."""

import math

from batch_checks import assert_rows_equal, sequence
from bench.auto_speed import random_walk
from cdr_translator import TranslatorSolver
from cdr_translator.fidelity import auto_runs, FidelitySolver, pose_errors, verdicts
from cdr_translator.fidelity.auto import CHECK_GROWTH
from cdr_translator.fidelity.validation import box_half_widths
import numpy as np
import pytest

BUDGET = (1e-3, 0.5)


@pytest.fixture(scope='module')
def full(params):
    """Return the full model, the errors' reference (its own error far below the budget)."""
    return TranslatorSolver(params)


def budget_solver(params):
    """Return 'auto' at 1 mm and 0.5 deg."""
    return FidelitySolver(params, max_position_error=BUDGET[0], max_angle_error_deg=BUDGET[1])


def errors(result, full, wrench):
    """(position m, angle deg) of ``result`` against the full model at ``wrench``."""
    position, angle = pose_errors(result, full.solve(wrench[:3], wrench[3:]))
    return position, math.degrees(angle)


def learned_solver(params):
    """Return 'auto' after two expansions along a slow ramp, the check's gain measured."""
    solver = budget_solver(params)
    for step in range(200):
        solver.solve([10.0 + 0.05 * step, 1.0, 0.0], [0.02, 0.0, 0.0])
        if solver.auto.counts['expansions'] >= 2 and np.isfinite(solver.auto.gain).all():
            return solver
    raise AssertionError(f'no second expansion with a measured gain: {solver.auto.counts}')


def test_check_measures_the_linear_error(params, full):
    """The check's estimate is within a factor of two of the linear answer's true error."""
    solver = learned_solver(params)
    origin = solver.tangent.origin
    for size in (0.02, 0.06, 0.12):
        wrench = origin + size * box_half_widths() * np.array([1.0, 0.5, -0.5, 0.3, 0.2, 0.4])
        estimate = solver.auto.check_prediction(wrench, solver.tangent.unknowns(wrench))
        linear = solver.levels['linear'].answer(wrench, False, {})
        position, angle = errors(linear, full, wrench)
        assert 0.5 < estimate[0] / position < 2.0, (size, estimate, position)
        assert 0.3 < estimate[1] / angle < 3.0, (size, estimate, angle)


def test_failed_check_escalates(params, full):
    """A linear answer whose check fails is replaced by another level, inside the budget."""
    solver = learned_solver(params)
    solver.auto.curvature = solver.auto.curvature * 1e-3  # a trust region far too wide
    origin = solver.tangent.origin
    wrench = origin + 0.3 * box_half_widths() * np.array([1.0, 0.5, -0.5, 0.3, 0.2, 0.4])
    assert solver.auto.linear_verdict(wrench) == 'check'
    linear = solver.levels['linear'].answer(wrench, False, {})
    assert errors(linear, full, wrench)[0] > BUDGET[0]  # the linear answer would miss
    failed = solver.auto.counts['failed_checks']
    here = full.solve(wrench[:3], wrench[3:])  # a verdict at hand: else 'full' answers for it
    solver.auto.note_full_answer(wrench, here.stable, here.stability_margin)
    result = solver.solve(wrench[:3], wrench[3:])
    assert solver.auto.counts['failed_checks'] == failed + 1
    assert result.fidelity != 'linear' and result.converged, result.message
    position, angle = errors(result, full, wrench)
    assert position <= BUDGET[0] and angle <= BUDGET[1]


def test_passed_checks_widen_the_trust_region(params):
    """
    A new expansion's first check is a full solve measuring the gain, the next answer 'linear'.

    Each check that passes trusts offsets up to CHECK_GROWTH times its own.
    """
    solver = learned_solver(params)
    origin = np.array([14.0, 1.0, 0.0, 0.02, 0.0, 0.0])
    # a new expansion trusts half its radius
    solver.auto.answer_in_full(origin, True, False, {}, 'a new expansion')
    assert not np.isfinite(solver.auto.gain).any()
    direction = box_half_widths() * np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    results = []
    for _ in range(2):
        scale = 1.1 * solver.auto.trusted
        wrench = origin + scale * direction
        assert solver.auto.linear_verdict(wrench) == 'check'
        results.append(solver.solve(wrench[:3], wrench[3:]))
        assert solver.auto.trusted == pytest.approx(CHECK_GROWTH * scale)
    assert results[0].fidelity == 'full' and np.isfinite(solver.auto.gain).all()
    assert results[1].fidelity == 'linear' and 'checked' in results[1].message


def test_budget_holds_along_a_sequence(params, full):
    """Along a smooth sequence every answer is inside the budget, many 'linear', checked."""
    forces, moments = sequence(600)
    solver = budget_solver(params)
    levels = []
    for force, moment in zip(forces, moments):
        result = solver.solve(force, moment)
        levels.append(result.fidelity)
        position, angle = errors(result, full, np.r_[force, moment])
        assert position <= BUDGET[0] and angle <= BUDGET[1], result.message
    assert levels.count('linear') > len(levels) // 10, set(levels)
    assert solver.auto.counts['checks'] > 0


def test_budget_holds_on_random_wrenches(params, full):
    """Seeded random wrenches of the validated box's sizes: every answer inside the budget."""
    rng = np.random.default_rng(2718)
    solver = budget_solver(params)
    levels = set()
    sizes = rng.uniform(0.0, 1.0, (40, 1))
    for wrench in rng.uniform(-1.0, 1.0, (40, 6)) * sizes * box_half_widths():
        result = solver.solve(wrench[:3], wrench[3:])
        levels.add(result.fidelity)
        position, angle = errors(result, full, wrench)
        assert position <= BUDGET[0] and angle <= BUDGET[1], result.message
    assert levels & {'cc', 'rod'}, levels


def test_batch_equals_single_solves_with_checks(params):
    """solve_many takes the same levels and answers as single solves, checks included."""
    forces, moments = sequence(200)
    single = budget_solver(params)
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    batched = budget_solver(params)
    batch = batched.solve_many(forces, moments)
    assert batch.fidelity.tolist() == [result.fidelity for result in results]
    assert_rows_equal(batch, results)
    assert batched.auto.counts['checks'] == single.auto.counts['checks'] > 0


@pytest.mark.parametrize('budget, level', [((1e-5, 0.01), 'full'), ((1e-2, 3.0), 'cc')])
def test_batch_equals_single_solves_in_runs(params, budget, level):
    """
    Rows run at full (a tight budget) or mostly below it (a wide one) in a batch.

    Each run is one call of that level's batch path; the rows still equal single solves,
    and the solver is left as they leave it. At the wide budget a full answer now and then
    gives the reduced answers near it their stability verdict.
    """
    forces, moments = sequence(60)
    single, batched = (FidelitySolver(params, max_position_error=budget[0],
                                      max_angle_error_deg=budget[1]) for _ in range(2))
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    batch = batched.solve_many(forces, moments)
    levels = batch.fidelity.tolist()
    assert level in levels
    if level != 'full':  # a few full answers: verdicts (and expansions, when they pay)
        assert levels.count('full') < 0.2 * len(levels), levels
    else:
        assert set(levels) == {'full'}
    assert all(result.stable is not None for result in results)
    assert batch.fidelity.tolist() == [result.fidelity for result in results]
    assert_rows_equal(batch, results)
    assert batched.auto.last_level == single.auto.last_level
    assert np.array_equal(batched.auto.last_wrench, single.auto.last_wrench)
    assert batched.auto.counts == single.auto.counts


@pytest.mark.parametrize('sigma', [0.1, 0.4])
def test_batch_equals_single_solves_on_noisy_walks(params, full, sigma):
    """
    A noisy random walk (bench.auto_speed's): rows equal single solves, each inside the budget.

    Its steps mix every kind of row a batch tells in advance (trusted 'linear', 'cc', full
    runs) with single answers between them, where the look-ahead starts from one row.
    """
    walk = random_walk(sigma, count=120, seed=7)
    single = budget_solver(params)
    results = [single.solve(wrench[:3], wrench[3:]) for wrench in walk]
    batched = budget_solver(params)
    batch = batched.solve_many(walk[:, :3], walk[:, 3:])
    assert batch.fidelity.tolist() == [result.fidelity for result in results]
    assert_rows_equal(batch, results)
    assert batched.auto.counts == single.auto.counts
    for wrench, result in zip(walk[::10], results[::10]):
        position, angle = errors(result, full, wrench)
        assert position <= BUDGET[0] and angle <= BUDGET[1], result.message
        assert result.stable is not None, result.message
        if result.fidelity != 'full':
            assert result.accuracy_met is True, result.message


def test_look_ahead_reads_one_row_where_no_run_starts(params, monkeypatch):
    """
    Where the next row is a check (outside the trust region), no window of rows is judged.

    The batch asks at every single answer whether a run starts there; the answer comes
    from that row alone, in floats, not from the verdict coverage of a window of rows.
    """
    solver = learned_solver(params)
    origin = solver.tangent.origin
    direction = box_half_widths() * np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    rows = origin + np.linspace(1.1, 1.5, 32)[:, None] * solver.auto.trusted * direction
    assert solver.auto.linear_verdict(rows[0]) == 'check'
    judged = []
    covered = verdicts.Judge.covered

    def counting(judge, wrenches):
        judged.append(len(wrenches))
        return covered(judge, wrenches)

    monkeypatch.setattr(verdicts.Judge, 'covered', counting)
    assert auto_runs.trusted_rows(solver.auto, rows) == 0
    assert auto_runs.full_rows(solver.auto, rows)[0] == 0
    assert judged == []
    inside = origin + np.linspace(0.0, 0.9, 40)[:, None] * solver.auto.trusted * direction
    assert auto_runs.trusted_rows(solver.auto, inside) == len(inside)
    assert judged and sum(judged) == len(inside) - 1  # the first row in floats, then windows


def test_a_check_trusts_the_offsets_near_it_not_its_scale_everywhere(params):
    """
    Past a check, an unchecked answer lies near a check that passed, not merely as far out.

    The curvature is measured along the offsets checked: at the same scale in another
    direction the linear error may be larger, so that offset is checked first.
    """
    solver = learned_solver(params)
    auto = solver.auto
    assert auto.passed_checks and auto.trusted > auto.trusted_everywhere
    checked, reach = auto.passed_checks[-1]
    origin = solver.tangent.origin
    half = box_half_widths()
    offset = (checked - origin) / half
    scale = np.abs(offset).max()
    assert scale > auto.trusted_everywhere
    assert auto.linear_verdict(checked) == 'take'
    turned = offset.copy()
    turned[1] = -np.sign(offset[0]) * scale  # as far out, another way
    turned[0] = offset[1]
    elsewhere = origin + turned * half
    assert np.abs(turned).max() == pytest.approx(scale)
    assert auto.linear_verdict(elsewhere) == 'check'


def test_reduced_answers_on_a_rough_walk_lie_within_the_budget(params):
    """
    A random walk of 0.4 N per sample: every reduced answer is within the budget of full.

    Its offsets from an expansion point every way; trusting a check's scale in every
    direction gave 'linear' answers past the budget with accuracy_met True.
    """
    walk = random_walk(0.4)[:420]
    auto = budget_solver(params).solve_many(walk[:, :3], walk[:, 3:])
    full = FidelitySolver(params, fidelity='full').solve_many(walk[:, :3], walk[:, 3:])
    reduced = auto.fidelity != 'full'
    assert reduced.sum() > 20 and 'linear' in set(auto.fidelity.tolist())
    position = np.linalg.norm(auto.end_disk_position - full.end_disk_position, axis=1)
    dots = np.abs((auto.end_disk_quaternion_xyzw * full.end_disk_quaternion_xyzw).sum(axis=1))
    angle = np.degrees(2.0 * np.arccos(np.minimum(dots, 1.0)))
    assert all(auto.accuracy_met[reduced])
    assert position[reduced].max() <= BUDGET[0], np.argmax(np.where(reduced, position, 0.0))
    assert angle[reduced].max() <= BUDGET[1]
