"""
Replay recorded wrenches through the solver offline: what translator_node would have published.

Reads the WrenchStamped messages of an MCAP (salvaging a damaged file), handles each as the
node does (``processing.WrenchProcessor``: same checks, frames, warm-started solver, time
limit) and writes a new MCAP holding the input messages and every output the node publishes
(end_disk_pose, bending_angles, compliance_eigenvalues, compliance, /diagnostics and, on
request, backbones) with header stamps equal to the input stamps and log times equal to the
input log times. Output topics take the input topic's namespace ('/robot/wrench' gives
'/robot/end_disk_pose'). Optionally a CSV row per message and a plot. No rclpy needed.

Memory stays bounded however long the input: messages stream through, the statistics are
running ones (solve-time percentiles from a log-spaced histogram), the plotted series is
thinned to at most ``SERIES_LIMIT`` points and at most ``WARNING_LIMIT`` per-message
warnings are kept. Exit codes: see ``EXIT_CODES`` and docs/replay.md.
"""

import csv
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import sys
import time
from typing import Collection, Dict, IO, List, Optional, Sequence, Tuple, Union

from cdr_translator.console import unwritable_reason
from cdr_translator.interface import messages
from cdr_translator.interface.processing import WrenchProcessor
from cdr_translator.interface.settings import TranslatorSettings
from msg_tools.interrupts import deferred_sigint
from msg_tools.log_status import LogStatus
from msg_tools.mcap_log import McapLog
from msg_tools.plots import check_plot_path, plot_replay
from msg_tools.reader import Decoders, McapSource, ReadReport
import numpy as np

#: CSV columns, one row per input message (SI units, radians).
CSV_COLUMNS = (
    ['index', 'topic', 'stamp_ns', 'log_time_ns', 'frame_id', 'fx_n', 'fy_n', 'fz_n',
     'mx_nm', 'my_nm', 'mz_nm', 'status', 'message', 'iterations', 'residual_norm',
     'solve_time_ms']
    + [f'{name}_rad' for name in messages.JOINT_NAMES]
    + ['x_m', 'y_m', 'z_m', 'qx', 'qy', 'qz', 'qw']
    + [f'compliance_eigenvalue_{k}' for k in range(1, 7)])


#: Exit codes of ``python -m msg_tools replay`` (docs/replay.md).
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

#: Most points kept in ``Series`` (thinned by halves beyond that).
SERIES_LIMIT = 5_000
#: Most per-message warnings kept (the rest are counted).
WARNING_LIMIT = 20


class ReplayError(ValueError):
    """The input cannot be replayed at all (no such file, no usable wrench topic)."""


class OutputError(ReplayError):
    """An output file cannot be written (found before reading, or a write error)."""


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
    """Counts, timings and ranges of one replay (constant memory whatever the input)."""

    input_report: ReadReport
    topics: List[str]
    warnings: List[str]
    messages: int = 0
    solved: int = 0
    not_converged: int = 0
    rejected: int = 0
    undecodable: int = 0
    solve_times: TimeStats = field(default_factory=TimeStats)
    wall_s: float = 0.0
    interrupted: bool = False
    series: Series = field(default_factory=Series)
    warnings_dropped: int = 0
    joints_range: Optional[np.ndarray] = None
    position_range: Optional[np.ndarray] = None
    output_status: Optional[LogStatus] = None
    output_error: str = ''
    #: Messages of the replayed topics the input's summary lists (None: no summary).
    total: Optional[int] = None

    @property
    def stopped_early(self) -> bool:
        """Tell whether the replay ended before the input did (Ctrl-C or a write error)."""
        return self.interrupted or bool(self.output_error) or bool(
            self.output_status is not None and self.output_status.lost)

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
        """Widen the running joint (rad) and position (m) ranges."""
        values = np.array(joints + position)
        if self.joints_range is None or self.position_range is None:
            self.joints_range = np.array([values[:5], values[:5]])
            self.position_range = np.array([values[5:], values[5:]])
            return
        self.joints_range = np.array([np.minimum(self.joints_range[0], values[:5]),
                                      np.maximum(self.joints_range[1], values[:5])])
        self.position_range = np.array([np.minimum(self.position_range[0], values[5:]),
                                        np.maximum(self.position_range[1], values[5:])])

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
        read = self.input_report.describe()
        if self.stopped_early:
            read += ' up to where the replay stopped'
        rows = [('input', read),
                ('wrench topics', ', '.join(self.topics)),
                ('messages', str(self.messages)),
                ('solved (converged)', str(self.solved)),
                ('not converged', str(self.not_converged)),
                ('rejected (bad input)', str(self.rejected)),
                ('undecodable', str(self.undecodable)),
                ('duplicates skipped', str(self.input_report.duplicates))]
        if self.solve_times.count:
            p50, p90, p99 = (1e3 * self.solve_times.percentile(q) for q in (50, 90, 99))
            rows.append(('solve time ms p50/p90/p99/max',
                         f'{p50:.3f} / {p90:.3f} / {p99:.3f} / '
                         f'{1e3 * self.solve_times.max_s:.3f}'))
        if self.joints_range is not None and self.position_range is not None:
            joints = np.degrees(self.joints_range)
            for column, name in enumerate(messages.JOINT_NAMES):
                rows.append((f'{name} deg min..max',
                             f'{joints[0, column]:.3f} .. {joints[1, column]:.3f}'))
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


class Progress:
    """A one-line progress bar on a text stream (carriage return, at most 10 redraws/s)."""

    def __init__(self, stream: IO[str], total: Optional[int], width: int = 30) -> None:
        """Draw to ``stream``; ``total`` None shows a count only."""
        self.stream, self.total, self.width = stream, total, width
        self.started = time.perf_counter()
        self._drawn = -math.inf

    def update(self, done: int, force: bool = False) -> None:
        """Redraw for ``done`` messages (rate limited unless ``force``)."""
        now = time.perf_counter()
        if not force and now - self._drawn < 0.1:
            return
        self._drawn = now
        rate = done / max(now - self.started, 1e-9)
        if self.total:
            fraction = min(done / self.total, 1.0)
            filled = int(round(fraction * self.width))
            bar = '#' * filled + '.' * (self.width - filled)
            text = f'\r[{bar}] {100 * fraction:5.1f}% {done}/{self.total} {rate:8.1f} msg/s'
        else:
            text = f'\r{done} messages {rate:8.1f} msg/s'
        self.stream.write(text)
        self.stream.flush()

    def close(self, done: int) -> None:
        """Draw the final state and end the line."""
        self.update(done, force=True)
        self.stream.write('\n')
        self.stream.flush()


def output_topic(input_topic: str, name: str) -> str:
    """
    Return the node's output topic ``name`` in the namespace of ``input_topic``.

    The namespace is everything before the topic's last name: '/robot/wrench' and
    '/robot/wrench_filtered' both give '/robot/' (a remapped input, as the node would have
    been started in that namespace), '/wrench' gives '/'.
    """
    if name.startswith('/'):
        return name
    return input_topic.rsplit('/', 1)[0] + '/' + name


def select_topics(source: McapSource, requested: Optional[Sequence[str]]
                  ) -> Tuple[List[str], List[str], Optional[int]]:
    """
    Return (topics to replay, warnings, number of their messages if known).

    Without ``requested``: every channel whose schema is WrenchStamped. A requested topic
    that is missing or has another schema is a warning; none usable is a ReplayError that
    lists what the file holds.
    """
    channels, schemas, counts, _ = source.channel_overview()
    types: Dict[str, str] = {}
    for channel in channels.values():
        schema = schemas.get(channel.schema_id)
        types[channel.topic] = schema.name if schema is not None else '(no schema)'
    available = ', '.join(f'{topic} [{type_name}]' for topic, type_name in sorted(types.items()))
    warnings = []
    if requested:
        chosen = []
        for topic in requested:
            if topic not in types:
                warnings.append(f'topic {topic!r} is not in {source.path}')
            elif types[topic] != messages.WRENCH_TYPE:
                warnings.append(f'topic {topic!r} has schema {types[topic]!r}, not '
                                f'{messages.WRENCH_TYPE!r}: skipped')
            else:
                chosen.append(topic)
    else:
        chosen = sorted(topic for topic, type_name in types.items()
                        if type_name == messages.WRENCH_TYPE)
    if not chosen:
        damage = ('' if source.report.complete
                  else f'; the file is damaged: {source.report.describe()}')
        raise ReplayError('; '.join(warnings + [
            f'no {messages.WRENCH_TYPE} topic to replay in {source.path}; it holds: '
            f'{available or "no channels"}{damage}']))
    shared = _sharing_a_namespace(chosen)
    if shared:
        raise ReplayError(f'the wrench topics {" and ".join(shared)} are in one namespace, so '
                          'their outputs would be mixed on the same topics; replay one at a '
                          'time with --topic')
    total = None
    if counts is not None:
        total = sum(count for channel_id, count in counts.items()
                    if channel_id in channels and channels[channel_id].topic in chosen)
    return chosen, warnings, total


def _sharing_a_namespace(topics: Sequence[str]) -> List[str]:
    """Return the first two of ``topics`` whose outputs would land on the same topics."""
    seen: Dict[str, str] = {}
    for topic in topics:
        namespace = output_topic(topic, '')
        if namespace in seen:
            return [seen[namespace], topic]
        seen[namespace] = topic
    return []


def _csv_row(index: int, raw, force, moment, frame_id, stamp_ns, outcome) -> list:
    """Return one CSV row (empty cells where there is no value)."""
    row = [index, raw.topic, stamp_ns, raw.log_time_ns, frame_id, *force, *moment]
    result = outcome.result
    if result is None:
        return row + [outcome.error.split(':')[0], outcome.error] + [''] * (
            len(CSV_COLUMNS) - len(row) - 2)
    row += ['solved' if result.converged else 'not converged', result.message,
            result.iterations, result.residual_norm, 1e3 * result.solve_time_s]
    if not result.converged:
        return row + [''] * (len(CSV_COLUMNS) - len(row))
    row += messages.joint_positions(result)
    row += result.end_disk_position.tolist() + result.end_disk_quaternion_xyzw.tolist()
    compliance = getattr(result, 'compliance', None)
    row += ([float(v) for v in compliance.eigenvalues] if compliance is not None
            else [''] * 6)
    return row


def check_output(path: Union[str, Path], what: str) -> None:
    """
    Make sure ``path`` can be written before any input is read; OutputError if not.

    Creates the missing folders (as the writers would) and a probe file next to ``path``,
    so a read-only folder, a file in the way or a folder given as ``path`` are found.
    """
    reason = unwritable_reason(path)
    if reason is not None:
        raise OutputError(f'cannot write the {what} {path}: {reason}')


def _same_file(first: Path, second: Path) -> bool:
    """Tell whether two paths name one file: the same path, a symbolic or a hard link."""
    if first.resolve() == second.resolve():
        return True
    try:
        return os.path.samefile(first, second)
    except OSError:   # one of them does not exist (yet): then they are not one file
        return False


def check_distinct(input_path: Union[str, Path],
                   outputs: Sequence[Tuple[str, Union[str, Path, None]]]) -> None:
    """
    Raise OutputError when an output is the input file or another output (links included).

    ``outputs``: (what, path) pairs, a None or empty path being no output. Opening an
    output for writing truncates it: the input would be destroyed before it is read, two
    outputs would overwrite each other.
    """
    named = [('input', Path(input_path))]
    named += [(what, Path(path)) for what, path in outputs if path]
    for position, (what, path) in enumerate(named):
        for other_what, other in named[:position]:
            if _same_file(path, other):
                raise OutputError(f'the {what} {path} is the same file as the {other_what} '
                                  f'{other}: give each output its own path')


def replay(input_path: Union[str, Path], output_path: Union[str, Path], *,
           topics: Optional[Sequence[str]] = None,
           params_path: Union[str, Path, None] = None, compliance: bool = True,
           backbones: bool = False, csv_path: Union[str, Path, None] = None,
           progress: Optional[IO[str]] = None, flush_every_messages: int = 1000,
           flush_every_s: float = 2.0, plot_samples: Collection[int] = (),
           other_outputs: Sequence[Tuple[str, Union[str, Path]]] = ()) -> ReplaySummary:
    """
    Replay ``input_path`` into ``output_path``; return the summary.

    ReplayError when nothing can be replayed (OutputError when an output cannot be
    written: checked before the input is read). A write error during the replay ends it
    with ``summary.output_error`` or ``summary.output_status.lost`` set. Ctrl-C (SIGINT;
    in the main thread it is taken between two messages, see ``interrupts``) or a
    KeyboardInterrupt stops the replay early: the output MCAP (and CSV) are still
    finalized, and ``summary.interrupted`` is True. ``plot_samples``: message indices kept
    in ``summary.series`` whatever its thinning (ValueError when one is negative, or
    beyond the input's messages). ``other_outputs``: (what, path) of files the caller
    writes afterwards (the plot), checked with the others before the input is read.
    """
    if Path(input_path).is_dir():
        raise ReplayError(f'{input_path} is a folder, not an MCAP file')
    if not Path(input_path).is_file():
        raise ReplayError(f'no such MCAP file: {input_path}')
    outputs = [('output MCAP', output_path), ('CSV', csv_path), *other_outputs]
    check_distinct(input_path, outputs)
    for what, path in outputs:
        if path:
            check_output(path, what)
    negative = sorted(index for index in plot_samples if index < 0)
    if negative:
        raise ValueError(f'plot samples are message indices >= 0, got {negative}')
    source = McapSource(input_path)
    chosen, warnings, total = select_topics(source, topics)
    if total is not None and any(index >= total for index in plot_samples):
        beyond = sorted(index for index in plot_samples if index >= total)
        raise ValueError(f"plot samples {beyond} are beyond the input's {total} messages "
                         f'(indices 0..{total - 1})')
    settings = TranslatorSettings.from_params_file(params_path)
    params = settings.params
    source = McapSource(input_path, topics=chosen)
    processors = {topic: WrenchProcessor(params, settings, compliance=compliance,
                                         backbones=backbones) for topic in chosen}
    summary = ReplaySummary(source.report, chosen, warnings, total=total)
    summary.series.keep = frozenset(plot_samples)
    decoders = Decoders()
    bar = Progress(progress, total) if progress is not None else None
    started = time.perf_counter()
    first_stamp_ns = None
    try:
        csv_file = open(csv_path, 'w', newline='') if csv_path else None
        log = McapLog(output_path, flush_every_messages=flush_every_messages,
                      flush_every_s=flush_every_s, if_exists='overwrite')
    except OSError as error:
        raise OutputError(f'cannot write {error.filename or output_path}: {error}') from None
    with deferred_sigint() as interrupt:
        try:
            table = csv.writer(csv_file) if csv_file else None
            if table:
                table.writerow(CSV_COLUMNS)
            for topic in chosen:
                log.register(topic, messages.WRENCH_TYPE, qos='sensor_data')
            try:
                for index, raw in enumerate(source.messages()):
                    if interrupt.requested:
                        summary.interrupted = True
                        break
                    summary.messages += 1
                    log.write_serialized(raw.topic, messages.WRENCH_TYPE, raw.data,
                                         raw.log_time_ns, raw.publish_time_ns)
                    try:
                        force, moment, frame_id, stamp = messages.wrench_from_message(
                            decoders.decode(raw))
                    except (ValueError, AttributeError, TypeError) as error:
                        summary.undecodable += 1
                        summary.warn(f'message {index} on {raw.topic}: {error}')
                        if table:
                            row = ([index, raw.topic, '', raw.log_time_ns, ''] + [''] * 6
                                   + ['undecodable', str(error)])
                            table.writerow(row + [''] * (len(CSV_COLUMNS) - len(row)))
                        continue
                    outcome = processors[raw.topic].process(force, moment, frame_id, stamp)
                    for name, type_name, message in outcome.outputs:
                        log.write(output_topic(raw.topic, name), type_name, message,
                                  raw.log_time_ns, raw.log_time_ns)
                    stamp_ns = messages.stamp_to_ns(stamp)
                    result = outcome.result
                    if result is None:
                        summary.rejected += 1
                    elif not result.converged:
                        summary.not_converged += 1
                        summary.solve_times.add(result.solve_time_s)
                    else:
                        summary.solved += 1
                        summary.solve_times.add(result.solve_time_s)
                        first_stamp_ns = stamp_ns if first_stamp_ns is None else first_stamp_ns
                        joints = messages.joint_positions(result)
                        position = result.end_disk_position.tolist()
                        summary.converged(joints, position)
                        wrench = np.concatenate([result.force, result.moment])
                        summary.series.add(index, 1e-9 * (stamp_ns - first_stamp_ns), joints,
                                           position, wrench)
                    if table:
                        table.writerow(_csv_row(index, raw, force, moment, frame_id,
                                                stamp_ns, outcome))
                    if bar:
                        bar.update(summary.messages)
                    if not log.status().ok:
                        summary.output_error = f'output MCAP: {log.status().message}'
                        break
            except KeyboardInterrupt:
                summary.interrupted = True
            except OSError as error:   # the CSV (the MCAP writer reports through its status)
                summary.output_error = f'cannot write {error.filename or csv_path}: {error}'
        finally:
            summary.output_status = log.close()
            if csv_file:
                try:
                    csv_file.close()
                except OSError as error:
                    summary.output_error = summary.output_error or f'CSV {csv_path}: {error}'
            if bar:
                bar.close(summary.messages)
            summary.wall_s = time.perf_counter() - started
    return summary


def main_replay(args) -> int:
    """Run ``python -m msg_tools replay`` with parsed ``args``; return the exit code."""
    stream = sys.stderr if (args.progress == 'always' or (
        args.progress == 'auto' and sys.stderr.isatty())) else None
    try:
        for option, value in (('--out', args.out), ('--csv', args.csv), ('--plot', args.plot)):
            if value is not None and not value.strip():
                raise ValueError(f'{option} needs a file name, got {value!r}')
        if args.plot:
            check_plot_path(args.plot)
        summary = replay(args.input, args.out, topics=args.topic, params_path=args.params,
                         compliance=not args.no_compliance, backbones=args.backbones,
                         csv_path=args.csv, progress=stream,
                         plot_samples=args.plot_samples or (),
                         other_outputs=[('plot', args.plot)] if args.plot else [])
    except (ReplayError, ValueError) as error:
        print(f'error: {error}', file=sys.stderr)
        return EXIT_USAGE
    for warning in summary.warnings:
        print(f'warning: {warning}', file=sys.stderr)
    if summary.warnings_dropped:
        print(f'warning: {summary.warnings_dropped} more such warnings not shown',
              file=sys.stderr)
    if not summary.input_report.complete:
        print(f'warning: {summary.input_report.describe()}', file=sys.stderr)
    print(summary.table())
    written = ', '.join(str(path) for path in (args.out, args.csv) if path)
    print(f'wrote {written}' if not summary.output_error else
          f'wrote {written} up to the write error')
    code = summary.exit_code()
    if args.plot:
        if summary.series.time_s:
            try:
                samples = plot_replay(summary.series, args.plot, params_path=args.params,
                                      samples=args.plot_samples)
                print(f'wrote {args.plot} (deflected shapes of messages {samples})')
            except ValueError as error:   # chosen messages that did not converge
                print(f'error: no plot written: {error}', file=sys.stderr)
                if code in (EXIT_OK, EXIT_DAMAGED_INPUT):
                    code = EXIT_USAGE
        else:
            print('warning: nothing converged, no plot written', file=sys.stderr)
    if summary.output_error or summary.exit_code() == EXIT_USAGE:
        status = summary.output_status
        print('error: ' + '; '.join(
            part for part in (summary.output_error,
                              f'output MCAP {status.describe()}' if status is not None else '')
            if part), file=sys.stderr)
    elif code == EXIT_NOTHING_SOLVED:
        print(f'error: nothing could be solved: {summary.messages} messages read, '
              f'{summary.undecodable} undecodable, {summary.rejected} rejected, '
              f'{summary.not_converged} not converged', file=sys.stderr)
    return code
