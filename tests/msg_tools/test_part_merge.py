"""The merge of replay parts: records copied as stored, diagnostics counters continued."""

from cdr_translator.interface import messages
from cdr_wire.cdr_codecs import decoder, encoder
from cdr_wire.reader import McapSource
from mcap_ros2.reader import read_ros2_messages
from msg_tools import synth
from msg_tools.part_merge import continue_counters, COUNTERS, part_messages
from msg_tools.replay import replay
import pytest

STAMP = {'sec': 12, 'nanosec': 345}


def _diagnostics(values, statuses=1):
    """Return a DiagnosticArray dict with ``statuses`` copies of a status of ``values``."""
    message = messages.diagnostics_message(STAMP, messages.OK, 'converged', values,
                                           hardware_id='odd-length id')
    status = message['status'][0]
    message['status'] = [dict(status, name=f'status {k}',
                              values=[dict(value) for value in status['values']])
                         for k in range(statuses)]
    return message


def _raised(message, offsets):
    """Return ``message`` with the first status's counters raised by ``offsets``."""
    for value in message['status'][0]['values']:
        if value['key'] in offsets:
            value['value'] = str(int(value['value']) + offsets[value['key']])
    return message


@pytest.mark.parametrize('values, statuses', [
    ({'converged': True, 'iterations': 4, 'received': 9, 'rejected': 0, 'solved': 9,
      'not_converged': 0, 'skipped': 0}, 1),
    ({'received': 99, 'a': 'xyz', 'solved': 7, 'not_converged': 1, 'b': 'odd'}, 1),
    ({'received': 5, 'solved': 5, 'tail': 'ab'}, 2),
])
@pytest.mark.parametrize('offset', [0, 1, 9, 999, 123456])
def test_continued_counters_equal_a_reencoded_message(values, statuses, offset):
    """Raised in the CDR bytes: the bytes of the decoded, raised and re-encoded message."""
    encode = encoder(messages.DIAGNOSTIC_ARRAY_TYPE)
    data = encode(_diagnostics(values, statuses))
    offsets = {key: offset for key in COUNTERS}
    counts = {}
    raised = continue_counters(data, offsets, counts)
    expected = _raised(_diagnostics(values, statuses), offsets)
    assert raised == encode(expected)
    assert decoder(messages.DIAGNOSTIC_ARRAY_TYPE)(raised) == expected
    assert counts == {key: int(value) + offset for key, value in values.items()
                      if key in COUNTERS}


def test_part_messages_are_the_stored_records(tmp_path):
    """The part's messages as the reader gives them: topics, types, bytes, times, order."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=30))
    replay(bag, tmp_path / 'part.mcap')
    expected = [(raw.topic, raw.schema_name, raw.data, raw.log_time_ns, raw.publish_time_ns)
                for raw in McapSource(tmp_path / 'part.mcap').messages()]
    assert list(part_messages(tmp_path / 'part.mcap')) == expected
    assert len(expected) == len(list(read_ros2_messages(str(tmp_path / 'part.mcap'))))
