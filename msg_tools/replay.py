"""
Replay recorded wrenches through the solver offline: what translator_node would have published.

Reads the WrenchStamped messages of an MCAP (salvaging a damaged file), handles each as the
node does (``wrench_processing.WrenchProcessor``: same checks, frames, warm-started solver,
time limit) and writes a new MCAP holding the input messages and every output the node
publishes (end_disk_pose, bending_angles, compliance_eigenvalues, compliance, solve_status
and, on request, backbones) with header stamps equal to the input stamps and log times equal
to the input log times, and one aggregated /diagnostics array every ``diagnostics_period_s``
of log time (``msg_tools.replay_diagnostics``). Output topics take the input topic's
namespace ('/robot/wrench' gives '/robot/end_disk_pose'). Measured end-disk poses give the
node's wrench estimates (``msg_tools.replay_estimates``). Optionally a CSV row per input
message (``msg_tools.replay_csv``) and a plot. No rclpy needed.
Wrenches are read in blocks of up to BLOCK_SIZE messages and solved together where the
processor batches (``WrenchProcessor.process_many``: one ``solve_many``, the same outputs);
measured poses read meanwhile join the block and are answered in their place.

Memory stays bounded however long the input: messages stream through and the statistics
are running ones (``msg_tools.replay_summary``). The topics replayed are chosen by
``msg_tools.replay_topics``, the outputs checked by ``msg_tools.output_paths`` before the
input is read; the command line is ``python -m msg_tools replay`` (``msg_tools.__main__``).
"""

import csv
import math
from pathlib import Path
import time
from typing import (Any, Callable, Collection, Dict, IO, List, Mapping, Optional, Sequence,
                    Tuple, Union)

from cdr_translator.console import deferred_sigint
from cdr_translator.interface import messages
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import Outcome, Wrench, WrenchProcessor
from cdr_wire.cdr_codecs import ShippedDecoders
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource, RawMessage
from msg_tools.errors import OutputError, ReplayError
from msg_tools.log_time_window import LogTimeWindow, warm_up, window_messages
from msg_tools.output_paths import check_distinct, check_output
from msg_tools.replay_csv import CSV_COLUMNS, csv_row, wrench_row
from msg_tools.replay_diagnostics import ReplayDiagnostics
from msg_tools.replay_estimates import pose_processors, register_poses, replay_pose
from msg_tools.replay_summary import fidelity_text, REPLAY_RECORD, ReplaySummary
from msg_tools.replay_topics import output_topic, select_topics
import numpy as np

#: Wrench messages of one topic solved together at most (``WrenchProcessor.process_many``):
#: enough that a block's Python overhead is shared, few enough that memory and the work
#: lost to an interrupt stay small.
BLOCK_SIZE = 256


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


class _Block:
    """
    Messages read ahead: wrenches of one topic solved together, everything written in order.

    ``WrenchProcessor.process_many`` solves a block's base-frame wrenches by one
    ``solve_many``; measured poses read between them join the block (their estimates
    follow the pose stream alone, so they wait without changing), so that a pose stream
    does not cut the wrenches into blocks of one. Each message is then written with its
    outputs, its CSV row and its place in the summary, exactly as if handled alone.
    """

    def __init__(self, log: McapLog, table: Any, summary: ReplaySummary,
                 bar: Optional[Progress], processors: Dict[str, WrenchProcessor],
                 answer_pose: Callable[[int, RawMessage], None]) -> None:
        """
        Write to ``log`` and ``table`` (None: no CSV), count in ``summary``.

        ``answer_pose(index, raw)`` estimates and writes a measured pose.
        """
        self.log, self.table, self.summary, self.bar = log, table, summary, bar
        self.processors = processors
        self.answer_pose = answer_pose
        #: (index, message, its wrench; None for a measured pose), in the input's order
        self.pending: List[Tuple[int, RawMessage, Optional[Wrench]]] = []
        self.topic: Optional[str] = None  # of the wrenches pending

    def add(self, index: int, raw: RawMessage, wrench: Wrench) -> bool:
        """Take wrench message ``index``; False when a write failed (the replay ends)."""
        if ((self.topic is not None and self.topic != raw.topic)
                or len(self.pending) >= BLOCK_SIZE):
            if not self.flush():
                return False
        processor = self.processors[raw.topic]
        if processor.batches:
            self.pending.append((index, raw, wrench))
            self.topic = raw.topic
            return True
        if not self.flush():  # the poses read before it are answered first
            return False
        self._write_input(raw)  # then its outputs, as soon as solved
        self._write(index, raw, wrench, processor.process(*wrench))
        return self._log_ok()

    def add_pose(self, index: int, raw: RawMessage) -> bool:
        """Take measured pose ``index``; False when a write failed (the replay ends)."""
        if len(self.pending) >= BLOCK_SIZE and not self.flush():
            return False
        self.pending.append((index, raw, None))
        return True

    def flush(self) -> bool:
        """Solve, estimate and write the messages taken; False when a write failed."""
        if not self.pending:
            return True
        pending, self.pending = self.pending, []
        topic, self.topic = self.topic, None
        outcomes = iter(()) if topic is None else iter(self.processors[topic].process_many(
            [wrench for _, _, wrench in pending if wrench is not None]))
        for index, raw, wrench in pending:
            if wrench is None:
                self.answer_pose(index, raw)
            else:
                self._write_input(raw)
                self._write(index, raw, wrench, next(outcomes))
            if not self._log_ok():
                return False
        return True

    def _log_ok(self) -> bool:
        """Whether the output MCAP is still written; else say why in the summary."""
        if not self.log.ok:
            self.summary.output_error = f'output MCAP: {self.log.status().message}'
        return self.log.ok

    def _write_input(self, raw: RawMessage) -> None:
        """Write and count an input message."""
        self.summary.messages += 1
        self.log.write_serialized(raw.topic, messages.WRENCH_TYPE, raw.data, raw.log_time_ns,
                                  raw.publish_time_ns)

    def undecodable(self, index: int, raw: RawMessage, error: Exception) -> None:
        """Write and count a message that is no WrenchStamped."""
        self._write_input(raw)
        self.summary.undecodable += 1
        self.summary.warn(f'message {index} on {raw.topic}: {error}')
        if self.table:
            self.table.writerow(csv_row({'index': index, 'topic': raw.topic,
                                         'log_time_ns': raw.log_time_ns,
                                         'status': 'undecodable', 'message': str(error)}))
        if self.bar:
            self.bar.update(self.summary.messages)

    def _write(self, index: int, raw: RawMessage, wrench: Wrench, outcome: Outcome) -> None:
        """Write the outputs and CSV row of a message written; count them in the summary."""
        summary, log = self.summary, self.log
        force, moment, frame_id, stamp = wrench
        for name, type_name, message in outcome.outputs:
            log.write(output_topic(raw.topic, name), type_name, message, raw.log_time_ns,
                      raw.log_time_ns)
        stamp_ns = messages.stamp_to_ns(stamp)
        result = outcome.result
        if result is None:
            summary.rejected += 1
            summary.series.add_gap(stamp_ns, 'rejected')
        elif not result.converged:
            summary.not_converged += 1
            summary.series.add_gap(stamp_ns, 'not converged')
            summary.solve_times.add(result.solve_time_s)
        else:
            summary.solved += 1
            summary.count_level(result.fidelity)
            summary.solve_times.add(result.solve_time_s)
            if summary.first_stamp_ns is None:
                summary.first_stamp_ns = stamp_ns
            joints = messages.joint_positions(result)
            position = result.end_disk_position.tolist()
            summary.converged(joints, position)
            summary.series.add(index, 1e-9 * (stamp_ns - summary.first_stamp_ns), joints,
                               position, np.concatenate([result.force, result.moment]))
        if self.table:
            self.table.writerow(wrench_row(index, raw, force, moment, frame_id, stamp_ns,
                                           outcome))
        if self.bar:
            self.bar.update(summary.messages)


def replay(input_path: Union[str, Path], output_path: Union[str, Path], *,
           topics: Optional[Sequence[str]] = None,
           params_path: Union[str, Path, None] = None, compliance: bool = True,
           backbones: bool = False, csv_path: Union[str, Path, None] = None,
           progress: Optional[IO[str]] = None, flush_every_messages: int = 1000,
           flush_every_s: float = 2.0, plot_samples: Collection[int] = (),
           other_outputs: Sequence[Tuple[str, Union[str, Path]]] = (),
           window: Optional[LogTimeWindow] = None,
           parameters: Optional[Mapping[str, Any]] = None) -> ReplaySummary:
    """
    Replay ``input_path`` into ``output_path``; return the summary.

    ReplayError when nothing can be replayed (OutputError when an output cannot be
    written: checked before the input is read). A write error during the replay ends it
    with ``summary.output_error`` or ``summary.output_status.lost`` set. Ctrl-C (SIGINT;
    in the main thread it is taken between two messages, the messages read before it
    answered; see ``interrupts``) or a KeyboardInterrupt (the block in hand is lost)
    stops the replay early: the output MCAP (and CSV) are still finalized, and
    ``summary.interrupted`` is True. ``plot_samples``: message indices kept
    in ``summary.series`` whatever its thinning (ValueError when one is negative, or
    beyond the input's messages). ``other_outputs``: (what, path) of files the caller
    writes afterwards (the plot), checked with the others before the input is read.
    ``window``: replay only the messages logged in it (``log_time_window``).
    ``parameters``: translator_node parameter values over those of ``params_path`` (the
    estimate's, from the command line's flags), checked as the node checks them.
    """
    if Path(input_path).is_dir():
        raise ReplayError(f'{input_path} is a folder, not an MCAP file')
    if not Path(input_path).exists():
        raise ReplayError(f'no such MCAP file: {input_path}')
    if not Path(input_path).is_file():
        raise ReplayError(f'{input_path} is not a regular file, so not an MCAP file')
    outputs = [('output MCAP', output_path), ('CSV', csv_path), *other_outputs]
    check_distinct(input_path, outputs)
    for what, path in outputs:
        if path:
            check_output(path, what)
    negative = sorted(index for index in plot_samples if index < 0)
    if negative:
        raise ValueError(f'plot samples are message indices >= 0, got {negative}')
    source = McapSource(input_path)
    chosen, warnings, total, poses = select_topics(source, topics)
    if total is not None and any(index >= total for index in plot_samples):
        beyond = sorted(index for index in plot_samples if index >= total)
        raise ValueError(f"plot samples {beyond} are beyond the input's {total} messages "
                         f'(indices 0..{total - 1})')
    settings = TranslatorSettings.from_params_file(params_path)
    if parameters:
        settings = settings.with_values(**parameters)
    params = settings.params
    source = McapSource(input_path, topics=chosen + poses, check_data_crc=True)
    estimators = pose_processors(poses, settings)
    processors = {topic: WrenchProcessor(params, settings, compliance=compliance,
                                         backbones=backbones) for topic in chosen}
    diagnostics = ReplayDiagnostics(settings.diagnostics_period_s, processors, estimators)
    summary = ReplaySummary(source.report, chosen, warnings, total=total,
                            fidelity=fidelity_text(settings.fidelity,
                                                   settings.max_position_error,
                                                   settings.max_angle_error))
    summary.series.keep = frozenset(plot_samples)
    decoders = ShippedDecoders()

    def warm_wrench(raw: RawMessage) -> None:
        diagnostics.preceding(raw.log_time_ns)
        if raw.topic in processors:  # a measured pose's estimate warm-starts by itself
            warm_up(processors[raw.topic], decoders, raw)
    bar = Progress(progress, total) if progress is not None else None
    started = time.perf_counter()
    # Ctrl-C is deferred from before the outputs exist: once the output file is created, an
    # interrupt always ends in a finalized file and the summary's "interrupted"
    with deferred_sigint() as interrupt:
        try:
            csv_file = open(csv_path, 'w', newline='') if csv_path else None
            log = McapLog(output_path, flush_every_messages=flush_every_messages,
                          flush_every_s=flush_every_s, if_exists='overwrite')
        except OSError as error:
            raise OutputError(f'cannot write {error.filename or output_path}: '
                              f'{error}') from None
        try:
            table = csv.writer(csv_file) if csv_file else None
            if table:
                table.writerow(CSV_COLUMNS)
            for topic in chosen:
                log.register(topic, messages.WRENCH_TYPE, qos='sensor_data')
            register_poses(log, poses)
            block = _Block(log, table, summary, bar, processors, lambda index, raw: replay_pose(
                log, raw, estimators[raw.topic], decoders, summary, index, table))
            try:
                for index, raw in window_messages(source.messages(), window, warm_wrench):
                    if interrupt.requested:
                        summary.interrupted = True
                        block.flush()  # the messages read before it are answered
                        break
                    if diagnostics.due(raw.log_time_ns):
                        if not block.flush():   # the period's messages answered first
                            break
                        diagnostics.write(log, raw.log_time_ns)
                    if raw.topic in estimators:
                        if not block.add_pose(index, raw):
                            break
                        continue
                    try:
                        wrench = messages.wrench_from_message(decoders.decode(raw))
                    except (ValueError, AttributeError, TypeError) as error:
                        if not block.flush():
                            break
                        block.undecodable(index, raw, error)
                        continue
                    if not block.add(index, raw, wrench):
                        break
                else:
                    block.flush()
            except KeyboardInterrupt:
                summary.interrupted = True
            except OSError as error:   # the CSV (the MCAP writer reports through its status)
                summary.output_error = f'cannot write {error.filename or csv_path}: {error}'
        finally:
            diagnostics.close(log)   # the closing counts
            summary.settle()
            log.add_metadata(REPLAY_RECORD, summary.record())   # 'partial' if stopped early
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
