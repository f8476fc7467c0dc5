"""
What every command line's help and option errors tell a newcomer.

Each subcommand of ``python -m cdr_translator`` and ``python -m msg_tools`` has a
description of its own, help on every argument (positional ones too), and reports an
option it does not know with its own usage (the shared ``console.CommandParser``);
``scripts/demo.py`` documents its flags; ``calibrate`` shows what it needs to fit.
"""

from pathlib import Path
import re
import subprocess
import sys

from cdr_translator import cli
from cdr_translator.console import add_command, CommandParser
from msg_tools import __main__ as msg_tools_main
import pytest

ROOT = Path(__file__).resolve().parents[2]

#: Every subcommand: (program, its main, subcommand, arguments that satisfy its required ones).
SUBCOMMANDS = [
    ('cdr_translator', cli.main, 'solve', ['--force', '1', '0', '0']),
    ('cdr_translator', cli.main, 'paper', []),
    ('cdr_translator', cli.main, 'delta', ['--sliders', '0', '0', '0']),
    ('cdr_translator', cli.main, 'delta-ik', ['--target', '0', '0', '-0.13']),
    ('cdr_translator', cli.main, 'atlas', ['--grid', '2', '--out', 'x.zarr']),
    ('cdr_translator', cli.main, 'compile', []),
    ('msg_tools', msg_tools_main.main, 'info', ['x.mcap']),
    ('msg_tools', msg_tools_main.main, 'synth', ['x.mcap', '--profile', 'ramp']),
    ('msg_tools', msg_tools_main.main, 'replay', ['x.mcap', '--out', 'y.mcap']),
    ('msg_tools', msg_tools_main.main, 'calibrate', ['x.mcap', '--fit', 'youngs_modulus']),
]


def _help(main, argv, capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main([*argv, '--help'])
    assert stop.value.code == 0
    return capsys.readouterr().out


def _sections(text: str) -> dict:
    """Split a help text into its sections: 'usage', 'description', then each titled one."""
    blocks = text.strip('\n').split('\n\n')
    sections = {'usage': blocks[0], 'description': ''}
    for block in blocks[1:]:
        title, _, body = block.partition('\n')
        if title.endswith(':') and not title.startswith(' '):
            sections[title[:-1]] = body
        elif not sections['description']:
            sections['description'] = block
    return sections


@pytest.mark.parametrize('program, main, command, required', SUBCOMMANDS,
                         ids=[f'{p} {c}' for p, _, c, _ in SUBCOMMANDS])
def test_every_subcommand_describes_itself_and_each_argument(program, main, command, required,
                                                             capsys):
    """A description paragraph under the usage, and help text on every argument."""
    sections = _sections(_help(main, [command], capsys))
    assert sections['usage'].startswith(f'usage: python -m {program} {command}')
    assert len(sections['description'].split()) >= 4, sections['description']
    for title, body in sections.items():
        if title in ('usage', 'description'):
            continue
        entries = re.split(r'\n(?=  \S)', '\n' + body)[1:]
        for entry in entries:   # '  NAME   help' or '  NAME\n        help'
            assert len(entry.split(None, 1)) == 2 and (
                '  ' in entry.strip() or '\n' in entry.strip()), (
                f'{program} {command}: {entry.strip()!r} has no help')


@pytest.mark.parametrize('program, main, command, required', SUBCOMMANDS,
                         ids=[f'{p} {c}' for p, _, c, _ in SUBCOMMANDS])
def test_an_unknown_option_shows_the_subcommands_own_usage(program, main, command, required,
                                                           capsys):
    """Exit 2 and the usage of the subcommand meant, so its real options are in sight."""
    with pytest.raises(SystemExit) as stop:
        main([command, *required, '--no-such-option', '3'])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert error.startswith(f'usage: python -m {program} {command} ')
    assert error.rstrip().endswith('error: unrecognized arguments: --no-such-option 3')


def test_the_parser_class_is_shared_by_the_subcommands():
    """A subcommand added by ``add_command`` gets the strict parser and a description."""
    parser = CommandParser(prog='tool')
    commands = parser.add_subparsers(dest='command', required=True)
    command = add_command(commands, 'go', 'do a thing', 'More about it.')
    assert isinstance(command, CommandParser)
    assert command.description == 'Do a thing.\n\nMore about it.'
    assert command.format_help().startswith('usage: tool go [-h]')


def test_synth_profiles_and_fidelity_levels_are_explained(capsys):
    """--profile says what each profile is; solve and replay share the level options."""
    synth = _help(msg_tools_main.main, ['synth'], capsys)
    for profile in ('ramp:', 'step:', 'sinusoid:', 'random-walk:', 'paper:', 'hard:'):
        assert profile in ' '.join(synth.split())
    solve, replay = (_help(main, [command], capsys) for main, command in (
        (cli.main, 'solve'), (msg_tools_main.main, 'replay')))
    for flag in ('--fidelity {full,rod,cc,auto}', '--max-position-error M',
                 '--max-angle-error DEG'):
        assert flag in solve and flag in replay


def test_calibrate_shows_that_something_must_be_fitted(capsys):
    """--fit and --fit-frame stand under a heading saying one of them is required."""
    text = ' '.join(_help(msg_tools_main.main, ['calibrate'], capsys).split())
    assert 'what to fit (required: --fit, --fit-frame or both):' in text
    usage = text.split(' Fit model parameters')[0]
    assert usage.startswith('usage: python -m msg_tools calibrate [-h] (--fit NAME [NAME ...] '
                            '[--fit-frame] | --fit-frame) ')
    options = set(re.findall(r'(?<=\s)--[a-z-]+', text.split(' options: ')[1]))
    assert options and options - {'--help'} <= set(re.findall(r'--[a-z-]+', usage))   # all
    with pytest.raises(SystemExit):
        msg_tools_main.main(['calibrate', '--help'])
    code = msg_tools_main.main(['calibrate', str(ROOT / 'bags' / 'paper_cases.mcap')])
    assert code == 2
    assert 'nothing to fit: give --fit NAME [NAME ...] and/or --fit-frame' in (
        capsys.readouterr().err)


def test_demo_flags_have_help():
    """``scripts/demo.py --help``: a description and help on each flag."""
    process = subprocess.run([sys.executable, str(ROOT / 'scripts' / 'demo.py'), '--help'],
                             cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert process.returncode == 0, process.stderr
    sections = _sections(process.stdout)
    assert 'translator_node' in sections['description']
    options = ' '.join(sections['options'].split())
    for flag in ('--bags FILE.mcap [FILE.mcap ...] WrenchStamped recordings',
                 '--out FILE.mcap the node',
                 '--speed FACTOR playback speed factor'):
        assert flag in options


@pytest.mark.parametrize('module, commands', [
    (cli, ('solve', 'delta', 'delta-ik', 'atlas')), (msg_tools_main, ('replay',))])
def test_each_synopsis_shows_the_fidelity_option(module, commands):
    """The module's synopsis (its docstring) gives --fidelity on each command that takes it."""
    synopsis = module.__doc__.split('Exit codes')[0]
    blocks = re.split(r'\n(?=    python -m )', synopsis)
    for command in commands:
        block = next(block for block in blocks if re.match(rf'    python -m \S+ {command} ',
                                                           block))
        assert '--fidelity' in block, block
