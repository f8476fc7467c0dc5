"""
A stream's diagnostics over a period: one aggregated status a period, not one a message.

REP 107 and diagnostic_updater publish /diagnostics about once a second, each status
summing up what happened since the last one, so that an aggregator or a robot monitor is
not flooded. ``StreamDiagnostics`` keeps that summary for one input stream (the wrenches,
the measured poses): the stream's owner notes each answer's level, residual and time as it
goes (``note``, a few attribute updates under a lock), and the publisher asks once a period
for the status (``status``): the running counts it is given, the rates and skipped share
over the period, the worst residual and the longest time, the latest verdict, and the
period's worst level with a message that names the last fault. A fault inside a period
therefore makes that period's status at least WARN or ERROR. ``diagnostics_array`` wraps
the statuses of one period into the DiagnosticArray dict. Pure Python, no rclpy: the node
and replay both publish these.
"""

from dataclasses import dataclass
import math
import threading
from typing import Any, Dict, Mapping, Optional, Sequence

from . import messages

#: DiagnosticStatus level names, by level.
LEVEL_NAMES = {messages.OK: 'OK', messages.WARN: 'WARN', messages.ERROR: 'ERROR',
               messages.STALE: 'STALE'}


@dataclass
class PeriodNotes:
    """What a stream's answers gave within one period (``StreamDiagnostics.note``)."""

    answered: int = 0
    warned: int = 0
    failed: int = 0
    level: int = messages.OK
    worst_residual: float = -math.inf
    time_total_s: float = 0.0
    timed: int = 0
    max_time_s: float = 0.0
    latest_level: Optional[int] = None
    latest_message: str = ''
    fault: str = ''


class StreamDiagnostics:
    """
    The aggregated DiagnosticStatus of one input stream, a period at a time.

    ``name`` is the status name (e.g. 'translator_node: kinestatics'), ``what`` names the
    inputs in its message ('wrenches'); ``residual_key`` and ``time_key`` name the worst
    residual and the time the notes carry (``worst_<residual_key>``, ``max_<time_key>_ms``).
    ``note`` may be called from one thread while ``status`` is called from another.
    """

    def __init__(self, name: str, what: str, *, residual_key: str = 'residual_norm',
                 time_key: str = 'solve_time', hardware_id: str = messages.HARDWARE_ID
                 ) -> None:
        """Start with no period begun (``begin`` or the first ``status`` begins one)."""
        self.name = name
        self.what = what
        self.residual_key = residual_key
        self.time_key = time_key
        self.hardware_id = hardware_id
        self._lock = threading.Lock()
        self._notes = PeriodNotes()
        self._started_s: Optional[float] = None
        self._counts_before: Dict[str, int] = {}

    def begin(self, now_s: float) -> None:
        """Start the first period at ``now_s`` (s, on the clock ``status`` is given)."""
        self._started_s = now_s

    def discard_notes(self) -> None:
        """Forget the answers noted in this period (a replay window's warm-up solves)."""
        with self._lock:
            self._notes = PeriodNotes()

    def note(self, level: int, message: str, residual: Optional[float] = None,
             time_s: Optional[float] = None) -> None:
        """
        Note one answer: its level, its message, and (when solved) residual and time (s).

        A rejected input is an ERROR with its reason and neither residual nor time.
        """
        with self._lock:
            notes = self._notes
            notes.answered += 1
            if level >= messages.ERROR:
                notes.failed += 1
            elif level == messages.WARN:
                notes.warned += 1
            if level > notes.level:
                notes.level = level
            if level != messages.OK:
                notes.fault = message
            if residual is not None and residual > notes.worst_residual:
                notes.worst_residual = residual
            if time_s is not None:
                notes.time_total_s += time_s
                notes.timed += 1
                if time_s > notes.max_time_s:
                    notes.max_time_s = time_s
            notes.latest_level = level
            notes.latest_message = message

    def status(self, counts: Mapping[str, Any], now_s: float) -> dict:
        """
        Return the DiagnosticStatus dict of the period ending at ``now_s``; start the next.

        ``counts`` are the stream's running counts (received, solved, ..., skipped), reported
        as they are; ``received`` and ``solved`` give the rates over the period, ``skipped``
        the share of the period's received inputs that were skipped.
        """
        with self._lock:
            notes, self._notes = self._notes, PeriodNotes()
        started = now_s if self._started_s is None else self._started_s
        self._started_s = now_s
        elapsed = max(now_s - started, 0.0)
        before, self._counts_before = self._counts_before, {
            key: int(value) for key, value in counts.items() if isinstance(value, int)}
        delta = {key: value - before.get(key, 0) for key, value in self._counts_before.items()}
        values: Dict[str, Any] = {'period_s': elapsed, **counts}
        received = delta.get('received', 0)
        if elapsed > 0.0:
            values['received_per_s'] = received / elapsed
            if 'solved' in delta:
                values['solved_per_s'] = delta['solved'] / elapsed
        if 'skipped' in delta:
            values['skipped_share'] = delta['skipped'] / received if received > 0 else 0.0
        values.update({'answered_in_period': notes.answered, 'warned_in_period': notes.warned,
                       'failed_in_period': notes.failed})
        if notes.worst_residual > -math.inf:
            values[f'worst_{self.residual_key}'] = notes.worst_residual
        if notes.timed:
            values[f'mean_{self.time_key}_ms'] = 1e3 * notes.time_total_s / notes.timed
            values[f'max_{self.time_key}_ms'] = 1e3 * notes.max_time_s
        if notes.latest_level is not None:
            values['latest_level'] = LEVEL_NAMES[notes.latest_level]
            values['latest_message'] = notes.latest_message
        return {'level': notes.level, 'name': self.name,
                'message': self._message(notes, elapsed, received),
                'hardware_id': self.hardware_id,
                'values': [{'key': str(key), 'value': messages.value_text(value)}
                           for key, value in values.items()]}

    def _message(self, notes: PeriodNotes, elapsed: float, received: int) -> str:
        """Return the period's message: the faults (the last named) or what was answered."""
        span = f'in the last {elapsed:.3g} s'
        if notes.level >= messages.ERROR:
            return (f'{notes.failed} of {notes.answered} {self.what} failed or rejected '
                    f'{span}; last: {notes.fault}')
        if notes.level == messages.WARN:
            return (f'{notes.warned} of {notes.answered} {self.what} not to be acted on '
                    f'{span}; last: {notes.fault}')
        if not notes.answered and not received:
            return f'idle: no {self.what} {span}'
        return f'{notes.answered} {self.what} answered, {received} received {span}'


def diagnostics_array(stamp: Mapping[str, int], statuses: Sequence[dict]) -> dict:
    """Return the DiagnosticArray dict of one period's statuses."""
    return {'header': messages.header(stamp, ''), 'status': list(statuses)}
