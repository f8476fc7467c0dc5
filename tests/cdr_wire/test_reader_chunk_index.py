"""
A chunk index that does not lead to its chunks, under a summary CRC that matches.

The CRC says the summary is as written, not that the writer wrote it right. The data
section, validated by its own CRC, holds every message: the reader reads it rather than
losing the chunk the index misplaces, and says why the index was not used. The metadata
records are read back either way.
"""

from pathlib import Path
import struct
import zlib

from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource
from mcap.reader import make_reader
import pytest

STAMP = {'sec': 1_700_000_000, 'nanosec': 0}
#: Messages written, two to a chunk.
COUNT = 8
#: Footer record: opcode, length, summary start, summary offset start, summary CRC.
FOOTER = struct.Struct('<BQQQI')
MAGIC_SIZE = 8


def _wrench(force: float) -> dict:
    return {'header': messages.header(STAMP, ''),
            'wrench': {'force': {'x': force, 'y': 0.0, 'z': 0.0},
                       'torque': {'x': 0.0, 'y': 0.0, 'z': 0.0}}}


def _write(path: Path) -> None:
    with McapLog(path, flush_every_messages=2, flush_every_s=0.0) as log:
        log.register(messages.WRENCH_TOPIC, messages.WRENCH_TYPE, qos='sensor_data')
        for index in range(COUNT):
            log.write(messages.WRENCH_TOPIC, messages.WRENCH_TYPE, _wrench(float(index)),
                      log_time_ns=1000 + index)
        log.add_metadata('how', {'made': 'by a test'})


def _misplace_chunk(path: Path, chunk: int, new_offset) -> None:
    """Point the index entry of ``chunk`` elsewhere and make the summary CRC match again."""
    data = bytearray(path.read_bytes())
    with open(path, 'rb') as stream:
        indexes = make_reader(stream).get_summary().chunk_indexes
    entry = indexes[chunk]
    old = struct.pack('<QQQ', entry.message_start_time, entry.message_end_time,
                      entry.chunk_start_offset)
    where = bytes(data).index(old)   # in the summary section: the chunk index record
    offset = new_offset([index.chunk_start_offset for index in indexes])
    data[where + 16:where + 24] = struct.pack('<Q', offset)
    footer_at = len(data) - MAGIC_SIZE - FOOTER.size
    opcode, length, summary_start, summary_offsets, _ = FOOTER.unpack_from(data, footer_at)
    crc = zlib.crc32(bytes(data[summary_start:len(data) - MAGIC_SIZE - 4]))
    FOOTER.pack_into(data, footer_at, opcode, length, summary_start, summary_offsets, crc)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize('new_offset', [
    lambda offsets: offsets[1] + 3,      # inside the chunk: no record starts there
    lambda offsets: offsets[0],          # another chunk: the index lists it twice
], ids=['into the chunk', 'onto another chunk'])
def test_a_misplaced_chunk_loses_nothing_under_a_valid_summary_crc(tmp_path, new_offset):
    """Every message is read from the validated data section; the report says why."""
    path = tmp_path / 'run.mcap'
    _write(path)
    _misplace_chunk(path, 1, new_offset)
    source = McapSource(path)
    assert len(list(source.messages())) == COUNT
    assert source.data_crc == 'valid'
    assert source.report.mode == 'salvaged' and 'chunk index' in source.report.reason
    assert not source.report.unread_bytes and source.report.lost_messages is None
    assert source.metadata()[-1] == ('how', {'made': 'by a test'})


def test_an_intact_file_is_read_through_its_index(tmp_path):
    """The check costs an intact file nothing: indexed, complete, metadata from the index."""
    path = tmp_path / 'run.mcap'
    _write(path)
    source = McapSource(path)
    assert len(list(source.messages())) == COUNT
    assert source.report.complete and source.report.mode == 'indexed'
    assert source.metadata()[-1] == ('how', {'made': 'by a test'})
