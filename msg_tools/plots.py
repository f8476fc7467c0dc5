"""
Plots of a replay (matplotlib, Agg backend: no display needed).

One PNG with three panels: the bending angles and the end-disk rotation against time, the
end-disk position against time, and the deflected shape (the five backbones, 3-D, mm) at a
few chosen messages with the least-squares circular arc fitted to each backbone in each
joint (``cdr_translator.geometry.fit_circle``), as in the paper's Fig. 4.
"""

import math
from pathlib import Path
from typing import List, Optional, Sequence, Union

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.geometry import fit_circle
from cdr_translator.params import DEFAULT_PARAMS_PATH
import matplotlib
matplotlib.use('Agg')
from matplotlib.backend_bases import FigureCanvasBase  # noqa: E402,I100 - after the backend
import matplotlib.pyplot as plt  # noqa: E402 - after choosing the backend
import numpy as np  # noqa: E402

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


def plot_replay(series, path: Union[str, Path], params_path: Union[str, Path, None] = None,
                samples: Optional[Sequence[int]] = None) -> List[int]:
    """
    Draw the replay ``series`` (replay.Series) to ``path``; return the message indices drawn.

    The deflected shapes are solved again (cold) from the wrenches the replay solved.
    """
    positions = choose_samples(series.index, samples)
    time_s = np.array(series.time_s)
    joints = np.degrees(np.array(series.joints))
    figure = plt.figure(figsize=(14, 5.5))
    angles = figure.add_subplot(1, 3, 1)
    for column, label in ((0, 'PJ bending'), (2, 'DJ bending'), (4, 'end-disk rotation')):
        angles.plot(time_s, joints[:, column], label=label)
    angles.set(xlabel='time (s)', ylabel='angle (deg)', title='Bending angles')
    angles.legend()
    angles.grid(True, alpha=0.3)
    position = figure.add_subplot(1, 3, 2)
    for column, axis in enumerate('xyz'):
        position.plot(time_s, 1e3 * np.array(series.position)[:, column], label=axis)
    position.set(xlabel='time (s)', ylabel='end-disk position (mm)', title='End-disk position')
    position.legend()
    position.grid(True, alpha=0.3)
    shape = figure.add_subplot(1, 3, 3, projection='3d')
    solver = TranslatorSolver(TranslatorParams.from_yaml(params_path or DEFAULT_PARAMS_PATH))
    colours = plt.rcParams['axes.prop_cycle'].by_key()['color']
    every_point = []
    for number, position_in_series in enumerate(positions):
        wrench = series.wrench[position_in_series]
        result = solver.solve(wrench[:3], wrench[3:], warm_start=False)
        colour = colours[number % len(colours)]
        half = result.backbones.shape[1] // 2
        for rod_number, rod in enumerate(1e3 * result.backbones):
            shape.plot(*rod.T, color=colour, linewidth=2.0 if rod_number == 0 else 1.0,
                       label=(f'message {series.index[position_in_series]}'
                              if rod_number == 0 else None))
            for rows in (slice(0, half), slice(half, None)):
                shape.plot(*arc_points(rod[rows]).T, color='black', linewidth=0.6,
                           linestyle='--')
            every_point.append(rod)
    points = np.concatenate(every_point)
    span = np.ptp(points, axis=0)
    shape.set_box_aspect(np.maximum(span, 0.3 * span.max()))
    shape.set(xlabel='x (mm)', ylabel='y (mm)', zlabel='z (mm)',
              title='Deflected shape (dashed: fitted arcs)')
    shape.legend(loc='upper left', fontsize='small')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return [series.index[position] for position in positions]
