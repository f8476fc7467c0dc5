"""
``python -m msg_tools calibrate``: read, pair, fit, report, write the fitted params file.

Exit codes: 0 fitted; 1 fitted, but an input file was damaged (what could be read was
used); 2 bad arguments or unusable input (no such file, an unknown or non-numeric key, no
wrench paired with a pose, a wrench that does not solve at the start; nothing written; a
damaged input is named as ``info`` names it); 3 the fit did not converge (nothing written
but the report and the plot); 4 refused: the recordings cannot determine the requested
parameters (the reason names the rank, the condition number, the parameters); 5 the fit
converged but does not explain the measurements: its reduced chi-square is above
pose_fit.MAX_REDUCED_CHI_SQUARE (nothing written but the report and the plot). 130 and 141
as every command.
"""

import argparse
import json
import math
from pathlib import Path
import sys
from typing import Any, Dict, List, Optional

from cdr_translator.calibration.fit_parameters import check_fit_names
from cdr_translator.calibration.pose_error import check_frame, FRAME_NAMES
from cdr_translator.calibration.pose_fit import (fit_poses, fit_summary, FitResult,
                                                 MAX_REDUCED_CHI_SQUARE, rms_angle_deg,
                                                 rms_position, UnidentifiableError)
from cdr_translator.console import add_command, finite_or_none
from cdr_translator.params.translator_params import translator_values, TranslatorParams
from msg_tools.calibration import fitted_params_text, Pairing, read_pairs
from msg_tools.calibration_plot import plot_calibration
from msg_tools.info import damage_text
from msg_tools.output_paths import check_distinct, check_output
from msg_tools.plots import check_plot_path

EXIT_OK, EXIT_DAMAGED_INPUT, EXIT_USAGE, EXIT_NOT_CONVERGED, EXIT_UNIDENTIFIABLE = 0, 1, 2, 3, 4
#: The fit converged, but its residuals are far beyond the measurements' covariances.
EXIT_POOR_FIT = 5


def add_frame_option(parser: argparse.ArgumentParser, flag: str, what: str) -> None:
    """Add ``flag`` taking a tracker frame's 6 numbers (cdr_translator.calibration.pose_error)."""
    parser.add_argument(flag, type=float, nargs=6, metavar='N',
                        help=f'{what}, in the base frame: X Y Z (m) RX RY RZ (rotation '
                             'vector, rad); default all 0')


def add_parser(commands: Any) -> None:
    """Add the ``calibrate`` subcommand to the subparsers ``commands``."""
    calibrate = add_command(
        commands, 'calibrate', 'fit model parameters (and a tracker frame) to measured poses',
        'Pairs each recorded wrench with the measured pose of the same stamp, fits, reports '
        'the fit and its cross-validation, and writes the fitted keys (--out).',
        # argparse has no "at least one of": the usage says it, run_calibrate enforces it
        usage='%(prog)s [-h] (--fit NAME [NAME ...] [--fit-frame] | --fit-frame)\n'
              '       [--frame N N N N N N] [--params PARAMS] [--out OUT] [--json] '
              '[--plot PLOT]\n       [--stamp-tolerance S] [--sigma POS_M ANG_DEG] '
              '[--folds FOLDS]\n       RUN.mcap [RUN.mcap ...]')
    calibrate.add_argument('inputs', nargs='+', metavar='RUN.mcap',
                           help='recordings holding wrenches and measured end-disk poses')
    fitted = calibrate.add_argument_group(
        'what to fit (required: --fit, --fit-frame or both)')
    fitted.add_argument('--fit', nargs='+', default=[], metavar='NAME',
                        help='translator_node keys to fit, e.g. youngs_modulus tube_length')
    fitted.add_argument('--fit-frame', action='store_true',
                        help='fit the tracker frame (6 numbers: x y z, rotation vector)')
    add_frame_option(calibrate, '--frame', 'tracker frame when not fitted')
    calibrate.add_argument('--params', help='params file of the starting values (default: '
                                            'config/translator.yaml)')
    calibrate.add_argument('--out', help='write the fitted keys as a partial params file')
    calibrate.add_argument('--json', action='store_true', help='print the report as JSON')
    calibrate.add_argument('--plot', help='PNG: measured against predicted poses, errors')
    calibrate.add_argument('--stamp-tolerance', type=float, default=0.002, metavar='S',
                           help='largest stamp difference of a wrench and its pose; '
                                'default 0.002 s')
    calibrate.add_argument('--sigma', type=float, nargs=2, default=[1e-3, 0.5],
                           metavar=('POS_M', 'ANG_DEG'),
                           help='assumed standard deviations of poses without covariance; '
                                'default 0.001 m 0.5 deg')
    calibrate.add_argument('--folds', type=int, default=5,
                           help='k of the k-fold cross-validation (0: none, else 2 or more; '
                                'at most one fold per sample is made); default 5')


def _number(value: float) -> Optional[float]:
    """Return ``value`` for JSON (None when not finite)."""
    return float(value) if math.isfinite(value) else None


def _pairing_report(pairing: Pairing, tolerance_s: float) -> Dict[str, Any]:
    """Return the pairing part of the JSON report."""
    return {'wrenches': pairing.wrenches, 'poses': pairing.poses, 'matched': pairing.matched,
            'largest_stamp_gap_s': _number(pairing.largest_gap_s),
            'stamp_tolerance_s': tolerance_s, 'skipped': dict(pairing.skipped),
            'covariance_source': pairing.covariance_source,
            'pose_frame': pairing.pose_frames[0] if pairing.pose_frames else None,
            'inputs': [report.describe() for report in pairing.reports]}


def _fit_report(result: FitResult) -> Dict[str, Any]:
    """Return the fit part of the JSON report."""
    names = list(result.names)
    cv = result.cross_validated_errors
    return {
        'parameters': {name: {'value': result.values[name],
                              'standard_error': _number(result.standard_errors[name]),
                              'initial': result.initial[name]} for name in names},
        'samples': result.samples,
        'rms_position_error_m': rms_position(result.errors),
        'rms_angle_error_deg': rms_angle_deg(result.errors),
        'max_position_error_m': float(max(map(float, (
            (result.errors[:, :3] ** 2).sum(axis=1) ** 0.5)))),
        'initial_rms_position_error_m': rms_position(result.errors_initial),
        'initial_rms_angle_error_deg': rms_angle_deg(result.errors_initial),
        'cross_validated_rms_position_error_m': _number(rms_position(cv)),
        'cross_validated_rms_angle_error_deg': _number(rms_angle_deg(cv)),
        'folds': result.cross_validation_folds,
        'cross_validation_skipped': result.cross_validation_skipped or None,
        'correlation': {'names': names, 'matrix': finite_or_none(result.correlation.tolist())},
        'reduced_chi_square': _number(result.reduced_chi_square),
        'explains_measurements': result.explains_measurements,
        'max_reduced_chi_square': MAX_REDUCED_CHI_SQUARE,
        'degrees_of_freedom': result.degrees_of_freedom,
        'condition_number': _number(result.condition_number), 'rank': result.rank,
        'converged': result.converged, 'message': result.message,
        'warnings': result.warnings,
        'max_discretization_error_m': _number(result.max_discretization_error_m),
        'timing': {'fit_s': result.fit_time_s,
                   'cross_validation_s': result.cross_validation_time_s,
                   'model_passes': result.model_passes}}


def _refusal_report(error: UnidentifiableError, names: List[str],
                    start: Dict[str, float]) -> Dict[str, Any]:
    """Return the JSON report of a refused fit."""
    return {'parameters': {name: {'value': None, 'standard_error': None,
                                  'initial': start.get(name)} for name in names},
            'samples': None, 'rms_position_error_m': None, 'rms_angle_error_deg': None,
            'cross_validated_rms_position_error_m': None, 'converged': False,
            'identifiable': False, 'message': error.reason, 'rank': error.rank,
            'condition_number': _number(error.condition_number),
            'predicted_standard_errors_units': {
                name: _number(value) for name, value in error.predicted_standard_errors.items()}}


def _prepare(args: argparse.Namespace) -> tuple:
    """Check the arguments, read and pair the inputs; ValueError saying what is wrong."""
    for option, value in (('--out', args.out), ('--plot', args.plot)):
        if value is not None and not value.strip():
            raise ValueError(f'{option} needs a file name, got {value!r}')
    if args.plot:
        check_plot_path(args.plot)
    for path in args.inputs:
        check_distinct(path, [('fitted params file', args.out), ('plot', args.plot)])
    for what, path in (('fitted params file', args.out), ('plot', args.plot)):
        if path:
            check_output(path, what)
    if args.folds < 0 or args.folds == 1:
        raise ValueError(f'--folds must be 0 (no cross-validation) or 2 or more (one fold '
                         f'holds nothing out), got {args.folds}')
    values = translator_values(args.params)
    names = list(check_fit_names(args.fit, values))
    if not names and not args.fit_frame:
        raise ValueError('nothing to fit: give --fit NAME [NAME ...] and/or --fit-frame')
    if args.frame is not None:
        check_frame(args.frame)
    pairing = read_pairs(args.inputs, args.stamp_tolerance, values['base_frame'], args.sigma)
    if not pairing.matched:
        skipped = ', '.join(f'{reason}: {count}' for reason, count in sorted(
            pairing.skipped.items()))
        raise ValueError('; '.join([damage_text(report) for report in pairing.reports
                                    if not report.complete] + [
            f'no wrench paired with a measured pose within {args.stamp_tolerance:g} s '
            f'({pairing.wrenches} wrenches, {pairing.poses} poses read; skipped: '
            f'{skipped or "none"})']))
    return values, names, pairing


def run_calibrate(args: argparse.Namespace) -> int:
    """Run ``calibrate`` with parsed ``args``; return the exit code."""
    try:
        values, names, pairing = _prepare(args)
        report = _pairing_report(pairing, args.stamp_tolerance)
        for problem in pairing.reports:
            if not problem.complete:
                print(f'warning: {damage_text(problem)}', file=sys.stderr)
        result = fit_poses(pairing.samples, TranslatorParams.from_mapping(values), names,
                           args.fit_frame, args.frame, args.folds)
    except UnidentifiableError as error:
        report.update(_refusal_report(error, names + list(FRAME_NAMES if args.fit_frame
                                                          else ()),
                                      {name: values[name] for name in names}))
        report['samples'] = pairing.matched
        if args.json:
            _emit(args, report, [])
        print(f'error: refused: {error.reason}', file=sys.stderr)
        return EXIT_UNIDENTIFIABLE
    except ValueError as error:
        print(f'error: {error}', file=sys.stderr)
        return EXIT_USAGE
    report.update(_fit_report(result))
    lines = [f'{pairing.matched} of {pairing.wrenches} wrenches paired with a pose (largest '
             f'stamp gap {pairing.largest_gap_s:.3g} s, tolerance {args.stamp_tolerance:g} s; '
             f'weights: {pairing.covariance_source})'] + [
        f'skipped {count}: {reason}' for reason, count in sorted(pairing.skipped.items())]
    lines += fit_summary(result) + [f'{"converged" if result.converged else "NOT converged"}: '
                                    f'{result.message}']
    report['fitted_params_file'] = report['plot'] = None
    poor = result.explains_measurements is False
    if args.out and result.converged and not poor:
        Path(args.out).write_text(fitted_params_text(
            result.values, names, args.inputs, result.samples, values['base_frame'],
            report['pose_frame'] or ''), encoding='utf-8')
        report['fitted_params_file'] = args.out
        lines.append(f'wrote {args.out}')
    if args.plot:
        plot_calibration(result, args.plot)
        report['plot'] = args.plot
        lines.append(f'wrote {args.plot}')
    _emit(args, report, lines)
    if not result.converged:
        print(f'error: not converged: {result.message}', file=sys.stderr)
        return EXIT_NOT_CONVERGED
    if poor:
        print(f'error: the fit does not explain the measurements: reduced chi-square '
              f'{result.reduced_chi_square:.3g} (at most {MAX_REDUCED_CHI_SQUARE:g}), residuals '
              f'{math.sqrt(result.reduced_chi_square):.3g} times the measurement standard '
              'deviations: a key left out, a wrong tracker frame, covariances too small '
              '(--sigma) or wrong pairs; nothing written', file=sys.stderr)
        return EXIT_POOR_FIT
    return EXIT_OK if pairing.complete else EXIT_DAMAGED_INPUT


def _emit(args: argparse.Namespace, report: Dict[str, Any], lines: List[str]) -> None:
    """Print the report: JSON with ``--json``, else the text lines."""
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=False))
    else:
        print('\n'.join(lines))
