"""
Figures of one (variant, payload) block of the robot atlas: workspace and stiffness maps.

``AtlasBlock`` holds the arrays a figure needs (from an atlas store with ``atlas_block``,
or built directly); ``workspace_figure`` and ``stiffness_figure`` return matplotlib
Figures, ``save_atlas_figures`` writes both as PNG.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import textwrap
from typing import Dict, List, Sequence

from matplotlib.figure import Figure
import numpy as np

from .samples import AtlasSpec
from ..plotting import colour_scale, load_text, thin_ticks

#: What the stiffness margin is, as the stiffness figure states it.
MARGIN_MEANING = ('Stiffness margin: smallest eigenvalue of the symmetric part of the platform '
                  'stiffness, rotations counted as displacements over the leg stack height; '
                  'positive means the closed chain is stable. Smallest translational '
                  'stiffness: 1 / largest eigenvalue of the translational block of the '
                  'platform compliance (force at the platform origin).')

#: Stability verdicts: name, colour.
VERDICTS = (('stable', 'tab:green'), ('unstable', 'tab:red'), ('not converged', 'grey'))


@dataclass
class AtlasBlock:
    """The samples of one (variant, payload) block and the sweep they come from."""

    position_m: np.ndarray         # (n, 3) platform origin in {w}
    converged: np.ndarray          # (n,) bool
    stable: np.ndarray             # (n,) bool
    parasitic_rad: np.ndarray      # (n,) platform rotation angle from home
    smallest_stiffness: np.ndarray  # (n,) N/m, 1 / largest translational compliance
    margin: np.ndarray             # (n,) N/m, the stiffness margin
    grid: int
    stroke_m: float
    payload_n: Sequence[float]
    volumes: Dict[str, float]      # convex_hull_m3, jacobian_m3

    @property
    def verdicts(self) -> np.ndarray:
        """Return the index into VERDICTS of every sample."""
        return np.where(~self.converged, 2, np.where(self.stable, 0, 1))

    def context(self) -> str:
        """Return the sweep in words: grid, slider stroke and payload."""
        return (f'{self.grid}\u00b3 slider grid over \u00b1{1e3 * self.stroke_m:g} mm, payload '
                f'{load_text(self.payload_n)}')


def atlas_block(spec: AtlasSpec, results: Dict[str, np.ndarray], volume: dict) -> AtlasBlock:
    """Return the first (variant, payload) block of an atlas (``load_results``)."""
    block = slice(0, spec.block)
    with np.errstate(divide='ignore'):
        stiffness = 1.0 / results['compliance_eigenvalues_translation'][block][:, -1]
    return AtlasBlock(results['platform_position'][block], results['converged'][block],
                      results['stable'][block], results['parasitic_rotation'][block],
                      stiffness, results['stiffness_margin'][block], spec.grid,
                      spec.strokes[0], spec.payloads[0],
                      {key: volume[key] for key in ('convex_hull_m3', 'jacobian_m3')})


def _volume_text(volumes: Dict[str, float]) -> str:
    hull, jacobian = volumes['convex_hull_m3'], volumes['jacobian_m3']
    parts = []
    if math.isfinite(hull):
        parts.append(f'{1e6 * hull:.1f} cm\u00b3 (convex hull of the converged stable samples)')
    if math.isfinite(jacobian):
        parts.append(f'{1e6 * jacobian:.1f} cm\u00b3 (integral of |det dp/dq| over the '
                     'slider box)')
    return 'workspace volume ' + ', '.join(parts) if parts else 'workspace volume not computed'


def _label_3d(axes, title: str) -> None:  # axes: a 3-D Axes
    axes.set_title(title, fontsize=9)
    axes.set_xlabel('x (mm)', labelpad=10)
    axes.set_ylabel('y (mm)', labelpad=10)
    axes.set_zlabel('z (mm)', labelpad=10)
    thin_ticks(axes, (5, 5, 5))


def workspace_figure(block: AtlasBlock) -> Figure:
    """Platform positions in 3-D: stability verdict (left) and parasitic rotation (right)."""
    figure = Figure(figsize=(12, 6.4), dpi=110)
    figure.subplots_adjust(left=0.02, right=0.98, top=0.86, bottom=0.04, wspace=0.12)
    position = 1e3 * block.position_m
    verdicts = block.verdicts
    axes = figure.add_subplot(1, 2, 1, projection='3d')
    counts = [int(np.sum(verdicts == k)) for k in range(len(VERDICTS))]
    for k, (name, colour) in enumerate(VERDICTS):
        if counts[k]:
            axes.scatter(*position[verdicts == k].T, color=colour, s=8,
                         label=f'{name} ({counts[k]})')
    shown = [k for k in range(len(VERDICTS)) if counts[k]]
    title = 'Stability verdict of each sample'
    if len(shown) == 1:
        title += f'\nall {counts[shown[0]]} samples {VERDICTS[shown[0]][0]}: one colour'
    _label_3d(axes, title)
    axes.legend(loc='upper left', fontsize=8)
    axes = figure.add_subplot(1, 2, 2, projection='3d')
    converged = block.converged
    scale = colour_scale(np.degrees(block.parasitic_rad[converged]), 'parasitic rotation',
                         'deg', 'viridis')
    if scale.constant:
        axes.scatter(*position[converged].T, color='tab:blue', s=8)
        _label_3d(axes, f'Parasitic rotation of the platform\n{scale.note}')
    else:
        points = axes.scatter(*position[converged].T, c=scale.values, s=8,
                              cmap=scale.colour_map, vmin=scale.limits[0],
                              vmax=scale.limits[1])
        figure.colorbar(points, ax=axes, orientation='horizontal', shrink=0.6, pad=0.08,
                        label=scale.label)
        _label_3d(axes, 'Parasitic rotation of the platform (converged samples)')
    figure.suptitle(f'Continuum Delta Robot workspace: platform positions, {block.context()}\n'
                    f'{_volume_text(block.volumes)}', fontsize=9)
    return figure


def stiffness_figure(block: AtlasBlock) -> Figure:
    """Smallest translational stiffness and stiffness margin, in x-z and x-y projections."""
    figure = Figure(figsize=(10.5, 10), dpi=110)
    axes = figure.subplots(2, 2, gridspec_kw={'left': 0.07, 'right': 0.88, 'top': 0.9,
                                              'bottom': 0.12, 'hspace': 0.3, 'wspace': 0.25})
    position = 1e3 * block.position_m
    views = ((0, 2, 'side view, x-z'), (0, 1, 'top view, x-y'))
    quantities = ((block.smallest_stiffness, 'smallest translational stiffness'),
                  (block.margin, 'stiffness margin'))
    for row, (values, name) in enumerate(quantities):
        shown = block.converged & np.isfinite(values)
        scale = colour_scale(1e-3 * values[shown], name, 'kN/m', 'plasma')
        points = None
        for column, (i, j, view) in enumerate(views):
            panel = axes[row, column]
            if scale.constant:
                points = panel.scatter(position[shown, i], position[shown, j], s=12,
                                       color='tab:purple')
            else:
                points = panel.scatter(position[shown, i], position[shown, j], s=12,
                                       c=scale.values, cmap=scale.colour_map,
                                       vmin=scale.limits[0], vmax=scale.limits[1])
            panel.set_title(f'{name[0].upper() + name[1:]}, {view}\n{scale.note}', fontsize=9)
            panel.set_xlabel(f'{"xyz"[i]} (mm)')
            panel.set_ylabel(f'{"xyz"[j]} (mm)')
            panel.set_aspect('equal', adjustable='datalim')
        if points is not None and not scale.constant:
            figure.colorbar(points, ax=list(axes[row]), label=scale.label, shrink=0.9)
    figure.suptitle(f'Continuum Delta Robot stiffness maps, {block.context()}\n'
                    'projections of the converged samples (nearer samples hide those behind)',
                    fontsize=10)
    figure.text(0.05, 0.015, textwrap.fill(MARGIN_MEANING, 150), fontsize=8, va='bottom')
    return figure


def save_atlas_figures(block: AtlasBlock, stem: Path) -> List[Path]:
    """Write STEM_workspace.png and STEM_stiffness.png; return their paths."""
    paths = [Path(f'{stem}_workspace.png'), Path(f'{stem}_stiffness.png')]
    for path, figure in zip(paths, (workspace_figure(block), stiffness_figure(block))):
        figure.savefig(path, dpi=110)
    return paths
