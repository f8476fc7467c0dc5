"""
The marked blocks of docs/tutorial/getting_started.md, and how its tests run them.

A marker line ``<!-- docs-test: KIND -->`` (optionally ``KIND (why)``) right above a fenced
block says what the tests do with it:

* ``python``: executed; ``feed``: run as ``feed.py`` beside a running translator_node;
* ``shell``: every line one command run offline, ``node``: the node's command line,
  ``node-log``: commands run on the node's log; each line ends with a comment naming its
  exit code (``# exit 0``);
* ``output``: an excerpt of what the block above prints (its last command, for commands):
  every line must appear, with runs of blanks taken as one, within a line of that output;
* ``not-run``: shown only (``make setup`` builds the venv the tests run in).
"""

from dataclasses import dataclass, field
import os
from pathlib import Path
import re
import shlex
import subprocess
import sys
from typing import Dict, List, Mapping, Sequence, Tuple

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / 'docs' / 'tutorial' / 'getting_started.md'
KINDS = {'python', 'feed', 'shell', 'node', 'node-log', 'output', 'not-run'}
#: Kinds whose lines are commands, each with its documented exit code.
COMMAND_KINDS = {'shell', 'node', 'node-log'}
FENCED = re.compile(r'^```(\w*)\n(.*?)^```', re.MULTILINE | re.DOTALL)
MARKER = re.compile(r'<!-- docs-test: ([\w-]+)(?: \([^)]*\))? -->\n\Z')
EXIT_COMMENT = re.compile(r'^(?P<command>.*?)\s+#[^#]*\bexit (?P<code>\d+)\s*$')
#: Where the guide's commands find the venv; the tests use the interpreter running them.
VENV_BIN = '.venv/bin/'
#: Seconds one offline command may take (a cold robot solve included).
COMMAND_TIMEOUT_S = 180.0


@dataclass
class Block:
    """A marked fenced block and the output excerpt that follows it, if any."""

    kind: str
    language: str
    text: str
    expected: List[str] = field(default_factory=list)


def fenced_blocks(text: str) -> List[Tuple[str, str, str]]:
    """Return (marker kind or '', language, body) of every fenced block in ``text``."""
    found = []
    for match in FENCED.finditer(text):
        marker = MARKER.search(text[:match.start()])
        found.append((marker.group(1) if marker else '', match.group(1), match.group(2)))
    return found


def guide_blocks(kind: str) -> List[Block]:
    """Return the guide's blocks of ``kind``, each with the excerpt marked below it."""
    blocks: List[Block] = []
    for marked, language, body in fenced_blocks(GUIDE.read_text(encoding='utf-8')):
        if marked == 'output':
            assert blocks, 'an output excerpt before any block'
            blocks[-1].expected = [line for line in body.splitlines() if line.strip()]
        else:
            blocks.append(Block(marked, language, body))
    return [block for block in blocks if block.kind == kind]


def commands(block: Block) -> List[Tuple[List[str], int]]:
    """Return (argv, documented exit code) of every command line of ``block``."""
    parsed = []
    for line in block.text.splitlines():
        match = EXIT_COMMENT.match(line)
        assert match, f'no "# ... exit N" comment on: {line}'
        parsed.append((local_argv(shlex.split(match.group('command'))),
                       int(match.group('code'))))
    return parsed


def local_argv(argv: Sequence[str]) -> List[str]:
    """Return ``argv`` with the venv's programs taken from the interpreter running the tests."""
    program = argv[0]
    if program.startswith(VENV_BIN):
        name = program[len(VENV_BIN):]
        program = sys.executable if name == 'python' else str(Path(sys.executable).parent / name)
    return [program, *argv[1:]]


def checkout_env(base: Mapping[str, str]) -> Dict[str, str]:
    """Return ``base`` with this checkout first on PYTHONPATH (run from any folder)."""
    env = dict(base)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(ROOT), env.get('PYTHONPATH')]))
    return env


def run_commands(block: Block, cwd: Path, env: Mapping[str, str]) -> str:
    """Run ``block``'s commands in ``cwd``; check each exit code; return the last output."""
    output = ''
    for argv, code in commands(block):
        process = subprocess.run(argv, cwd=cwd, env=dict(env), capture_output=True, text=True,
                                 timeout=COMMAND_TIMEOUT_S)
        output = process.stdout + process.stderr
        assert process.returncode == code, f'{shlex.join(argv)}: exit {process.returncode}, ' \
                                           f'documented {code}\n{output}'
    return output


def assert_shows(expected: Sequence[str], output: str) -> None:
    """Check that every line of an excerpt appears within a line of ``output``."""
    lines = [' '.join(line.split()) for line in output.splitlines()]
    for wanted in expected:
        wanted = ' '.join(wanted.split())
        assert any(wanted in line for line in lines), f'{wanted!r} not in:\n{output}'
