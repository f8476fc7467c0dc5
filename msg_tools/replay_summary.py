"""
What a replay did: counts, solve-time percentiles, joint angles, positions, its exit code.

Constant memory however long the input: the solve-time percentiles come from a log-spaced
histogram (``TimeStats``), the plotted series is thinned to at most ``SERIES_LIMIT`` points
and at most ``WARNING_LIMIT`` per-message warnings are kept; the joint angles are summarized
by ``JointSummary`` (ranges, and the bending directions, which wrap at ±180°, by circular
mean and circular standard deviation). ``ReplaySummary.table`` is
the table ``python -m msg_tools replay`` prints; ``EXIT_CODES`` its exit codes
(docs/howto/replay.md).
"""

from dataclasses import dataclass, field
import math
import re
from typing import Collection, Dict, List, Optional, Sequence, Tuple

from cdr_translator.interface.joint_summary import JointSummary
from cdr_wire.log_status import LogStatus
from cdr_wire.reader import ReadReport
import numpy as np

#: Converged messages whose joint angles and position are counted together, as one block
#: of arrays (``ReplaySummary.settle``): per message the numpy calls cost more than a solve's
#: Python.
SETTLE_EVERY = 256

#: Exit codes of ``python -m msg_tools replay`` (docs/reference/cli.md).
EXIT_OK = 0
EXIT_DAMAGED_INPUT = 1
EXIT_USAGE = 2
EXIT_NOTHING_SOLVED = 3
EXIT_INTERRUPTED = 130
EXIT_CODES: Dict[int, str] = {
    EXIT_OK: 'all good: the input was intact and at least one wrench converged',
    EXIT_DAMAGED_INPUT: 'the input was damaged (unreadable chunks, cut, duplicates); '
                        'everything readable was replayed',
    EXIT_USAGE: 'bad arguments, no usable input, or an output that cannot be written '
                '(checked before reading; or a write error during the replay)',
    EXIT_NOTHING_SOLVED: 'nothing could be decoded or solved: no wrench gave a converged '
                         'solve (all undecodable, rejected or not converged, or none)',
    EXIT_INTERRUPTED: 'interrupted by Ctrl-C; the outputs are finalized and hold what was '
                      'done',
}

#: Name of the metadata record a replay's output MCAP ends with (``ReplaySummary.record``):
#: whether it holds the whole replay ('complete') or only part of it ('partial').
REPLAY_RECORD = 'msg_tools.replay'

#: Most points kept in ``Series`` (thinned by halves beyond that).
SERIES_LIMIT = 5_000
#: Most per-message warnings kept (the rest are counted).
WARNING_LIMIT = 20

#: Kinds of reason the summary table names for flagged and failed estimates (the rest are
#: counted).
REASONS_SHOWN = 4

#: A parenthesized aside of a flag: '(stability margin 0.0184)', '(chi-square ...)'.
_ASIDE = re.compile(r'\s*\([^)]*\)')


def reason_kind(flag: str) -> str:
    """
    Return the kind of an estimate's flag: its text before any ':', without asides.

    'near a bifurcation (stability margin 0.0184): another wrench may match this pose'
    is 'near a bifurcation'; the values that differ from pose to pose are dropped.
    """
    return ' '.join(_ASIDE.sub('', flag.split(':', 1)[0]).split())


@dataclass
class Series:
    """
    Time series of the converged messages, for the plots; at most ``limit`` points.

    Beyond ``limit`` every other point is dropped and the stride doubles, except the
    message indices in ``keep`` (the shapes asked for).
    """

    time_s: List[float] = field(default_factory=list)
    joints: List[List[float]] = field(default_factory=list)
    position: List[List[float]] = field(default_factory=list)
    index: List[int] = field(default_factory=list)
    wrench: List[np.ndarray] = field(default_factory=list)
    limit: int = field(default_factory=lambda: SERIES_LIMIT)
    keep: Collection[int] = ()
    stride: int = 1
    #: Messages without an answer to plot: (header stamp ns, 'rejected' or 'not
    #: converged'); at most ``limit``, thinned by halves beyond that.
    gaps: List[Tuple[int, str]] = field(default_factory=list)

    def add_gap(self, stamp_ns: int, kind: str) -> None:
        """Remember a message that was rejected or did not converge, for the plot."""
        self.gaps.append((stamp_ns, kind))
        if len(self.gaps) > self.limit:
            self.gaps = self.gaps[::2]

    def add(self, index: int, time_s: float, joints: List[float], position: List[float],
            wrench: np.ndarray) -> None:
        """Append a converged message when it falls on the stride (or is to be kept)."""
        if index % self.stride and index not in self.keep:
            return
        self.time_s.append(time_s)
        self.joints.append(joints)
        self.position.append(position)
        self.index.append(index)
        self.wrench.append(wrench)
        if len(self.index) > self.limit:
            self.stride *= 2
            chosen = [k for k, kept in enumerate(self.index)
                      if kept % self.stride == 0 or kept in self.keep]
            for name in ('time_s', 'joints', 'position', 'index', 'wrench'):
                values = getattr(self, name)
                setattr(self, name, [values[k] for k in chosen])

    def merge(self, later: 'Series', time_shift_s: float = 0.0) -> None:
        """
        Append the points of ``later`` (a series of later messages), its times shifted.

        The points left are those a single series fed every message would hold: the
        coarser stride of the two, doubled until at most ``limit`` points remain.
        """
        self.stride = max(self.stride, later.stride)
        self.gaps += later.gaps
        while len(self.gaps) > self.limit:
            self.gaps = self.gaps[::2]
        self.time_s += [time_s + time_shift_s for time_s in later.time_s]
        for name in ('joints', 'position', 'index', 'wrench'):
            getattr(self, name).extend(getattr(later, name))
        while True:
            chosen = [k for k, kept in enumerate(self.index)
                      if kept % self.stride == 0 or kept in self.keep]
            for name in ('time_s', 'joints', 'position', 'index', 'wrench'):
                values = getattr(self, name)
                setattr(self, name, [values[k] for k in chosen])
            if len(self.index) <= self.limit:
                return
            self.stride *= 2


class TimeStats:
    """Count, maximum and percentiles (within 1.2 %) of durations, in constant memory."""

    LOW_S, DECADES, PER_DECADE = 1e-7, 10, 200

    def __init__(self) -> None:
        """Start empty."""
        self.count = 0
        self.max_s = 0.0
        self._bins = np.zeros(self.DECADES * self.PER_DECADE + 2, dtype=np.int64)

    def add(self, seconds: float) -> None:
        """Count one duration."""
        self.count += 1
        self.max_s = max(self.max_s, seconds)
        position = (math.log10(max(seconds, self.LOW_S)) - math.log10(self.LOW_S)) * \
            self.PER_DECADE
        self._bins[min(int(position) + 1, len(self._bins) - 1)] += 1

    def merge(self, other: 'TimeStats') -> None:
        """Count the durations of ``other`` too."""
        self.count += other.count
        self.max_s = max(self.max_s, other.max_s)
        self._bins += other._bins

    def percentile(self, q: float) -> float:
        """Return the ``q`` percentile in s (the geometric middle of its bin)."""
        if not self.count:
            return math.nan
        rank = max(math.ceil(q / 100.0 * self.count), 1)
        position = int(np.searchsorted(np.cumsum(self._bins), rank))
        if position == 0:
            return self.LOW_S
        value = self.LOW_S * 10 ** ((position - 0.5) / self.PER_DECADE)
        return min(value, self.max_s)


@dataclass
class ReplaySummary:
    """Counts, timings, joint and position statistics of one replay (constant memory)."""

    input_report: ReadReport
    topics: List[str]
    warnings: List[str]
    messages: int = 0
    solved: int = 0
    not_converged: int = 0
    rejected: int = 0
    undecodable: int = 0
    #: Measured end-disk poses replayed, each counted once more as: estimated (converged,
    #: no flag), flagged (converged, not to be acted on), failed (not converged) or
    #: rejected (undecodable or bad input).
    poses: int = 0
    estimated: int = 0
    flagged: int = 0
    failed: int = 0
    rejected_poses: int = 0
    #: Time of each estimate (converged or not).
    estimate_times: TimeStats = field(default_factory=TimeStats)
    solve_times: TimeStats = field(default_factory=TimeStats)
    wall_s: float = 0.0
    interrupted: bool = False
    series: Series = field(default_factory=Series)
    warnings_dropped: int = 0
    joints: JointSummary = field(default_factory=JointSummary)
    position_range: Optional[np.ndarray] = None
    output_status: Optional[LogStatus] = None
    output_error: str = ''
    #: Messages of the replayed topics the input's summary lists (None: no summary).
    total: Optional[int] = None
    #: Header stamp (ns) of the first converged message: time zero of ``series``.
    first_stamp_ns: Optional[int] = None
    #: Joint angles and positions of converged messages not counted yet (``settle``).
    pending: List[List[float]] = field(default_factory=list, repr=False)
    #: The model level asked for (translator_node's ``fidelity``, with the budget of
    #: 'auto': ``fidelity_text``); '' when not said.
    fidelity: str = ''
    #: Converged messages by the level that answered them ('full', 'cc', ...).
    levels: Dict[str, int] = field(default_factory=dict)
    #: Flagged and failed estimates by reason (``reason_kind`` of each flag).
    pose_reasons: Dict[str, int] = field(default_factory=dict)

    def count_reasons(self, flags: Sequence[str]) -> None:
        """Count a flagged or failed estimate under each kind of reason it gives (once each)."""
        for kind in dict.fromkeys(reason_kind(flag) for flag in flags):
            self.pose_reasons[kind] = self.pose_reasons.get(kind, 0) + 1

    def reasons_text(self) -> str:
        """Return the reasons of flagged and failed estimates, most frequent first."""
        ranked = sorted(self.pose_reasons.items(), key=lambda item: (-item[1], item[0]))
        shown = ', '.join(f'{count} {kind}' for kind, count in ranked[:REASONS_SHOWN])
        rest = len(ranked) - REASONS_SHOWN
        return shown + (f', {rest} other reason(s)' if rest > 0 else '')

    def count_level(self, level: str) -> None:
        """Count a converged message answered at ``level``."""
        self.levels[level] = self.levels.get(level, 0) + 1

    def level_text(self) -> str:
        """Return the level asked for and those that answered ('auto (...); answered by ...')."""
        answered = ', '.join(f'{count} {level}' for level, count in sorted(
            self.levels.items(), key=lambda item: -item[1]))
        if not answered:
            return self.fidelity or 'not said'
        if list(self.levels) == [self.fidelity]:
            return self.fidelity
        return f'{self.fidelity or "not said"}; answered by {answered}'

    @property
    def stopped_early(self) -> bool:
        """Tell whether the replay ended before the input did (Ctrl-C or a write error)."""
        return self.interrupted or bool(self.output_error) or bool(
            self.output_status is not None and self.output_status.lost)

    def record(self) -> Dict[str, str]:
        """
        Return the metadata (``REPLAY_RECORD``) the output MCAP ends with.

        'status' is 'partial' when the replay stopped before the input ended (Ctrl-C, a
        write error; 'reason' says which), else 'complete'; the message counts and the
        model level go with it.
        """
        reason = ('interrupted (Ctrl-C)' if self.interrupted
                  else self.output_error or ('write error' if self.stopped_early else ''))
        return {'status': 'partial' if self.stopped_early else 'complete', 'reason': reason,
                'messages_replayed': str(self.messages),
                'messages_in_input': 'unknown' if self.total is None else str(self.total),
                'fidelity': self.fidelity}

    def not_replayed(self) -> str:
        """Return how much of the input a replay that stopped early left (for the table)."""
        if self.total is None:
            return 'the rest of the input (its summary gives no count)'
        return f'{max(self.total - self.messages, 0)} of {self.total} messages'

    @property
    def throughput(self) -> float:
        """Messages per second of wall time (reading, solving and writing)."""
        return self.messages / self.wall_s if self.wall_s > 0 else math.nan

    def warn(self, text: str) -> None:
        """Keep a per-message warning (the first ``WARNING_LIMIT``; the rest are counted)."""
        if len(self.warnings) < WARNING_LIMIT:
            self.warnings.append(text)
        else:
            self.warnings_dropped += 1

    def converged(self, joints: List[float], position: List[float]) -> None:
        """
        Count a converged message's joint angles (rad); widen the position (m) range.

        Counted by blocks of ``SETTLE_EVERY``: ``settle`` counts the rest (the replay does
        when it ends, ``merge`` and ``table`` before they read).
        """
        self.pending.append(joints + position)
        if len(self.pending) >= SETTLE_EVERY:
            self.settle()

    def settle(self) -> None:
        """Count the pending converged messages in ``joints`` and ``position_range``."""
        if not self.pending:
            return
        block = np.array(self.pending, dtype=float)
        self.pending.clear()
        self.joints.add(block[:, :-3])
        self.converged_range(block[:, -3:])

    def merge(self, later: 'ReplaySummary') -> None:
        """
        Add the replay of later messages of the same input (a window) to this one.

        Counts add, statistics combine, warnings append up to ``WARNING_LIMIT``; the read
        report becomes ``later``'s (each window reads the whole input).
        """
        self.settle()
        later.settle()
        for name in ('messages', 'solved', 'not_converged', 'rejected', 'undecodable',
                     'warnings_dropped', 'poses', 'estimated', 'flagged', 'failed',
                     'rejected_poses'):
            setattr(self, name, getattr(self, name) + getattr(later, name))
        for text in later.warnings:
            self.warn(text)
        for level, count in later.levels.items():
            self.levels[level] = self.levels.get(level, 0) + count
        for kind, count in later.pose_reasons.items():
            self.pose_reasons[kind] = self.pose_reasons.get(kind, 0) + count
        self.fidelity = self.fidelity or later.fidelity
        self.solve_times.merge(later.solve_times)
        self.estimate_times.merge(later.estimate_times)
        self.joints.merge(later.joints)
        if later.position_range is not None:
            self.converged_range(later.position_range)
        shift = 0.0
        if later.first_stamp_ns is not None:
            if self.first_stamp_ns is None:
                self.first_stamp_ns = later.first_stamp_ns
            shift = 1e-9 * (later.first_stamp_ns - self.first_stamp_ns)
        self.series.merge(later.series, shift)
        self.interrupted = self.interrupted or later.interrupted
        self.output_error = self.output_error or later.output_error
        self.input_report = later.input_report

    def converged_range(self, values: np.ndarray) -> None:
        """Widen the position (m) range to hold ``values`` (rows: positions)."""
        low, high = np.min(values, axis=0), np.max(values, axis=0)
        if self.position_range is None:
            self.position_range = np.array([low, high])
            return
        self.position_range = np.array([np.minimum(self.position_range[0], low),
                                        np.maximum(self.position_range[1], high)])

    def pose_counts(self) -> str:
        """Return what became of every measured pose: '400: 209 estimated, 150 flagged, ...'."""
        return (f'{self.poses}: {self.estimated} estimated, {self.flagged} flagged, '
                f'{self.failed} failed, {self.rejected_poses} rejected')

    def exit_code(self) -> int:
        """Return the exit code (``EXIT_CODES``) this replay ends with."""
        if self.output_error or (self.output_status is not None and self.output_status.lost):
            return EXIT_USAGE
        if self.interrupted:
            return EXIT_INTERRUPTED
        if not self.solved:
            return EXIT_NOTHING_SOLVED
        return EXIT_OK if self.input_report.complete else EXIT_DAMAGED_INPUT

    def table(self) -> str:
        """Return the summary table printed at the end of a replay."""
        self.settle()
        read = self.input_report.describe()
        if self.stopped_early:
            read += ' up to where the replay stopped'
        rows = [('input', read),
                ('wrench topics', ', '.join(self.topics)),
                ('fidelity (model level)', self.level_text()),
                ('messages', str(self.messages)),
                ('solved (converged)', str(self.solved)),
                ('not converged', str(self.not_converged)),
                ('rejected (bad input)', str(self.rejected)),
                ('undecodable', str(self.undecodable)),
                ('duplicates skipped', str(self.input_report.duplicates))]
        if self.poses:
            rows.append(('measured poses', self.pose_counts()))
        if self.pose_reasons:
            rows.append(('flagged or failed, why', self.reasons_text()))
        if self.solve_times.count:
            p50, p90, p99 = (1e3 * self.solve_times.percentile(q) for q in (50, 90, 99))
            rows.append(('solve time ms p50/p90/p99/max',
                         f'{p50:.3f} / {p90:.3f} / {p99:.3f} / '
                         f'{1e3 * self.solve_times.max_s:.3f}'))
        if self.estimate_times.count:
            p50, p95 = (1e3 * self.estimate_times.percentile(q) for q in (50, 95))
            rows.append(('estimate time ms p50/p95/max',
                         f'{p50:.3f} / {p95:.3f} / {1e3 * self.estimate_times.max_s:.3f}'))
        rows.extend(self.joints.rows())
        if self.position_range is not None:
            position = 1e3 * self.position_range
            for column, axis in enumerate('xyz'):
                rows.append((f'end disk {axis} mm min..max',
                             f'{position[0, column]:.3f} .. {position[1, column]:.3f}'))
        rows.append(('wall time s', f'{self.wall_s:.3f}'))
        rows.append(('throughput msg/s', f'{self.throughput:.1f}'))
        if self.output_status is not None:
            rows.append(('output records', f'{self.output_status.written} written, '
                                           f'{self.output_status.lost} lost'))
        if self.interrupted:
            rows.append(('interrupted', 'yes (Ctrl-C): the output holds what was done'))
        if self.stopped_early:
            rows.append(('not replayed', self.not_replayed()))
        width = max(len(name) for name, _ in rows)
        return '\n'.join(f'{name:<{width}}  {value}' for name, value in rows)


def fidelity_text(fidelity: str, max_position_error: float, max_angle_error: float) -> str:
    """Return the model level asked for as the summary and the plot name it ('auto (...)')."""
    if fidelity != 'auto':
        return fidelity
    if max_position_error <= 0.0 or max_angle_error <= 0.0:   # as fidelity.admission reads it
        return 'auto (no error budget: it needs a position and an angle error, so full)'
    return f'auto (budget {1e3 * max_position_error:g} mm, {max_angle_error:g} deg)'
