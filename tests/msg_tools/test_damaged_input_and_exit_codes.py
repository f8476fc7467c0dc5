"""info tells the truth, duplicates are skipped, replay exit codes mean something."""

import errno
from pathlib import Path
import subprocess
import sys

from cdr_translator.interface import messages
from cdr_wire.mcap_log import _FileSink
from cdr_wire.reader import McapSource
from chunked import chunk_offsets, write_chunked, write_undecodable
from mcap.writer import Writer
from msg_tools import __main__ as command_line, replay as replay_module, synth
from msg_tools.__main__ import main
from msg_tools.info import describe
from msg_tools.replay import replay
from msg_tools.replay_summary import (EXIT_DAMAGED_INPUT, EXIT_NOTHING_SOLVED, EXIT_OK,
                                      EXIT_USAGE)
import pytest

ROOT = Path(__file__).resolve().parents[2]


_chunked, _chunks = write_chunked, chunk_offsets


def _replay_cli(*args):
    """Run ``python -m msg_tools replay`` in a child; return the CompletedProcess."""
    return subprocess.run([sys.executable, '-m', 'msg_tools', 'replay', *map(str, args),
                           '--no-compliance', '--progress', 'never'],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


# ------------------------------------------------------------------------ info
def test_info_checks_crcs_of_an_intact_file(tmp_path, capsys):
    """Intact: every chunk read, data-section CRC valid; --no-crc says it trusted the summary."""
    _chunked(tmp_path / 'a.mcap')
    text = describe(tmp_path / 'a.mcap')
    assert 'complete: every chunk read, CRCs valid (data-section CRC valid), 40' in text
    assert main(['info', '--no-crc', str(tmp_path / 'a.mcap')]) == 0
    out = capsys.readouterr().out
    assert 'counts from the summary, CRCs not checked' in out and 'messages:  40' in out


def test_flipped_byte_in_a_chunk(tmp_path):
    """The summary is intact but a chunk is not: info says DAMAGED, 10 lost; replay exits 1."""
    path = tmp_path / 'a.mcap'
    _chunked(path)
    (_, _), (second, length), _, _ = _chunks(path)
    data = bytearray(path.read_bytes())
    data[second + length - 30] ^= 0x01
    path.write_bytes(bytes(data))
    text = describe(path)
    assert 'DAMAGED' in text and '10 messages lost' in text and 'messages:  30' in text
    assert 'counts from the summary' in describe(path, verify=False)   # the opt-out trusts
    process = _replay_cli(path, '--out', tmp_path / 'out.mcap')
    assert process.returncode == EXIT_DAMAGED_INPUT, process.stderr
    assert 'solved (converged)              30' in process.stdout
    assert '10 messages lost' in process.stderr


def test_flipped_byte_outside_the_chunks_fails_the_data_crc(tmp_path):
    """A flipped byte in a message index (not in any chunk): the data-section CRC finds it."""
    path = tmp_path / 'a.mcap'
    _chunked(path)
    (first, length), (second, _), _, _ = _chunks(path)
    data = bytearray(path.read_bytes())
    data[first + length + 20] ^= 0x01      # a time inside the message index of chunk 1
    assert first + length + 20 < second
    path.write_bytes(bytes(data))
    text = describe(path)
    assert 'DAMAGED' in text and 'data-section CRC MISMATCH' in text


def test_zeroed_chunk(tmp_path):
    """A chunk overwritten with zeros: its messages are lost and said to be."""
    path = tmp_path / 'a.mcap'
    stamps = _chunked(path)
    _, _, (third, length), _ = _chunks(path)
    data = bytearray(path.read_bytes())
    data[third:third + length] = bytes(length)
    path.write_bytes(bytes(data))
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps[:20] + stamps[30:]
    text = describe(path)
    assert 'DAMAGED' in text and '10 messages lost' in text
    process = _replay_cli(path, '--out', tmp_path / 'out.mcap')
    assert process.returncode == EXIT_DAMAGED_INPUT, process.stderr


def test_duplicated_chunk_is_counted_and_skipped(tmp_path):
    """A chunk written twice: its copy is skipped, counted, and the summary says so."""
    path = tmp_path / 'a.mcap'
    stamps = _chunked(path)
    (first, _), (second, _), _, _ = _chunks(path)
    data = path.read_bytes()
    copied = data[:second] + data[first:second] + data[second:]   # chunk 1 and its index
    path.write_bytes(copied)
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps
    assert source.report.duplicates == 10 and not source.report.complete
    assert '10 duplicate messages skipped' in describe(path)
    summary = replay(path, tmp_path / 'out.mcap', compliance=False)
    assert (summary.messages, summary.solved, summary.input_report.duplicates) == (40, 40, 10)
    assert 'duplicates skipped              10' in summary.table()
    assert summary.exit_code() == EXIT_DAMAGED_INPUT


def test_duplicate_messages_in_different_chunks(tmp_path):
    """Single messages repeated in a later chunk (same channel, sequence, time, bytes)."""
    path = tmp_path / 'a.mcap'
    with open(path, 'wb') as stream:
        writer = Writer(stream, chunk_size=1)
        writer.start(profile='ros2')
        schema = writer.register_schema(messages.WRENCH_TYPE, 'ros2msg', b'int32 a')
        channel = writer.register_channel('/wrench', 'cdr', schema)
        for k in [0, 1, 2, 1, 3, 2]:
            writer.add_message(channel, log_time=k, publish_time=k, sequence=k,
                               data=bytes([0, 1, 0, 0, k, 0, 0, 0]))
        writer.add_message(channel, log_time=1, publish_time=1, sequence=1,
                           data=bytes([0, 1, 0, 0, 9, 0, 0, 0]))   # other bytes: kept
        writer.finish()
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == [0, 1, 2, 3, 1]
    assert source.report.duplicates == 2


# ------------------------------------------------------------------------ exit codes
def test_all_good_exits_0(tmp_path):
    """An intact input with converged solves."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    assert _replay_cli(bag, '--out', tmp_path / 'o.mcap').returncode == EXIT_OK


def test_all_undecodable_exits_3(tmp_path):
    """Every message undecodable: exit 3, one line saying so, warnings capped."""
    bag = tmp_path / 'odd.mcap'
    write_undecodable(bag, 213)
    process = _replay_cli(bag, '--out', tmp_path / 'o.mcap')
    assert process.returncode == EXIT_NOTHING_SOLVED, process.stderr
    assert 'nothing could be solved: 213 messages read, 213 undecodable' in process.stderr
    assert '193 more such warnings not shown' in process.stderr
    assert 'Traceback' not in process.stderr


def test_all_rejected_exits_3(tmp_path):
    """Only NaN wrenches: nothing solved."""
    bag = tmp_path / 'nan.mcap'
    synth.write_wrenches(bag, [synth.Sample(k, [float('nan'), 0, 0], [0, 0, 0], '')
                               for k in range(3)])
    summary = replay(bag, tmp_path / 'o.mcap', compliance=False)
    assert summary.rejected == 3 and summary.exit_code() == EXIT_NOTHING_SOLVED


@pytest.mark.parametrize('where', ['out under a file', 'csv under a file', 'out is a folder',
                                   'csv in /proc', 'plot under a file'])
def test_unwritable_output_exits_2_before_reading(tmp_path, where, monkeypatch, capsys):
    """An output that cannot be written: exit 2 and a clear message, the input never read."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    (tmp_path / 'file').write_text('x')
    out, extra = tmp_path / 'o.mcap', []
    if where == 'out under a file':
        out = tmp_path / 'file' / 'o.mcap'
    elif where == 'csv under a file':
        extra = ['--csv', str(tmp_path / 'file' / 'o.csv')]
    elif where == 'out is a folder':
        out = tmp_path
    elif where == 'csv in /proc':
        extra = ['--csv', '/proc/o.csv']
    else:
        extra = ['--plot', str(tmp_path / 'file' / 'p.png')]

    class Unread:

        def __init__(self, *args, **kwargs):
            raise AssertionError('the input was read before the outputs were checked')

    monkeypatch.setattr(replay_module, 'McapSource', Unread)
    code = main(['replay', str(bag), '--out', str(out), '--progress', 'never'] + extra)
    error = capsys.readouterr().err
    assert code == EXIT_USAGE and error.startswith('error: cannot write the'), error
    assert 'Traceback' not in error


def test_unwritable_output_in_a_child_process(tmp_path):
    """The same from the command line: no traceback, exit 2."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    (tmp_path / 'file').write_text('x')
    process = _replay_cli(bag, '--out', tmp_path / 'file' / 'o.mcap')
    assert process.returncode == EXIT_USAGE
    assert 'error: cannot write the output MCAP' in process.stderr
    assert 'Traceback' not in process.stderr


def test_write_error_during_replay_exits_2(tmp_path, monkeypatch, capsys):
    """The disk fills during a replay: it stops, says how many records were lost, exit 2."""
    bag = tmp_path / 'walk.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=30))
    original, calls = _FileSink.os_write, []

    def failing(fd, data):
        calls.append(1)
        if len(calls) > 6:
            raise OSError(errno.ENOSPC, 'No space left on device')
        return original(fd, data)

    monkeypatch.setattr(_FileSink, 'os_write', staticmethod(failing))
    monkeypatch.setattr(command_line, 'replay', _small_flushes(replay_module.replay))
    code = main(['replay', str(bag), '--out', str(tmp_path / 'o.mcap'), '--progress', 'never',
                 '--no-compliance'])
    captured = capsys.readouterr()
    assert code == EXIT_USAGE
    assert 'No space left on device' in captured.err and 'lost' in captured.err
    assert 'Traceback' not in captured.err


def _small_flushes(function):
    """Wrap replay() so that its output is flushed every 4 records."""
    def wrapped(*args, **kwargs):
        return function(*args, flush_every_messages=4, **kwargs)
    return wrapped
