"""
Replay's model level, its CSV columns, its partial outputs and its plot.

``--fidelity`` and its budget as ``solve`` takes them, the level named in the summary, the
CSV and the plot; the verdict, unit and estimate columns of the CSV; an output that holds
only part of a replay marked so, and ``info`` saying so; the plot read as a newcomer would.
"""

import csv
import os
from pathlib import Path
import signal

from cdr_wire.reader import McapSource
from figure_checks import assert_readable
from interrupting import interrupt_processing_at
from msg_tools import synth
from msg_tools.__main__ import main
from msg_tools.info import describe
from msg_tools.plots import plot_replay, replay_figure, replay_shapes
from msg_tools.replay import replay
from msg_tools.replay_csv import CSV_COLUMNS
from msg_tools.replay_summary import REPLAY_RECORD
from msg_tools.replay_windows import replay_on_dask, replay_window
from msg_tools.synth_poses import check_noise, measure
import numpy as np
import pytest

#: The CSV columns of earlier releases, in their order: scripts read them by name and place.
EARLIER_COLUMNS = (
    ['index', 'topic', 'stamp_ns', 'log_time_ns', 'frame_id', 'fx_n', 'fy_n', 'fz_n',
     'mx_nm', 'my_nm', 'mz_nm', 'status', 'message', 'iterations', 'residual_norm',
     'solve_time_ms', 'pj_bending_rad', 'pj_direction_rad', 'dj_bending_rad',
     'dj_direction_rad', 'end_disk_rotation_rad', 'x_m', 'y_m', 'z_m', 'qx', 'qy', 'qz', 'qw']
    + [f'compliance_eigenvalue_{k}' for k in range(1, 7)])


def _rows(path: Path):
    with open(path, newline='') as stream:
        return list(csv.DictReader(stream))


def test_replay_takes_the_fidelity_options_of_solve_and_names_the_level(tmp_path, capsys):
    """`--fidelity cc`: solved at cc, said in the summary table and in every CSV row."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    code = main(['replay', str(bag), '--out', str(tmp_path / 'out.mcap'), '--progress', 'never',
                 '--fidelity', 'cc', '--csv', str(tmp_path / 'out.csv')])
    assert code == 0
    table = capsys.readouterr().out
    assert [line.split(None, 3)[-1] for line in table.splitlines()
            if line.startswith('fidelity (model level)')] == ['cc']
    assert {row['fidelity'] for row in _rows(tmp_path / 'out.csv')} == {'cc'}


def test_auto_with_a_budget_says_which_levels_answered(tmp_path, capsys):
    """`--fidelity auto --max-position-error 0.001`: the budget and the levels are named."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    assert main(['replay', str(bag), '--out', str(tmp_path / 'out.mcap'), '--progress',
                 'never', '--fidelity', 'auto', '--max-position-error', '0.001',
                 '--max-angle-error', '0.5', '--no-compliance']) == 0
    line = next(line for line in capsys.readouterr().out.splitlines()
                if line.startswith('fidelity (model level)'))
    assert 'auto (budget 1 mm, 0.5 deg); answered by' in line or line.endswith(
        'auto (budget 1 mm, 0.5 deg)')


@pytest.mark.parametrize('argv, message', [
    (['--fidelity', 'bogus'], "invalid choice: 'bogus'"),
    (['--max-position-error', '-1'], '--max-position-error: '),
    (['--fidelitx', 'cc'], 'unrecognized arguments: --fidelitx cc'),
])
def test_a_bad_level_option_is_one_line_with_the_replay_usage(tmp_path, capsys, argv, message):
    """Exit 2 before reading; argparse's errors show replay's usage, not the top level's."""
    bag = tmp_path / 'paper.mcap'
    synth.write_wrenches(bag, synth.generate('paper'))
    try:
        code = main(['replay', str(bag), '--out', str(tmp_path / 'out.mcap'), *argv])
    except SystemExit as stop:
        code = stop.code
    assert code == 2
    error = capsys.readouterr().err
    assert message in error
    if error.startswith('usage:'):
        assert error.startswith('usage: python -m msg_tools replay')
    assert not (tmp_path / 'out.mcap').exists()


def test_csv_adds_verdicts_levels_and_units_and_keeps_the_earlier_columns(tmp_path):
    """The earlier columns first, unchanged; a solved row fills the verdicts and the units."""
    assert CSV_COLUMNS[:len(EARLIER_COLUMNS)] == EARLIER_COLUMNS
    for name in ('fidelity', 'stable', 'error_estimate_m', 'error_estimate_rad',
                 'accuracy_met'):
        assert name in CSV_COLUMNS
    bag = tmp_path / 'hard.mcap'
    synth.write_wrenches(bag, synth.generate('hard'))
    replay(bag, tmp_path / 'out.mcap', csv_path=tmp_path / 'out.csv')
    rows = _rows(tmp_path / 'out.csv')
    solved = [row for row in rows if row['status'] == 'solved']
    assert solved and len(solved) < len(rows)
    for row in solved:
        assert row['fidelity'] == 'full' and row['stable'] in ('true', 'false')
        assert row['accuracy_met'] in ('true', 'false', '')   # '' only: not assessed
        assert float(row['error_estimate_m']) >= 0.0
        for k in range(1, 7):
            axis, unit = row[f'compliance_eigenvalue_{k}_axis'], row[
                f'compliance_eigenvalue_{k}_unit']
            assert unit == {'translation': 'm/N', 'rotation': 'rad/(N m)'}[axis.split()[0]]
            assert float(row[f'compliance_eigenvalue_{k}']) > 0.0
    assert any(row['accuracy_met'] == 'true' for row in solved)
    for row in rows:
        if row['status'] != 'solved':
            assert row['stable'] == row['accuracy_met'] == row['x_m'] == ''


def test_measured_poses_get_csv_rows_with_their_estimate(tmp_path):
    """A measured pose's row: status, the estimated wrench and its standard deviations."""
    bag = tmp_path / 'measured.mcap'
    samples = synth.generate('ramp', count=6, force=(8.0, 0.0, 0.0))
    poses, frame_id = measure(samples, check_noise((1e-5, 0.01)), None, (0.0,) * 6, 0, 0.0)
    synth.write_wrenches(bag, samples, poses=poses, pose_frame_id=frame_id)
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False,
                     csv_path=tmp_path / 'out.csv')
    rows = _rows(tmp_path / 'out.csv')
    pose_rows = [row for row in rows if 'pose' in row['topic']]
    assert len(pose_rows) == summary.poses > 0
    assert len(rows) == summary.messages + summary.poses
    assert [int(row['index']) for row in rows] == list(range(len(rows)))
    for row in pose_rows:
        assert row['status'] in ('estimated', 'flagged', 'not converged', 'rejected')
        assert row['fx_n'] == ''   # the input has no wrench: the estimate has its own columns
    estimated = [row for row in pose_rows if row['status'] in ('estimated', 'flagged')]
    assert estimated
    for row in estimated:
        assert abs(float(row['estimated_fx_n'])) < 20.0
        assert float(row['estimate_sd_fx_n']) > 0.0
        assert row['accuracy_met'] in ('true', 'false', '') and row['x_m']


def test_an_interrupted_replay_is_marked_partial_and_info_says_so(tmp_path, monkeypatch):
    """Ctrl-C midway: the finalized output says 'partial' and ``info`` calls it PARTIAL."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=20))
    complete = replay(bag, tmp_path / 'complete.mcap', compliance=False)
    assert complete.exit_code() == 0
    assert dict(McapSource(tmp_path / 'complete.mcap').metadata())[REPLAY_RECORD][
        'status'] == 'complete'
    assert 'PARTIAL' not in describe(tmp_path / 'complete.mcap')
    interrupt_processing_at(monkeypatch, 6)
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False)
    assert summary.interrupted
    record = dict(McapSource(tmp_path / 'out.mcap').metadata())[REPLAY_RECORD]
    assert record['status'] == 'partial' and record['messages_in_input'] == '20'
    text = describe(tmp_path / 'out.mcap')
    assert 'complete: every chunk read' in text   # the file itself is intact
    assert 'PARTIAL replay output (interrupted (Ctrl-C)): only 6 of 20' in text


class _Future:
    """A Dask future stand-in: the first window runs at once, the second never finishes."""

    def __init__(self, function, args, finishes: bool) -> None:
        self.function, self.args, self.finishes = function, args, finishes
        self.value = function(*args) if finishes else None

    def done(self) -> bool:
        if not self.finishes:   # Ctrl-C while the replay waits for this window
            os.kill(os.getpid(), signal.SIGINT)
        return self.finishes

    def result(self):
        return self.value

    def release(self) -> None:
        pass

    def cancel(self) -> None:
        pass


class _Client:
    """A Dask client stand-in of two workers, running the windows in this process."""

    def __init__(self) -> None:
        self.submitted = 0

    def scheduler_info(self, n_workers: int = -1) -> dict:
        return {'workers': {'a': {}, 'b': {}}}

    def submit(self, function, *args, **kwargs) -> _Future:
        assert function is replay_window
        self.submitted += 1
        return _Future(function, args, finishes=self.submitted == 1)


def test_an_interrupted_windowed_replay_is_marked_partial(tmp_path):
    """SIGINT while waiting for the second window: half the wrenches, marked 'partial'."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=40))
    summary = replay_on_dask(bag, tmp_path / 'out.mcap', client=_Client(), window_messages=10,
                             compliance=False)
    assert summary.interrupted and 0 < summary.messages < 40
    record = dict(McapSource(tmp_path / 'out.mcap').metadata())[REPLAY_RECORD]
    assert record['status'] == 'partial'
    assert record['messages_replayed'] == str(summary.messages)
    assert 'PARTIAL replay output' in describe(tmp_path / 'out.mcap')


def test_replay_plot_names_the_level_marks_gaps_and_keeps_shapes_true(tmp_path):
    """Rejected messages marked, the level in the title, equal 3-D scales, nothing cut."""
    bag = tmp_path / 'hard.mcap'
    synth.write_wrenches(bag, synth.generate('hard'))
    summary = replay(bag, tmp_path / 'out.mcap', compliance=False)
    series = summary.series
    assert [kind for _, kind in series.gaps].count('rejected') == summary.rejected == 4
    gaps = [(1e-9 * (stamp - summary.first_stamp_ns), kind) for stamp, kind in series.gaps]
    figure = replay_figure(series.time_s, np.array(series.joints), np.array(series.position),
                           replay_shapes(series), summary.level_text(), gaps)
    assert_readable(figure)
    assert 'full' in figure.texts[0].get_text() and 'fidelity' in figure.texts[0].get_text()
    time_panels = figure.axes[:2]
    for axes in time_panels:
        assert 'rejected (4)' in [text.get_text() for text in axes.get_legend().get_texts()]
        # the lines break at each gap instead of joining its neighbours
        assert all(np.isnan(line.get_ydata()).sum() == 4 for line in axes.get_lines()[:3])
    shape = figure.axes[2]
    spans = np.array([np.ptp(shape.get_xlim()), np.ptp(shape.get_ylim()),
                      np.ptp(shape.get_zlim())])
    box = np.asarray(shape.get_box_aspect())
    np.testing.assert_allclose(box / box.max(), spans / spans.max(), rtol=1e-9)
    assert plot_replay(series, tmp_path / 'plot.png', level=summary.level_text(),
                       origin_ns=summary.first_stamp_ns)
