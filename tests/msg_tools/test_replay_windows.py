"""Replay in log-time windows on Dask workers: equal to a one-process replay, clean failures."""

import csv
import time

from cdr_translator.interface.joint_summary import JointSummary
from mcap_ros2.reader import read_ros2_messages
from msg_tools import synth
from msg_tools.__main__ import main
from msg_tools.log_time_window import LogTimeWindow
from msg_tools.replay import replay
from msg_tools.replay_summary import Series, TimeStats
from msg_tools.replay_windows import plan_windows, replay_on_dask
import numpy as np
import pytest

#: The solver's accuracy target: end-disk position (m) and angle (deg).
POSITION_TOLERANCE_M, ANGLE_TOLERANCE_DEG = 2e-5, 5e-4


def _by_topic(path):
    """Map each topic of an MCAP to its (log time, message) pairs in file order."""
    topics = {}
    for message in read_ros2_messages(str(path)):
        topics.setdefault(message.channel.topic, []).append((message.log_time_ns,
                                                             message.ros_msg))
    return topics


def _counters(diagnostics):
    """Return the message counters of each /diagnostics message."""
    keys = ('received', 'rejected', 'solved', 'not_converged')
    return [[value.value for value in message.status[0].values if value.key in keys]
            for _, message in diagnostics]


def test_windows_cover_every_log_time_once():
    """Consecutive windows, open at both ends: each log time falls in exactly one."""
    windows = plan_windows(1_000, 1_999, 4)
    assert [window.start_ns for window in windows] == [None, 1_250, 1_500, 1_750]
    assert [window.stop_ns for window in windows] == [1_250, 1_500, 1_750, None]
    for log_time in (0, 999, 1_000, 1_249, 1_250, 1_999, 5_000):
        assert sum(window.holds(log_time) for window in windows) == 1
    assert plan_windows(5, 5, 1) == [LogTimeWindow()]
    with pytest.raises(ValueError):
        plan_windows(0, 10, 0)


def test_merged_statistics_equal_those_of_one_pass():
    """Series, TimeStats and JointSummary of two halves merged equal one pass over all."""
    rng = np.random.default_rng(3)
    times, joints = 10 ** rng.uniform(-5, -2, 300), rng.uniform(-3, 3, (300, 5))
    whole, first, second = Series(limit=40), Series(limit=40), Series(limit=40)
    stats = [TimeStats(), TimeStats(), TimeStats()]
    summaries = [JointSummary(), JointSummary(), JointSummary()]
    for index in range(300):
        half = 1 if index < 170 else 2
        for series, zero_s in ((whole, 0.0), ((first, second)[half - 1], 1.7 * (half - 1))):
            series.add(index, 0.01 * index - zero_s, joints[index, :3], joints[index, 3:],
                       joints[index])
        for group in (stats, summaries):
            group[0].add(times[index] if group is stats else joints[index])
            group[half].add(times[index] if group is stats else joints[index])
    first.merge(second, 1.7)
    assert first.index == whole.index and first.stride == whole.stride
    np.testing.assert_allclose(first.time_s, whole.time_s, atol=1e-12)
    stats[1].merge(stats[2])
    assert [stats[1].percentile(q) for q in (1, 50, 99, 100)] == [
        stats[0].percentile(q) for q in (1, 50, 99, 100)]
    summaries[1].merge(summaries[2])
    assert summaries[1].rows() == summaries[0].rows()


def test_two_workers_equal_one_process(tmp_path):
    """A replay split over 2 workers equals the one-process replay within the accuracy."""
    bag = tmp_path / 'walk.mcap'
    synth.write_wrenches(bag, synth.generate('random-walk', count=600, rate_hz=100.0,
                                             force=(20.0, 5.0, 0.0), seed=4))
    one = replay(bag, tmp_path / 'one.mcap', csv_path=tmp_path / 'one.csv')
    started = time.monotonic()
    split = replay_on_dask(bag, tmp_path / 'split.mcap', workers=2,
                           csv_path=tmp_path / 'split.csv', window_messages=150,
                           plot_samples=[5, 301])
    assert time.monotonic() - started < 300
    for name in ('messages', 'solved', 'not_converged', 'rejected', 'undecodable'):
        assert getattr(split, name) == getattr(one, name), name
    assert split.exit_code() == one.exit_code() == 0
    assert split.solve_times.count == one.solve_times.count
    assert split.joints.count == one.joints.count
    assert {5, 301} <= set(split.series.index)
    np.testing.assert_allclose(split.position_range, one.position_range,
                               atol=POSITION_TOLERANCE_M)
    expected, merged = _by_topic(tmp_path / 'one.mcap'), _by_topic(tmp_path / 'split.mcap')
    assert {topic: len(rows) for topic, rows in merged.items()} == {
        topic: len(rows) for topic, rows in expected.items()}
    for topic in expected:
        assert [time for time, _ in merged[topic]] == [time for time, _ in expected[topic]]
    poses = [np.array([[pose.pose.position.x, pose.pose.position.y, pose.pose.position.z,
                        pose.pose.orientation.x, pose.pose.orientation.y,
                        pose.pose.orientation.z, pose.pose.orientation.w]
                       for _, pose in rows['/end_disk_pose']]) for rows in (expected, merged)]
    assert np.abs(poses[0][:, :3] - poses[1][:, :3]).max() <= POSITION_TOLERANCE_M
    turn = 2 * np.degrees(np.arccos(np.clip(np.abs(np.sum(poses[0][:, 3:] * poses[1][:, 3:],
                                                          axis=1)), 0.0, 1.0)))
    assert turn.max() <= ANGLE_TOLERANCE_DEG
    assert _counters(merged['/diagnostics']) == _counters(expected['/diagnostics'])
    rows = [list(csv.reader(open(tmp_path / name, newline='')))
            for name in ('one.csv', 'split.csv')]
    assert len(rows[0]) == len(rows[1]) == 601 and rows[0][0] == rows[1][0]
    assert [row[:6] for row in rows[0]] == [row[:6] for row in rows[1]]
    assert not list(tmp_path.glob('.replay-parts-*'))


def test_bad_worker_count_is_one_line_exit_2(tmp_path, capsys):
    """--workers 0 is a usage error: exit 2, one line on stderr, no output written."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=5))
    assert main(['replay', str(bag), '--out', str(tmp_path / 'out.mcap'),
                 '--workers', '0']) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and '--workers must be at least 1' in error
    assert not (tmp_path / 'out.mcap').exists()


def test_unreachable_scheduler_is_one_line_exit_2(tmp_path, capsys):
    """No scheduler at the address: exit 2 after the connect timeout, one line on stderr."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=5))
    started = time.monotonic()
    assert main(['replay', str(bag), '--out', str(tmp_path / 'out.mcap'),
                 '--scheduler', 'tcp://127.0.0.1:1']) == 2
    assert time.monotonic() - started < 120
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and error.startswith('error: Dask cluster tcp://127.0.0.1:1')
