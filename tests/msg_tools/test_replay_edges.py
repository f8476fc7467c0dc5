"""
Replay at the edges a user meets.

Outputs that alias the input or each other, bad plot options, a closed stdout, topics
outside '.../wrench', a source read twice, synth values no stamp can hold (a replay that
stops early: test_replay.test_ctrl_c_finalizes_the_output).
"""

import csv
import os
from pathlib import Path
import subprocess
import sys

from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource
from chunked import write_undecodable
from msg_tools import replay as replay_module, synth
from msg_tools.__main__ import EXIT_BROKEN_PIPE, main
from msg_tools.errors import ReplayError
from msg_tools.replay import CSV_COLUMNS, replay
from msg_tools.replay_summary import EXIT_USAGE
from msg_tools.replay_topics import output_topic
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _paper_bag(folder: Path) -> Path:
    bag = folder / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    return bag


def _replay(bag, out, *extra) -> int:
    return main(['replay', str(bag), '--out', str(out), '--no-compliance', '--progress',
                 'never', *map(str, extra)])


@pytest.mark.parametrize('case', ['csv is the input', 'out is a hard link to the input',
                                  'out is a symbolic link to the input', 'csv is the out',
                                  'plot is the out'])
def test_an_output_that_is_another_file_of_the_run_is_refused(tmp_path, case, capsys):
    """Exit 2 naming both, before anything is opened: the input keeps every byte."""
    bag = _paper_bag(tmp_path)
    before = bag.read_bytes()
    out, extra = tmp_path / 'out.mcap', []
    if case == 'csv is the input':
        extra = ['--csv', bag]
    elif case == 'out is a hard link to the input':
        out = tmp_path / 'hard.mcap'
        os.link(bag, out)
    elif case == 'out is a symbolic link to the input':
        out = tmp_path / 'soft.mcap'
        out.symlink_to(bag)
    elif case == 'csv is the out':
        extra = ['--csv', out]
    else:
        out = tmp_path / 'both.png'
        extra = ['--plot', out]
    assert _replay(bag, out, *extra) == EXIT_USAGE
    error = capsys.readouterr().err
    assert 'is the same file as the' in error and 'Traceback' not in error, error
    assert bag.read_bytes() == before
    if case in ('csv is the out', 'plot is the out'):
        assert not out.exists()


@pytest.mark.parametrize('extra, message', [
    (['--plot', 'shapes'], 'its suffix must name an image format'),
    (['--plot', 'shapes.txt'], 'its suffix must name an image format'),
    (['--plot', 'p.png', '--plot-samples', '-1'], 'message indices >= 0, got [-1]'),
    (['--plot', 'p.png', '--plot-samples', '0', '999'], "[999] are beyond the input's 2"),
    (['--csv', ''], "--csv needs a file name, got ''"),
])
def test_bad_plot_and_output_options_exit_2_before_replaying(tmp_path, extra, message,
                                                             capsys, monkeypatch):
    """Checked before the first solve: no traceback after a long replay, no output made."""
    bag = _paper_bag(tmp_path)
    monkeypatch.chdir(tmp_path)

    def no_solving(*args, **kwargs):
        raise AssertionError('a wrench was processed before the options were checked')

    monkeypatch.setattr(replay_module.WrenchProcessor, 'process', no_solving)
    assert _replay(bag, tmp_path / 'out.mcap', *extra) == EXIT_USAGE
    error = capsys.readouterr().err
    assert message in error and 'Traceback' not in error, error
    assert not (tmp_path / 'out.mcap').exists()


def test_a_plot_sample_that_did_not_converge_is_an_error_not_a_traceback(tmp_path, capsys):
    """Known only after the replay: the outputs stand, the plot is not written, exit 2."""
    bag = tmp_path / 'hard.mcap'
    synth.write_wrenches(bag, synth.generate('hard'))
    nan_message = next(index for index, sample in enumerate(synth.generate('hard'))
                       if sample.force[0] != sample.force[0])
    assert _replay(bag, tmp_path / 'out.mcap', '--plot', tmp_path / 'p.png',
                   '--plot-samples', nan_message) == EXIT_USAGE
    captured = capsys.readouterr()
    assert 'error: no plot written' in captured.err and 'Traceback' not in captured.err
    assert f'wrote {tmp_path / "out.mcap"}' in captured.out
    assert not (tmp_path / 'p.png').exists()


@pytest.mark.parametrize('command', [['info', 'bags/random_walk.mcap'],
                                     ['replay', 'bags/paper_cases.mcap', '--no-compliance',
                                      '--progress', 'never']])
def test_closed_stdout_ends_quietly_with_141(tmp_path, command):
    """`| head -1`: no BrokenPipeError traceback; 141 as for a process SIGPIPE ended."""
    if command[0] == 'replay':
        command = command + ['--out', str(tmp_path / 'out.mcap')]
    process = subprocess.Popen([sys.executable, '-m', 'msg_tools', *command], cwd=ROOT,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()   # the reader goes away before anything is printed
    error = process.stderr.read().decode()
    assert process.wait(timeout=300) == EXIT_BROKEN_PIPE, error
    assert 'Traceback' not in error and 'BrokenPipe' not in error, error
    if command[0] == 'replay':   # the output was finished before the table was printed
        assert McapSource(tmp_path / 'out.mcap').report is not None
        assert sum(1 for _ in McapSource(tmp_path / 'out.mcap').messages()) > 0


def test_outputs_take_the_namespace_of_any_input_topic():
    """A remapped input keeps its namespace; the root namespace stays the root."""
    assert output_topic('/robot/wrench_filtered', 'end_disk_pose') == '/robot/end_disk_pose'
    assert output_topic('/robot/wrench', 'end_disk_pose') == '/robot/end_disk_pose'
    assert output_topic('/wrench', 'end_disk_pose') == '/end_disk_pose'
    assert output_topic('/a/b/ft', 'bending_angles') == '/a/b/bending_angles'
    assert output_topic('/robot/wrench', '/diagnostics') == '/diagnostics'


def test_two_wrench_topics_in_one_namespace_are_refused(tmp_path):
    """Their outputs would interleave on the same topics: ReplayError; --topic picks one."""
    bag = tmp_path / 'two.mcap'
    sample = synth.generate('paper')[0]
    with McapLog(bag, flush_every_messages=0, flush_every_s=0.0) as log:
        for topic in ('/wrench', '/wrench_filtered', '/left/wrench'):
            log.register(topic, replay_module.messages.WRENCH_TYPE, qos='sensor_data')
            log.write(topic, replay_module.messages.WRENCH_TYPE,
                      replay_module.messages.wrench_message(
                          sample.force, sample.moment, '',
                          replay_module.messages.stamp_from_ns(sample.stamp_ns)),
                      log_time_ns=sample.stamp_ns)
    with pytest.raises(ReplayError, match="'/wrench' and '/wrench_filtered' are in one "
                                          'namespace'.replace("'", '')):
        replay(bag, tmp_path / 'out.mcap', compliance=False)
    summary = replay(bag, tmp_path / 'out.mcap', topics=['/wrench_filtered', '/left/wrench'],
                     compliance=False)
    assert summary.solved == 2
    topics = {raw.topic for raw in McapSource(tmp_path / 'out.mcap').messages()}
    assert {'/end_disk_pose', '/left/end_disk_pose'} <= topics


def test_a_source_read_twice_says_so():
    """The second messages() is a ValueError, not an empty read counted as duplicates."""
    source = McapSource(ROOT / 'bags' / 'paper_cases.mcap')
    assert sum(1 for _ in source.messages()) == 2
    with pytest.raises(ValueError, match='has been read through this McapSource already'):
        list(source.messages())
    assert source.report.duplicates == 0


def test_a_damaged_file_with_nothing_readable_says_it_is_damaged(tmp_path):
    """Random bytes: the error names the damage, not only 'no channels'."""
    bag = tmp_path / 'noise.mcap'
    bag.write_bytes(bytes(range(256)) * 40)
    with pytest.raises(ReplayError, match='the file is damaged: .*InvalidMagic'):
        replay(bag, tmp_path / 'out.mcap')


def test_undecodable_rows_have_every_csv_column(tmp_path):
    """A CSV reader sees one width: the undecodable rows are padded like the others."""
    bag = tmp_path / 'odd.mcap'
    write_undecodable(bag, 3)
    replay(bag, tmp_path / 'out.mcap', compliance=False, csv_path=tmp_path / 'o.csv')
    with open(tmp_path / 'o.csv', newline='') as stream:
        rows = list(csv.reader(stream))
    assert len(rows) == 4 and {len(row) for row in rows} == {len(CSV_COLUMNS)}


@pytest.mark.parametrize('bad, message', [
    ({'rate_hz': 1e-9}, 'beyond what a ROS 2 stamp holds'),
    ({'rate_hz': 1e-300}, 'beyond what a ROS 2 stamp holds'),
    ({'profile': 'sinusoid', 'frequency_hz': 1e308}, 'gives non-finite wrenches'),
    ({'profile': 'random-walk', 'seed': -1}, 'seed must be an int >= 0, got -1'),
])
def test_synth_values_no_stamp_or_wrench_can_hold(bad, message):
    """A ValueError names the value: no struct.error, no NaN wrenches."""
    arguments = {'profile': 'ramp', 'count': 3, **bad}
    with pytest.raises(ValueError, match=message):
        synth.generate(**arguments)
