"""
``python -m msg_tools info FILE``: topics, types, counts and time range of an MCAP.

By default every chunk is read and its CRC checked, and so are the summary and
data-section CRCs: the counts are those of the messages that can be read, and a damaged
file is reported as such with what was lost, even when its summary is intact (a damaged
summary is not used: the data section is read through, ``cdr_wire.reader``).
``verify=False`` (``--no-crc``) takes the counts from the summary without reading the
chunks (fast, for trusted files). Memory stays bounded: messages are counted as they
stream by. A replay's output that holds only part of the replay (interrupted, a write
error: its ``msg_tools.replay`` metadata record says 'partial') is named PARTIAL, however
intact the file.
"""

from datetime import datetime, timezone
from pathlib import Path
from typing import Dict, List, Tuple, Union

from cdr_wire.reader import McapSource, ReadReport
from msg_tools.replay_summary import REPLAY_RECORD


def _utc(time_ns: int) -> str:
    """Return an ISO-8601 UTC time with nanoseconds."""
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    stamp = datetime.fromtimestamp(seconds, tz=timezone.utc).strftime('%Y-%m-%dT%H:%M:%S')
    return f'{stamp}.{nanoseconds:09d}Z'


_DATA_CRC = {'valid': 'data-section CRC valid', 'absent': 'no data-section CRC stored',
             'mismatch': 'data-section CRC MISMATCH', 'unchecked': 'data-section CRC unchecked'}


def damage_text(report: ReadReport) -> str:
    """Return how every command names a damaged input: 'DAMAGED: ' and what was lost."""
    return 'DAMAGED: ' + report.describe()


def replay_text(metadata: List[Tuple[str, Dict[str, str]]]) -> str:
    """
    Return what a replay's output says of itself ('' for a file no replay wrote).

    'PARTIAL: ...' when its record says the replay stopped early (the file can be intact
    and still hold only the first messages of the input).
    """
    records = [values for name, values in metadata if name == REPLAY_RECORD]
    if not records:
        return ''
    values = records[-1]
    counts = (f"{values.get('messages_replayed', '?')} of "
              f"{values.get('messages_in_input', 'unknown')} input messages replayed")
    level = f", fidelity {values['fidelity']}" if values.get('fidelity') else ''
    if values.get('status') == 'complete':
        return f'complete replay output: {counts}{level}'
    reason = values.get('reason') or 'stopped early'
    return f'PARTIAL replay output ({reason}): only {counts}{level}'


def describe(path: Union[str, Path], verify: bool = True) -> str:
    """Return the info text of ``path``; salvages a damaged file and says so."""
    source = McapSource(path, check_data_crc=verify)
    channels, schemas, counts, span = source.channel_overview(verify=verify)
    report = source.report
    if not verify and report.mode == 'indexed' and not report.messages_read:
        read = 'counts from the summary, CRCs not checked (--no-crc)'
    elif report.complete:
        read = (f'complete: every chunk read, CRCs valid ({_DATA_CRC[source.data_crc]}), '
                f'{report.messages_read} messages')
    else:
        read = damage_text(report)
        if verify:
            read += f'; {_DATA_CRC[source.data_crc]}'
    lines = [f'file:      {source.path} ({report.size_bytes} bytes)', f'read:      {read}']
    replayed = replay_text(source.metadata())
    if replayed:
        lines.append(f'replay:    {replayed}')
    total = sum(counts.values()) if counts else 0
    lines.append(f'messages:  {total}')
    if span is not None:
        lines.append(f'start:     {_utc(span[0])}')
        lines.append(f'end:       {_utc(span[1])}')
        lines.append(f'duration:  {1e-9 * (span[1] - span[0]):.6f} s')
    rows = []
    for channel_id, channel in sorted(channels.items(), key=lambda item: item[1].topic):
        schema = schemas.get(channel.schema_id)
        rows.append((channel.topic, schema.name if schema is not None else '(no schema)',
                     str((counts or {}).get(channel_id, 0)), channel.message_encoding,
                     'yes' if channel.metadata.get('topic_type_hash') else 'no'))
    header = ('topic', 'type', 'count', 'encoding', 'type hash')
    widths = [max(len(row[k]) for row in rows + [header]) for k in range(len(header))]
    lines.append('')
    for row in [header] + rows:
        lines.append('  '.join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())
    return '\n'.join(lines)
