"""
Every figure the project draws reads without the docs, drawn here from small inputs.

No text covers another or lies on another panel, every panel has a title, every axis a
unit, short series have markers, legends name the physical case, and colour scales say
when a quantity hardly varies (figure_checks has the geometric checks).
"""

import json
import math

from bench.speed_vs_error import PAPER_SCENES, RESULTS, SEQUENCE_LENGTH
from bench.speed_vs_error_figure import Measurement, measurements, non_dominated
from bench.speed_vs_error_figure import short_label, speed_error_figure
from cdr_translator.plotting import colour_scale, load_text
from cdr_translator.robot.atlas_figures import AtlasBlock, stiffness_figure, workspace_figure
from figure_checks import assert_readable, label_problems, text_problems
from matplotlib.figure import Figure
from msg_tools.plots import DeflectedShape, replay_figure
import numpy as np
import pytest


def _legend_texts(figure: Figure) -> list:
    legends = list(figure.legends) + [axes.get_legend() for axes in figure.axes
                                      if axes.get_legend() is not None]
    return [text.get_text() for legend in legends for text in legend.get_texts()]


def test_the_checks_find_overlaps_missing_units_and_bare_lines():
    """A figure with piled labels, a unitless axis and a 2-point line fails every check."""
    figure = Figure(figsize=(4, 3))
    axes = figure.add_subplot()
    axes.plot([0.0, 1.0], [0.0, 1.0])
    axes.annotate('rod 2', (0.5, 0.5))
    axes.annotate('rod 4', (0.5, 0.5), xytext=(3, 0), textcoords='offset points')
    axes.set_xlabel('time')
    problems = text_problems(figure) + label_problems(figure)
    assert any("'rod 2' overlaps 'rod 4'" in problem for problem in problems)
    assert any("'time'" in problem and 'no unit' in problem for problem in problems)
    assert any('has no marker' in problem for problem in problems)
    assert any('without a title' in problem for problem in problems)


def test_the_checks_find_a_label_under_a_colour_bar():
    """An axis label drawn on a colour bar's area is reported."""
    figure = Figure(figsize=(4, 3))
    axes = figure.add_subplot()
    figure.colorbar(axes.scatter([0, 1], [0, 1], c=[0, 1]), ax=axes, label='value (N)')
    axes.set(title='panel', xlabel='x (mm)', ylabel='y (mm)')
    axes.yaxis.set_label_position('right')
    axes.yaxis.labelpad = 14
    assert any('lies on the axes' in problem for problem in text_problems(figure))


def test_colour_scale_is_relative_below_one_percent_and_says_constant():
    """Under 1 % of spread: per cent from the mean; no spread: constant; else as given."""
    small = colour_scale(np.array([5.88, 5.90, 5.93]), 'stiffness margin', 'kN/m')
    assert small.label == 'stiffness margin (% from its mean 5.9 kN/m)'
    assert np.ptp(small.values) == pytest.approx(100 * 0.05 / 5.903333, rel=1e-3)
    assert 'varies by only 0.85 %' in small.note
    constant = colour_scale(np.full(4, 2.5), 'rotation', 'deg')
    assert constant.constant and constant.note == 'constant: 2.5 deg at every sample'
    wide = colour_scale(np.array([180.0, 270.0]), 'stiffness', 'kN/m', 'plasma')
    assert wide.label == 'stiffness (kN/m)' and not wide.constant
    assert np.array_equal(wide.values, [180.0, 270.0])
    assert wide.limits == (180.0, 270.0) and wide.colour_map == 'plasma'
    assert wide.note == '180 to 270 kN/m'


def test_colour_scale_paints_a_small_variation_small():
    """
    The colours span at least 5 % of the mean: a 0.85 % variation fills a sixth of them.

    A colour bar stretched over the data's own range would paint it dark to bright, as it
    paints a 40 % one.
    """
    small = colour_scale(np.array([5.88, 5.90, 5.93]), 'stiffness margin', 'kN/m')
    assert small.limits == (-2.5, 2.5) and small.colour_map == 'coolwarm'
    assert np.ptp(small.values) / np.diff(small.limits)[0] < 0.2
    narrow = colour_scale(np.array([99.0, 100.0, 101.0]), 'stiffness', 'kN/m', 'plasma')
    assert narrow.label == 'stiffness (kN/m)' and narrow.colour_map == 'plasma'
    assert narrow.limits == pytest.approx((97.5, 102.5))  # a 2 % spread on 5 % of colours
    assert narrow.note == '99 to 101 kN/m'


def test_load_text_names_force_and_moment():
    """The load reads 'F = (12, 0, 0) N', with the moment only when there is one."""
    assert load_text([12.0, -0.0, 0.0, 0.0, 0.0, 0.0]) == 'F = (12, 0, 0) N'
    assert load_text([15, -8, -5, 0.3, 0.2, 0.25]) == \
        'F = (15, -8, -5) N; M = (0.3, 0.2, 0.25) N m'


def test_speed_vs_error_figure_is_readable_with_piled_points():
    """Piled points: the fronts' points are named without covering each other, the rest not."""
    measured = [Measurement('rod', f'rod: {steps} steps', 2e-4, 1.5e-3, 0.6, 1e-4, 9e-4, 0.3)
                for steps in (1, 2, 4)]
    measured += [Measurement('full', 'full: 8 steps (default)', 5e-3, 8e-8, 1e-4,
                             1.8e-4, 9e-8, 1e-4),
                 Measurement('auto', 'auto: budget 0.01 mm, 0.01 deg', 5e-3, 8e-8, 1e-4,
                             1.8e-4, 9e-8, 1e-4),
                 Measurement('linear', 'linear: about the unloaded state', 1e-4, 0.07, 18.0,
                             1e-4, 7e-3, 1.4),
                 Measurement('full', 'full: 16 steps', 7e-3, 0.0, 0.0, 2e-4, 3e-9, 4e-6),
                 Measurement('paper', "paper's numerics, paper 12 N case", 20.0, 1e-8, 5e-5)]
    figure = speed_error_figure(measured, 1000)
    assert_readable(figure)
    key = _legend_texts(figure)
    assert key[2:-1] == ['rod', 'full', 'auto', 'linear'] and key[-1].startswith(
        "paper's numerics")
    titles = [axes.get_title() for axes in figure.axes]
    assert 'drawn at 1e-07 mm' in titles[0] and 'drawn at 1e-07 deg' in titles[1]
    names = sorted(text.get_text() for text in figure.axes[0].texts)
    # cold: linear, rod 1 step and full 16 steps (exact) are on the front; warm: full 8
    # steps and auto tie, and full 16 steps
    assert 'full 16 steps' in names and 'linear' in names and 'rod 1 step' in names
    assert 'full 8 steps*' in names and 'auto' in names   # the only auto: its level names it
    assert not any(name.startswith("paper's numerics") for name in names)   # dominated


def test_short_labels_name_a_point_briefly():
    """The name beside a point: level and setting, shorter words, * for a default."""
    assert short_label('full: 8 steps (default)') == 'full 8 steps*'
    assert short_label('rod: 1 steps per interval') == 'rod 1 step/interval'
    assert short_label('full: 2 spacer disks per joint, 8 steps') == 'full 2 disks/joint, 8 steps'
    assert short_label('auto: budget 1 mm, 0.5 deg') == 'auto 1 mm/0.5 deg'
    assert short_label('cc: one arc per joint', alone=True) == 'cc'
    assert short_label("paper's numerics, paper 20 N case, cold\n(method='paper')") == \
        "paper's numerics, 20 N"


def test_non_dominated_keeps_the_front_and_ties():
    """A point beaten in time and error is off the front; equal points both stay on it."""
    points = [(1.0, 1.0), (2.0, 0.5), (2.0, 2.0), (3.0, 0.5), (1.0, 1.0), (0.5, 3.0)]
    assert non_dominated(points) == [True, True, False, False, True, True]


def _robot_numbers() -> dict:
    """Numbers of bench.robot_levels' JSON form: rod slower and less exact than full."""
    return {'settings': 24, 'payloads_n': [0.0, 9.81, 19.62],
            'errors_against_full': {'rod': {'max_position_m': 1.7e-6},
                                    'cc': {'max_position_m': 3.8e-5}},
            'warm_forward_statics_s': {'full': 6.4e-4, 'rod': 6.5e-4, 'cc': 2.0e-4},
            'atlas_samples_per_s': {'full': 64.0, 'rod': 114.0, 'cc': 406.0}}


def test_speed_vs_error_figure_has_a_readable_robot_panel_with_its_front():
    """The robot panel names each leg level; full legs are a reference line, not a point."""
    measured = [Measurement('cc', 'cc: one arc per joint', 4e-5, 3e-3, 0.9, 2e-5, 2e-3, 0.6,
                            1.3e-5),
                Measurement('full', 'full: 8 steps (default)', 8e-3, 8e-8, 1e-4, 1.4e-4,
                            5e-8, 7e-5, 5e-4)]
    figure = speed_error_figure(measured, 1000, _robot_numbers())
    assert_readable(figure)
    key = _legend_texts(figure)
    assert key[0].startswith('Pareto front') and key[1].startswith('dominated')
    robot = figure.axes[2]
    assert 'Delta robot' in robot.get_title() and '(ms)' in robot.get_xlabel()
    assert 'drawn at' not in robot.get_title()   # no made-up error for the reference
    assert sorted(text.get_text() for text in robot.texts) == [
        'cc legs\n(atlas 406 samples/s)', 'full legs: the reference\n(atlas 64 samples/s)',
        'rod legs\n(atlas 114 samples/s)']
    low, _ = robot.get_ylim()
    assert low > 1e-4   # the axis spans the levels' errors, not a floor for full legs
    front = [line for line in robot.get_lines() if line.get_drawstyle() == 'steps-post']
    assert [list(line.get_xdata()) for line in front] == [[pytest.approx(0.2),
                                                           pytest.approx(0.65)]]
    reference = [line for line in robot.get_lines() if line.get_linestyle() == '-.']
    assert all(x == pytest.approx(0.64) for x in reference[0].get_xdata())


def test_speed_vs_error_figure_spans_three_decades_of_time():
    """
    The project's own levels' per-answer times, and so the figure's time axes, span 10^3.

    Cold static scenes, the warm sequence and its batch, the paper's numerics aside: what a
    user picks between, from the cheapest batch answer to the costliest cold solve.
    """
    report = json.loads((RESULTS / 'speed_vs_error.json').read_text())
    measured = measurements(report['rows'], report['paper_baseline'], PAPER_SCENES)
    times = [time for value in measured if value.level != 'paper'
             for time in (value.static_time_s, value.sequence_time_s, value.batch_time_s)
             if math.isfinite(time)]
    assert max(times) / min(times) >= 1e3, (min(times), max(times))
    figure = speed_error_figure(measured, SEQUENCE_LENGTH)
    for axes in figure.axes[:2]:
        low, high = axes.get_xlim()
        assert axes.get_xscale() == 'log' and high / low >= 1e3, (low, high)
        assert 'per answer (ms)' in axes.get_xlabel()


def _block(margin_spread: float, grid: int = 3, stable: bool = True) -> AtlasBlock:
    """Return a sheared grid of platform positions with smooth made-up fields."""
    levels = np.linspace(-0.03, 0.03, grid)
    sliders = np.array(np.meshgrid(levels, levels, levels)).reshape(3, -1).T
    position = sliders @ np.array([[0.8, 0.0, 0.3], [-0.4, 0.7, 0.3], [-0.4, -0.7, 0.3]])
    position += (0.0, 0.0, -0.13)
    radius = np.hypot(position[:, 0], position[:, 1])
    count = len(position)
    converged = np.ones(count, dtype=bool)
    is_stable = np.ones(count, dtype=bool)
    if not stable:
        converged[0] = False
        is_stable[1:3] = False
    return AtlasBlock(position, converged, is_stable, np.radians(0.7) * radius / radius.max(),
                      2.7e5 - 8e5 * radius, 5930.0 * (1.0 - margin_spread * radius / 0.04),
                      grid, 0.03, (0.0, 0.0, -9.81),
                      {'convex_hull_m3': 8.4e-5, 'jacobian_m3': 7.7e-5})


@pytest.mark.parametrize('stable', [True, False])
def test_atlas_workspace_figure_is_readable(stable):
    """The stability panel says when it is one colour; the verdicts are counted."""
    figure = workspace_figure(_block(0.006, stable=stable))
    assert_readable(figure)
    title = figure.axes[0].get_title()
    legend = _legend_texts(figure)
    if stable:
        assert 'all 27 samples stable: one colour' in title and legend == ['stable (27)']
    else:
        assert 'one colour' not in title
        assert legend == ['stable (24)', 'unstable (2)', 'not converged (1)']
    assert 'F = (0, 0, -9.81) N' in figure.get_suptitle()
    assert '84.0 cm\u00b3' in figure.get_suptitle()


def test_atlas_stiffness_figure_is_readable_and_honest():
    """kN/m ticks; a margin that varies by under 1 % is shown as % from its mean."""
    figure = stiffness_figure(_block(0.006))
    assert_readable(figure)
    colour_bars = [axes for axes in figure.axes if axes.get_label() == '<colorbar>']
    labels = [axes.get_ylabel() for axes in colour_bars]
    assert labels[0] == 'smallest translational stiffness (kN/m)'
    assert labels[1].startswith('stiffness margin (% from its mean 5.9')
    titles = [axes.get_title() for axes in figure.axes if axes not in colour_bars]
    assert len(titles) == 4 and all('varies by only' in title for title in titles[2:])
    # the margin's 0.6 % fills a small share of a colour bar of +-2.5 %, pale about its mean
    margin = [panel.collections[0] for panel in figure.axes[2:4]]
    assert all(points.get_clim() == (-2.5, 2.5) for points in margin)
    assert all(points.get_cmap().name == 'coolwarm' for points in margin)
    assert any('Stiffness margin: smallest eigenvalue' in text.get_text()
               for text in figure.texts)


def test_atlas_stiffness_figure_says_when_a_quantity_is_constant():
    """A constant margin gets no colour bar and a title that says it is constant."""
    figure = stiffness_figure(_block(0.0))
    assert_readable(figure)
    colour_bars = [axes for axes in figure.axes if axes.get_label() == '<colorbar>']
    assert len(colour_bars) == 1
    assert 'constant: 5.93 kN/m at every sample' in figure.axes[2].get_title()


def _bent_backbones(force: float) -> np.ndarray:
    """Five rods bending in x-z like the translator's under a lateral force (m)."""
    s = np.linspace(0.0, 0.17, 41)
    angle = 0.4 * force / 12.0 * s / 0.17
    rods = []
    for offset in (0.0, 0.008, -0.008):
        for side in (0.0, 0.005) if offset else (0.0,):
            rods.append(np.stack([0.1 * np.sin(angle) * s + offset * np.cos(angle),
                                  side + 0 * s, s], axis=1))
    return np.array(rods)


@pytest.mark.parametrize('count', [2, 200])
def test_replay_figure_is_readable(count):
    """Markers on a 2-message replay; the legend names each shape's load."""
    time_s = np.linspace(0.0, 1.0, count)
    force = np.linspace(12.0, 20.0, count)
    joints = np.radians(np.outer(force / 12.0, [22.4, 0.0, 11.0, 0.0, 33.0, 0.0]))
    position = np.stack([0.01 * force / 12.0, 0 * force, 0.05 + 0 * force], axis=1)
    shapes = [DeflectedShape(0, (12.0, 0.0, 0.0, 0.0, 0.0, 0.0), _bent_backbones(12.0)),
              DeflectedShape(count - 1, (20.0, 0.0, 0.0, 0.0, 0.0, 0.1),
                             _bent_backbones(20.0))]
    figure = replay_figure(time_s, joints, position, shapes)
    assert_readable(figure)
    legend = _legend_texts(figure)
    assert 'F = (12, 0, 0) N (message 0)' in legend
    assert f'F = (20, 0, 0) N; M = (0, 0, 0.1) N m (message {count - 1})' in legend
    markers = {line.get_marker() for axes in figure.axes[:2] for line in axes.get_lines()}
    assert markers == ({'o'} if count == 2 else {'None'})
