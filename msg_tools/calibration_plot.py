"""
The picture of a calibration (matplotlib, no display): measured against predicted poses.

Three panels: the end-disk positions predicted with the fitted values against the measured
ones (each axis relative to the mean measured position, so that the deflections and not
the stack height fill the panel; on the diagonal when the model fits), and the position
and the orientation error of every sample with the starting and with the fitted values
(and, when cross-validated, the held-out prediction error).
"""

from pathlib import Path
from typing import Union

from cdr_translator.calibration.pose_fit import FitResult
from cdr_translator.plotting import sample_marker
from matplotlib.figure import Figure
import numpy as np


def _value_text(result: FitResult, name: str) -> str:
    """Return 'name = value +- error' with the error's precision."""
    return (f'{name} = {result.values[name]:.5g} '
            f'\N{PLUS-MINUS SIGN} {result.standard_errors[name]:.2g}')


def calibration_figure(result: FitResult) -> Figure:
    """Draw ``result`` (cdr_translator.calibration.pose_fit.FitResult) in three panels."""
    figure = Figure(figsize=(15, 5.2), dpi=110)
    figure.subplots_adjust(left=0.05, right=0.98, top=0.82, bottom=0.12, wspace=0.3)
    scatter, positions, angles = figure.subplots(1, 3)
    centre = result.measured_positions.mean(axis=0)
    measured = 1e3 * (result.measured_positions - centre)
    predicted = 1e3 * (result.predicted_positions - centre)
    for axis, name in enumerate('xyz'):
        scatter.plot(measured[:, axis], predicted[:, axis], linestyle='none', marker='.',
                     markersize=4, label=name)
    low = float(min(measured.min(), predicted.min()))
    high = float(max(measured.max(), predicted.max()))
    diagonal = np.linspace(low, high, 100)   # a drawn line, not two samples
    scatter.plot(diagonal, diagonal, color='black', linewidth=0.8, label='equal')
    scatter.set(xlabel='measured - mean measured (mm)',
                ylabel='predicted - mean measured (mm)',
                title='End-disk position, fitted model')
    scatter.set_aspect('equal', adjustable='datalim')
    scatter.legend(fontsize='small')
    index = np.arange(result.samples)
    marker = sample_marker(result.samples)
    series = [('start', result.errors_initial, 'tab:gray', '-')]
    if result.cross_validation_folds:   # under the fitted line, which it nearly equals
        series.append((f'held out ({result.cross_validation_folds}-fold)',
                       result.cross_validated_errors, 'tab:orange', '-'))
    series.append(('fitted', result.errors, 'tab:blue', ':'))
    for label, errors, colour, style in series:
        positions.plot(index, 1e3 * np.linalg.norm(errors[:, :3], axis=1), color=colour,
                       marker=marker, linewidth=1.0, linestyle=style, label=label)
        angles.plot(index, np.degrees(np.linalg.norm(errors[:, 3:], axis=1)), color=colour,
                    marker=marker, linewidth=1.0, linestyle=style, label=label)
    positions.set(xlabel='sample (count)', ylabel='|predicted - measured| (mm)',
                  title='Position error', yscale='log')
    angles.set(xlabel='sample (count)', ylabel='rotation error (deg)',
               title='Orientation error', yscale='log')
    for axes in (scatter, positions, angles):
        axes.grid(True, alpha=0.3)
    positions.legend(fontsize='small')
    names = list(result.names)
    lines = ['; '.join(_value_text(result, name) for name in names[i:i + 3])
             for i in range(0, len(names), 3)]
    figure.suptitle('\n'.join(lines) + f'\n{result.samples} samples, reduced chi-square '
                    f'{result.reduced_chi_square:.3g}', fontsize='medium')
    return figure


def plot_calibration(result: FitResult, path: Union[str, Path]) -> None:
    """Draw ``result`` to ``path`` (format from its suffix)."""
    calibration_figure(result).savefig(path, dpi=110)
