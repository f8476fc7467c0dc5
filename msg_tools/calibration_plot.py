"""
The picture of a calibration (matplotlib, no display): how well the fitted model matches.

Three panels: the fitted model's position residual (predicted - measured) per axis against
how far each measured pose lies from the mean one, which shows a misfit of a fraction of a
millimetre and whether it grows with the deflection; and the position and the orientation
error of every sample with the starting values, with the fitted values and, when
cross-validated, predicted with each sample held out of the fit.
"""

import math
from pathlib import Path
from typing import Dict, Tuple, Union

from cdr_translator.calibration.fit_parameters import SI_UNITS
from cdr_translator.calibration.pose_fit import FitResult
from cdr_translator.plotting import sample_marker
from matplotlib.figure import Figure
import numpy as np

#: Unit a fitted value is shown in, and the factor from its SI unit (SI_UNITS) to it.
DISPLAY_UNITS: Dict[str, Tuple[str, float]] = {
    'm': ('mm', 1e3), 'Pa': ('GPa', 1e-9), 'rad': ('deg', math.degrees(1.0)), '1': ('', 1.0)}


def value_text(result: FitResult, name: str) -> str:
    """Return 'name = value +- error unit' in the name's display unit (GPa, mm, deg)."""
    unit, factor = DISPLAY_UNITS[SI_UNITS[name]]
    value, error = factor * result.values[name], factor * result.standard_errors[name]
    spread = f'{error:.2g}' if math.isfinite(error) else 'not assessed'
    return f'{name} = {value:.6g} \N{PLUS-MINUS SIGN} {spread}' + (f' {unit}' if unit else '')


def calibration_figure(result: FitResult) -> Figure:
    """Draw ``result`` (cdr_translator.calibration.pose_fit.FitResult) in three panels."""
    figure = Figure(figsize=(15, 5.6), dpi=110)
    figure.subplots_adjust(left=0.06, right=0.98, top=0.80, bottom=0.22, wspace=0.3)
    residual, positions, angles = figure.subplots(1, 3)
    centre = result.measured_positions.mean(axis=0)
    distance = 1e3 * np.linalg.norm(result.measured_positions - centre, axis=1)
    misfit = 1e3 * (result.predicted_positions - result.measured_positions)
    for axis, name in enumerate('xyz'):
        residual.plot(distance, misfit[:, axis], linestyle='none', marker='.', markersize=4,
                      label=f'residual {name}')
    span = np.linspace(float(distance.min()), float(distance.max()), 100)   # not 2 samples
    residual.plot(span, np.zeros_like(span), color='black', linewidth=0.8, label='_nolegend_')
    rms = float(np.sqrt(np.mean(np.sum(misfit ** 2, axis=1))))
    residual.set(xlabel='distance of the measured pose from the mean one (mm)',
                 ylabel='predicted - measured position (mm)',
                 title=f'Fitted position residual (rms {rms:.3g} mm)')
    index = np.arange(result.samples)
    marker = sample_marker(result.samples)
    panels = ((positions, 1e3 * np.linalg.norm(result.errors_initial[:, :3], axis=1),
               1e3 * np.linalg.norm(result.errors[:, :3], axis=1),
               1e3 * np.linalg.norm(result.cross_validated_errors[:, :3], axis=1)),
              (angles, np.degrees(np.linalg.norm(result.errors_initial[:, 3:], axis=1)),
               np.degrees(np.linalg.norm(result.errors[:, 3:], axis=1)),
               np.degrees(np.linalg.norm(result.cross_validated_errors[:, 3:], axis=1))))
    for axes, start, fitted, held_out in panels:
        axes.plot(index, start, color='tab:gray', marker=marker, linewidth=1.0,
                  label='starting values')
        axes.plot(index, fitted, color='tab:blue', marker=marker, linewidth=1.0,
                  label='fitted values')
        if result.cross_validation_folds:   # points, so the fitted line shows through them
            axes.plot(index, held_out, color='tab:orange', linestyle='none', marker='o',
                      markersize=3.5, markerfacecolor='none', markeredgewidth=0.8,
                      label=f'each sample held out of the fit '
                            f'({result.cross_validation_folds}-fold)')
        axes.set(xlabel='sample (count)', yscale='log')
    positions.set(ylabel='|predicted - measured| (mm)', title='Position error')
    angles.set(ylabel='rotation error (deg)', title='Orientation error')
    for axes in (residual, positions, angles):
        axes.grid(True, alpha=0.3)
    handles, labels = residual.get_legend_handles_labels()
    more_handles, more_labels = positions.get_legend_handles_labels()
    figure.legend(handles + more_handles, labels + more_labels, loc='lower center',
                  ncol=len(labels + more_labels), fontsize='small', frameon=False)
    names = list(result.names)
    lines = ['; '.join(value_text(result, name) for name in names[i:i + 3])
             for i in range(0, len(names), 3)]
    figure.suptitle('\n'.join(lines) + f'\n{result.samples} samples, reduced chi-square '
                    f'{result.reduced_chi_square:.3g}', fontsize='medium')
    return figure


def plot_calibration(result: FitResult, path: Union[str, Path]) -> None:
    """Draw ``result`` to ``path`` (format from its suffix)."""
    calibration_figure(result).savefig(path, dpi=110)
