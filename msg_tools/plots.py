"""
Plots of a replay (matplotlib, Agg backend: no display needed).

One PNG with three panels: the bending angles and the end-disk rotation against time, the
end-disk position against time, and the deflected shape (the five backbones, 3-D, mm, equal
scales on the three axes) at a few chosen messages with the least-squares circular arc
fitted to each backbone in each joint (``cdr_translator.geometry.fit_circle``), as in the
paper's Fig. 4. The title names the model level of the replay; messages without an answer
(rejected, not converged) break the time lines and are marked on the time axis.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from typing import List, Optional, Sequence, Tuple, Union

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.geometry import fit_circle
from cdr_translator.params.translator_params import DEFAULT_PARAMS_PATH
from cdr_translator.plotting import equal_aspect_3d, load_text, sample_marker, thin_ticks
import matplotlib
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.figure import Figure
import numpy as np

#: Shapes drawn when no samples are chosen: this many, evenly spread over the run.
DEFAULT_SHAPES = 3


def arc_points(points: np.ndarray, count: int = 60) -> np.ndarray:
    """
    Return ``count`` points of the circle fitted to ``points``, from the first to the last.

    The arc runs the way the points do (through the middle point); a straight fit
    (infinite radius) gives the segment between the end points.
    """
    chord = points[-1] - points[0]
    length = float(np.linalg.norm(chord))
    across = points - points[0] - np.outer((points - points[0]) @ chord, chord) / max(
        length * length, 1e-300)
    if np.linalg.norm(across, axis=1).max() <= 1e-9 * length:
        # straight (fit_circle's algebraic fit is rank deficient for collinear points)
        return np.linspace(points[0], points[-1], count)
    centre, normal, radius = fit_circle(points)
    if math.isinf(radius):
        return np.linspace(points[0], points[-1], count)
    radial = points[0] - centre
    radial -= (radial @ normal) * normal
    u = radial / np.linalg.norm(radial)
    v = np.cross(normal, u)

    def angle(point: np.ndarray) -> float:
        offset = point - centre
        return math.atan2(offset @ v, offset @ u) % (2.0 * math.pi)

    end, middle = angle(points[-1]), angle(points[len(points) // 2])
    sweep = end if middle <= end else end - 2.0 * math.pi
    t = np.linspace(0.0, sweep, count)
    return centre + radius * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))


def choose_samples(indices: Sequence[int], samples: Optional[Sequence[int]]) -> List[int]:
    """Return positions in the series of the chosen message indices (default: spread)."""
    if samples:
        where = {index: position for position, index in enumerate(indices)}
        missing = [sample for sample in samples if sample not in where]
        if missing:
            raise ValueError(f'message(s) {missing} did not converge or do not exist; '
                             f'converged messages run {indices[0]}..{indices[-1]}')
        return [where[sample] for sample in samples]
    count = min(DEFAULT_SHAPES, len(indices))
    return sorted(set(np.linspace(0, len(indices) - 1, count).round().astype(int).tolist()))


def check_plot_path(path: Union[str, Path]) -> None:
    """
    Raise ValueError unless ``path`` ends in a format matplotlib writes (.png, .pdf, .svg...).

    Without the check a missing suffix gets '.png' appended behind the caller's back, and
    an unknown one fails only once the replay is done.
    """
    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    suffix = Path(path).suffix.lower().lstrip('.')
    if suffix not in formats:
        raise ValueError(f'plot file {path}: its suffix must name an image format, one of '
                         f'{", ".join(formats)}')


@dataclass
class DeflectedShape:
    """One drawn shape: its message, its wrench [f (N); m (N m)] and backbones (m)."""

    message: int
    wrench: Sequence[float]
    backbones: np.ndarray  # (rods, points, 3); rod 0 is the central backbone


#: How a message without an answer is marked on the time panels: marker, colour.
GAP_MARKS = {'rejected': ('x', 'tab:red'), 'not converged': ('|', 'tab:purple')}


def _with_gaps(time_s: np.ndarray, columns: np.ndarray, gap_times: np.ndarray
               ) -> Tuple[np.ndarray, np.ndarray]:
    """Return the series with a NaN row at each gap time, so a line breaks there."""
    if not gap_times.size:
        return time_s, columns
    times = np.concatenate([time_s, gap_times])
    rows = np.concatenate([columns, np.full((gap_times.size, columns.shape[1]), np.nan)])
    order = np.argsort(times, kind='stable')
    return times[order], rows[order]


def _time_panel(axes, time_s: np.ndarray, columns: np.ndarray, labels: Sequence[str],
                ylabel: str, title: str, gaps: Sequence[Tuple[float, str]] = ()) -> None:
    marker = sample_marker(len(time_s))
    gap_times = np.array([time for time, _ in gaps], dtype=float)
    times, rows = _with_gaps(time_s, columns, gap_times)
    for values, label in zip(rows.T, labels):
        axes.plot(times, values, label=label, marker=marker, markersize=4)
    for kind, (symbol, colour) in GAP_MARKS.items():
        at = [time for time, what in gaps if what == kind]
        if at:   # on the time axis, whatever the values' range (x in data, y in axes units)
            axes.plot(at, [0.03] * len(at), linestyle='none', marker=symbol, color=colour,
                      markersize=7, transform=axes.get_xaxis_transform(), scalex=False,
                      scaley=False, label=f'{kind} ({len(at)})')
    axes.set(xlabel='time (s)', ylabel=ylabel, title=title)
    axes.legend(fontsize='small')
    axes.grid(True, alpha=0.3)


def _shape_panel(axes, shapes: Sequence[DeflectedShape]) -> None:
    colours = matplotlib.rcParams['axes.prop_cycle'].by_key()['color']
    every_point = []
    for number, shape in enumerate(shapes):
        colour = colours[number % len(colours)]
        backbones = 1e3 * np.asarray(shape.backbones)
        half = backbones.shape[1] // 2
        for rod_number, rod in enumerate(backbones):
            axes.plot(*rod.T, color=colour, linewidth=2.0 if rod_number == 0 else 1.0,
                      label=(f'{load_text(shape.wrench)} (message {shape.message})'
                             if rod_number == 0 else None))
            for rows in (slice(0, half), slice(half, None)):
                axes.plot(*arc_points(rod[rows]).T, color='black', linewidth=0.6,
                          linestyle='--')
            every_point.append(rod)
    points = np.concatenate(every_point)
    equal_aspect_3d(axes, points)
    aspect = np.asarray(axes.get_box_aspect())
    # fewer ticks on the short sides of the box, or their labels run into each other
    thin_ticks(axes, [max(2, int(round(6 * side / aspect.max()))) for side in aspect])
    axes.set_title('Deflected shapes, equal scales (solved again with the full model;\n'
                   'dashed: arcs fitted to each joint)', fontsize='medium')
    for axis, name, pad in ((axes.xaxis, 'x', 12), (axes.yaxis, 'y', 12), (axes.zaxis, 'z', 18)):
        axis.set_label_text(f'{name} (mm)')
        axis.labelpad = pad


def replay_figure(time_s: Sequence[float], joints_rad: np.ndarray, position_m: np.ndarray,
                  shapes: Sequence[DeflectedShape], level: str = '',
                  gaps: Sequence[Tuple[float, str]] = ()) -> Figure:
    """
    Draw a replay: angles and end-disk position against time, and deflected shapes.

    ``joints_rad`` has the columns of replay.Series.joints (0 PJ bending, 2 DJ bending,
    4 end-disk rotation), ``position_m`` is (n, 3). ``level``: the model level the replay
    ran at, named in the title. ``gaps``: (time s, 'rejected' or 'not converged') of the
    messages without an answer.
    """
    figure = Figure(figsize=(16, 6.5), dpi=110)
    # the time panels and the 3-D box each get their own columns, with room between them
    # for the middle panel's y label; the shapes' legend goes under the time panels
    grid = figure.add_gridspec(1, 3, width_ratios=(1.0, 1.0, 1.25), left=0.05, right=0.99,
                               top=0.86, bottom=0.25, wspace=0.28)
    seconds = np.asarray(time_s, dtype=float)
    joints = np.degrees(np.asarray(joints_rad, dtype=float))
    _time_panel(figure.add_subplot(grid[0, 0]), seconds, joints[:, [0, 2, 4]],
                ('PJ bending', 'DJ bending', 'end-disk rotation'), 'angle (deg)',
                'Bending angles', gaps)
    _time_panel(figure.add_subplot(grid[0, 1]), seconds,
                1e3 * np.asarray(position_m, dtype=float), ('x', 'y', 'z'),
                'end-disk position (mm)', 'End-disk position', gaps)
    shape = figure.add_subplot(grid[0, 2], projection='3d')
    _shape_panel(shape, shapes)
    figure.suptitle(f'Replay: {len(seconds)} converged messages plotted, model level '
                    f'(fidelity) {level or "not said"}', fontsize='large')
    figure.legend(*shape.get_legend_handles_labels(), loc='lower left',
                  bbox_to_anchor=(0.05, 0.0), fontsize='small', ncol=2,
                  title='load of each drawn shape', title_fontsize='small')
    return figure


def replay_shapes(series, params_path: Union[str, Path, None] = None,
                  samples: Optional[Sequence[int]] = None) -> List[DeflectedShape]:
    """Solve again (cold) the chosen messages of the replay ``series`` (replay.Series)."""
    solver = TranslatorSolver(TranslatorParams.from_yaml(params_path or DEFAULT_PARAMS_PATH))
    shapes = []
    for position_in_series in choose_samples(series.index, samples):
        wrench = series.wrench[position_in_series]
        result = solver.solve(wrench[:3], wrench[3:], warm_start=False)
        shapes.append(DeflectedShape(series.index[position_in_series], wrench,
                                     result.backbones))
    return shapes


def plot_replay(series, path: Union[str, Path], params_path: Union[str, Path, None] = None,
                samples: Optional[Sequence[int]] = None, level: str = '',
                origin_ns: Optional[int] = None) -> List[int]:
    """
    Draw the replay ``series`` (replay.Series) to ``path``; return the message indices drawn.

    The deflected shapes are solved again (cold, full model) from the wrenches the replay
    solved. ``level``: the replay's model level, named in the title. ``origin_ns``: the
    stamp of the series' time zero, which places its gaps (``Series.gaps``) in time.
    """
    shapes = replay_shapes(series, params_path, samples)
    gaps = ([(1e-9 * (stamp_ns - origin_ns), kind) for stamp_ns, kind in series.gaps]
            if origin_ns is not None else [])
    figure = replay_figure(series.time_s, np.array(series.joints), np.array(series.position),
                           shapes, level, gaps)
    figure.savefig(path, dpi=110)
    return [shape.message for shape in shapes]
