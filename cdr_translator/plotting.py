"""
Conventions shared by the project's figures, so that each reads without the docs.

Colour scales that do not exaggerate (a quantity that varies by under 1 % is shown as
per cent from its mean, a constant one is said to be constant), tick density on 3-D
panels, equal scales on 3-D shapes, markers on short series, and the text of a load. The
figures use ``matplotlib.figure.Figure`` directly (no pyplot): no display, no global state.
"""

from dataclasses import dataclass
from typing import Optional, Sequence

from matplotlib.axes import Axes
from matplotlib.ticker import MaxNLocator
import numpy as np

#: Series of at most this many samples are drawn with a marker on every sample.
FEW_SAMPLES = 30

#: Below this relative spread (max - min over |mean|) a colour scale shows % from the mean.
RELATIVE_BELOW = 0.01

#: Ticks this close to either end of a 3-D axis (fraction of its length) are left out.
CORNER_MARGIN = 0.08

#: Below this relative spread the quantity is called constant.
CONSTANT_BELOW = 1e-9


def sample_marker(count: int) -> Optional[str]:
    """Return the marker for a line of ``count`` samples: 'o' when they are few, else None."""
    return 'o' if count <= FEW_SAMPLES else None


@dataclass(frozen=True)
class ColourScale:
    """What a colour scale shows: the values, the colour-bar label and a note for the title."""

    values: np.ndarray
    label: str
    constant: bool
    note: str


def colour_scale(values: np.ndarray, name: str, unit: str) -> ColourScale:
    """
    Return the honest colour scale of ``values`` (already in ``unit``).

    A spread under RELATIVE_BELOW of the mean would paint a tiny variation as a large one
    (a colour bar stretches to the data's range), so it is shown as per cent from the mean
    and the note says how small it is; a constant quantity gets no scale at all.
    """
    values = np.asarray(values, dtype=float)
    mean = float(np.mean(values)) if values.size else 0.0
    spread = float(np.ptp(values)) if values.size else 0.0
    size = max(abs(mean), np.finfo(float).tiny)
    if spread <= CONSTANT_BELOW * size:
        return ColourScale(values, f'{name} ({unit})', True,
                           f'constant: {mean:.4g} {unit} at every sample')
    if spread < RELATIVE_BELOW * size:
        return ColourScale(100.0 * (values / mean - 1.0),
                           f'{name} (% from its mean {mean:.3g} {unit})', False,
                           f'varies by only {100.0 * spread / size:.2g} % '
                           f'around {mean:.3g} {unit}')
    return ColourScale(values, f'{name} ({unit})', False,
                       f'{np.min(values):.3g} to {np.max(values):.3g} {unit}')


def thin_ticks(axes: Axes, bins: Sequence[int]) -> None:
    """
    Cap the number of ticks on each axis of ``axes`` (x, y[, z]) so labels do not touch.

    Call it once the data are drawn. On a 3-D axes the ticks near either end of an axis go
    too: at the corners where two axes meet their labels run into each other ('100-10').
    """
    axis_objects = [(axes.xaxis, axes.get_xlim()), (axes.yaxis, axes.get_ylim())]
    if hasattr(axes, 'zaxis'):
        axis_objects.append((getattr(axes, 'zaxis'), getattr(axes, 'get_zlim')()))
    for (axis, (low, high)), count in zip(axis_objects, bins):
        locator = MaxNLocator(nbins=count, steps=[1, 2, 2.5, 5, 10])
        if len(axis_objects) == 3:
            margin = CORNER_MARGIN * (high - low)
            axis.set_ticks([tick for tick in locator.tick_values(low, high)
                            if low + margin <= tick <= high - margin])
        else:
            axis.set_major_locator(locator)


def equal_aspect_3d(axes: Axes, points: np.ndarray, least: float = 0.3) -> None:
    """
    Give a 3-D ``axes`` equal scales on x, y and z around ``points`` (n, 3).

    A millimetre is as long on every axis, so a shape is not straightened or bent by its
    box; a side spanning less than ``least`` of the longest is widened to that (around its
    middle), so a flat shape still gets a box with room for its ticks.
    """
    points = np.asarray(points, dtype=float)
    low, high = points.min(axis=0), points.max(axis=0)
    middle, span = 0.5 * (low + high), high - low
    sides = np.maximum(span, least * max(float(span.max()), np.finfo(float).tiny))
    axes.set_xlim(middle[0] - sides[0] / 2, middle[0] + sides[0] / 2)
    axes.set_ylim(middle[1] - sides[1] / 2, middle[1] + sides[1] / 2)
    getattr(axes, 'set_zlim')(middle[2] - sides[2] / 2, middle[2] + sides[2] / 2)
    getattr(axes, 'set_box_aspect')(sides)


def number_text(value: float) -> str:
    """Return ``value`` to 3 significant digits, with no minus sign on zero."""
    text = f'{value:.3g}'
    return '0' if text in ('-0', '0') else text


def load_text(wrench: Sequence[float]) -> str:
    """
    Return the load of a 6-D wrench [f (N); m (N m)] as 'F = (12, 0, 0) N'.

    The moment is added ('; M = (...) N m') only when it is not zero.
    """
    force = ', '.join(number_text(value) for value in wrench[:3])
    text = f'F = ({force}) N'
    if len(wrench) > 3 and any(value != 0.0 for value in wrench[3:6]):
        moment = ', '.join(number_text(value) for value in wrench[3:6])
        text += f'; M = ({moment}) N m'
    return text
