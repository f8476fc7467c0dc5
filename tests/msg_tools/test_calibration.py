"""msg_tools calibrate and synth --measured-pose-noise: fitted parameters, refusals, frames."""

import contextlib
import io
import json
import math

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.calibration.pose_error import FRAME_NAMES
from cdr_translator.calibration.pose_fit import fit_poses, fit_summary, MAX_REDUCED_CHI_SQUARE
from cdr_translator.cli import main as cdr_main
from cdr_translator.interface.settings import TranslatorSettings
from figure_checks import assert_readable
from mcap_ros2.reader import read_ros2_messages
from msg_tools.__main__ import main
from msg_tools.calibration import (read_pairs, SHARED_POSE_STAMP, SHARED_WRENCH_STAMP,
                                   yaml_number)
from msg_tools.calibration_plot import calibration_figure
import numpy as np
import pytest
import yaml

#: The hidden prototype: another modulus and tube length than config/translator.yaml's.
TRUE_MODULUS, TRUE_TUBE_LENGTH = 8.2e10, 0.1405
#: Samples of the main synthetic recording (seeded).
SAMPLES = 150
#: Measurement noise: position (m), angle (deg).
NOISE = ('2e-4', '0.1')
#: A fitted value must lie this many standard errors from the truth at most (two-sided
#: 99.7 % for an unbiased estimate with correct standard errors).
WITHIN_ERRORS = 3.0
#: Keys of the JSON report that are a contract.
CONTRACT_KEYS = {'parameters', 'samples', 'matched', 'rms_position_error_m',
                 'rms_angle_error_deg', 'cross_validated_rms_position_error_m', 'converged',
                 'message'}


def _run(*args):
    """Run ``python -m msg_tools`` in this process; return (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(arg) for arg in args])
    return code, out.getvalue(), err.getvalue()


def _synth(path, *extra, count=SAMPLES, profile='random-walk'):
    code, _, err = _run('synth', path, '--profile', profile, '--count', count, '--seed', 7,
                        *extra)
    assert code == 0, err
    return path


def _calibrate(*args):
    """Run calibrate with --json; return (exit code, report or None, stderr)."""
    code, out, err = _run('calibrate', *args, '--json')
    return code, json.loads(out) if out.strip() else None, err


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    """Make a folder for this module's recordings and outputs."""
    return tmp_path_factory.mktemp('calibration')


@pytest.fixture(scope='module')
def true_params(folder):
    """Write a partial params file of the hidden prototype."""
    path = folder / 'true.yaml'
    path.write_text('translator_node:\n  ros__parameters:\n'
                    f'    youngs_modulus: {yaml_number(TRUE_MODULUS)}\n'
                    f'    tube_length: {yaml_number(TRUE_TUBE_LENGTH)}\n')
    return path


@pytest.fixture(scope='module')
def recording(folder, true_params):
    """150 random-walk wrenches (bending both ways, axial load, moments) and their poses."""
    return _synth(folder / 'run.mcap', '--force', 10, 10, 5, '--moment', 0.1, 0.1, 0.1,
                  '--measured-pose-noise', *NOISE, '--true-params', true_params,
                  '--pose-stamp-jitter', 0.0005)


@pytest.fixture(scope='module')
def fitted(recording, folder):
    """Calibrate modulus and tube length on ``recording``: (exit code, report, file, plot)."""
    out, plot = folder / 'fitted.yaml', folder / 'calibration.png'
    code, report, err = _calibrate(recording, '--fit', 'youngs_modulus', 'tube_length',
                                   '--out', out, '--plot', plot)
    return code, report, out, plot, err


def test_synth_writes_measured_poses_with_covariance(recording):
    """Each wrench has a pose and a pose with covariance, stamped within the jitter."""
    by_topic = {}
    for item in read_ros2_messages(str(recording)):
        by_topic.setdefault(item.channel.topic, []).append(item.ros_msg)
    wrenches = by_topic['/wrench']
    plain, with_cov = by_topic['/measured_end_disk_pose'], by_topic['/measured_end_disk_pose_cov']
    assert len(wrenches) == len(plain) == len(with_cov) == SAMPLES
    gaps = [abs((pose.header.stamp.sec - wrench.header.stamp.sec) * 10 ** 9
                + pose.header.stamp.nanosec - wrench.header.stamp.nanosec)
            for wrench, pose in zip(wrenches, plain)]
    assert 0 < max(gaps) <= 500_000
    for pose, covariant in zip(plain, with_cov):
        assert (pose.header.stamp.sec, pose.header.stamp.nanosec, pose.header.frame_id) == (
            covariant.header.stamp.sec, covariant.header.stamp.nanosec, 'translator_base')
        for part in ('position', 'orientation'):
            assert ([getattr(getattr(pose.pose, part), axis) for axis in 'xyzw'[:3 + (
                part == 'orientation')]] == [getattr(getattr(covariant.pose.pose, part), axis)
                                             for axis in 'xyzw'[:3 + (part == 'orientation')]])
    covariance = np.reshape(with_cov[0].pose.covariance, (6, 6))
    assert np.allclose(covariance, np.diag([4e-8] * 3 + [math.radians(0.1) ** 2] * 3))


def test_synth_pose_options_need_the_noise(folder, true_params):
    """--true-params without --measured-pose-noise is bad input (exit 2), and so is noise 0."""
    code, _, err = _run('synth', folder / 'x.mcap', '--profile', 'ramp', '--true-params',
                        true_params)
    assert code == 2 and '--measured-pose-noise' in err
    code, _, err = _run('synth', folder / 'x.mcap', '--profile', 'ramp',
                        '--measured-pose-noise', 0, 0.1)
    assert code == 2 and 'positive' in err


def test_calibration_recovers_the_hidden_modulus_and_tube_length(fitted):
    """Both within WITHIN_ERRORS standard errors of the truth, which are small; JSON keys."""
    code, report, _, _, err = fitted
    assert code == 0, err
    assert CONTRACT_KEYS <= set(report)
    assert report['converged'] and report['matched'] == report['samples'] == SAMPLES
    assert 0 < report['largest_stamp_gap_s'] <= 0.0005 + 1e-9
    for name, truth in (('youngs_modulus', TRUE_MODULUS), ('tube_length', TRUE_TUBE_LENGTH)):
        entry = report['parameters'][name]
        assert set(entry) == {'value', 'standard_error', 'initial'}
        assert entry['initial'] == getattr(TranslatorParams.from_yaml(), name)
        assert 0 < entry['standard_error'] < 1e-3 * truth
        assert abs(entry['value'] - truth) <= WITHIN_ERRORS * entry['standard_error'], entry
    # the residuals are the noise: about sqrt(3) * 0.2 mm and sqrt(3) * 0.1 deg
    assert report['rms_position_error_m'] == pytest.approx(math.sqrt(3) * 2e-4, rel=0.15)
    assert report['rms_angle_error_deg'] == pytest.approx(math.sqrt(3) * 0.1, rel=0.15)
    assert report['rms_position_error_m'] < report['cross_validated_rms_position_error_m'] \
        < 1.2 * report['rms_position_error_m']
    assert report['initial_rms_position_error_m'] > 5 * report['rms_position_error_m']
    assert report['reduced_chi_square'] == pytest.approx(1.0, abs=0.15)
    assert report['explains_measurements'] is True and report['folds'] == 5
    assert report['cross_validation_skipped'] is None


def test_fitted_file_reloads_and_changes_the_model(fitted, true_params):
    """A partial params file: the library, the CLI and the node's settings load it."""
    _, report, out, _, _ = fitted
    section = yaml.safe_load(out.read_text())['translator_node']['ros__parameters']
    assert set(section) == {'youngs_modulus', 'tube_length'}
    params = TranslatorParams.from_yaml(out)
    default = TranslatorParams.from_yaml()
    assert params.youngs_modulus == report['parameters']['youngs_modulus']['value']
    assert params.tube_length == report['parameters']['tube_length']['value']
    assert params.with_changes(youngs_modulus=default.youngs_modulus,
                               tube_length=default.tube_length) == default
    assert TranslatorSettings.from_params_file(out).params == params
    out_text = io.StringIO()
    with contextlib.redirect_stdout(out_text):
        assert cdr_main(['solve', '--force', '10', '0', '0', '--params', str(out),
                         '--json']) == 0
    position = json.loads(out_text.getvalue())['end_disk_position_m']
    assert position == pytest.approx(list(TranslatorSolver(params).solve(
        [10.0, 0.0, 0.0]).end_disk_position), abs=1e-9)
    # the fitted model predicts the hidden prototype, the defaults do not
    truth = TranslatorSolver(TranslatorParams.from_yaml(true_params)).solve(
        [10.0, 0.0, 0.0]).end_disk_position
    default_position = TranslatorSolver(default).solve([10.0, 0.0, 0.0]).end_disk_position
    assert np.linalg.norm(default_position - truth) > 1e-3
    assert np.linalg.norm(np.array(position) - truth) < 0.05 * np.linalg.norm(
        default_position - truth)


def test_plot_is_written_and_readable(fitted, recording):
    """The picture: written by the command, and every panel titled, labelled with units."""
    _, report, _, plot, _ = fitted
    assert report['plot'] == str(plot) and plot.stat().st_size > 10_000
    pairing = read_pairs([recording])
    assert pairing.matched == SAMPLES


def test_unidentifiable_requests_are_refused_with_the_reason(folder):
    """Collinear keys and a key without effect: exit 4, rank and condition number named."""
    lateral = _synth(folder / 'lateral.mcap', '--force', 10, 0, 0, '--measured-pose-noise',
                     *NOISE, count=20, profile='ramp')
    code, report, err = _calibrate(lateral, '--fit', 'youngs_modulus', 'backbone_diameter')
    assert code == 4 and not report['converged'] and not report['identifiable']
    assert 'condition number' in report['message'] and 'rank 2 of 2' in report['message']
    assert 'youngs_modulus' in report['message'] and 'backbone_diameter' in report['message']
    assert report['condition_number'] > 100
    assert CONTRACT_KEYS <= set(report) and report['parameters']['youngs_modulus']['value'] \
        is None
    assert 'refused' in err
    unloaded = _synth(folder / 'one.mcap', '--measured-pose-noise', *NOISE, count=1,
                      profile='ramp')
    code, report, _ = _calibrate(unloaded, '--fit', 'youngs_modulus', 'tube_length')
    assert code == 4 and report['rank'] == 1
    assert 'youngs_modulus does not change the predicted poses' in report['message']
    code, report, _ = _calibrate(lateral, '--fit', 'poisson_ratio')
    assert code == 4 and 'predicted standard error above one unit' in report['message']


@pytest.mark.parametrize('names, reason', [
    (['youngs_modulu'], 'did you mean youngs_modulus'),
    (['base_frame'], 'base_frame: not numeric'),
    (['spacers_per_joint'], 'spacers_per_joint: a whole number'),
    (['max_force'], 'max_force: does not change the predicted pose'),
])
def test_bad_keys_are_named(recording, names, reason):
    """Unknown, non-numeric, discrete and non-model keys: exit 2 before any solve."""
    code, report, err = _calibrate(recording, '--fit', *names)
    assert code == 2 and report is None and reason in err


def test_stamp_tolerance_pairs_nearest_and_reports(recording):
    """A tolerance below the jitter leaves wrenches unpaired, counted; the gap stays within."""
    pairing = read_pairs([recording], tolerance_s=0.0002)
    assert 0 < pairing.matched < SAMPLES
    assert pairing.skipped == {'wrench without a pose within the stamp tolerance':
                               SAMPLES - pairing.matched}
    assert pairing.largest_gap_s <= 0.0002


def test_frame_fit_recovers_the_tracker_frame(folder):
    """A tracker 30 cm away, turned 0.46 rad: the frame and the modulus within errors."""
    offset = [0.05, -0.02, 0.3, 0.1, -0.2, 0.4]
    path = _synth(folder / 'tracker.mcap', '--force', 10, 10, 5, '--moment', 0.1, 0.1, 0.1,
                  '--measured-pose-noise', *NOISE, '--frame-offset', *offset, count=60)
    code, report, err = _calibrate(path, '--fit', 'youngs_modulus', '--fit-frame',
                                   '--folds', 0)
    assert code == 0, err
    assert report['pose_frame'] == 'tracker'
    truth = dict(zip(FRAME_NAMES, offset), youngs_modulus=TranslatorParams.from_yaml(
    ).youngs_modulus)
    for name, value in truth.items():
        entry = report['parameters'][name]
        assert abs(entry['value'] - value) <= WITHIN_ERRORS * entry['standard_error'], name
    assert report['cross_validated_rms_position_error_m'] is None   # --folds 0
    # the frame left out: the modulus alone cannot explain a tracker 30 cm away
    short = _synth(folder / 'tracker_short.mcap', '--force', 10, 10, 5,
                   '--measured-pose-noise', *NOISE, '--frame-offset', *offset, count=10)
    code, report, err = _calibrate(short, '--fit', 'youngs_modulus', '--folds', 0,
                                   '--out', folder / 'never.yaml')
    assert code == 3 and not report['converged'] and 'not converged' in err
    assert 'youngs_modulus ran to the end' in report['message']
    assert report['rms_position_error_m'] > 0.1 and 'tracker frame' in report['warnings'][0]
    assert report['fitted_params_file'] is None and not (folder / 'never.yaml').exists()
    # no optimum, so nothing assessed there: no standard error, no correlation, no CV
    assert report['parameters']['youngs_modulus']['standard_error'] is None
    assert report['explains_measurements'] is None
    assert report['cross_validation_skipped'] == 'the fit did not converge'
    assert err.count('not converged') == 1, err


def test_a_fit_that_did_not_converge_says_so_plainly(recording):
    """The text report: the last trial, not a 'fitted' value; no standard error of 0."""
    pairing = read_pairs([recording])
    result = fit_poses(pairing.samples.subset(np.arange(20)), TranslatorParams.from_yaml(),
                       ['youngs_modulus'], max_evaluations=1)   # stopped before its optimum
    assert not result.converged and not result.message.startswith('not converged')
    assert math.isnan(result.standard_errors['youngs_modulus'])
    assert result.explains_measurements is None
    lines = fit_summary(result)
    assert lines[0].split()[-4:] == ['last', 'trial', 'std', 'error'], lines[0]
    assert lines[1].split()[0] == 'youngs_modulus' and lines[1].endswith('not assessed')
    assert 'cross-validation not done: the fit did not converge' in lines


def test_cross_validation_is_reported_only_when_something_was_held_out(folder):
    """One sample, 5 folds asked: fitted, and said plainly that nothing was held out."""
    one = _synth(folder / 'single.mcap', '--force', 10, 10, 5, '--measured-pose-noise',
                 *NOISE, count=1)
    code, out, err = _run('calibrate', one, '--fit', 'youngs_modulus')
    assert code == 0, err
    assert 'cross-validated' not in out
    assert 'cross-validation not done: 1 sample cannot be split' in out
    code, report, err = _calibrate(one, '--fit', 'youngs_modulus')
    assert report['folds'] == 0 and report['cross_validated_rms_position_error_m'] is None
    assert report['cross_validation_skipped'].startswith('1 sample cannot be split')
    code, out, err = _run('calibrate', one, '--fit', 'youngs_modulus', '--folds', 0)
    assert 'cross-validation not done: not asked for (0 folds)' in out
    code, out, err = _run('calibrate', one, '--fit', 'youngs_modulus', '--folds', 1)
    assert code == 2 and out == '' and 'one fold holds nothing out' in err


def test_ambiguous_pairs_are_dropped_counted_and_reported(folder):
    """40 wrenches and poses on 5 stamps (1e10 Hz): none paired, exit 2, the counts named."""
    path = _synth(folder / 'shared_stamps.mcap', '--rate', '1e10', '--measured-pose-noise',
                  '1e-5', '0.01', count=40)
    pairing = read_pairs([path])
    assert pairing.matched == 0 and pairing.wrenches == pairing.poses == 40
    assert pairing.skipped == {SHARED_WRENCH_STAMP: 40, SHARED_POSE_STAMP: 40}
    code, report, err = _calibrate(path, '--fit', 'youngs_modulus')
    assert code == 2 and report is None
    assert f'{SHARED_WRENCH_STAMP}: 40' in err and f'{SHARED_POSE_STAMP}: 40' in err


def test_a_fit_that_does_not_explain_the_measurements_is_not_a_success(folder):
    """A tube 20 mm shorter than the model's, only the modulus fitted: exit 5, no file."""
    short_tube = folder / 'short_tube.yaml'
    short_tube.write_text('translator_node:\n  ros__parameters:\n    tube_length: 0.12\n')
    path = _synth(folder / 'short_tube.mcap', '--force', 10, 10, 5, '--measured-pose-noise',
                  '1e-4', '0.05', '--true-params', short_tube, count=30)
    out = folder / 'not_written.yaml'
    code, report, err = _calibrate(path, '--fit', 'youngs_modulus', '--out', out)
    assert code == 5 and report['converged'] and report['explains_measurements'] is False
    assert report['reduced_chi_square'] > report['max_reduced_chi_square'] == \
        MAX_REDUCED_CHI_SQUARE
    assert report['fitted_params_file'] is None and not out.exists()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        'error: the fit does not explain the measurements: reduced chi-square'), err


def test_figure_is_readable(recording):
    """The calibration figure passes the project's readability checks."""
    pairing = read_pairs([recording])
    subset = pairing.samples.subset(np.arange(20))
    result = fit_poses(subset, TranslatorParams.from_yaml(), ['youngs_modulus', 'tube_length'],
                       folds=2)
    figure = calibration_figure(result)
    assert_readable(figure)
    title = figure.texts[0].get_text()   # the suptitle: every value with its unit
    assert ' GPa' in title.split(';')[0] and title.split(';')[1].split('\n')[0].endswith(' mm')
    residual = figure.axes[0]
    assert residual.get_title().startswith('Fitted position residual (rms ')
    low, high = residual.get_ylim()   # the residual's own scale, not the deflections'
    assert high - low < 20 * 1e3 * np.abs(result.predicted_positions
                                          - result.measured_positions).max()
    assert all(axes.get_legend() is None for axes in figure.axes)   # none covers data
    held_out = [line for line in figure.axes[1].get_lines() if 'held out' in line.get_label()]
    fitted = [line for line in figure.axes[1].get_lines() if line.get_label() == 'fitted values']
    assert held_out[0].get_linestyle() == 'None' and fitted[0].get_linestyle() == '-'
    assert held_out[0].get_color() != fitted[0].get_color()


def test_fit_report_names_the_si_unit_of_every_value(recording):
    """The text report's parameter column says each value's SI unit."""
    pairing = read_pairs([recording])
    result = fit_poses(pairing.samples.subset(np.arange(10)), TranslatorParams.from_yaml(),
                       ['youngs_modulus'], folds=0)
    lines = fit_summary(result)
    assert lines[0].startswith('parameter (SI unit)') and lines[1].startswith(
        'youngs_modulus (Pa)')


def test_damaged_input_is_used_and_reported(folder):
    """A file cut inside its summary: the pairs are salvaged, fitted, and the exit code is 1."""
    path = _synth(folder / 'cut.mcap', '--force', 10, 0, 0, '--measured-pose-noise', *NOISE,
                  count=20, profile='ramp')
    path.write_bytes(path.read_bytes()[:-40])
    code, report, err = _calibrate(path, '--fit', 'youngs_modulus', '--folds', 0)
    assert code == 1 and report['converged'] and report['matched'] == 20
    assert 'salvaged' in err and 'salvaged' in report['inputs'][0]


def _info_damage(path):
    """Return what ``msg_tools info`` says of a damaged file, but the data-CRC verdict."""
    code, out, _ = _run('info', path)
    assert code == 0
    read = next(line for line in out.splitlines() if line.startswith('read:'))
    damage = read.split(':', 1)[1].strip()
    for verdict in ('valid', 'MISMATCH', 'unchecked'):   # info's own last words
        damage = damage.removesuffix(f'; data-section CRC {verdict}')
    return damage.removesuffix('; no data-section CRC stored')


def test_an_unusable_damaged_input_is_named_as_info_names_it(folder):
    """An empty file, one with 30 flipped bytes: the damage as info says it, not 'none'."""
    empty = folder / 'empty.mcap'
    empty.write_bytes(b'')
    damage = _info_damage(empty)
    assert damage.startswith('DAMAGED: ')
    code, report, err = _calibrate(empty, '--fit', 'youngs_modulus')
    assert code == 2 and report is None and damage in err and len(err.splitlines()) == 1
    flipped = _synth(folder / 'flipped.mcap', '--force', 10, 0, 0, '--measured-pose-noise',
                     *NOISE, count=20, profile='ramp')
    data = bytearray(flipped.read_bytes())
    for index in np.linspace(8, len(data) - 9, 30).astype(int):
        data[index] ^= 0xFF
    flipped.write_bytes(bytes(data))
    damage = _info_damage(flipped)
    assert damage.startswith('DAMAGED: ') and 'unreadable' in damage
    code, report, err = _calibrate(flipped, '--fit', 'youngs_modulus', '--folds', 0)
    assert code in (1, 2) and damage in err, err
