"""Diagnostics of a solve (node and replay alike): unstable or inaccurate answers are WARN."""

from cdr_translator import TranslatorSolver
from cdr_translator.interface import messages
from cdr_translator.solve import branch


def _diagnostic(result) -> dict:
    (topic, _, message), = [entry for entry in messages.output_messages(
        result, {'sec': 0, 'nanosec': 0}, 'base') if entry[0] == messages.SOLVE_STATUS_TOPIC]
    status = message['status'][0]
    return {'level': status['level'],
            'values': {pair['key']: pair['value'] for pair in status['values']}}


def test_stable_answer_is_ok_and_carries_its_verdict_and_error_bound(params):
    """A Table II solve: OK, with stable, margin and the error estimate in the values."""
    diagnostic = _diagnostic(TranslatorSolver(params).solve((12.0, 0.0, 0.0)))
    assert diagnostic['level'] == messages.OK
    for key in ('stable', 'stability_margin', 'error_estimate_m', 'error_estimate_deg',
                'accuracy_met', 'steps_per_segment'):
        assert key in diagnostic['values']
    assert diagnostic['values']['stable'] == 'true'


def test_unstable_answer_is_published_at_warn(params, monkeypatch):
    """The straight -40 N state (branch following off) converges but is WARN."""
    monkeypatch.setattr(branch, 'BRANCH_ATTEMPTS', 0)
    result = TranslatorSolver(params).solve((0.0, 0.0, -40.0))
    assert result.converged and result.stable is False
    diagnostic = _diagnostic(result)
    assert diagnostic['level'] == messages.WARN
    assert diagnostic['values']['stable'] == 'false'
