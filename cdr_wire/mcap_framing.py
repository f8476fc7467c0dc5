"""
Whether an MCAP file's summary section can be trusted: closing magic, footer, summary CRC.

The summary (schemas, channels, statistics, chunk index) repeats what the data section
holds. A damaged summary must not stand in for the data: a flipped byte in a channel's
topic would hide its messages, one in a chunk offset would lose a chunk. The footer's
summary CRC covers the whole summary section and the footer itself, so a file whose CRC
matches can be read through its index; otherwise the data section is read through
(``cdr_wire.reader``). A CRC only says the summary is as written, not that the writer wrote
it right: the chunk index is also checked against the chunk records it points at
(``chunk_index_problem``), so a wrong offset sends the read to the data section (when that
section's own CRC holds) rather than losing an intact chunk.
"""

import io
import struct
from typing import BinaryIO, Iterable, Tuple
import zlib

from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE
from mcap.records import ChunkIndex, Footer
from mcap.stream_reader import MAGIC_SIZE, StreamReader
from mcap.writer import MCAP0_MAGIC

#: Bytes hashed at a time when checking the summary CRC (memory stays bounded).
CRC_BLOCK = 1 << 20
#: Size of the summary CRC field at the end of the footer record.
CRC_SIZE = 4
#: A record's opcode (1 byte) and length (8 bytes).
RECORD_PREFIX = 9
#: What opens a chunk record after its prefix: message start and end time, uncompressed size.
CHUNK_HEAD = struct.Struct('<QQQ')


def summary_problem(stream: BinaryIO, size: int) -> Tuple[str, bool]:
    """
    Return (why the summary cannot be trusted or '', whether a summary CRC is stored).

    Checks the closing magic, that a footer precedes it, and the summary CRC. Raises the
    mcap reader's errors for a footer that does not parse.
    """
    if size < 2 * MAGIC_SIZE + FOOTER_SIZE:
        return 'the file is too short to hold a footer', False
    stream.seek(size - MAGIC_SIZE)
    if stream.read(MAGIC_SIZE) != MCAP0_MAGIC:
        return 'the file does not end with the MCAP magic', False
    stream.seek(size - MAGIC_SIZE - FOOTER_SIZE)
    footer = next(StreamReader(stream, skip_magic=True, record_size_limit=FOOTER_SIZE).records)
    if not isinstance(footer, Footer):
        return f'a {type(footer).__name__} record where the footer belongs', False
    if footer.summary_crc == 0:
        return '', False
    end = size - MAGIC_SIZE - CRC_SIZE
    if not 0 < footer.summary_start < end:
        return f'the footer points at byte {footer.summary_start}, outside the file', True
    stream.seek(footer.summary_start)
    crc, left = 0, end - footer.summary_start
    while left:
        block = stream.read(min(left, CRC_BLOCK))
        if not block:
            return 'the file ends inside its summary', True
        crc = zlib.crc32(block, crc)
        left -= len(block)
    if crc != footer.summary_crc:
        return (f'summary CRC mismatch (stored {footer.summary_crc:#010x}, computed '
                f'{crc:#010x}): a summary record or the footer is damaged'), True
    return '', True


def chunk_index_problem(stream: BinaryIO, indexes: Iterable[ChunkIndex]) -> str:
    """
    Return why a chunk index entry does not lead to its chunk record, or ''.

    The record at each entry's offset must be a chunk of the entry's length, time range and
    uncompressed size, and no two entries may share an offset (one would hide a chunk).
    """
    seen = set()
    for index in indexes:
        where = (f'the chunk index points at byte {index.chunk_start_offset}, where no '
                 f'chunk of {index.chunk_length} bytes')
        if index.chunk_start_offset in seen:
            return f'the chunk index lists byte {index.chunk_start_offset} twice'
        seen.add(index.chunk_start_offset)
        stream.seek(index.chunk_start_offset, io.SEEK_SET)
        prefix = stream.read(RECORD_PREFIX + CHUNK_HEAD.size)
        if (len(prefix) < RECORD_PREFIX + CHUNK_HEAD.size or prefix[0] != Opcode.CHUNK
                or RECORD_PREFIX + int.from_bytes(prefix[1:RECORD_PREFIX], 'little')
                != index.chunk_length):
            return where + ' starts'
        start, end, size = CHUNK_HEAD.unpack_from(prefix, RECORD_PREFIX)
        if (start, end, size) != (index.message_start_time, index.message_end_time,
                                  index.uncompressed_size):
            return (where + f' with messages logged {index.message_start_time}..'
                    f'{index.message_end_time} ns starts')
    return ''
