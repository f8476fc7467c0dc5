"""
Replay and info hold no per-message lists: traced peak memory against length.

The 1 M-message peak-RSS measurement is ``python -m bench.replay_memory``
(bench/results/replay_memory.md); here the Python heap (tracemalloc) of a short and a
five-times-longer input is compared, with the bounded windows (plotted series, duplicate
window) made small so that what is left would be a per-message list. (What does grow is
per chunk: the MCAP writer keeps one chunk index per 1000 output records for the summary.)
"""

import tracemalloc

from cdr_translator.interface import messages
from cdr_wire import reader
from cdr_wire.mcap_log import McapLog
from msg_tools import replay_summary
from msg_tools.info import describe
from msg_tools.replay import replay
from msg_tools.synth import DEFAULT_START_NS


def _input(path, count):
    """Every 10th wrench solvable (0.5-5 N), the others above max_force (rejected)."""
    with McapLog(path, flush_every_messages=1000, flush_every_s=0.0) as log:
        for k in range(count):
            force = 0.5 * (1 + (k // 100) % 10) if k % 10 == 0 else 1e6
            stamp = DEFAULT_START_NS + 10_000_000 * k
            log.write('/wrench', messages.WRENCH_TYPE, messages.wrench_message(
                [force, 0.0, 0.0], [0.0, 0.0, 0.0], '', messages.stamp_from_ns(stamp)),
                log_time_ns=stamp)


def _peak(function) -> int:
    """Return the traced peak (bytes) above the start while ``function()`` runs."""
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        function()
        return tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()


def test_replay_and_info_peaks_do_not_grow_with_the_message_count(tmp_path, monkeypatch):
    """
    4000 more messages (400 more solves) add < 100 kB to the peak (was ~0.9 kB each).

    Both runs are long enough (50 and 90 s of log time) for the output's buffers to have
    filled once: the first chunk and the aggregated /diagnostics arrays, one a second, in it.
    """
    monkeypatch.setattr(replay_summary, 'SERIES_LIMIT', 50)
    monkeypatch.setattr(reader, 'DUPLICATE_WINDOW', 200)
    short, long = tmp_path / 'short.mcap', tmp_path / 'long.mcap'
    _input(short, 5000)
    _input(long, 9000)

    def run(path):
        summary = replay(path, tmp_path / 'out.mcap', compliance=False, flush_every_s=0.0)
        assert summary.solved == summary.messages // 10 and summary.rejected > 0
        assert len(summary.series.index) <= 51

    run(short)   # warm-up: kernels, decoders, caches,
    run(long)    # and whatever fills once on a first long run (seen after the robot tests)
    replay_growth = _peak(lambda: run(long)) - _peak(lambda: run(short))
    info_growth = _peak(lambda: describe(long)) - _peak(lambda: describe(short))
    assert replay_growth < 100_000, replay_growth
    assert info_growth < 100_000, info_growth
