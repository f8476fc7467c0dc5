"""``python -m msg_tools info FILE``: topics, types, counts and time range of an MCAP."""

from datetime import datetime, timezone
from pathlib import Path
from typing import Union

from msg_tools.reader import McapSource


def _utc(time_ns: int) -> str:
    """Return an ISO-8601 UTC time with nanoseconds."""
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    stamp = datetime.fromtimestamp(seconds, tz=timezone.utc).strftime('%Y-%m-%dT%H:%M:%S')
    return f'{stamp}.{nanoseconds:09d}Z'


def describe(path: Union[str, Path]) -> str:
    """Return the info text of ``path``; salvages a damaged file and says so."""
    source = McapSource(path)
    channels, schemas, counts, span = source.channel_overview()
    summary_used = source.report.mode == 'indexed' and not source.report.messages_read
    lines = [f'file:      {source.path} ({source.report.size_bytes} bytes)',
             'read:      ' + ('complete (counts from the summary)' if summary_used
                              else source.report.describe())]
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
