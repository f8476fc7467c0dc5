"""
Replay a long recording on a Dask cluster: log-time windows solved in parallel, merged in order.

``replay_on_dask`` cuts the replayed messages into windows of consecutive log times
(``log_time_window``), each warmed up on the messages just before it. Each window is one
Dask task, ``replay_window``: a whole ``replay.replay`` of the input restricted to that
window, written into its own part (MCAP, and CSV when asked) in a temporary folder beside
the output. This process merges the parts into the output in window order, so in log-time
order, each as soon as it and the ones before it are done (``part_merge``: records copied
as stored), and combines the windows' summaries (``ReplaySummary.merge``).

The cluster is the atlas's (``cdr_translator.robot.atlas.dask_client``): a LocalCluster of
single-threaded worker processes that ignore Ctrl-C, or a running scheduler whose workers
can read the input and the output's folder (a shared file system). The output equals a
one-process replay within the solver's accuracy: a window's first solves start from the
warm-up's state, not from the exact state the sequential replay reaches there. The
aggregated /diagnostics arrays are written at the same messages as in a one-process replay
(``replay_diagnostics``: at multiples of the period in log time; only the last window
closes), and their counters (received, solved, ...) count from the start of the input: the
merge adds the earlier windows' counts to them (``part_merge.continue_counters``). The
period values (rates, worst residual, answered in the period) of the first array after a
window's start cover that window's messages only.
"""

import csv
from pathlib import Path
import shutil
import tempfile
import time
from typing import Any, Collection, IO, List, Mapping, Optional, Sequence, Tuple, Union

from cdr_translator.console import deferred_sigint
from cdr_translator.interface import messages
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.robot.atlas import dask_client
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import McapSource
from msg_tools.errors import OutputError, ReplayError
from msg_tools.log_time_window import LogTimeWindow
from msg_tools.output_paths import check_distinct, check_output
from msg_tools.part_merge import PartMerger
from msg_tools.replay import Progress, replay
from msg_tools.replay_csv import CSV_COLUMNS
from msg_tools.replay_summary import fidelity_text, REPLAY_RECORD, ReplaySummary
from msg_tools.replay_topics import select_topics

#: Fewest messages per window: shorter windows spend too much on warm-up and reading.
MIN_WINDOW_MESSAGES = 2000

#: Windows per worker: a little slack to even out windows that solve slower.
WINDOWS_PER_WORKER = 2

#: How often the wait for windows looks for a Ctrl-C (s).
POLL_S = 0.05


def plan_windows(start_ns: int, end_ns: int, count: int) -> List[LogTimeWindow]:
    """
    Return ``count`` windows of equal log-time span covering ``start_ns``..``end_ns``.

    The first is open below and the last above, so every message lands in exactly one.
    """
    if count < 1:
        raise ValueError(f'window count must be at least 1, got {count}')
    span = end_ns - start_ns + 1
    cuts = [start_ns + (span * k) // count for k in range(1, count)]
    starts: List[Optional[int]] = [None, *cuts]
    stops: List[Optional[int]] = [*cuts, None]
    return [LogTimeWindow(start, stop) for start, stop in zip(starts, stops)]


def replay_window(input_path: str, part_path: str, csv_path: Optional[str],
                  window: LogTimeWindow, topics: List[str], params_path: Optional[str],
                  compliance: bool, backbones: bool, plot_samples: Collection[int],
                  parameters: Optional[Mapping[str, Any]] = None) -> ReplaySummary:
    """Replay the messages of ``window`` into the part ``part_path`` (a Dask task)."""
    return replay(input_path, part_path, topics=topics, params_path=params_path,
                  compliance=compliance, backbones=backbones, csv_path=csv_path,
                  flush_every_messages=0, flush_every_s=0.0, plot_samples=plot_samples,
                  window=window, parameters=parameters)


def _check_outputs(input_path: Union[str, Path],
                   outputs: Sequence[Tuple[str, Union[str, Path, None]]]) -> None:
    """Refuse what ``replay`` refuses before reading: a missing input, unwritable outputs."""
    if not Path(input_path).is_file():
        raise ReplayError(f'no such MCAP file: {input_path}' if not Path(input_path).exists()
                          else f'{input_path} is not a regular file, so not an MCAP file')
    check_distinct(input_path, outputs)
    for what, path in outputs:
        if path:
            check_output(path, what)


def replay_on_dask(input_path: Union[str, Path], output_path: Union[str, Path], *,
                   workers: Optional[int] = None, scheduler: Optional[str] = None,
                   topics: Optional[Sequence[str]] = None,
                   params_path: Union[str, Path, None] = None, compliance: bool = True,
                   backbones: bool = False, csv_path: Union[str, Path, None] = None,
                   progress: Optional[IO[str]] = None, plot_samples: Collection[int] = (),
                   other_outputs: Sequence[Tuple[str, Union[str, Path]]] = (),
                   window_messages: int = MIN_WINDOW_MESSAGES, client: Any = None,
                   parameters: Optional[Mapping[str, Any]] = None) -> ReplaySummary:
    """
    Replay as ``replay.replay`` does, in log-time windows on Dask workers; return the summary.

    The windows run on ``client`` (left open) if given, else on the cluster at
    ``scheduler``, else on a new LocalCluster of ``workers`` processes (ValueError below 1;
    OSError or TimeoutError when the scheduler cannot be reached). ``window_messages``:
    fewest messages per window. Ctrl-C stops at the windows merged so far (the outputs are
    finalized, ``summary.interrupted`` is True).
    """
    if workers is not None and workers < 1:
        raise ValueError(f'--workers must be at least 1, got {workers}')
    _check_outputs(input_path, [('output MCAP', output_path), ('CSV', csv_path),
                                *other_outputs])
    settings = TranslatorSettings.from_params_file(params_path)
    if parameters:  # refused here, not in every window
        settings = settings.with_values(**parameters)
    source = McapSource(input_path)
    chosen, warnings, total, _ = select_topics(source, topics)
    span = source.channel_overview()[3]
    if total is not None and any(not 0 <= index < total for index in plot_samples):
        raise ValueError(f'plot samples are message indices 0..{total - 1}, '
                         f'got {sorted(plot_samples)}')
    started = time.perf_counter()
    owned = client is None
    cluster = None
    if owned:
        client, cluster = dask_client(workers, scheduler)
    parts = Path(tempfile.mkdtemp(prefix='.replay-parts-', dir=Path(output_path).parent))
    summary = ReplaySummary(source.report, chosen, warnings, total=total,
                            fidelity=fidelity_text(settings.fidelity,
                                                   settings.max_position_error,
                                                   settings.max_angle_error))
    summary.series.keep = frozenset(plot_samples)
    futures: List[Any] = []   # distributed.Future (distributed is the atlas's optional extra)
    try:
        count = max(1, len(client.scheduler_info(n_workers=-1)['workers']))
        windows = [LogTimeWindow()]
        if span:
            windows = plan_windows(*span, min(WINDOWS_PER_WORKER * count, max(
                1, (total or 0) // max(window_messages, 1))))
        futures = [
            client.submit(replay_window, str(input_path), str(parts / f'{k}.mcap'),
                          str(parts / f'{k}.csv') if csv_path else None, window, chosen,
                          str(params_path) if params_path else None, compliance, backbones,
                          sorted(plot_samples), dict(parameters or {}), pure=False,
                          key=f'replay-window-{k}-{time.time_ns()}')
            for k, window in enumerate(windows)]
        _merge(futures, parts, output_path, csv_path, summary, progress, total)
    finally:
        for future in futures:
            future.cancel()
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()
        shutil.rmtree(parts, ignore_errors=True)
    summary.wall_s = time.perf_counter() - started
    return summary


def _merge(futures: List[Any], parts: Path, output_path: Union[str, Path],
           csv_path: Union[str, Path, None], summary: ReplaySummary,
           progress: Optional[IO[str]], total: Optional[int]) -> None:
    """Merge the windows' parts into the outputs in window order, as they complete."""
    try:
        table = open(csv_path, 'w', newline='') if csv_path else None
        log = McapLog(output_path, if_exists='overwrite')
    except OSError as error:
        raise OutputError(f'cannot write {error.filename or output_path}: {error}') from None
    bar = Progress(progress, total) if progress is not None else None
    merger = PartMerger(log, table)
    with deferred_sigint() as interrupt:
        try:
            if table:
                csv.writer(table).writerow(CSV_COLUMNS)
            for topic in summary.topics:
                log.register(topic, messages.WRENCH_TYPE, qos='sensor_data')
            for k, future in enumerate(futures):
                while not future.done() and not interrupt.requested:
                    time.sleep(POLL_S)   # not done yet: look for a Ctrl-C again
                if interrupt.requested:
                    summary.interrupted = True
                    break
                summary.merge(future.result())
                future.release()
                merger.merge(parts / f'{k}.mcap', parts / f'{k}.csv' if table else None)
                (parts / f'{k}.mcap').unlink()
                if bar:
                    bar.update(summary.messages, force=True)
                if summary.stopped_early or not log.status().ok:
                    summary.output_error = summary.output_error or (
                        f'output MCAP: {log.status().message}' if not log.status().ok else '')
                    break
        except KeyboardInterrupt:
            summary.interrupted = True
        except OSError as error:
            summary.output_error = f'cannot write {error.filename or csv_path}: {error}'
        finally:
            merger.finish()   # the last merged window's closing arrays
            log.add_metadata(REPLAY_RECORD, summary.record())   # 'partial' if stopped early
            summary.output_status = log.close()
            if table:
                table.close()
            if bar:
                bar.close(summary.messages)
