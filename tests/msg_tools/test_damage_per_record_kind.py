"""
A flipped byte in each kind of record: info and replay say what is damaged, read the rest.

The data section is the source of truth: a damaged summary (schemas, channels, statistics,
chunk index, offsets, footer) is not used and the data section is read through; damage
outside the chunks of the data section fails its CRC. Either way every intact message is
replayed and replay exits 1 (docs/reference/cli.md).
"""

from cdr_wire.reader import McapSource
from chunked import record_spans, write_chunked
from msg_tools.__main__ import main
from msg_tools.info import describe
from msg_tools.replay_summary import EXIT_DAMAGED_INPUT
import pytest

#: Where to flip in a record: bytes after its 9-byte prefix (opcode and length).
INSIDE = {'SCHEMA': 2 + 4 + 1,            # a letter of the schema name
          'CHANNEL': 2 + 2 + 4 + 1,       # a letter of the topic ('/wrench')
          'CHUNK_INDEX': 8 + 8,           # the chunk's offset
          'FOOTER': 8}                    # the summary offset start
SUMMARY_KINDS = ['SCHEMA', 'CHANNEL', 'STATISTICS', 'CHUNK_INDEX', 'METADATA_INDEX',
                 'SUMMARY_OFFSET', 'FOOTER']
DATA_KINDS = ['HEADER', 'METADATA', 'MESSAGE_INDEX', 'DATA_END']


def _flip(path, kind):
    """Flip one byte inside the first record of ``kind`` (after the data section's end)."""
    spans = record_spans(path)
    data_end = next(offset for name, offset, _ in spans if name == 'DATA_END')
    in_summary = kind in SUMMARY_KINDS
    offset, length = next((offset, length) for name, offset, length in spans
                          if name == kind and (offset > data_end) == in_summary)
    where = offset + 9 + INSIDE.get(kind, (length - 9) // 2)
    data = bytearray(path.read_bytes())
    data[where] ^= 0x01
    path.write_bytes(bytes(data))


def _replay(path, tmp_path, capsys):
    """Replay ``path`` in process; return (exit code, stdout, stderr)."""
    code = main(['replay', str(path), '--out', str(tmp_path / 'out.mcap'),
                 '--no-compliance', '--progress', 'never'])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _info_and_replay(tmp_path, capsys, kind, damage):
    """
    Damage a record of ``kind``; check info and replay name ``damage`` and keep all 40.

    Returns info's text for the checks particular to the kind.
    """
    path = tmp_path / 'a.mcap'
    write_chunked(path)
    _flip(path, kind)
    text = describe(path)
    assert 'DAMAGED' in text and damage in text, text
    assert '40 messages read' in text and 'messages:  40' in text, text
    code, out, err = _replay(path, tmp_path, capsys)
    assert code == EXIT_DAMAGED_INPUT, err
    assert 'solved (converged)              40' in out
    assert damage.lower() in err.lower() and 'Traceback' not in err
    return text


@pytest.mark.parametrize('kind', SUMMARY_KINDS)
def test_a_damaged_summary_is_not_used(tmp_path, capsys, kind):
    """Summary CRC mismatch: the data section is read through, all 40 messages replayed."""
    text = _info_and_replay(tmp_path, capsys, kind, 'summary CRC mismatch')
    assert 'data-section CRC valid' in text and 'messages lost' not in text, text
    assert '/wrench ' in text and 'geometry_msgs/msg/WrenchStamped' in text, text


@pytest.mark.parametrize('kind', DATA_KINDS)
def test_damage_outside_the_chunks_fails_the_data_crc(tmp_path, capsys, kind):
    """Every message read through the index; the data-section CRC mismatch makes exit 1."""
    text = _info_and_replay(tmp_path, capsys, kind, 'data-section CRC MISMATCH')
    assert 'indexed' in text, text


@pytest.mark.parametrize('end', ['leading', 'trailing'])
def test_a_damaged_magic_is_read_past(tmp_path, capsys, end):
    """The magic at either end: reported, the records in between read all the same."""
    path = tmp_path / 'a.mcap'
    stamps = write_chunked(path)
    data = bytearray(path.read_bytes())
    data[3 if end == 'leading' else len(data) - 3] ^= 0x01
    path.write_bytes(bytes(data))
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps
    assert source.report.mode == 'salvaged' and 'messages lost' not in source.report.describe()
    assert 'magic' in source.report.describe()
    code, out, err = _replay(path, tmp_path, capsys)
    assert code == EXIT_DAMAGED_INPUT, err
    assert 'solved (converged)              40' in out


def test_a_chunk_index_without_summary_crc_is_checked_against_the_chunks(tmp_path):
    """No summary CRC stored: a chunk offset that misses its chunk makes the index unused."""
    path = tmp_path / 'a.mcap'
    stamps = write_chunked(path)
    _, footer, _ = record_spans(path)[-1]
    data = bytearray(path.read_bytes())
    data[footer + 9 + 16:footer + 9 + 20] = bytes(4)   # the summary CRC: none stored
    path.write_bytes(bytes(data))
    assert 'complete: every chunk read' in describe(path)
    _flip(path, 'CHUNK_INDEX')
    source = McapSource(path)
    assert [m.log_time_ns for m in source.messages()] == stamps
    assert 'the chunk index points at byte' in source.report.reason
    assert source.data_crc == 'valid'


def test_the_overview_of_a_damaged_file_is_read_once(tmp_path):
    """A damaged summary: the overview reads the messages once and answers again from that."""
    path = tmp_path / 'a.mcap'
    write_chunked(path)
    _flip(path, 'FOOTER')
    source = McapSource(path)
    first = source.channel_overview()
    assert sum(first[2].values()) == 40
    assert source.channel_overview() == first


@pytest.mark.parametrize('command', ['info', 'replay'])
def test_a_device_is_not_read_as_an_mcap(tmp_path, capsys, command):
    """/dev/zero is not a regular file: one line and exit 2, nothing read."""
    extra = ['--out', str(tmp_path / 'out.mcap')] if command == 'replay' else []
    assert main([command, '/dev/zero'] + extra) == 2
    error = capsys.readouterr().err
    assert error == 'error: /dev/zero is not a regular file, so not an MCAP file\n'
