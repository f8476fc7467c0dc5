"""msg_tools reader (salvage), info, synth, replay (parity with the CLI, bad input, Ctrl-C)."""

import csv
import json
import math
import os
from pathlib import Path
import select
import shlex
import signal
import subprocess
import sys
import time

from cdr_translator import TranslatorSolver
from cdr_translator.interface import messages
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import WrenchProcessor
from cdr_translator.params.translator_params import Accuracy, DEFAULT_PARAMS_PATH
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource
from chunked import chunk_offsets, write_chunked, write_undecodable
from figure_checks import assert_readable
from interrupting import interrupt_processing_at
from mcap.reader import make_reader
from mcap_ros2.reader import read_ros2_messages
from msg_tools import synth
from msg_tools.__main__ import main
from msg_tools.errors import ReplayError
from msg_tools.plots import arc_points, plot_replay, replay_figure, replay_shapes
from msg_tools.replay import replay
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
BAGS = ROOT / 'bags'

#: Runs ``python -m msg_tools ...`` with rclpy and every ROS message package unimportable.
NO_ROS = """
import importlib.abc, runpy, sys
class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        top = name.split('.')[0]
        if top in ('rclpy', 'rosidl_runtime_py', 'rcl_interfaces') or top.endswith('_msgs'):
            raise ImportError(f'{name} blocked: no ROS here')
        return None
sys.meta_path.insert(0, NoRos())
try:
    import rclpy  # noqa
except ImportError:
    pass
else:
    raise SystemExit('rclpy was importable')
sys.argv = ['msg_tools'] + sys.argv[1:]
runpy.run_module('msg_tools', run_name='__main__')
"""


def _run(*args, no_ros=False, timeout=300):
    command = ([sys.executable, '-c', NO_ROS] if no_ros else
               [sys.executable, '-m', 'msg_tools']) + [str(arg) for arg in args]
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=timeout)


_chunked, _chunk_offsets = write_chunked, chunk_offsets


# ---------------------------------------------------------------------------- reader
def test_complete_file_is_read_through_its_index(tmp_path):
    """A finished file: indexed, every message, nothing lost."""
    stamps = _chunked(tmp_path / 'a.mcap')
    source = McapSource(tmp_path / 'a.mcap')
    assert [m.log_time_ns for m in source.messages()] == stamps
    assert source.report.complete and source.report.lost_messages == 0


@pytest.mark.parametrize('cut', ['in the summary', 'inside the third chunk', 'after magic'])
def test_truncated_file_keeps_every_complete_chunk(tmp_path, cut):
    """A cut file: salvaged by streaming, the complete chunks kept, the loss reported."""
    path = tmp_path / 'a.mcap'
    stamps = _chunked(path)
    (first, _), (_, _), (third, third_length), (fourth, fourth_length) = _chunk_offsets(path)
    data = path.read_bytes()
    size, kept = {'in the summary': (fourth + fourth_length + 40, 40),
                  'inside the third chunk': (third + third_length // 2, 20),
                  'after magic': (10, 0)}[cut]
    path.write_bytes(data[:size])
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps[:kept]
    report = source.report
    assert report.mode == 'salvaged' and not report.complete
    assert 'no readable summary' in report.reason
    if kept < 40:
        assert report.unread_bytes > 0 and 'unreadable from byte' in report.describe()


def test_corrupt_chunk_loses_only_its_messages(tmp_path):
    """A flipped byte inside one chunk: the others are read, indexed or streamed."""
    path = tmp_path / 'a.mcap'
    stamps = _chunked(path)
    (_, _), (second, length), _, _ = _chunk_offsets(path)
    data = bytearray(path.read_bytes())
    data[second + length - 30] ^= 0xFF
    path.write_bytes(bytes(data))
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps[:10] + stamps[20:]
    assert source.report.mode == 'indexed' and source.report.lost_messages == 10
    assert 'unreadable' in source.report.problems[0]
    path.write_bytes(bytes(data[:-200]))   # and without the summary: streamed past it
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps[:10] + stamps[20:]
    assert source.report.mode == 'salvaged'
    assert 'chunk at byte' in source.report.problems[0]
    assert 'unreadable from byte' in source.report.problems[1]   # the cut summary


def test_not_an_mcap(tmp_path):
    """Garbage: nothing read, a report that says why; a missing file is a ValueError."""
    path = tmp_path / 'x.mcap'
    path.write_bytes(b'this is not an mcap file at all')
    source = McapSource(path)
    assert list(source.messages()) == []
    assert 'InvalidMagic' in source.report.describe()
    with pytest.raises(ValueError, match='no such MCAP'):
        McapSource(tmp_path / 'missing.mcap')


# ---------------------------------------------------------------------------- synth, info
def test_synth_profiles():
    """Ramp, step, sinusoid, random walk, the paper's cases and the hard cases."""
    ramp = synth.generate('ramp', count=5, force=(20, 0, 0))
    assert [s.force[0] for s in ramp] == [0.0, 5.0, 10.0, 15.0, 20.0]
    assert [s.stamp_ns - ramp[0].stamp_ns for s in ramp] == [k * 10**7 for k in range(5)]
    assert [s.force[0] for s in synth.generate('step', count=6)] == [0, 0, 20, 20, 20, 20]
    wave = synth.generate('sinusoid', count=101, rate_hz=100, frequency_hz=1.0)
    assert wave[25].force[0] == pytest.approx(20.0) and wave[75].force[0] == pytest.approx(-20)
    walk = synth.generate('random-walk', count=500, force=(20, 0, 0), moment=(0, 0, 0.1))
    forces = np.array([s.force for s in walk])
    assert np.all(np.linalg.norm(forces, axis=1) <= 20.0 + 1e-12)
    assert np.all(np.ptp(forces, axis=0) > 1.0)   # every component moves
    again = synth.generate('random-walk', count=500, force=(20, 0, 0), moment=(0, 0, 0.1))
    assert all(np.array_equal(a.moment, b.moment) for a, b in zip(walk, again))
    assert [s.force.tolist() for s in synth.generate('paper')] == [[12, 0, 0], [20, 0, 0]]
    hard = synth.generate('hard')
    assert any(np.isnan(s.force).any() for s in hard) and 'world' in [s.frame_id for s in hard]
    for bad in ({'profile': 'square'}, {'profile': 'ramp', 'count': 0},
                {'profile': 'ramp', 'rate_hz': -1.0}, {'profile': 'ramp', 'force': (1, 2)}):
        with pytest.raises(ValueError):
            synth.generate(**bad)


def test_info_describes_complete_and_damaged_files(tmp_path, capsys):
    """Topics, types, counts, time range; a cut file is salvaged and said to be."""
    path = tmp_path / 'a.mcap'
    _chunked(path)
    assert main(['info', str(path)]) == 0
    text = capsys.readouterr().out
    assert 'complete' in text and '/wrench' in text and messages.WRENCH_TYPE in text
    assert 'messages:  40' in text and 'duration:  0.390000 s' in text
    path.write_bytes(path.read_bytes()[:-300])
    assert main(['info', str(path)]) == 0
    assert 'salvaged' in capsys.readouterr().out
    assert main(['info', str(tmp_path / 'nothing.mcap')]) == 2


def _synth_command(bag):
    """Return the synth command stored in a bag's metadata, or None for a recorded bag."""
    with open(bag, 'rb') as stream:
        metadata = {m.name: m.metadata for m in make_reader(stream).iter_metadata()}
    return metadata.get('msg_tools.synth', {}).get('command')


@pytest.mark.parametrize('bag', sorted(BAGS.glob('*.mcap')), ids=lambda path: path.name)
def test_sample_bags_are_small(bag):
    """Every shipped bag, synthetic or recorded, stays under 1 MB."""
    assert bag.stat().st_size < 1_000_000


@pytest.mark.parametrize('bag', [bag for bag in sorted(BAGS.glob('*.mcap'))
                                 if _synth_command(bag)], ids=lambda path: path.name)
def test_synthetic_bags_are_reproducible(bag, tmp_path):
    """A synthetic bag holds its command, which makes the same messages again."""
    args = shlex.split(_synth_command(bag))[3:]   # after "... msg_tools"
    args[1] = str(tmp_path / 'again.mcap')
    assert main(args) == 0
    original = [(m.log_time, m.data) for _, _, m in make_reader(open(bag, 'rb')).iter_messages()]
    again = [(m.log_time, m.data) for _, _, m in
             make_reader(open(tmp_path / 'again.mcap', 'rb')).iter_messages()]
    assert again == original


# ---------------------------------------------------------------------------- replay
def _cli_position(force):
    process = subprocess.run([sys.executable, '-m', 'cdr_translator', 'solve', '--force',
                              *map(str, force), '--json'], cwd=ROOT, capture_output=True,
                             text=True, timeout=300)
    assert process.returncode == 0, process.stderr
    return np.array(json.loads(process.stdout)['end_disk_position_m'])


def test_replay_without_ros_equals_the_cli(tmp_path):
    """Without an importable rclpy, replay works; poses equal the CLI's to 1e-9 m; stamps kept."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    out, table, picture = tmp_path / 'out.mcap', tmp_path / 'out.csv', tmp_path / 'out.png'
    process = _run('replay', bag, '--out', out, '--csv', table, '--plot', picture,
                   no_ros=True)
    assert process.returncode == 0, process.stderr
    assert 'solved (converged)              2' in process.stdout
    assert picture.stat().st_size > 20_000
    inputs = {m.channel.topic: [] for m in read_ros2_messages(str(out))}
    for item in read_ros2_messages(str(out)):
        inputs[item.channel.topic].append(item.ros_msg)
    assert set(inputs) == {'/wrench', '/end_disk_pose', '/bending_angles', '/solve_status',
                           '/diagnostics', '/compliance', '/compliance_eigenvalues'}
    for wrench, pose in zip(inputs['/wrench'], inputs['/end_disk_pose']):
        assert (pose.header.stamp.sec, pose.header.stamp.nanosec) == (
            wrench.header.stamp.sec, wrench.header.stamp.nanosec)
        assert pose.header.frame_id == 'translator_base'
        force = [wrench.wrench.force.x, wrench.wrench.force.y, wrench.wrench.force.z]
        position = [pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]
        assert np.abs(np.array(position) - _cli_position(force)).max() < 1e-9
    rows = list(csv.DictReader(open(table)))
    assert [row['status'] for row in rows] == ['solved', 'solved']
    assert math.degrees(float(rows[0]['pj_bending_rad'])) == pytest.approx(22.448, abs=0.5)


def test_warm_replay_agrees_with_cold_solves(tmp_path):
    """
    Along a random walk the warm-started replay equals cold solves to 1e-10 m.

    Each at the steps per segment the replay's solve used (its diagnostic says which: a
    warm solve keeps the steps of an earlier refinement, a cold one refines from the base
    count and may stop at other steps, both within the accuracy target).
    """
    bag = tmp_path / 'walk.mcap'
    synth.write_wrenches(bag, synth.generate('random-walk', count=60, moment=(0, 0, 0.1)))
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False)
    assert summary.solved == 60
    params = TranslatorSolver().params
    solvers = {}
    poses = [m.ros_msg.pose.position for m in
             read_ros2_messages(str(tmp_path / 'out.mcap'), topics=['/end_disk_pose'])]
    steps = [int(next(item.value for item in m.ros_msg.status[0].values
                      if item.key == 'steps_per_segment'))
             for m in read_ros2_messages(str(tmp_path / 'out.mcap'), topics=['/solve_status'])]
    assert len(poses) == len(steps) == 60
    for wrench, pose, count in zip(summary.series.wrench, poses, steps):
        if count not in solvers:  # that discretization, no refinement of its own
            solvers[count] = TranslatorSolver(params.with_changes(steps_per_segment=count),
                                              accuracy=Accuracy(0.0, 0.0))
        cold = solvers[count].solve(wrench[:3], wrench[3:], warm_start=False)
        assert np.abs(cold.end_disk_position - [pose.x, pose.y, pose.z]).max() < 1e-10


def test_bad_messages_are_reported_and_the_rest_processed(tmp_path):
    """NaN, Inf, unknown frame, absurd magnitude: rejected with an ERROR status each."""
    bag = tmp_path / 'hard.mcap'
    synth.write_wrenches(bag, synth.generate('hard'))
    table = tmp_path / 'hard.csv'
    summary = replay(bag, tmp_path / 'out.mcap', csv_path=table, compliance=False)
    assert (summary.messages, summary.rejected) == (12, 4)
    assert summary.solved + summary.not_converged == 8
    rows = list(csv.DictReader(open(table)))
    assert len(rows) == 12
    rejected = [row['message'] for row in rows if row['status'] == 'rejected']
    assert any('nan' in text for text in rejected) and any('inf' in text for text in rejected)
    assert any("unknown frame_id 'world'" in text for text in rejected)
    assert any('exceeds max_force' in text for text in rejected)
    statuses = [m.ros_msg.status[0] for m in
                read_ros2_messages(str(tmp_path / 'out.mcap'), topics=['/solve_status'])]
    assert len(statuses) == 12
    assert sum(status.level == messages.ERROR and 'rejected' in status.message
               for status in statuses) == 4
    arrays = [m.ros_msg for m in
              read_ros2_messages(str(tmp_path / 'out.mcap'), topics=['/diagnostics'])]
    assert any(array.status[0].level == messages.ERROR for array in arrays)
    counts = {kv.key: kv.value for kv in arrays[-1].status[0].values}
    assert counts['received'] == '12' and counts['rejected'] == '4'


def test_summary_gives_directions_by_circular_statistics(tmp_path, capsys):
    """Two loads along -x bend towards +180 and -180 deg: the summary says 180, spread ~0."""
    bag = tmp_path / 'reversed.mcap'
    synth.write_wrenches(bag, [
        synth.Sample(synth.DEFAULT_START_NS + k, np.array([-12.0, side, 0.0]), np.zeros(3),
                     'translator_base') for k, side in enumerate((1e-6, -1e-6))])
    assert main(['replay', str(bag), '--out', str(tmp_path / 'o.mcap'),
                 '--progress', 'never']) == 0
    rows = dict(line.split(None, 2)[::2] for line in capsys.readouterr().out.splitlines()
                if line.startswith(('pj_direction', 'dj_direction')))
    assert rows['pj_direction'] in ('circular mean 180.000, circular std 0.000',
                                    'circular mean -180.000, circular std 0.000')
    assert rows['dj_direction'] in ('circular mean 0.000, circular std 0.000',
                                    'circular mean -0.000, circular std 0.000')


def test_missing_topic_and_wrong_schema(tmp_path, capsys):
    """A missing topic or a non-wrench schema: exit 2 naming what the file holds."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=4))
    assert main(['replay', str(bag), '--out', str(tmp_path / 'o.mcap'), '--topic', '/nope',
                 '--progress', 'never']) == 2
    error = capsys.readouterr().err
    assert "'/nope' is not in" in error and '/wrench [geometry_msgs/msg/WrenchStamped]' in error
    replay(bag, tmp_path / 'first.mcap', compliance=False)
    with pytest.raises(ReplayError, match="has schema 'geometry_msgs/msg/PoseStamped'"):
        replay(tmp_path / 'first.mcap', tmp_path / 'o.mcap', topics=['/end_disk_pose'])
    summary = replay(bag, tmp_path / 'o.mcap', topics=['/wrench', '/nope'], compliance=False)
    assert summary.solved == 4 and summary.warnings == [f"topic '/nope' is not in {bag}"]
    with pytest.raises(ReplayError, match='no such MCAP'):
        replay(tmp_path / 'none.mcap', tmp_path / 'o.mcap')


def test_undecodable_messages_are_counted(tmp_path):
    """A channel called WrenchStamped whose definition is something else: counted, skipped."""
    bag = tmp_path / 'odd.mcap'
    write_undecodable(bag, 3)
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False)
    assert (summary.messages, summary.undecodable, summary.solved) == (3, 3, 0)
    assert 'cannot' in summary.warnings[0] or 'has no attribute' in summary.warnings[0]


def test_ctrl_c_finalizes_the_output(tmp_path, monkeypatch):
    """Stop by KeyboardInterrupt midway: the output MCAP has its summary and what was done."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=20))
    interrupt_processing_at(monkeypatch, 6)
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False, csv_path=tmp_path / 'o.csv')
    assert summary.interrupted and summary.solved == 5
    with open(tmp_path / 'out.mcap', 'rb') as stream:
        found = make_reader(stream).get_summary()
    counts = {found.channels[channel].topic: count
              for channel, count in found.statistics.channel_message_counts.items()}
    assert counts.pop('/wrench') == 6 and counts.pop('/diagnostics') >= 1
    assert sorted(counts.values()) == [5, 5, 5]   # pose, angles, solve_status
    assert len(list(csv.DictReader(open(tmp_path / 'o.csv')))) == 5
    # the summary says the input was not read through, and how much was left
    assert summary.stopped_early and summary.total == 20
    assert 'up to where the replay stopped' in summary.table()
    assert '14 of 20 messages' in summary.table()   # the sixth was read, not solved


def test_sigint_inside_a_write_waits_for_the_message(tmp_path, monkeypatch):
    """SIGINT arriving inside the MCAP writer: the message is finished, then the replay stops."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=20))
    original = McapLog.write
    calls = []

    def signalled(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 7:   # the first output of the third message (three outputs each)
            os.kill(os.getpid(), signal.SIGINT)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(McapLog, 'write', signalled)
    # Python's own handler, as in an interactive shell (a CI job may start with SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        summary = replay(bag, tmp_path / 'out.mcap', compliance=False)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)
    assert summary.interrupted and summary.messages == summary.solved == 3
    source = McapSource(tmp_path / 'out.mcap')
    topics = [m.topic for m in source.messages()]
    # 3 inputs, 3 x 3 outputs, the closing /diagnostics array
    assert source.report.complete and len(topics) == 13 and topics[-1] == '/diagnostics'


def _default_sigint() -> None:
    """Give the child process the default SIGINT disposition (run before its exec)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_sigint_during_replay(tmp_path):
    """A real SIGINT to the CLI: exit 130, a complete output MCAP, the summary printed."""
    bag = tmp_path / 'walk.mcap'
    synth.write_wrenches(bag, synth.generate('random-walk', count=3000))
    # a shell's background job ignores SIGINT and children inherit that; restore the default
    # so that Python installs its KeyboardInterrupt handler, as in an interactive shell
    process = subprocess.Popen([sys.executable, '-m', 'msg_tools', 'replay', str(bag), '--out',
                                str(tmp_path / 'out.mcap'), '--progress', 'always'],
                               cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               preexec_fn=_default_sigint)
    deadline = time.monotonic() + 120
    seen = b''
    while b'msg/s' not in seen and time.monotonic() < deadline and process.poll() is None:
        if select.select([process.stderr], [], [], 0.1)[0]:
            seen += os.read(process.stderr.fileno(), 4096)
    process.send_signal(signal.SIGINT)
    stdout = process.communicate(timeout=120)[0].decode()
    assert process.returncode == 130, stdout
    assert 'interrupted' in stdout
    source = McapSource(tmp_path / 'out.mcap')
    done = sum(1 for m in source.messages() if m.topic == '/solve_status')
    assert source.report.complete and 0 < done < 3000


def test_fitted_arc_follows_a_circle():
    """arc_points on points of a known arc: on that circle, from the first to the last."""
    t = np.linspace(0.2, 1.4, 9)
    points = np.column_stack([0.05 * np.cos(t), np.full(9, 0.01), 0.05 * np.sin(t)])
    arc = arc_points(points, count=30)
    assert np.allclose(arc[0], points[0], atol=1e-12)
    assert np.allclose(arc[-1], points[-1], atol=1e-12)
    radii = np.hypot(arc[:, 0], arc[:, 2])
    assert np.allclose(radii, 0.05, atol=1e-12) and np.allclose(arc[:, 1], 0.01, atol=1e-12)
    line = arc_points(np.column_stack([np.zeros(5), np.zeros(5), np.arange(5.0)]))
    assert np.allclose(line[:, 2], np.linspace(0, 4, 60))


def _recorded_poses(path, topic):
    return {(m.ros_msg.header.stamp.sec, m.ros_msg.header.stamp.nanosec):
            np.array([m.ros_msg.pose.position.x, m.ros_msg.pose.position.y,
                      m.ros_msg.pose.position.z])
            for m in read_ros2_messages(str(path), topics=[topic])}


def _node_recordings():
    """Bags recorded from the live node: they hold its end_disk_pose output."""
    found = []
    for bag in sorted(BAGS.glob('*.mcap')):
        with open(bag, 'rb') as stream:
            topics = [c.topic for c in make_reader(stream).get_summary().channels.values()]
        found += [(bag, topic) for topic in topics if topic.endswith('/end_disk_pose')]
    return found


@pytest.mark.parametrize('bag, topic', _node_recordings() or [pytest.param(
    None, None, marks=pytest.mark.skip(reason='no bag recorded from the live node yet'))])
def test_live_node_recording_replays_to_the_same_poses(bag, topic, tmp_path):
    """Live/offline parity: every pose the node published is replayed within 1e-9 m."""
    summary = replay(bag, tmp_path / 'offline.mcap', compliance=False)
    assert summary.solved > 0
    live = _recorded_poses(bag, topic)
    offline = _recorded_poses(tmp_path / 'offline.mcap', topic)
    assert live and set(live) <= set(offline)
    assert max(np.abs(live[stamp] - offline[stamp]).max() for stamp in live) < 1e-9


def test_fidelity_setting_reaches_the_diagnostics(params, tmp_path):
    """`fidelity: cc` in the params file: replay solves with it and the log says so."""
    path = tmp_path / 'cc.yaml'
    path.write_text(DEFAULT_PARAMS_PATH.read_text().replace('fidelity: full', 'fidelity: cc'))
    settings = TranslatorSettings.from_params_file(path)
    assert settings.fidelity == 'cc'
    processor = WrenchProcessor(params, settings, compliance=False)
    outcome = processor.process(np.array([12.0, 0.0, 0.0]), np.zeros(3), '',
                                {'sec': 1, 'nanosec': 0})
    assert outcome.result.converged and outcome.result.fidelity == 'cc'
    status = next(message for topic, _, message in outcome.outputs
                  if topic == messages.SOLVE_STATUS_TOPIC)['status'][0]
    assert {kv['key']: kv['value'] for kv in status['values']}['fidelity'] == 'cc'


def test_plot_of_the_paper_cases_is_readable(tmp_path):
    """The plot of the paper's two loads: markers, the loads named, no text on text."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    series = replay(bag, tmp_path / 'out.mcap', compliance=False).series
    assert plot_replay(series, tmp_path / 'plot.png') == [0, 1]
    assert (tmp_path / 'plot.png').stat().st_size > 20_000
    figure = replay_figure(series.time_s, np.array(series.joints), np.array(series.position),
                           replay_shapes(series))
    assert_readable(figure)
    legend = [text.get_text() for text in figure.legends[0].get_texts()]
    assert legend == ['F = (12, 0, 0) N (message 0)', 'F = (20, 0, 0) N (message 1)']
