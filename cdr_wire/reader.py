"""
Read every message of an MCAP file that can still be read, and say what could not.

A finished file whose summary can be trusted (its CRC matches: ``cdr_wire.mcap_framing``;
a chunk index that misses its chunks while the data section's own CRC holds is not trusted)
is read through its summary (chunk index and statistics): each chunk is located by its
index, checked against its CRC and decompressed on its own, so a damaged chunk loses only
its own messages (counted from the statistics). A file without a trustworthy summary (the
writer was killed, the file was cut, a summary record or the footer is damaged) is salvaged
by a streaming read of the data section from the start, which is the source of truth: every
complete chunk and message up to the first unreadable record is kept, a damaged chunk is
skipped as long as its record length can be trusted, and the summary's copies of schemas
and channels are not used. Messages come
in file order (the order the recorder received them). ``ReadReport`` tells how the file
was read and what was lost.

Duplicates (the same channel, sequence, log time and bytes as a message already read, e.g.
from a chunk written twice) are skipped and counted: a chunk identical to an earlier one
anywhere in the file, and single messages within a window of the last ``DUPLICATE_WINDOW``
messages, so memory stays bounded however long the file. ``check_data_crc`` (default) also
checks the data-section CRC of the DataEnd record (an extra streaming pass for an indexed
read).
"""

from collections import deque
from dataclasses import dataclass, field
import io
import itertools
from pathlib import Path
import stat
import struct
from typing import Callable, Deque, Dict, Iterable, Iterator, List, Optional, Set, Tuple, Union
import zlib

from cdr_wire.errors import error_text
from cdr_wire.mcap_framing import chunk_index_problem, summary_problem
from mcap.data_stream import ReadDataStream
from mcap.exceptions import InvalidMagic, McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import (Channel, Chunk, DataEnd, Footer, McapRecord, Message, Metadata,
                          Schema)
from mcap.stream_reader import (CRCValidationError, get_chunk_data_stream, MAGIC_SIZE,
                                read_magic, StreamReader)
from mcap_ros2.decoder import DecoderFactory
import zstandard

#: Exceptions that mean "this part of the file cannot be read": struct.error for cut
#: records, ZstdError (lz4: RuntimeError) for damaged compressed data, CRC mismatches
#: (ValueError) and McapError for the rest.
READ_ERRORS = (McapError, struct.error, zstandard.ZstdError, ValueError, RuntimeError,
               EOFError, OSError, MemoryError)

#: Messages remembered (as small fingerprints) to recognize a duplicate outside a copied
#: chunk; about 100 bytes each.
DUPLICATE_WINDOW = 16384


def chunk_records(chunk: Chunk) -> Iterator[McapRecord]:
    """
    Yield the schema, channel and message records of ``chunk`` one at a time.

    mcap's ``breakup_chunk`` without its list: the chunk is decompressed and its CRC
    checked at the first ``next()`` (errors there mean the whole chunk is unreadable), then
    records are parsed as they are consumed, so memory holds one chunk's bytes, not one
    object per message of it.
    """
    stream, length = get_chunk_data_stream(chunk, validate_crc=True)
    readers: Dict[int, Callable[[int], McapRecord]] = {
        Opcode.CHANNEL: lambda size: Channel.read(stream),
        Opcode.MESSAGE: lambda size: Message.read(stream, size),
        Opcode.SCHEMA: lambda size: Schema.read(stream)}
    while stream.count < length:
        opcode = stream.read1()
        size = stream.read8()
        read = readers.get(opcode)
        if read is None:
            stream.read(size)
        else:
            yield read(size)


class Duplicates:
    """
    Recognize messages read before: whole chunks anywhere, single messages in a window.

    A message is a duplicate when its channel, sequence, log time and bytes equal those of
    an earlier one. Memory: one fingerprint per distinct chunk plus ``window`` messages.
    """

    def __init__(self, window: Optional[int] = None) -> None:
        """Start with nothing seen; ``window`` defaults to ``DUPLICATE_WINDOW``."""
        self.window = DUPLICATE_WINDOW if window is None else window
        self._chunks: Set[Tuple[int, int, int, int, int]] = set()
        self._recent: Set[Tuple[int, int, int, int, int]] = set()
        self._order: Deque[Tuple[int, int, int, int, int]] = deque()

    def chunk_seen(self, chunk: Chunk) -> bool:
        """Tell whether an identical chunk was read before (and remember this one)."""
        key = (len(chunk.data), zlib.crc32(chunk.data), chunk.uncompressed_crc,
               chunk.message_start_time, chunk.message_end_time)
        if key in self._chunks:
            return True
        self._chunks.add(key)
        return False

    def message_seen(self, message: Message) -> bool:
        """Tell whether the same message is in the window (and remember this one)."""
        key = (message.channel_id, message.sequence, message.log_time,
               len(message.data), zlib.crc32(message.data))
        if key in self._recent:
            return True
        self._recent.add(key)
        self._order.append(key)
        if len(self._order) > self.window:
            self._recent.discard(self._order.popleft())
        return False


@dataclass(frozen=True)
class RawMessage:
    """One message as stored: its channel, schema, times and CDR bytes."""

    channel: Channel
    schema: Optional[Schema]
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes

    @property
    def topic(self) -> str:
        """Return the channel topic."""
        return self.channel.topic

    @property
    def schema_name(self) -> str:
        """Return the schema name ('package/msg/Name'), '' when the channel has none."""
        return self.schema.name if self.schema is not None else ''


@dataclass
class ReadReport:
    """How a file was read (``mode`` 'indexed' or 'salvaged') and what was lost."""

    path: str
    size_bytes: int
    mode: str = 'indexed'
    reason: str = ''
    messages_read: int = 0
    messages_expected: Optional[int] = None
    unread_bytes: int = 0
    duplicates: int = 0
    problems: List[str] = field(default_factory=list)

    @property
    def lost_messages(self) -> Optional[int]:
        """Messages known to be lost (None when the file no longer says how many it had)."""
        if self.messages_expected is None:
            return None
        return max(self.messages_expected - self.messages_read, 0)

    @property
    def complete(self) -> bool:
        """Tell whether the file was read through its index, intact, nothing lost or doubled."""
        return self.mode == 'indexed' and not self.problems and not self.duplicates

    def describe(self) -> str:
        """Return a one-paragraph, human-readable account of the read."""
        if self.complete:
            return f'{self.path}: complete, {self.messages_read} messages'
        head = f'{self.path}: {self.mode}'
        if self.reason:
            head += f' ({self.reason})'
        lost = self.lost_messages
        parts = [f'{self.messages_read} messages read',
                 f'{lost} messages lost' if lost is not None else 'an unknown number of '
                 'messages lost after the last complete chunk' if self.unread_bytes else '']
        if self.unread_bytes:
            parts.append(f'{self.unread_bytes} of {self.size_bytes} bytes unreadable')
        if self.duplicates:
            parts.append(f'{self.duplicates} duplicate messages skipped (same channel, '
                         'sequence, log time and bytes as one read before)')
        return '; '.join([head] + [part for part in parts if part] + self.problems)


class McapSource:
    """
    The messages of one MCAP file, read by index or salvaged by streaming.

    ``messages()`` may be iterated once (a second call is a ValueError, not an empty
    read); ``report`` is complete when it ends. ``channel_overview`` reads the messages too
    when the summary cannot serve it (a damaged file, or ``verify``), and then fills
    ``report``. ``topics`` (optional) keeps only those channels; ``check_data_crc`` also
    checks the data-section CRC.
    """

    def __init__(self, path: Union[str, Path], topics: Optional[List[str]] = None,
                 check_data_crc: bool = True) -> None:
        """Open ``path`` lazily; ValueError if it does not exist or is not a regular file."""
        self.path = Path(path)
        if not self.path.exists():
            raise ValueError(f'no such MCAP file: {self.path}')
        if not stat.S_ISREG(self.path.stat().st_mode):
            raise ValueError(f'{self.path} is not a regular file, so not an MCAP file')
        self.topics = set(topics) if topics is not None else None
        self.check_data_crc = check_data_crc
        self.report = ReadReport(str(self.path), self.path.stat().st_size)
        self.schemas: Dict[int, Schema] = {}
        self.channels: Dict[int, Channel] = {}
        self.duplicates = Duplicates()
        #: After ``messages()`` with ``check_data_crc``: 'valid', 'mismatch', 'absent' (the
        #: writer stored none) or 'unchecked' (the data section could not be read through).
        self.data_crc = 'unchecked'
        self._read = False
        self._overview_read: Optional[Tuple[Dict[int, Channel], Dict[int, Schema],
                                            Dict[int, int], Optional[Tuple[int, int]]]] = None

    # public -------------------------------------------------------------------------------
    def messages(self) -> Iterator[RawMessage]:
        """
        Yield every readable message in file order; fill ``report`` on the way.

        ValueError when this source has been read before: its duplicate filter and report
        already hold that read, so a second one would yield nothing and count duplicates.
        """
        if self._read:
            raise ValueError(f'{self.path} has been read through this McapSource already '
                             '(channel_overview reads a damaged file): make a new McapSource')
        self._read = True
        with open(self.path, 'rb') as stream:
            summary, reason = self._summary(stream)
            if summary is not None:
                yield from self._indexed(stream, summary)
                if self.check_data_crc:
                    stream.seek(0)
                    self._check_data_section(stream)
            else:
                self.report.mode, self.report.reason = 'salvaged', reason
                stream.seek(0)
                yield from self._streamed(stream)

    def channel_overview(self, verify: bool = False
                         ) -> Tuple[Dict[int, Channel], Dict[int, Schema],
                                    Optional[Dict[int, int]], Optional[Tuple[int, int]]]:
        """
        Return channels, schemas, per-channel counts and the (start, end) log time in ns.

        From the summary when it is readable and ``verify`` is False; otherwise by reading
        every message (CRCs checked: the counts and time range of what can be read).
        """
        with open(self.path, 'rb') as stream:
            summary, _ = self._summary(stream)
        if not verify and summary is not None and summary.statistics is not None:
            statistics = summary.statistics
            span = ((statistics.message_start_time, statistics.message_end_time)
                    if statistics.message_count else None)
            return (dict(summary.channels), dict(summary.schemas),
                    dict(statistics.channel_message_counts), span)
        if self._overview_read is not None:  # this source has read the file through once
            return self._overview_read
        counts: Dict[int, int] = {}
        start: Optional[int] = None
        end: Optional[int] = None
        for message in self.messages():
            counts[message.channel.id] = counts.get(message.channel.id, 0) + 1
            start = message.log_time_ns if start is None else min(start, message.log_time_ns)
            end = message.log_time_ns if end is None else max(end, message.log_time_ns)
        self._overview_read = (dict(self.channels), dict(self.schemas), counts,
                               (start, end) if start is not None and end is not None else None)
        return self._overview_read

    def metadata(self) -> List[Tuple[str, Dict[str, str]]]:
        """
        Return the file's metadata records, (name, values), in file order.

        Through the summary's metadata index when the summary can be trusted; otherwise by
        streaming the data section up to its first unreadable record (what could be read).
        Does not touch ``report``.
        """
        found: List[Tuple[str, Dict[str, str]]] = []
        with open(self.path, 'rb') as stream:
            summary, _ = self._summary(stream)
            if summary is not None:
                for index in sorted(summary.metadata_indexes, key=lambda item: item.offset):
                    try:
                        stream.seek(index.offset)
                        record = next(StreamReader(stream, skip_magic=True).records)
                    except READ_ERRORS:
                        continue
                    if isinstance(record, Metadata):
                        found.append((record.name, dict(record.metadata)))
                return found
            stream.seek(MAGIC_SIZE)
            records = StreamReader(stream, skip_magic=True, emit_chunks=True,
                                   record_size_limit=max(self.report.size_bytes, 1)).records
            try:
                for record in records:
                    if isinstance(record, Metadata):
                        found.append((record.name, dict(record.metadata)))
                    elif isinstance(record, DataEnd):
                        break
            except READ_ERRORS:
                pass   # what was read before the damage is all there is
        return found

    # indexed ------------------------------------------------------------------------------
    def _summary(self, stream: io.BufferedReader):
        """Return (summary, '') or (None, why the index cannot be used)."""
        try:
            summary = SeekingReader(stream).get_summary()
            problem, crc_stored = summary_problem(stream, self.report.size_bytes)
        except READ_ERRORS as error:
            return None, f'no readable summary: {error_text(error)}'
        if summary is None:
            return None, 'the file has no summary section'
        if problem:
            return None, f'summary not used: {problem}'
        if summary.statistics is None:
            return None, 'the summary has no statistics'
        if summary.statistics.message_count and not summary.chunk_indexes:
            return None, 'the messages are not chunked'
        problem = chunk_index_problem(stream, summary.chunk_indexes)
        if not problem:
            return summary, ''
        if not crc_stored:
            return None, f'summary not used: {problem}'
        # a summary CRC says the index is as written, not that the writer wrote it right:
        # when the data section's own CRC holds, it has every chunk the index misplaces; when
        # it does not, the index is the better guide (a damaged chunk loses only itself)
        if self._data_section_valid(stream):
            return None, (f'summary not used: {problem}; the data section, whose CRC is '
                          'valid, was read instead')
        return summary, ''

    def _data_section_valid(self, stream: io.BufferedReader) -> bool:
        """Tell whether the data section reads through to a DataEnd whose stored CRC holds."""
        stream.seek(0)
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True,
                              record_size_limit=max(self.report.size_bytes, 1))
        try:
            for record in reader.records:
                if isinstance(record, DataEnd):
                    return bool(record.data_section_crc)
        except READ_ERRORS:
            return False
        return False

    def _indexed(self, stream: io.BufferedReader, summary) -> Iterator[RawMessage]:
        """Yield the messages chunk by chunk through the chunk index."""
        self.schemas.update(summary.schemas)
        self.channels.update(summary.channels)
        self.report.messages_expected = sum(
            count for channel_id, count in summary.statistics.channel_message_counts.items()
            if self._wanted(channel_id))
        for index in sorted(summary.chunk_indexes, key=lambda item: item.chunk_start_offset):
            try:
                stream.seek(index.chunk_start_offset)
                chunk = next(StreamReader(stream, skip_magic=True, emit_chunks=True).records)
                if not isinstance(chunk, Chunk):
                    raise McapError(f'found a {type(chunk).__name__} record')
                records = chunk_records(chunk)
                first = next(records, None)   # decompressed and CRC-checked here
            except READ_ERRORS as error:
                self.report.problems.append(
                    f'chunk at byte {index.chunk_start_offset} unreadable '
                    f'({error_text(error)}): its messages are lost')
                continue
            yield from self._chunk(index.chunk_start_offset, chunk, first, records)

    def _check_data_section(self, stream: io.BufferedReader) -> None:
        """Stream the records up to DataEnd with CRCs on; set ``data_crc`` and report."""
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True,
                              record_size_limit=max(self.report.size_bytes, 1))
        try:
            for record in reader.records:
                if isinstance(record, DataEnd):
                    self.data_crc = 'valid' if record.data_section_crc else 'absent'
                    return
        except CRCValidationError as error:
            self._data_crc_mismatch(error)
        except READ_ERRORS as error:
            self.report.problems.append(
                f'data section not readable through ({error_text(error)})')

    def _data_crc_mismatch(self, error: BaseException) -> None:
        """Record a data-section CRC mismatch."""
        self.data_crc = 'mismatch'
        self.report.problems.append(f'data-section CRC mismatch ({error_text(error)}): '
                                    'some record outside the messages read is damaged')

    # streamed -----------------------------------------------------------------------------
    def _streamed(self, stream: io.BufferedReader) -> Iterator[RawMessage]:
        """Yield the messages of every complete record up to the first unreadable one."""
        position, records = self._stream_records(stream)
        crc_checked = self.check_data_crc and not position   # the CRC covers the magic
        data_ended = False
        mismatch: Optional[CRCValidationError] = None
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except CRCValidationError as error:   # only DataEnd raises it (chunks: below)
                mismatch, data_ended = error, True
                position = stream.tell()
                records = StreamReader(stream, skip_magic=True, emit_chunks=True,
                                       record_size_limit=max(self.report.size_bytes, 1)
                                       ).records
                continue
            except READ_ERRORS as error:
                self._unreadable(position, error, data_ended)
                break
            end = stream.tell()
            if data_ended:
                pass   # the summary section: its copies of schemas and channels are not used
            elif isinstance(record, Chunk):
                try:
                    inside = chunk_records(record)
                    first = next(inside, None)   # decompressed and CRC-checked here
                except READ_ERRORS as error:
                    self.report.problems.append(
                        f'chunk at byte {position} unreadable ({error_text(error)}): '
                        f'its messages are lost')
                    position = end
                    continue
                yield from self._chunk(position, record, first, inside)
            elif isinstance(record, DataEnd):
                data_ended = True
                if crc_checked:
                    self.data_crc = 'valid' if record.data_section_crc else 'absent'
            elif not isinstance(record, Footer):
                yield from self._records([record])
            position = end
        if mismatch is not None:
            self._data_crc_mismatch(mismatch)

    def _unreadable(self, position: int, error: BaseException, data_ended: bool) -> None:
        """Report that the records from ``position`` on cannot be read."""
        if data_ended:   # every message was read: only the summary copies are lost
            self.report.problems.append(f'summary section unreadable from byte {position} '
                                        f'({error_text(error)}); no message lost')
            return
        self.report.unread_bytes = max(self.report.size_bytes - position, 0)
        if self.report.unread_bytes:
            self.report.problems.append(
                f'unreadable from byte {position} ({error_text(error)})')

    def _stream_records(self, stream: io.BufferedReader) -> Tuple[int, Iterator[McapRecord]]:
        """
        Return (offset, records) of a streaming read from the start of the file.

        A damaged leading magic is reported and read past (the records after it may be
        intact); the data-section CRC, which covers the magic, then cannot be checked.
        """
        limit = max(self.report.size_bytes, 1)
        stream.seek(0)
        try:
            read_magic(ReadDataStream(stream))
        except InvalidMagic as error:
            self.report.problems.append(f'bytes 0-{MAGIC_SIZE - 1} are not the MCAP magic '
                                        f'({error_text(error)}): read on from byte '
                                        f'{MAGIC_SIZE}')
            return MAGIC_SIZE, StreamReader(stream, skip_magic=True, emit_chunks=True,
                                            record_size_limit=limit).records
        except READ_ERRORS:
            pass   # too short: the read below says so
        stream.seek(0)
        return 0, StreamReader(stream, emit_chunks=True, validate_crcs=self.check_data_crc,
                               record_size_limit=limit).records

    # shared -------------------------------------------------------------------------------
    def _chunk(self, offset: int, chunk: Chunk, first: Optional[McapRecord],
               records: Iterator[McapRecord]) -> Iterator[RawMessage]:
        """Yield the messages of a CRC-checked chunk; a record that does not parse ends it."""
        if first is None:
            return
        copied = self.duplicates.chunk_seen(chunk)
        try:
            yield from self._records(itertools.chain([first], records), copied)
        except READ_ERRORS as error:
            self.report.problems.append(f'chunk at byte {offset}: a record does not parse '
                                        f'({error_text(error)}); the rest of it is lost')

    def _wanted(self, channel_id: int) -> bool:
        """Tell whether messages of ``channel_id`` pass the topic filter."""
        if self.topics is None:
            return True
        channel = self.channels.get(channel_id)
        return channel is not None and channel.topic in self.topics

    def _records(self, records: Iterable, copied_chunk: bool = False
                 ) -> Iterator[RawMessage]:
        """Track schemas and channels; yield the wanted messages that are not duplicates."""
        for record in records:
            if isinstance(record, Schema):
                self.schemas[record.id] = record
            elif isinstance(record, Channel):
                self.channels[record.id] = record
            elif isinstance(record, Message):
                channel = self.channels.get(record.channel_id)
                if channel is None:
                    self.report.problems.append(
                        f'a message on unknown channel {record.channel_id} was skipped')
                    continue
                if not self._wanted(record.channel_id):
                    continue
                if copied_chunk or self.duplicates.message_seen(record):
                    self.report.duplicates += 1
                    continue
                self.report.messages_read += 1
                yield RawMessage(channel, self.schemas.get(channel.schema_id),
                                 record.log_time, record.publish_time, record.sequence,
                                 bytes(record.data))


class Decoders:
    """CDR decoders per schema, built once each from the file's own definitions."""

    def __init__(self) -> None:
        """Start with no decoder built."""
        self._factory = DecoderFactory()
        self._decoders: Dict[Tuple[int, str], Callable[[bytes], object]] = {}

    def decode(self, message: RawMessage) -> object:
        """Decode ``message``; ValueError saying why it cannot be."""
        key = (message.channel.schema_id, message.schema_name)
        if key not in self._decoders:
            if message.schema is None:
                raise ValueError(f'channel {message.topic!r} has no schema')
            try:
                decoder = self._factory.decoder_for(message.channel.message_encoding,
                                                    message.schema)
            except READ_ERRORS + (NotImplementedError, KeyError, IndexError) as error:
                raise ValueError(f'cannot parse the schema {message.schema_name!r} of '
                                 f'{message.topic!r}: {error_text(error)}') from error
            if decoder is None:
                raise ValueError(f'channel {message.topic!r}: no decoder for message encoding '
                                 f'{message.channel.message_encoding!r} with schema encoding '
                                 f'{message.schema.encoding!r}')
            self._decoders[key] = decoder
        try:
            return self._decoders[key](message.data)
        except READ_ERRORS + (IndexError, KeyError, NotImplementedError) as error:
            raise ValueError(f'cannot decode a {message.schema_name} on {message.topic!r}: '
                             f'{error_text(error)}') from error
