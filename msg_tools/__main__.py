"""
Command line of msg_tools (no ROS needed): info, synth, replay, calibrate.

    python -m msg_tools info FILE.mcap [--no-crc]
    python -m msg_tools synth OUT.mcap --profile ramp|step|sinusoid|random-walk|paper|hard
                              [--measured-pose-noise POS_M ANG_DEG [--true-params FILE]
                               [--frame-offset X Y Z RX RY RZ] [--pose-stamp-jitter S]]
    python -m msg_tools replay IN.mcap --out OUT.mcap [--topic NAME] [--params FILE]
                               [--csv FILE] [--plot FILE.png] [--fidelity full|rod|cc|auto
                               [--max-position-error M] [--max-angle-error DEG]]
                               [--workers K | --scheduler ADDRESS]
                               [--estimate COMPONENTS] [--held-force FX FY FZ]
                               [--held-moment MX MY MZ] [--prior-force-sd N]
                               [--prior-moment-sd NM] [--target-force-sd N]
                               [--target-moment-sd NM] [--pose-sd POSITION_M ORIENTATION_RAD]
    python -m msg_tools calibrate RUN.mcap [RUN2.mcap ...] --fit NAME [NAME ...]
                                  [--fit-frame] [--params FILE] [--out fitted.yaml] [--json]
                                  [--plot PATH.png] [--stamp-tolerance S]

Exit codes (replay; docs/reference/cli.md): 0 all good; 1 the input was damaged, what could be
read was replayed; 2 bad arguments, unusable input or an output that cannot be written
(checked before reading; message on stderr, no traceback); 3 nothing could be decoded or
solved; 130 interrupted by Ctrl-C (the output MCAP is finalized all the same). info and
synth: 0 done (info also for a damaged file, which it reports), 2 bad arguments or unusable
input. calibrate (docs/howto/measurements.md): 0 fitted; 1 fitted from a damaged input; 2 bad
arguments or unusable input; 3 not converged; 4 refused, the parameters cannot be
identified from the recordings; 5 the fit does not explain the measurements. All: 141
when stdout was closed early (``| head``).
"""

import argparse
import sys
from typing import Any, Dict, Optional, Sequence, Tuple

from cdr_translator.console import (add_command, CommandParser, EXIT_BROKEN_PIPE, quiet_sigint,
                                    run_command)

quiet_sigint()  # before the imports below load numpy and the solver: Ctrl-C stays one line

from cdr_translator.interface.fidelity_options import (  # noqa: E402
    add_fidelity_arguments, fidelity_parameters)
from cdr_translator.interface.settings import check_value, TranslatorSettings  # noqa: E402
from msg_tools import synth  # noqa: E402
from msg_tools.calibration_command import (  # noqa: E402
    add_frame_option, add_parser, run_calibrate)
from msg_tools.errors import ReplayError  # noqa: E402
from msg_tools.info import describe  # noqa: E402
from msg_tools.plots import check_plot_path, plot_replay  # noqa: E402
from msg_tools.replay import replay  # noqa: E402
from msg_tools.replay_summary import (  # noqa: E402
    EXIT_DAMAGED_INPUT, EXIT_NOTHING_SOLVED, EXIT_OK, EXIT_USAGE)
from msg_tools.replay_windows import replay_on_dask  # noqa: E402
from msg_tools.synth import PROFILES  # noqa: E402
from msg_tools.synth_poses import check_noise, measure  # noqa: E402

__all__ = ['ESTIMATE_FLAGS', 'EXIT_BROKEN_PIPE', 'main', 'replay_parameters']


def _parser() -> argparse.ArgumentParser:
    """Build the argument parser."""
    parser = CommandParser(prog='python -m msg_tools', description=__doc__.split(
        '\n\n')[0].strip(), formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest='command', required=True)

    info = add_command(commands, 'info', 'topics, types, counts and time range of an MCAP',
                       'Every chunk is read and its CRC checked; a damaged file is named '
                       'DAMAGED with what was lost, a partial replay output as PARTIAL.')
    info.add_argument('file', metavar='FILE.mcap', help='the MCAP file to describe')
    info.add_argument('--no-crc', action='store_true',
                      help='trust the summary: skip reading the chunks and checking CRCs')

    synth = add_command(commands, 'synth', 'write a synthetic WrenchStamped sequence',
                        'Stamps start at 2024-01-01T00:00:00Z; the MCAP log time of each '
                        'message is its stamp (reproducible files).')
    synth.add_argument('output', metavar='OUT.mcap', help='the MCAP file written')
    synth.add_argument('--profile', choices=PROFILES, required=True,
                       help='ramp: zero to the peak wrench in equal steps; step: zero for the '
                            'first third, then the peak; sinusoid: the peak times '
                            'sin(2 pi f t); random-walk: seeded Gaussian increments within the '
                            "peak; paper: the paper's two Table II cases; hard: large, "
                            'reversing and invalid inputs a node must survive')
    synth.add_argument('--count', type=int, default=200,
                       help='samples (ramp, step, sinusoid, random-walk); default 200')
    synth.add_argument('--rate', type=float, default=100.0, help='Hz; default 100')
    synth.add_argument('--force', type=float, nargs=3, default=[20.0, 0.0, 0.0],
                       metavar=('FX', 'FY', 'FZ'), help='peak force (N); default 20 0 0')
    synth.add_argument('--moment', type=float, nargs=3, default=[0.0, 0.0, 0.0],
                       metavar=('MX', 'MY', 'MZ'), help='peak moment (N m); default 0 0 0')
    synth.add_argument('--frequency', type=float, default=0.5, help='sinusoid Hz; default 0.5')
    synth.add_argument('--seed', type=int, default=0, help='random-walk seed; default 0')
    synth.add_argument('--frame-id', default='', help="header.frame_id; default ''")
    synth.add_argument('--topic', default='/wrench', help='default /wrench')
    synth.add_argument('--measured-pose-noise', type=float, nargs=2, metavar=('POS_M', 'ANG_DEG'),
                       help='also write noisy measured end-disk poses (seeded by --seed)')
    synth.add_argument('--true-params', metavar='FILE',
                       help='params file (over the defaults) the measured poses are solved with')
    add_frame_option(synth, '--frame-offset', 'tracker frame of the poses')
    synth.add_argument('--pose-stamp-jitter', type=float, default=0.0, metavar='S',
                       help='pose stamps = wrench stamps + uniform [-S, S] s; default 0')

    replay = add_command(commands, 'replay', 'solve recorded wrenches as the node would',
                         'Writes the inputs and every output translator_node would publish to '
                         '--out; optionally a CSV row per input message and a plot.')
    replay.add_argument('input', metavar='IN.mcap',
                        help='recording holding WrenchStamped (and measured poses)')
    replay.add_argument('--out', required=True, help='output MCAP (inputs + node outputs)')
    replay.add_argument('--topic', action='append',
                        help='wrench topic (repeatable); default: every WrenchStamped channel')
    replay.add_argument('--params', help='params file (default: config/translator.yaml)')
    replay.add_argument('--csv', help='one row per input message')
    replay.add_argument('--plot', help='PNG: angles and position vs time, deflected shapes')
    replay.add_argument('--plot-samples', type=int, nargs='+', metavar='INDEX',
                        help='message indices whose shape is drawn; default 3 spread out')
    replay.add_argument('--no-compliance', action='store_true',
                        help='skip the compliance topics (faster)')
    replay.add_argument('--backbones', action='store_true',
                        help='also write the backbones MarkerArray (large)')
    cluster = replay.add_mutually_exclusive_group()
    cluster.add_argument('--workers', type=int, metavar='K',
                         help='replay in log-time windows on K local Dask worker processes')
    cluster.add_argument('--scheduler', metavar='ADDRESS',
                         help='replay in log-time windows on the Dask cluster at ADDRESS')
    replay.add_argument('--progress', choices=('auto', 'always', 'never'), default='auto',
                        help='progress bar on stderr; auto: when stderr is a terminal')
    add_fidelity_arguments(replay.add_argument_group('model level'), from_params_file=True)
    estimate = replay.add_argument_group(
        "wrench estimates from measured poses (default: the params file's estimate_* keys)")
    estimate.add_argument('--estimate', metavar='COMPONENTS',
                          help="components estimated: '' (all six), wrench, force, moment, "
                               "lateral, or names such as 'fx fy' (estimate_components)")
    estimate.add_argument('--held-force', type=float, nargs=3, metavar=('FX', 'FY', 'FZ'),
                          help='N, the force components not estimated (estimate_held_force)')
    estimate.add_argument('--held-moment', type=float, nargs=3, metavar=('MX', 'MY', 'MZ'),
                          help='N m, the moment components not estimated '
                               '(estimate_held_moment)')
    estimate.add_argument('--prior-force-sd', type=float, metavar='N',
                          help='N, prior sd of each force component (estimate_prior_force_sd)')
    estimate.add_argument('--prior-moment-sd', type=float, metavar='NM',
                          help='N m, prior sd of each moment component '
                               '(estimate_prior_moment_sd)')
    estimate.add_argument('--target-force-sd', type=float, metavar='N',
                          help='N, posterior sd meeting the accuracy target '
                               '(estimate_target_force_sd)')
    estimate.add_argument('--target-moment-sd', type=float, metavar='NM',
                          help='N m, the same for the moment (estimate_target_moment_sd)')
    estimate.add_argument('--pose-sd', type=float, nargs=2,
                          metavar=('POSITION_M', 'ORIENTATION_RAD'),
                          help='noise assumed for a PoseStamped; 0 0: exact, accuracy not '
                               'assessed (estimate_pose_position_sd, '
                               'estimate_pose_orientation_sd)')
    add_parser(commands)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; return the exit code (EXIT_BROKEN_PIPE: stdout was closed)."""
    return run_command(lambda: _run(argv))


def _run(argv: Optional[Sequence[str]]) -> int:
    """Parse ``argv`` and run the subcommand; return the exit code."""
    args = _parser().parse_args(argv)
    if args.command == 'info':
        try:
            print(describe(args.file, verify=not args.no_crc))
        except ValueError as error:
            print(f'error: {error}', file=sys.stderr)
            return 2
        return 0
    if args.command == 'synth':
        return _run_synth(args, argv)
    if args.command == 'calibrate':
        return run_calibrate(args)
    return _run_replay(args)


def _run_synth(args: argparse.Namespace, argv: Optional[Sequence[str]]) -> int:
    """Run ``python -m msg_tools synth`` with parsed ``args``; return the exit code."""
    try:
        samples = synth.generate(args.profile, count=args.count, rate_hz=args.rate,
                                 force=args.force, moment=args.moment,
                                 frequency_hz=args.frequency, seed=args.seed,
                                 frame_id=args.frame_id)
        poses, frame_id = None, ''
        if args.measured_pose_noise is not None:
            poses, frame_id = measure(samples, check_noise(args.measured_pose_noise),
                                      args.true_params, args.frame_offset or (0.0,) * 6,
                                      args.seed, args.pose_stamp_jitter)
        elif args.true_params or args.frame_offset or args.pose_stamp_jitter:
            raise ValueError('--true-params, --frame-offset and --pose-stamp-jitter shape the '
                             'measured poses: give --measured-pose-noise POS_M ANG_DEG too')
        command = ' '.join(['python -m msg_tools'] + list(
            sys.argv[1:] if argv is None else argv))
        count = synth.write_wrenches(args.output, samples, args.topic,
                                     metadata={'command': command}, poses=poses,
                                     pose_frame_id=frame_id)
    except ValueError as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    measured = '' if poses is None else (
        f' and {sum(pose is not None for pose in poses)} measured poses (frame '
        f'{frame_id!r})')
    print(f'wrote {count} {args.profile} wrenches on {args.topic}{measured} to {args.output}')
    return 0


#: The replay flags that set translator_node's estimate parameters: flag, then the keys.
ESTIMATE_FLAGS = (
    ('--estimate', ('estimate_components',)),
    ('--held-force', ('estimate_held_force',)),
    ('--held-moment', ('estimate_held_moment',)),
    ('--prior-force-sd', ('estimate_prior_force_sd',)),
    ('--prior-moment-sd', ('estimate_prior_moment_sd',)),
    ('--target-force-sd', ('estimate_target_force_sd',)),
    ('--target-moment-sd', ('estimate_target_moment_sd',)),
    ('--pose-sd', ('estimate_pose_position_sd', 'estimate_pose_orientation_sd')),
)


def replay_parameters(args: argparse.Namespace) -> Dict[str, Any]:
    """
    Return the node parameters the replay flags given set, checked over ``--params``.

    The estimate's (``ESTIMATE_FLAGS``) and the model level's (``--fidelity`` and its
    budget, ``fidelity_options.FIDELITY_FLAGS``). ValueError naming the flag for a value
    the node would refuse.
    """
    given: Dict[str, Tuple[str, Any]] = fidelity_parameters(args)
    for flag, keys in ESTIMATE_FLAGS:
        value = getattr(args, flag[2:].replace('-', '_'))
        if value is None:
            continue
        if len(keys) == 1:
            given[keys[0]] = (flag, list(value) if isinstance(value, list) else value)
        else:
            given.update({key: (flag, item) for key, item in zip(keys, value)})
    parameters = {key: value for key, (_, value) in given.items()}
    others = {**TranslatorSettings.from_params_file(args.params).values(), **parameters}
    for key, (flag, value) in given.items():
        reason = check_value(key, value, others)
        if reason is not None:
            raise ValueError(f'{flag}: {reason}')
    return parameters


def _run_replay(args: argparse.Namespace) -> int:
    """Run ``python -m msg_tools replay`` with parsed ``args``; return the exit code."""
    stream = sys.stderr if (args.progress == 'always' or (
        args.progress == 'auto' and sys.stderr.isatty())) else None
    try:
        for option, value in (('--out', args.out), ('--csv', args.csv), ('--plot', args.plot)):
            if value is not None and not value.strip():
                raise ValueError(f'{option} needs a file name, got {value!r}')
        if args.plot:
            check_plot_path(args.plot)
        options = {'topics': args.topic, 'params_path': args.params,
                   'parameters': replay_parameters(args),
                   'compliance': not args.no_compliance, 'backbones': args.backbones,
                   'csv_path': args.csv, 'progress': stream,
                   'plot_samples': args.plot_samples or (),
                   'other_outputs': [('plot', args.plot)] if args.plot else []}
        if args.workers is None and args.scheduler is None:
            summary = replay(args.input, args.out, **options)
        else:
            summary = replay_on_dask(args.input, args.out, workers=args.workers,
                                     scheduler=args.scheduler, **options)
    except (ReplayError, ValueError) as error:
        print(f'error: {error}', file=sys.stderr)
        return EXIT_USAGE
    except (OSError, TimeoutError) as error:  # no scheduler there, or no worker in time
        print(f'error: Dask cluster {args.scheduler or "(local)"}: {error}', file=sys.stderr)
        return EXIT_USAGE
    for warning in summary.warnings:
        print(f'warning: {warning}', file=sys.stderr)
    if summary.warnings_dropped:
        print(f'warning: {summary.warnings_dropped} more such warnings not shown',
              file=sys.stderr)
    if not summary.input_report.complete:
        print(f'warning: {summary.input_report.describe()}', file=sys.stderr)
    print(summary.table())
    written = ', '.join(str(path) for path in (args.out, args.csv) if path)
    print(f'wrote {written}' if not summary.output_error else
          f'wrote {written} up to the write error')
    code = summary.exit_code()
    if args.plot:
        if summary.series.time_s:
            try:
                samples = plot_replay(summary.series, args.plot, params_path=args.params,
                                      samples=args.plot_samples, level=summary.level_text(),
                                      origin_ns=summary.first_stamp_ns)
                print(f'wrote {args.plot} (deflected shapes of messages {samples})')
            except ValueError as error:   # chosen messages that did not converge
                print(f'error: no plot written: {error}', file=sys.stderr)
                if code in (EXIT_OK, EXIT_DAMAGED_INPUT):
                    code = EXIT_USAGE
        else:
            print('warning: nothing converged, no plot written', file=sys.stderr)
    if summary.output_error or summary.exit_code() == EXIT_USAGE:
        status = summary.output_status
        print('error: ' + '; '.join(
            part for part in (summary.output_error,
                              f'output MCAP {status.describe()}' if status is not None else '')
            if part), file=sys.stderr)
    elif code == EXIT_NOTHING_SOLVED:
        print(f'error: nothing could be solved: {summary.messages} messages read, '
              f'{summary.undecodable} undecodable, {summary.rejected} rejected, '
              f'{summary.not_converged} not converged', file=sys.stderr)
    return code


if __name__ == '__main__':
    sys.exit(main())
