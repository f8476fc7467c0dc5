"""
Every fidelity level's answers say how accurate and how stable they are, or that they cannot.

``accuracy_met`` is True only where an estimate was checked against a target, and reads the
same as an attribute and in ``to_dict``; every converged answer carries a stability verdict
or a message saying why not; 'auto' answers always carry one (fidelity/verdicts.py).
"""

import math

from batch_checks import assert_rows_equal
from cdr_translator import TranslatorSolver
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.fidelity.validation import box_half_widths
from cdr_translator.interface import messages
from cdr_translator.interface.batch_row import BatchRow
import numpy as np
import pytest

BUDGET = {'max_position_error': 3e-3, 'max_angle_error_deg': 1.0}

#: FidelitySolver options per case: each fixed level, 'auto' without and with a budget.
CASES = {'full': {'fidelity': 'full'}, 'rod': {'fidelity': 'rod'}, 'cc': {'fidelity': 'cc'},
         'linear': {'fidelity': 'linear'}, 'auto': {'fidelity': 'auto'},
         'auto budget': {'fidelity': 'auto', **BUDGET}}


def noisy_walk(count=70, seed=11):
    """
    Return a seeded random walk of wrenches with noise, from no load to past the validated box.

    Steps of a few newtons (and hundredths of N m) that drift over the wrench range the node
    accepts near the model's own (the validated box is 20 N, 0.5 N m per component; the walk
    reaches about 1.4 times that), each sample with noise on top: not a smooth sequence.
    """
    rng = np.random.default_rng(seed)
    half = box_half_widths()
    steps = rng.normal(0.0, 0.08, (count, 6)) * half
    walk = np.cumsum(steps, axis=0)
    # reflect into +-1.4 box half-widths: the walk wanders in and out of the validated box
    bound = 1.4 * half
    walk = np.abs((walk + bound) % (4.0 * bound) - 2.0 * bound) - bound
    return walk + rng.normal(0.0, 0.01, (count, 6)) * half


def _said(result):
    """Whether a result states a stability verdict or why it has none."""
    return (result.stable is not None or not result.converged
            or 'stability not assessed' in result.message)


@pytest.fixture(scope='module')
def walk():
    """Return the noisy wrench sequence, one wrench of 6 components a row."""
    return noisy_walk()


@pytest.fixture(scope='module')
def answers(params, walk):
    """Single solves of the walk per case: {case: [SolveResult]}."""
    out = {}
    for case, options in CASES.items():
        solver = FidelitySolver(params, **options)
        out[case] = [solver.solve(wrench[:3], wrench[3:]) for wrench in walk]
    return out


@pytest.mark.parametrize('case', list(CASES))
def test_accuracy_met_is_the_same_everywhere_and_never_unfounded(answers, case):
    """
    Attribute and to_dict agree; True only with a finite estimate.

    Reduced levels without a budget claim nothing.
    """
    for result in answers[case]:
        summary = result.to_dict()
        assert summary['accuracy_met'] is result.accuracy_met, result.message
        if result.accuracy_met:
            assert math.isfinite(result.error_estimate_m), result.message
            assert math.isfinite(result.error_estimate_deg), result.message
        if result.fidelity != 'full' and case != 'auto budget':
            assert result.accuracy_met is None and summary['error_estimate_m'] is None


@pytest.mark.parametrize('case', list(CASES))
def test_every_answer_has_a_verdict_or_says_why_not(answers, case):
    """Converged answers carry ``stable`` or the message names the missing verdict."""
    results = answers[case]
    assert sum(result.converged for result in results) > len(results) // 2
    for result in results:
        assert _said(result), result.message
        if result.stable is not None:
            assert math.isfinite(result.stability_margin), result.message


@pytest.mark.parametrize('case', ['auto', 'auto budget'])
def test_auto_answers_carry_a_verdict(answers, case):
    """Every converged 'auto' answer has a verdict, whichever level gave it."""
    levels = set()
    for result in answers[case]:
        levels.add(result.fidelity)
        if result.converged:
            assert result.stable is not None, result.message
            assert result.to_dict()['stable'] is result.stable
    if case == 'auto budget':
        assert levels - {'full'}, levels  # reduced levels answered too


def test_auto_reduced_answers_are_estimated_within_the_budget(answers):
    """A reduced 'auto' answer carries its validated or checked error, inside the budget."""
    reduced = [result for result in answers['auto budget'] if result.fidelity != 'full']
    assert reduced
    for result in reduced:
        assert result.accuracy_met is True, result.message
        assert 0.0 <= result.error_estimate_m <= BUDGET['max_position_error']
        assert 0.0 <= result.error_estimate_deg <= BUDGET['max_angle_error_deg']


def test_carried_verdicts_agree_with_the_full_model(params, answers, walk):
    """Where a reduced answer says stable, the full model there says stable too."""
    full = TranslatorSolver(params)
    checked = 0
    for case in ('rod', 'cc', 'linear', 'auto budget'):
        for wrench, result in zip(walk, answers[case]):
            if result.fidelity == 'full' or result.stable is None:
                continue
            own = full.solve(wrench[:3], wrench[3:])
            assert own.stable is result.stable, (case, wrench, result.message)
            assert "full model's verdict" in result.message
            checked += 1
    assert checked > 0


@pytest.mark.parametrize('case', list(CASES))
def test_batch_rows_say_what_single_answers_say(params, answers, walk, case):
    """solve_many on the walk: each row's accuracy and stability are the single solve's."""
    batch = FidelitySolver(params, **CASES[case]).solve_many(walk[:, :3], walk[:, 3:])
    assert_rows_equal(batch, answers[case])
    for index, result in enumerate(answers[case]):
        row = BatchRow(batch, index)
        assert row.accuracy_met is result.accuracy_met
        if result.fidelity != 'full':  # the reduced levels' columns, as a single answer's
            assert row.stable is result.stable
            assert row.stability_margin == pytest.approx(result.stability_margin, nan_ok=True)


def test_diagnostics_of_an_unestimated_answer(params):
    """No 'accuracy_met' value and no warning for an answer with no estimate; OK if stable."""
    result = FidelitySolver(params, fidelity='cc').solve([0.5, 0.0, 0.0])
    assert result.converged and result.accuracy_met is None and result.stable is True
    assert 'accuracy_met' not in messages.solve_diagnostic_values(result)
    assert messages.solve_level(result) == messages.OK
    far = FidelitySolver(params, fidelity='cc').solve([15.0, 0.0, 0.0])
    assert far.stable is None and 'stability not assessed' in far.message
    assert messages.solve_level(far) == messages.OK
