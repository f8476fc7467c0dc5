"""
Command line of msg_tools (no ROS needed): info, synth, replay.

    python -m msg_tools info FILE.mcap [--no-crc]
    python -m msg_tools synth OUT.mcap --profile ramp|step|sinusoid|random-walk|paper|hard
    python -m msg_tools replay IN.mcap --out OUT.mcap [--topic NAME] [--params FILE]
                               [--csv FILE] [--plot FILE.png]

Exit codes (replay; docs/replay.md): 0 all good; 1 the input was damaged, what could be
read was replayed; 2 bad arguments, unusable input or an output that cannot be written
(checked before reading; message on stderr, no traceback); 3 nothing could be decoded or
solved (until issue 14 such a replay exited 0); 130 interrupted by Ctrl-C (the output MCAP
is finalized all the same). info and synth: 0 done (info also for a damaged file, which it
reports), 2 bad arguments or unusable input. All: 141 when stdout was closed early (``| head``).
"""

import argparse
import sys
from typing import Optional, Sequence

from cdr_translator.console import EXIT_BROKEN_PIPE, quiet_sigint, run_command

quiet_sigint()  # before the imports below load numpy and the solver: Ctrl-C stays one line

from msg_tools import synth  # noqa: E402
from msg_tools.info import describe  # noqa: E402
from msg_tools.replay import main_replay  # noqa: E402
from msg_tools.synth import PROFILES  # noqa: E402

__all__ = ['EXIT_BROKEN_PIPE', 'main']


def _parser() -> argparse.ArgumentParser:
    """Build the argument parser."""
    parser = argparse.ArgumentParser(prog='python -m msg_tools', description=__doc__.split(
        '\n\n')[0].strip(), formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest='command', required=True)

    info = commands.add_parser('info', help='topics, types, counts and time range of an MCAP')
    info.add_argument('file')
    info.add_argument('--no-crc', action='store_true',
                      help='trust the summary: skip reading the chunks and checking CRCs')

    synth = commands.add_parser('synth', help='write a synthetic WrenchStamped sequence')
    synth.add_argument('output')
    synth.add_argument('--profile', choices=PROFILES, required=True)
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

    replay = commands.add_parser('replay', help='solve recorded wrenches as the node would')
    replay.add_argument('input')
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
    replay.add_argument('--progress', choices=('auto', 'always', 'never'), default='auto',
                        help='progress bar on stderr; auto: when stderr is a terminal')
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
        try:
            samples = synth.generate(args.profile, count=args.count, rate_hz=args.rate,
                                     force=args.force, moment=args.moment,
                                     frequency_hz=args.frequency, seed=args.seed,
                                     frame_id=args.frame_id)
            command = ' '.join(['python -m msg_tools'] + list(
                sys.argv[1:] if argv is None else argv))
            count = synth.write_wrenches(args.output, samples, args.topic,
                                         metadata={'command': command})
        except ValueError as error:
            print(f'error: {error}', file=sys.stderr)
            return 2
        print(f'wrote {count} {args.profile} wrenches on {args.topic} to {args.output}')
        return 0
    return main_replay(args)


if __name__ == '__main__':
    sys.exit(main())
