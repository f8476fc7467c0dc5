"""Small chunked MCAP files for the reader tests (shared by several test modules)."""

from pathlib import Path

from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.stream_reader import MAGIC_SIZE
from mcap.writer import Writer
from msg_tools import synth


def write_chunked(path, count=40, every=10):
    """Write ``count`` wrenches in chunks of ``every`` messages; return the stamps (ns)."""
    stamps = [synth.DEFAULT_START_NS + 10_000_000 * k for k in range(count)]
    with McapLog(path, flush_every_messages=every, flush_every_s=0.0) as log:
        for k, stamp in enumerate(stamps):
            log.write('/wrench', messages.WRENCH_TYPE, messages.wrench_message(
                [0.2 * k, 0.0, 0.0], [0.0, 0.0, 0.0], '', messages.stamp_from_ns(stamp)),
                log_time_ns=stamp)
    return stamps


def chunk_offsets(path):
    """Return sorted (offset, length) of the chunks, from the summary."""
    with open(path, 'rb') as stream:
        indexes = make_reader(stream).get_summary().chunk_indexes
    return sorted((i.chunk_start_offset, i.chunk_length) for i in indexes)


def write_undecodable(path, count):
    """Write ``count`` messages on a '/wrench' channel whose WrenchStamped schema is wrong."""
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2')
        schema = writer.register_schema(messages.WRENCH_TYPE, 'ros2msg', b'int32 a')
        channel = writer.register_channel('/wrench', 'cdr', schema)
        for k in range(count):
            writer.add_message(channel, log_time=k, publish_time=k,
                               data=b'\x00\x01\x00\x00' + k.to_bytes(4, 'little'))
        writer.finish()


def record_spans(path):
    """Return (opcode name, offset, total length) of every top-level record, in file order."""
    data = Path(path).read_bytes()
    spans, offset = [], MAGIC_SIZE
    while offset + 9 <= len(data) - MAGIC_SIZE:
        length = int.from_bytes(data[offset + 1:offset + 9], 'little')
        spans.append((Opcode(data[offset]).name, offset, 9 + length))
        offset += 9 + length
    return spans
