"""
Replay recorded wrenches through the solver offline: what translator_node would have published.

Reads the WrenchStamped messages of an MCAP (salvaging a damaged file), handles each as the
node does (``processing.WrenchProcessor``: same checks, frames, warm-started solver, time
limit) and writes a new MCAP holding the input messages and every output the node publishes
(end_disk_pose, bending_angles, compliance_eigenvalues, compliance, /diagnostics and, on
request, backbones) with header stamps equal to the input stamps and log times equal to the
input log times. Output topics take the input topic's namespace ('/robot/wrench' gives
'/robot/end_disk_pose'). Optionally a CSV row per message and a plot. No rclpy needed.
"""

import csv
from dataclasses import dataclass, field
import math
from pathlib import Path
import sys
import time
from typing import Dict, IO, List, Optional, Sequence, Tuple, Union

from cdr_translator.interface import messages
from cdr_translator.interface.processing import WrenchProcessor
from cdr_translator.interface.settings import TranslatorSettings
from msg_tools.mcap_log import McapLog
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


class ReplayError(ValueError):
    """The input cannot be replayed at all (no such file, no usable wrench topic)."""


@dataclass
class Series:
    """Time series of the converged messages, for the plots."""

    time_s: List[float] = field(default_factory=list)
    joints: List[List[float]] = field(default_factory=list)
    position: List[List[float]] = field(default_factory=list)
    index: List[int] = field(default_factory=list)
    wrench: List[np.ndarray] = field(default_factory=list)


@dataclass
class ReplaySummary:
    """Counts, timings and ranges of one replay."""

    input_report: ReadReport
    topics: List[str]
    warnings: List[str]
    messages: int = 0
    solved: int = 0
    not_converged: int = 0
    rejected: int = 0
    undecodable: int = 0
    solve_times_s: List[float] = field(default_factory=list)
    wall_s: float = 0.0
    interrupted: bool = False
    series: Series = field(default_factory=Series)

    @property
    def throughput(self) -> float:
        """Messages per second of wall time (reading, solving and writing)."""
        return self.messages / self.wall_s if self.wall_s > 0 else math.nan

    def table(self) -> str:
        """Return the summary table printed at the end of a replay."""
        rows = [('input', self.input_report.describe()),
                ('wrench topics', ', '.join(self.topics)),
                ('messages', str(self.messages)),
                ('solved (converged)', str(self.solved)),
                ('not converged', str(self.not_converged)),
                ('rejected (bad input)', str(self.rejected)),
                ('undecodable', str(self.undecodable))]
        if self.solve_times_s:
            p50, p90, p99 = np.percentile(1e3 * np.array(self.solve_times_s), [50, 90, 99])
            rows.append(('solve time ms p50/p90/p99/max',
                         f'{p50:.3f} / {p90:.3f} / {p99:.3f} / '
                         f'{1e3 * max(self.solve_times_s):.3f}'))
        if self.series.joints:
            joints = np.degrees(np.array(self.series.joints))
            for column, name in enumerate(messages.JOINT_NAMES):
                rows.append((f'{name} deg min..max',
                             f'{joints[:, column].min():.3f} .. {joints[:, column].max():.3f}'))
            position = 1e3 * np.array(self.series.position)
            for column, axis in enumerate('xyz'):
                rows.append((f'end disk {axis} mm min..max',
                             f'{position[:, column].min():.3f} .. '
                             f'{position[:, column].max():.3f}'))
        rows.append(('wall time s', f'{self.wall_s:.3f}'))
        rows.append(('throughput msg/s', f'{self.throughput:.1f}'))
        if self.interrupted:
            rows.append(('interrupted', 'yes (Ctrl-C): the output holds what was done'))
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
    """Return the node's output topic ``name`` in the namespace of ``input_topic``."""
    if name.startswith('/'):
        return name
    namespace = input_topic[:-len(messages.WRENCH_TOPIC)] if input_topic.endswith(
        messages.WRENCH_TOPIC) else '/'
    if not namespace.endswith('/'):
        namespace = '/'
    return namespace + name


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
        raise ReplayError('; '.join(warnings + [
            f'no {messages.WRENCH_TYPE} topic to replay in {source.path}; it holds: '
            f'{available or "no channels"}']))
    total = None
    if counts is not None:
        total = sum(count for channel_id, count in counts.items()
                    if channel_id in channels and channels[channel_id].topic in chosen)
    return chosen, warnings, total


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


def replay(input_path: Union[str, Path], output_path: Union[str, Path], *,
           topics: Optional[Sequence[str]] = None,
           params_path: Union[str, Path, None] = None, compliance: bool = True,
           backbones: bool = False, csv_path: Union[str, Path, None] = None,
           progress: Optional[IO[str]] = None, flush_every_messages: int = 1000,
           flush_every_s: float = 2.0) -> ReplaySummary:
    """
    Replay ``input_path`` into ``output_path``; return the summary.

    ReplayError when nothing can be replayed. A KeyboardInterrupt stops the replay early:
    the output MCAP (and CSV) are still finalized, and ``summary.interrupted`` is True.
    """
    if not Path(input_path).is_file():
        raise ReplayError(f'no such MCAP file: {input_path}')
    source = McapSource(input_path)
    chosen, warnings, total = select_topics(source, topics)
    if Path(output_path).resolve() == Path(input_path).resolve():
        raise ReplayError('the output file must not be the input file')
    settings = TranslatorSettings.from_params_file(params_path)
    params = settings.params
    source = McapSource(input_path, topics=chosen)
    processors = {topic: WrenchProcessor(params, settings, compliance=compliance,
                                         backbones=backbones) for topic in chosen}
    summary = ReplaySummary(source.report, chosen, warnings)
    decoders = Decoders()
    bar = Progress(progress, total) if progress is not None else None
    started = time.perf_counter()
    first_stamp_ns = None
    csv_file = open(csv_path, 'w', newline='') if csv_path else None
    try:
        table = csv.writer(csv_file) if csv_file else None
        if table:
            table.writerow(CSV_COLUMNS)
        with McapLog(output_path, flush_every_messages=flush_every_messages,
                     flush_every_s=flush_every_s) as log:
            for topic in chosen:
                log.register(topic, messages.WRENCH_TYPE, qos='sensor_data')
            try:
                for index, raw in enumerate(source.messages()):
                    summary.messages += 1
                    log.write_serialized(raw.topic, messages.WRENCH_TYPE, raw.data,
                                         raw.log_time_ns, raw.publish_time_ns)
                    try:
                        force, moment, frame_id, stamp = messages.wrench_from_message(
                            decoders.decode(raw))
                    except (ValueError, AttributeError, TypeError) as error:
                        summary.undecodable += 1
                        summary.warnings.append(f'message {index} on {raw.topic}: {error}')
                        if table:
                            table.writerow([index, raw.topic, '', raw.log_time_ns, '']
                                           + [''] * 6 + ['undecodable', str(error)])
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
                        summary.solve_times_s.append(result.solve_time_s)
                    else:
                        summary.solved += 1
                        summary.solve_times_s.append(result.solve_time_s)
                        first_stamp_ns = stamp_ns if first_stamp_ns is None else first_stamp_ns
                        series = summary.series
                        series.time_s.append(1e-9 * (stamp_ns - first_stamp_ns))
                        series.joints.append(messages.joint_positions(result))
                        series.position.append(result.end_disk_position.tolist())
                        series.index.append(index)
                        series.wrench.append(np.concatenate([result.force, result.moment]))
                    if table:
                        table.writerow(_csv_row(index, raw, force, moment, frame_id,
                                                stamp_ns, outcome))
                    if bar:
                        bar.update(summary.messages)
            except KeyboardInterrupt:
                summary.interrupted = True
    finally:
        if csv_file:
            csv_file.close()
        if bar:
            bar.close(summary.messages)
        summary.wall_s = time.perf_counter() - started
    return summary


def main_replay(args) -> int:
    """Run ``python -m msg_tools replay`` with parsed ``args``; return the exit code."""
    stream = sys.stderr if (args.progress == 'always' or (
        args.progress == 'auto' and sys.stderr.isatty())) else None
    try:
        summary = replay(args.input, args.out, topics=args.topic, params_path=args.params,
                         compliance=not args.no_compliance, backbones=args.backbones,
                         csv_path=args.csv, progress=stream)
    except (ReplayError, ValueError) as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    for warning in summary.warnings:
        print(f'warning: {warning}', file=sys.stderr)
    if not summary.input_report.complete:
        print(f'warning: {summary.input_report.describe()}', file=sys.stderr)
    print(summary.table())
    print(f'wrote {args.out}' + (f', {args.csv}' if args.csv else ''))
    if args.plot:
        if summary.series.time_s:
            from msg_tools.plots import plot_replay  # matplotlib only when asked for
            samples = plot_replay(summary.series, args.plot, params_path=args.params,
                                  samples=args.plot_samples)
            print(f'wrote {args.plot} (deflected shapes of messages {samples})')
        else:
            print('warning: nothing converged, no plot written', file=sys.stderr)
    if summary.interrupted:
        return 130
    return 0 if summary.input_report.complete else 1
