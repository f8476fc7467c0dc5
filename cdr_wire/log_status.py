"""
What an MCAP writer reports: records written, pending and lost, and the last event.

Write errors are events, not exceptions (see ``cdr_wire.mcap_log``): ``LogStatus`` is how
the writer, the log process and the replay tell what reached the disk.
"""

from dataclasses import dataclass
from typing import Tuple


@dataclass(frozen=True)
class LogStatus:
    """
    What a McapLog has done: ``ok`` False while writing fails.

    ``written``: records in complete chunks on disk; ``pending``: records accepted but not
    yet flushed; ``lost``: records that will never be written (a write error, the file
    removed); ``errors``: write-error events; ``message``: the last event (error or resume),
    '' when nothing happened; ``files``: every file written, the current one last.
    """

    ok: bool
    path: str
    files: Tuple[str, ...]
    written: int
    pending: int
    lost: int
    errors: int
    message: str

    def describe(self) -> str:
        """Return a one-line account, e.g. for a node's closing log line."""
        state = 'ok' if self.ok else 'ERROR'
        files = ', '.join(self.files)
        text = (f'{state}: {self.written} records written, {self.lost} lost'
                + (f', {self.pending} pending' if self.pending else '') + f'; file(s) {files}')
        return text + (f'; {self.message}' if self.message else '')
