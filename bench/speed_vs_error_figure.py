"""
The figure of bench.speed_vs_error: solve time against error of every fidelity level.

Drawn from the report's rows (``speed_vs_error.json`` holds them, so the figure can be
redrawn without measuring again) and, in a third panel, from bench.robot_levels' numbers
(``robot_levels.json``). Each kind of measurement has its Pareto front: the points no
other point of that kind beats in both time and error, joined by a step line; dominated
points are hollow. Each point of a front carries its configuration's name beside it; a name
that has no room beside its point moves away along a leader line, so no label covers
another or a marker. Dominated points stay unnamed: speed_vs_error.md lists every
configuration with its numbers.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import re
import statistics
from typing import Any, Dict, List, Optional, Sequence, Tuple

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.transforms import Bbox
import numpy as np

COLOURS = {'full': 'tab:blue', 'rod': 'tab:green', 'cc': 'tab:orange', 'linear': 'tab:red',
           'auto': 'tab:purple', 'paper': 'black'}

#: Smaller errors are drawn at this value (of the panel's unit): a log axis has no zero.
FLOOR = 1e-7

#: Key line of the paper's numerics (stars).
PAPER_KEY = "paper's numerics, cold (Levenberg-Marquardt, finite-difference Jacobian)"

#: Font size of the point names (pt).
NUMBER_SIZE = 7

#: Distances (px) and directions (deg) tried for a number around its point, nearest first.
RADII_PX = (8, 13, 19, 27, 37, 50, 66, 85, 110, 140)
DIRECTIONS_DEG = (0, 45, -45, 90, -90, 135, -135, 180, 22, -22, 158, -158, 68, -68, 112, -112)

#: Points this close (px) with the same name share one.
SAME_PX = 30.0

#: Half the size (px) of the box a marker (a star) keeps free of numbers.
MARKER_HALF_PX, STAR_HALF_PX = 4.5, 7.5


@dataclass
class Measurement:
    """One configuration: cold solves of the static scenes, warm solves of the sequence."""

    level: str
    label: str
    static_time_s: float
    static_position_m: float
    static_angle_deg: float
    sequence_time_s: float = math.nan
    sequence_position_m: float = math.nan
    sequence_angle_deg: float = math.nan
    batch_time_s: float = math.nan  # solve_many along the sequence, per answer


#: Shorter words for a point's name on the plot.
SHORTER = ((' spacer disks per joint', ' disks/joint'), (' steps per interval', ' steps/interval'),
           ('tolerance ', 'tol '), (' (default)', '*'), ('1 steps', '1 step'), ('budget ', ''),
           (' mm, ', ' mm/'))


def short_label(label: str, alone: bool = False) -> str:
    """
    Return a point's name on the plot, from its key line: 'full 8 steps*' (* a default).

    ``alone``: the only configuration of its level, named by the level. The paper's
    numerics read "paper's numerics, 12 N".
    """
    first = label.split('\n')[0]
    paper = re.match(r"paper's numerics, paper (.*) case", first)
    if paper:
        return f"paper's numerics, {paper.group(1)}"
    if alone:
        return first.split(':')[0]
    text = first.replace(': ', ' ', 1)
    for long, short in SHORTER:
        text = text.replace(long, short)
    return text


def key_label(level: str, setting: str) -> str:
    """Return a key line: the level and its setting without long asides in parentheses."""
    return f"{level}: {re.sub(r' [(](?!default)[^)]{12,}[)]', '', setting)}"


def measurements(rows: Sequence[dict], paper: Dict[str, dict],
                 paper_scenes: Sequence[str]) -> List[Measurement]:
    """
    Return the plotted numbers of the report's ``rows`` and ``paper`` baseline.

    Static: the median time over ``paper_scenes`` and the worst error over every scene;
    sequence: the median time and the worst error.
    """
    result = []
    for row in rows:
        static, sequence = row['static'], row['sequence']
        result.append(Measurement(
            row['level'], key_label(row['level'], row['setting']),
            statistics.median(static[name]['time_s'] for name in paper_scenes),
            max(value['position_m'] for value in static.values()),
            max(value['angle_deg'] for value in static.values()),
            sequence['median_time_s'], sequence['max_position_m'],
            sequence['max_angle_deg'], sequence.get('batch_per_answer_s', math.nan)))
    for name, value in paper.items():
        result.append(Measurement(
            'paper', f"paper's numerics, {name} case, cold\n(method='paper': "
            'Levenberg-Marquardt, finite-difference Jacobian)',
            value['time_s'], value['position_m'], value['angle_deg']))
    return result


def _text_size(canvas: FigureCanvasAgg, text: str) -> Tuple[float, float]:
    """Return the width and height (px) a number's text takes, line spacing included."""
    probe = Text(0.0, 0.0, text, fontsize=NUMBER_SIZE)
    probe.set_figure(canvas.figure)
    extent = probe.get_window_extent(canvas.get_renderer())
    return extent.width, extent.height


def _overlaps(box: Bbox, others: List[Bbox]) -> bool:
    return any(box.x0 < other.x1 and other.x0 < box.x1 and box.y0 < other.y1
               and other.y0 < box.y1 for other in others)


def place_numbers(axes: Axes, canvas: FigureCanvasAgg,
                  points: List[Tuple[float, float, str, float]]) -> None:
    """
    Write each text beside its point, in the nearest free place.

    ``canvas``: the Agg canvas of the axes' figure, which measures the texts. ``points``:
    x, y (data coordinates), text, half-size of the marker (px). Free: inside the axes,
    clear of every marker and of the texts already placed. A text further than the
    nearest ring gets a leader line to its point.
    """
    frame = axes.get_window_extent().padded(-3.0)
    centres = [axes.transData.transform((x, y)) for x, y, _, _ in points]
    taken = [Bbox.from_extents(cx - half, cy - half, cx + half, cy + half)
             for (cx, cy), (_, _, _, half) in zip(centres, points)]
    # crowded points first, while the places near them are still free
    crowding = [sum(np.hypot(cx - ox, cy - oy) < 40.0 for ox, oy in centres)
                for cx, cy in centres]
    points_per_px = 72.0 / canvas.figure.dpi
    named: List[Tuple[str, Tuple[float, float]]] = []
    for k in sorted(range(len(points)), key=lambda index: -crowding[index]):
        x, y, text, _ = points[k]
        if not text or any(   # unnamed, or its name is already beside it
                name == text and math.hypot(centres[k][0] - px, centres[k][1] - py) < SAME_PX
                for name, (px, py) in named):
            continue
        named.append((text, (float(centres[k][0]), float(centres[k][1]))))
        (cx, cy), (width, height) = centres[k], _text_size(canvas, text)
        chosen = None
        for radius in RADII_PX:
            for degrees in DIRECTIONS_DEG:
                dx = radius * math.cos(math.radians(degrees))
                dy = radius * math.sin(math.radians(degrees))
                box = Bbox.from_bounds(cx + dx - width / 2 - 1.5, cy + dy - height / 2 - 1.5,
                                       width + 3, height + 3)
                if frame.contains(box.x0, box.y0) and frame.contains(box.x1, box.y1) \
                        and not _overlaps(box, taken):
                    chosen = (dx, dy, box)
                    break
            if chosen is not None:
                break
        if chosen is None:  # no room anywhere: the readability test reports it
            chosen = (RADII_PX[-1], 0.0, Bbox.from_bounds(cx + RADII_PX[-1], cy, width, height))
        dx, dy, box = chosen
        taken.append(box)
        leader = {'arrowstyle': '-', 'color': '0.45', 'linewidth': 0.5, 'shrinkA': 0.0,
                  'shrinkB': 3.0}
        axes.annotate(text, (x, y), xytext=(dx * points_per_px, dy * points_per_px),
                      textcoords='offset points', ha='center', va='center',
                      fontsize=NUMBER_SIZE, arrowprops=leader if math.hypot(dx, dy) > 10
                      else None, annotation_clip=False)


def _log_axes(axes: Axes, points: Sequence[Tuple[float, float, str, str]],
              x_margins: Tuple[float, float], y_margin: float) -> None:
    """Make both axes logarithmic, spanning ``points`` with these factors to spare."""
    axes.set_xscale('log')
    axes.set_yscale('log')
    times, errors = [point[0] for point in points], [point[1] for point in points]
    axes.set_xlim(min(times) / x_margins[0], max(times) * x_margins[1])
    axes.set_ylim(min(errors) / y_margin, max(errors) * y_margin)


def non_dominated(points: Sequence[Tuple[float, float]]) -> List[bool]:
    """
    Return, for each (time, error), whether it is on the Pareto front.

    A point is dominated when another is no slower and no less wrong, and better in one
    of the two; equal points are both on the front.
    """
    return [not any(t <= time and e <= error and (t < time or e < error) for t, e in points)
            for time, error in points]


#: Marker and step-line style of each kind of measurement (cold, warm one by one, batch).
KINDS = {'cold': ('o', '-'), 'warm': ('s', '--'), 'batch': ('^', ':')}


def _draw_front(axes: Axes, points: List[Tuple[float, float, str, str]]) -> List[bool]:
    """
    Draw each kind's points (x, y, colour, kind) with the kind's Pareto front.

    Points on the front are filled and joined by a step line, dominated points hollow. A
    kind ending in '*' is a star (the paper's numerics) of that kind. Return, for each
    point, whether it is on its kind's front.
    """
    on_fronts = [False] * len(points)
    for kind, (marker, style) in KINDS.items():
        members = [k for k, point in enumerate(points) if point[3] in (kind, f'{kind}*')]
        group = [points[k] for k in members]
        if not group:
            continue
        front = non_dominated([(x, y) for x, y, _, _ in group])
        for k, on_front in zip(members, front):
            on_fronts[k] = on_front
        for (x, y, colour, name), on_front in zip(group, front):
            shape, size = ('*', 90) if name.endswith('*') else (marker, 30)
            if on_front:
                axes.scatter(x, y, color=colour, marker=shape, s=size, zorder=3)
            else:
                axes.scatter(x, y, facecolors='none', edgecolors=colour, marker=shape, s=size,
                             linewidths=0.9, zorder=3)
        corners = sorted((x, y) for (x, y, _, _), on_front in zip(group, front) if on_front)
        axes.plot([x for x, _ in corners], [y for _, y in corners], color='0.35',
                  linestyle=style, linewidth=0.9, drawstyle='steps-post', marker=marker,
                  markersize=2, zorder=2)
    return on_fronts


def _translator_panels(figure: Figure, canvas: FigureCanvasAgg, panels: List[Axes],
                       measured: Sequence[Measurement]) -> None:
    """Time against position error (left) and angle error (right) of every configuration."""
    for axes, (field, scale, unit, what, title) in zip(panels, (
            ('position_m', 1e3, 'mm', 'position', 'End-disk position error'),
            ('angle_deg', 1.0, 'deg', 'angle',
             'Angle error (PJ, DJ bending and end-disk orientation)'))):
        points: List[Tuple[float, float, str, str]] = []
        numbers, floored = [], False
        for value in measured:
            pairs = [(value.static_time_s, getattr(value, f'static_{field}'), 'cold')]
            if math.isfinite(value.sequence_time_s):
                pairs.append((value.sequence_time_s, getattr(value, f'sequence_{field}'),
                              'warm'))
            if math.isfinite(value.batch_time_s):  # its rows are the sequence's answers
                pairs.append((value.batch_time_s, getattr(value, f'sequence_{field}'),
                              'batch'))
            for seconds, error, kind in pairs:
                shown = max(scale * error, FLOOR)
                floored |= scale * error < FLOOR
                star = value.level == 'paper'
                points.append((1e3 * seconds, shown, COLOURS[value.level],
                               kind + ('*' if star else '')))
                numbers.append((1e3 * seconds, shown, short_label(value.label, alone=sum(
                    other.level == value.level for other in measured) == 1),
                                STAR_HALF_PX if star else MARKER_HALF_PX))
        front = _draw_front(axes, points)
        # every marker keeps its place free; only the fronts' points are named
        numbers = [(x, y, text if on_front else '', half)
                   for (x, y, text, half), on_front in zip(numbers, front)]
        _log_axes(axes, points, (2.0, 2.5), 4.0)
        axes.set_xlabel('solve time per answer (ms)')
        axes.set_ylabel(f'{what} error, worst over the scenes ({unit})')
        axes.set_title(title + (f'\nerrors below {FLOOR:g} {unit} drawn at {FLOOR:g} {unit}'
                                if floored else ''), fontsize=10)
        axes.grid(True, which='major', alpha=0.3)
        place_numbers(axes, canvas, numbers)


def _robot_panel(axes: Axes, canvas: FigureCanvasAgg, robot: dict) -> None:
    """
    Draw the robot's platform error against its warm forward-statics time, per leg level.

    The error is the worst platform position error against full legs over the slider box
    and payloads of ``robot`` (bench.robot_levels' numbers). Full legs are the reference,
    with no error of their own to draw on a log axis: their time is a vertical line.
    """
    warm = robot['warm_forward_statics_s']
    errors, rate = robot['errors_against_full'], robot['atlas_samples_per_s']
    points, labels = [], []
    for level, seconds in warm.items():
        if level == 'full':
            continue
        error = 1e3 * errors[level]['max_position_m']
        points.append((1e3 * seconds, error, COLOURS[level], 'warm'))
        labels.append((1e3 * seconds, error,
                       f'{level} legs\n(atlas {rate[level]:.0f} samples/s)', MARKER_HALF_PX))
    _draw_front(axes, points)
    reference = 1e3 * warm['full']
    _log_axes(axes, points + [(reference, points[0][1], '', 'warm')], (3.0, 3.0), 10.0)
    low, high = axes.get_ylim()
    span = np.geomspace(low, high, 50)   # a drawn line, not two samples
    axes.plot(np.full_like(span, reference), span, color=COLOURS['full'], linestyle='-.',
              linewidth=1.2)
    axes.annotate(f'full legs: the reference\n(atlas {rate["full"]:.0f} samples/s)',
                  (reference, high), xytext=(-4, -4), textcoords='offset points', ha='right',
                  va='top', fontsize=NUMBER_SIZE, color=COLOURS['full'])
    axes.set_xlabel('warm forward statics per answer (ms)')
    axes.set_ylabel('platform position error against full legs (mm)')
    axes.set_title('Delta robot, legs at each level (warm, squares): worst over '
                   f"{robot['settings']} slider settings x {len(robot['payloads_n'])} payloads",
                   fontsize=10)
    axes.grid(True, which='major', alpha=0.3)
    place_numbers(axes, canvas, labels)


def speed_error_figure(measured: Sequence[Measurement], sequence_length: int,
                       robot: Optional[dict] = None) -> Figure:
    """
    Draw solve time against position and angle error; return the Figure.

    ``robot``: the numbers of bench.robot_levels (its JSON form); with them a third panel
    shows the robot's platform error against its warm forward-statics time per leg level.
    """
    figure = Figure(figsize=(13, 9 if robot is None else 13), dpi=110)
    canvas = FigureCanvasAgg(figure)
    if robot is None:
        panels = [figure.add_axes((0.07, 0.32, 0.4, 0.6)),
                  figure.add_axes((0.57, 0.32, 0.4, 0.6))]
    else:
        panels = [figure.add_axes((0.07, 0.53, 0.4, 0.41)),
                  figure.add_axes((0.57, 0.53, 0.4, 0.41))]
    _translator_panels(figure, canvas, panels, measured)
    if robot is not None:
        _robot_panel(figure.add_axes((0.07, 0.05, 0.36, 0.37)), canvas, robot)
    filled = tuple(Line2D([], [], color='grey', marker=marker, linestyle='none')
                   for marker, _ in KINDS.values())
    hollow = tuple(Line2D([], [], markeredgecolor='grey', markerfacecolor='none',
                          marker=marker, linestyle='none') for marker, _ in KINDS.values())
    handles: List[Any] = [filled, hollow]
    labels = ['Pareto front, named point by point and joined by a step line per kind:\n'
              'static scenes solved cold (circle, solid: worst error, median time of the '
              f'paper cases);\nthe {sequence_length}-wrench sequence warm-started (square, '
              'dashed: worst error,\nmedian time of one solve); the same sequence in one '
              'solve_many call\n(triangle, dotted: time per answer); * marks a default '
              'setting',
              'dominated: another point of the same kind is no slower and no less wrong\n'
              '(unnamed; speed_vs_error.md lists every configuration)']
    levels = list(dict.fromkeys(value.level for value in measured))
    for level in levels:
        handles.append(Line2D([], [], color=COLOURS[level], linestyle='none',
                              marker='*' if level == 'paper' else 'o'))
        labels.append(PAPER_KEY if level == 'paper' else level)
    figure.legend(handles, labels, loc='lower center' if robot is None else 'lower left',
                  ncol=2 if robot is None else 1,
                  bbox_to_anchor=(0.5, 0.005), fontsize=8, title='key: colour = fidelity level',
                  title_fontsize=8, handler_map={tuple: HandlerTuple(ndivide=None)})
    figure.suptitle('Solve time against error of every fidelity level (translator reference: '
                    'the full model at 32 RK4 steps per disk interval, residual 1e-12)',
                    fontsize=11)
    return figure


def save_speed_error_figure(report: dict, paper_scenes: Sequence[str],
                            sequence_length: int, path: Path,
                            robot: Optional[dict] = None) -> None:
    """Draw the figure of a speed_vs_error report (and robot_levels' numbers) to ``path``."""
    measured = measurements(report['rows'], report['paper_baseline'], paper_scenes)
    speed_error_figure(measured, sequence_length, robot).savefig(path, dpi=110)
