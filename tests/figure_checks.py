"""
Readability checks of a matplotlib Figure, shared by the figure tests.

A figure is drawn once on an Agg canvas while every Text artist that actually draws is
recorded with its window extent (tick labels of ticks outside the view are never drawn,
so they are never counted). Then: no two drawn texts overlap, no text lies on another
axes (a colour bar over a 3-D axis label), no text is cut by the figure's edge (a legend
placed past it), every panel has a title, every axis that shows
tick labels has a label with a unit in parentheses or brackets, and every short line has
markers.
"""

import re
from typing import List, Tuple
from unittest import mock

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.transforms import Bbox

#: Texts closer than this many pixels (minus this number) count as overlapping: touching
#: tick labels of two axes read as one number.
TOLERANCE_PX = -1.0

#: A unit: something in parentheses or brackets, e.g. '(mm)', '(% from its mean 5.9 kN/m)'.
UNIT = re.compile(r'\([^()]*\S[^()]*\)|\[[^\[\]]*\S[^\[\]]*\]')

#: Lines of at most this many samples must show a marker on each.
FEW_SAMPLES = 30


def drawn_texts(figure: Figure) -> List[Tuple[Text, Bbox]]:
    """Draw ``figure`` on an Agg canvas; return every non-empty Text drawn, with its extent."""
    FigureCanvasAgg(figure)
    drawn: List[Tuple[Text, Bbox]] = []
    draw = Text.draw

    def recording_draw(text: Text, renderer) -> None:
        draw(text, renderer)
        if text.get_visible() and text.get_text().strip():
            # the text alone: an Annotation's own extent takes in its arrow too
            drawn.append((text, Text.get_window_extent(text, renderer)))

    with mock.patch.object(Text, 'draw', recording_draw):
        figure.canvas.draw()
    return drawn


def _overlap(first: Bbox, second: Bbox) -> bool:
    width = min(first.x1, second.x1) - max(first.x0, second.x0)
    height = min(first.y1, second.y1) - max(first.y0, second.y0)
    return width > TOLERANCE_PX and height > TOLERANCE_PX


def _is_colour_bar(axes: Axes) -> bool:
    return axes.get_label() == '<colorbar>'


def text_problems(figure: Figure) -> List[str]:
    """Return what overlaps: text on text, on an axes it does not belong to, off the page."""
    drawn = drawn_texts(figure)
    problems = []
    page = figure.bbox
    for text, extent in drawn:
        if (extent.x0 < page.x0 - TOLERANCE_PX or extent.y0 < page.y0 - TOLERANCE_PX
                or extent.x1 > page.x1 + TOLERANCE_PX or extent.y1 > page.y1 + TOLERANCE_PX):
            problems.append(f'{text.get_text()!r} is cut by the edge of the figure')
    for k, (text, extent) in enumerate(drawn):
        for other, other_extent in drawn[k + 1:]:
            if _overlap(extent, other_extent):
                problems.append(f'{text.get_text()!r} overlaps {other.get_text()!r}')
        for axes in figure.axes:
            if axes is not text.axes and axes.get_visible() and _overlap(
                    extent, axes.get_window_extent()) and (
                    _is_colour_bar(axes) or axes.name != '3d'):
                problems.append(f'{text.get_text()!r} lies on the axes {axes.get_title()!r} '
                                f'({axes.get_label() or axes.name})')
    return problems


def label_problems(figure: Figure) -> List[str]:
    """Return panels without a title, axes without a unit, short lines without markers."""
    drawn = {id(text) for text, _ in drawn_texts(figure)}
    problems = []
    for axes in figure.axes:
        if not axes.get_visible():
            continue
        if not _is_colour_bar(axes) and not (axes.get_title() or axes.get_title('left')):
            problems.append(f'a panel without a title ({axes.get_xlabel()!r} ...)')
        axis_objects = [axes.xaxis, axes.yaxis] + ([axes.zaxis] if hasattr(axes, 'zaxis')
                                                   else [])
        for axis in axis_objects:
            ticks = [label for tick in axis.get_major_ticks()
                     for label in (tick.label1, tick.label2) if id(label) in drawn]
            if ticks and not UNIT.search(axis.get_label_text()):
                problems.append(f'axis label {axis.get_label_text()!r} of '
                                f'{axes.get_title()!r} has no unit')
        for line in axes.get_lines():
            count = len(line.get_xdata())
            if 1 < count <= FEW_SAMPLES and line.get_marker() in (None, 'None', '', ' '):
                problems.append(f'line {line.get_label()!r} of {count} samples has no marker')
    return problems


def assert_readable(figure: Figure) -> None:
    """Fail with every problem of ``figure`` listed."""
    problems = text_problems(figure) + label_problems(figure)
    assert not problems, '\n'.join(problems)
