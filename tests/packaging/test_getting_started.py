"""
docs/tutorial/getting_started.md as printed: its Python runs, its commands exit as shown.

The exit-code table of docs/reference/cli.md covers every command.

The node's part (starting translator_node, feeding it, its log) runs over DDS in
tests/ros/test_getting_started_node.py; here every block is checked to be marked, the
Python blocks are executed and the offline commands (solve, delta, delta-ik, msg_tools on a
sample bag and on what replay wrote) run in a temporary folder with this interpreter.
"""

import contextlib
import io
import os
import re

from cdr_translator import cli
from guide_blocks import assert_shows, Block, checkout_env, COMMAND_KINDS, commands
from guide_blocks import fenced_blocks, GUIDE, guide_blocks, KINDS, ROOT, run_commands
import msg_tools.__main__ as msg_tools_main
import pytest

#: The command-line reference, whose exit-code table names every command.
CLI_REFERENCE = ROOT / 'docs' / 'reference' / 'cli.md'
#: The rows of the exit-code table: the first cell of each.
TABLE_ROW = re.compile(r'^\| `([^`]+)`(?:, `([^`]+)`)? \|', re.MULTILINE)


def test_every_block_is_marked():
    """Each fenced block says what the tests do with it; commands name their exit codes."""
    found = fenced_blocks(GUIDE.read_text(encoding='utf-8'))
    assert found
    for kind, language, body in found:
        assert kind in KINDS, f'unmarked or unknown block ({kind!r}):\n{body}'
        if kind in COMMAND_KINDS:
            assert language == 'bash' and commands(Block(kind, language, body))
    for kind in ('python', 'feed', 'shell', 'node', 'node-log'):
        assert guide_blocks(kind), f'no {kind} block'


def _subcommands(main, prog: str) -> set:
    """Return the subcommands a command line's --help lists."""
    output = io.StringIO()
    with contextlib.redirect_stdout(output), pytest.raises(SystemExit):
        main(['--help'])
    choices = re.search(r'\{([\w,-]+)\}', output.getvalue())
    return {f'{prog} {name}' for name in choices.group(1).split(',')}


def test_exit_code_table_covers_every_command():
    """The exit-code table has a row for every subcommand and both nodes."""
    rows = {name for pair in TABLE_ROW.findall(CLI_REFERENCE.read_text(encoding='utf-8'))
            for name in pair if name}
    expected = (_subcommands(cli.main, 'cdr_translator')
                | _subcommands(msg_tools_main.main, 'msg_tools')
                | set(re.findall(r"'(\w+) = cdr_translator", (ROOT / 'setup.py').read_text())))
    assert expected == rows


@pytest.mark.parametrize('index', range(len(guide_blocks('python'))))
def test_python_block_runs_and_prints_what_the_guide_shows(index):
    """A Python block runs as printed, and its output excerpt appears."""
    block = guide_blocks('python')[index]
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        exec(compile(block.text, str(GUIDE), 'exec'), {'__name__': 'guide_example'})
    assert block.expected, 'a Python block shows no output'
    assert_shows(block.expected, output.getvalue())


def test_offline_commands_exit_and_print_as_documented(tmp_path):
    """Every offline command, in order, in a fresh folder: exit codes and output excerpts."""
    (tmp_path / 'bags').symlink_to(ROOT / 'bags')
    env = checkout_env(os.environ)
    for block in guide_blocks('shell'):
        assert_shows(block.expected, run_commands(block, tmp_path, env))
