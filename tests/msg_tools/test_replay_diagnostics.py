"""Replay's aggregated /diagnostics: one array a period of log time, as the node publishes."""

from cdr_translator.interface import messages
from mcap_ros2.reader import read_ros2_messages
from msg_tools import synth
from msg_tools.replay import replay
import pytest

#: 250 wrenches at 100 Hz: 2.49 s of log time, so arrays at 1 s and 2 s and a closing one.
COUNT, RATE_HZ = 250, 100.0


def _values(status):
    return {pair.key: pair.value for pair in status.values}


@pytest.mark.parametrize('compliance', [False, True], ids=['single', 'batched'])
def test_one_array_a_period_whose_counts_add_up(tmp_path, compliance):
    """
    Arrays at the first wrench past each whole second and at the end; counts add up.

    Batched (compliance: one solve_many per block) or one wrench at a time, the arrays are
    the same: a block is answered before the array its wrenches belong before is written.
    """
    bag = tmp_path / 'walk.mcap'
    samples = synth.generate('random-walk', count=COUNT, rate_hz=RATE_HZ, seed=5)
    samples[120] = samples[120]._replace(frame_id='elsewhere')   # rejected, in the 2nd period
    synth.write_wrenches(bag, samples)
    summary = replay(bag, tmp_path / 'out.mcap', compliance=compliance)
    assert (summary.messages, summary.rejected) == (COUNT, 1)
    records = list(read_ros2_messages(str(tmp_path / 'out.mcap')))
    wrench_times = [item.log_time_ns for item in records if item.channel.topic == '/wrench']
    statuses = [item for item in records if item.channel.topic == '/solve_status']
    assert len(statuses) == COUNT
    assert [messages.stamp_to_ns(item.ros_msg.header.stamp) for item in statuses] == [
        messages.stamp_to_ns(item.ros_msg.header.stamp) for item in records
        if item.channel.topic == '/wrench']
    arrays = [item for item in records if item.channel.topic == '/diagnostics']
    period_ns = 1_000_000_000
    boundaries = sorted({(time // period_ns + 1) * period_ns for time in wrench_times})
    expected = [min(time for time in wrench_times if time >= boundary)
                for boundary in boundaries if boundary <= wrench_times[-1]]
    assert [item.log_time_ns for item in arrays] == expected + [wrench_times[-1]]
    for item in arrays:   # each written after the wrenches before it were answered
        before = sum(time < item.log_time_ns for time in wrench_times)
        values = _values(item.ros_msg.status[0])
        if item is not arrays[-1]:
            assert int(values['received']) == before
    periods = [_values(item.ros_msg.status[0]) for item in arrays]
    final = periods[-1]
    assert int(final['received']) == COUNT == sum(
        int(final[key]) for key in ('solved', 'not_converged', 'rejected', 'skipped'))
    assert sum(int(values['answered_in_period']) for values in periods) == COUNT
    levels = [item.ros_msg.status[0].level for item in arrays]
    assert levels[1] == messages.ERROR and "unknown frame_id 'elsewhere'" in \
        arrays[1].ros_msg.status[0].message
    assert levels[0] == messages.OK and float(periods[0]['received_per_s']) > 0.0
    assert float(periods[0]['worst_residual_norm']) < 1e-9
