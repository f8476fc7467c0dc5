"""The aggregated diagnostics of a period: counts, rates, worst residual, the last fault."""

import math

from cdr_translator.interface import messages
from cdr_translator.interface.diagnostics_period import diagnostics_array, StreamDiagnostics
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import WrenchProcessor
import pytest

STAMP = {'sec': 5, 'nanosec': 0}


def _values(status: dict) -> dict:
    return {pair['key']: pair['value'] for pair in status['values']}


def test_a_fault_in_the_period_raises_its_level_and_is_named():
    """The worst level of the period wins; its message names the last fault; then idle OK."""
    stream = StreamDiagnostics('node: stage', 'wrenches')
    stream.begin(10.0)
    stream.note(messages.OK, 'converged', 1e-12, 0.001)
    stream.note(messages.WARN, 'unstable equilibrium', 3e-11, 0.004)
    stream.note(messages.OK, 'converged', 2e-12, 0.002)
    counts = {'received': 4, 'solved': 3, 'not_converged': 0, 'rejected': 0, 'skipped': 1}
    status = stream.status(counts, 12.0)
    values = _values(status)
    assert status['level'] == messages.WARN and status['name'] == 'node: stage'
    assert 'unstable equilibrium' in status['message'] and '1 of 3' in status['message']
    assert float(values['period_s']) == 2.0
    assert values['received'] == '4' and float(values['received_per_s']) == 2.0
    assert float(values['solved_per_s']) == 1.5 and float(values['skipped_share']) == 0.25
    assert float(values['worst_residual_norm']) == 3e-11
    assert float(values['max_solve_time_ms']) == pytest.approx(4.0)
    assert float(values['mean_solve_time_ms']) == pytest.approx(7.0 / 3.0, rel=1e-5)
    assert values['latest_level'] == 'OK' and values['latest_message'] == 'converged'
    assert (values['answered_in_period'], values['warned_in_period'],
            values['failed_in_period']) == ('3', '1', '0')
    stream.note(messages.ERROR, 'rejected: force x component is nan')
    status = stream.status({**counts, 'received': 5, 'rejected': 1}, 13.0)
    assert status['level'] == messages.ERROR and 'is nan' in status['message']
    assert float(_values(status)['received_per_s']) == 1.0   # over this period only
    idle = stream.status({**counts, 'received': 5, 'rejected': 1}, 14.0)
    assert idle['level'] == messages.OK and idle['message'].startswith('idle')
    assert 'worst_residual_norm' not in _values(idle) and 'latest_level' not in _values(idle)
    array = diagnostics_array(STAMP, [idle])
    assert array['header']['stamp'] == STAMP and array['status'] == [idle]


def test_wrench_processor_counts_add_up_and_statuses_stay_per_wrench():
    """Each wrench's own status on solve_status carries no counts; the period's add up."""
    settings = TranslatorSettings.from_params_file()
    processor = WrenchProcessor(settings.params, settings)
    processor.diagnostics.begin(0.0)
    wrenches = [((2.0, 0.0, 0.0), (0.0, 0.0, 0.0), ''), ((math.nan, 0.0, 0.0), (0.0,) * 3, ''),
                ((3.0, 1.0, 0.0), (0.0, 0.0, 0.0), ''), ((1.0, 0.0, 0.0), (0.0,) * 3, 'tool')]
    for force, moment, frame in wrenches:
        outcome = processor.process(force, moment, frame, STAMP)
        topic, type_name, status = outcome.outputs[-1]
        assert (topic, type_name) == (messages.SOLVE_STATUS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE)
        assert status['header']['stamp'] == STAMP
        assert not {'received', 'solved', 'skipped'} & set(_values(status['status'][0]))
    status = processor.diagnostics_status(2.0)
    values = _values(status)
    received = int(values['received'])
    assert received == len(wrenches)
    assert received == sum(int(values[key])
                           for key in ('solved', 'not_converged', 'rejected', 'skipped'))
    assert (values['solved'], values['rejected'], values['flagged']) == ('2', '2', '0')
    assert status['level'] == messages.ERROR and "unknown frame_id 'tool'" in status['message']
    assert float(values['received_per_s']) == 2.0 and float(values['worst_residual_norm']) < 1e-9
    assert processor.diagnostics_status(3.0)['level'] == messages.OK


@pytest.mark.parametrize('period', [0.0, -1.0, 1e4])
def test_diagnostics_period_must_be_positive_and_bounded(period):
    """diagnostics_period_s <= 0 (or beyond an hour) is refused, naming the key; 1 s ships."""
    settings = TranslatorSettings.from_params_file()
    assert settings.diagnostics_period_s == 1.0
    with pytest.raises(ValueError, match='diagnostics_period_s'):
        settings.with_values(diagnostics_period_s=period)
