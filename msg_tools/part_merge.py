"""
Merge the parts of a windowed replay into one output: records copied as stored, in order.

A part is an MCAP that one window's replay wrote (``msg_tools.replay_windows``), intact and
indexed. Its records are copied into the output log as CDR bytes, never decoded: each chunk
is decompressed once and its message records are cut out with ``struct``, so the copy costs
a few microseconds per record instead of a read and a write through the MCAP libraries'
record objects. The one change a record needs is to the counters of the aggregated
/diagnostics arrays (``COUNTERS`` of their first status, the wrenches'), which a window
counts from its own start: they are continued from the windows merged before, rewritten in
place in the CDR bytes (``continue_counters``). Every message's own status (solve_status,
estimate_status) is copied as it is. Each window closes with arrays of its final counts
(``replay_diagnostics``): the merge takes the counts from them but writes only the last
window's (``finish``), so that the output holds the arrays a one-process replay writes.
"""

from pathlib import Path
import shutil
import struct
from typing import Dict, IO, Iterator, List, Optional, Tuple

from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
from mcap.reader import SeekingReader
from mcap.records import Chunk
from mcap.stream_reader import get_chunk_data_stream, StreamReader
import zstandard

#: The /diagnostics values that count messages since the start (WrenchProcessor.counts).
COUNTERS = ('received', 'rejected', 'solved', 'flagged', 'not_converged', 'skipped')

#: MCAP opcode of a Message record, and the fixed fields that open one.
MESSAGE_OPCODE = 0x05
RECORD_HEAD = struct.Struct('<BQ')
MESSAGE_HEAD = struct.Struct('<HIQQ')
UINT32 = struct.Struct('<I')

#: Bytes of the CDR encapsulation header; CDR alignment counts from its end.
CDR_HEADER = 4

#: One part message: (topic, schema name, CDR bytes, log time, publish time).
PartMessage = Tuple[str, str, bytes, int, int]


def _chunk_data(chunk: Chunk) -> bytes:
    """Return the uncompressed records of ``chunk``."""
    if chunk.compression == 'zstd':
        return zstandard.ZstdDecompressor().decompress(
            chunk.data, max_output_size=chunk.uncompressed_size)
    if not chunk.compression:
        return bytes(chunk.data)
    stream, length = get_chunk_data_stream(chunk)
    return stream.read(length)


def part_messages(path: Path) -> Iterator[PartMessage]:
    """Yield the messages of the part ``path`` in file order, their bytes as stored."""
    with open(path, 'rb') as stream:
        summary = SeekingReader(stream).get_summary()
        if summary is None:
            raise ValueError(f'{path} has no summary: not a finished part')
        names = {channel.id: (channel.topic, summary.schemas[channel.schema_id].name
                              if channel.schema_id in summary.schemas else '')
                 for channel in summary.channels.values()}
        for index in sorted(summary.chunk_indexes, key=lambda item: item.chunk_start_offset):
            stream.seek(index.chunk_start_offset)
            chunk = next(StreamReader(stream, skip_magic=True, emit_chunks=True).records)
            if not isinstance(chunk, Chunk):
                raise ValueError(f'{path}: no chunk at byte {index.chunk_start_offset}')
            yield from _chunk_messages(_chunk_data(chunk), names)


def _chunk_messages(data: bytes, names: Dict[int, Tuple[str, str]]
                    ) -> Iterator[PartMessage]:
    """Yield the message records of one chunk's uncompressed ``data``."""
    view = memoryview(data)
    position, end = 0, len(data)
    head, fields = RECORD_HEAD.size, MESSAGE_HEAD.size
    while position < end:
        opcode, length = RECORD_HEAD.unpack_from(data, position)
        start = position + head
        position = start + length
        if opcode != MESSAGE_OPCODE:
            continue   # schemas and channels: the summary named them already
        channel_id, _, log_time, publish_time = MESSAGE_HEAD.unpack_from(data, start)
        topic, schema_name = names[channel_id]
        yield topic, schema_name, bytes(view[start + fields:position]), log_time, publish_time


def _string_end(data: bytes, position: int) -> int:
    """Return where the CDR string whose length field is at ``position`` ends."""
    return position + 4 + UINT32.unpack_from(data, position)[0]


def _aligned(position: int) -> int:
    """Return ``position`` rounded up to the CDR alignment of a uint32."""
    return position + (-(position - CDR_HEADER)) % 4


def continue_counters(data: bytes, offsets: Dict[str, int], counts: Dict[str, int]) -> bytes:
    """
    Return the DiagnosticArray ``data`` with its counters raised by ``offsets``.

    ``counts`` receives each counter's continued value. The counters are string values of
    the first status's key-value pairs; a longer or shorter number moves the bytes after
    it by whole multiples of 4 (padding redone), which keeps the alignment of everything
    that follows (strings, sequence lengths and bytes, none aligned beyond 4).
    """
    position = _aligned(_string_end(data, CDR_HEADER + 8))   # stamp, then frame_id
    if not UINT32.unpack_from(data, position)[0]:
        return data   # no status
    position = _aligned(position + 4) + 1   # the status count, then its level byte
    for _ in range(3):   # name, message, hardware_id
        position = _string_end(data, _aligned(position))
    position = _aligned(position)
    pairs = UINT32.unpack_from(data, position)[0]
    position += 4
    pieces: List[bytes] = []
    copied = 0
    for _ in range(pairs):
        key_end = _string_end(data, _aligned(position))
        key = data[_aligned(position) + 4:key_end - 1].decode()
        value_at = _aligned(key_end)
        position = _string_end(data, value_at)
        if key not in COUNTERS:
            continue
        count = int(data[value_at + 4:position - 1]) + offsets.get(key, 0)
        counts[key] = count
        if not offsets.get(key):
            continue
        text = str(count).encode() + b'\0'
        pieces += [data[copied:value_at], UINT32.pack(len(text)), text]
        copied = position
        if position < len(data):   # more follows: pad the new string as the old one was
            pieces.append(b'\0' * ((-(value_at + 4 + len(text) - CDR_HEADER)) % 4))
            copied = _aligned(position)
    if not pieces:
        return data
    pieces.append(data[copied:])
    return b''.join(pieces)


#: One stored message record: topic, schema name, CDR bytes, log time, publish time.
Record = Tuple[str, str, bytes, int, int]


class PartMerger:
    """Copies window parts into the output in order, continuing the diagnostics counters."""

    def __init__(self, log: McapLog, table: Optional[IO[str]]) -> None:
        """Merge into ``log`` and (rows without header) into the open CSV ``table``."""
        self.log, self.table = log, table
        #: Counters at the end of the windows merged so far, by the array's place among
        #: those written together (one per namespace, always in the same order).
        self.counts: Dict[int, Dict[str, int]] = {}
        #: The last arrays of the last part merged: its closing ones, written by ``finish``.
        self._held: List[Record] = []

    def merge(self, part: Path, csv_part: Optional[Path]) -> None:
        """Append the records of ``part`` (and the rows of ``csv_part``)."""
        offsets = {place: dict(counts) for place, counts in self.counts.items()}
        write = self.log.write_serialized
        self._held = []   # the part before closed where this one goes on
        place, grouped = 0, False
        for name, schema_name, data, log_time, publish_time in part_messages(part):
            if name != messages.DIAGNOSTICS_TOPIC:
                write(name, schema_name, data, log_time, publish_time)
                grouped = False
                continue
            if grouped:
                place += 1   # the next namespace's array, written right after the last
            else:
                self.finish()
                place, grouped = 0, True
            data = continue_counters(data, offsets.get(place, {}),
                                     self.counts.setdefault(place, {}))
            self._held.append((name, schema_name, data, log_time, publish_time))
        if csv_part is not None and self.table is not None:
            with open(csv_part, newline='') as rows:
                rows.readline()
                shutil.copyfileobj(rows, self.table)

    def finish(self) -> None:
        """Write the arrays held back: the closing ones once the last part is merged."""
        for record in self._held:
            self.log.write_serialized(*record)
        self._held = []
