"""
Ctrl-C in the command lines: one line on stderr, exit 130, no process left behind.

SIGINT goes to the command's process group, as Ctrl-C in a terminal: while the command
still imports (numpy, numba, scipy take seconds), and while it runs.
"""

from pathlib import Path
import subprocess
import sys

from interrupting import after, environment, interpreter_start_s, interrupt
import pytest

#: Moments while the command imports, after the interpreter itself has started.
IMPORT_MOMENTS_S = (0.05, 0.3)


@pytest.fixture(scope='module')
def start_s() -> float:
    """Return how long the interpreter takes to start here."""
    return interpreter_start_s()


@pytest.mark.parametrize('command', [['cdr_translator', 'paper'],
                                     ['msg_tools', 'info', 'missing.mcap']],
                         ids=['cdr_translator', 'msg_tools'])
@pytest.mark.parametrize('moment', IMPORT_MOMENTS_S)
def test_ctrl_c_while_importing(command, moment, start_s, tmp_path):
    """A SIGINT before the command has loaded its modules: quiet, exit 130."""
    interrupt([sys.executable, '-m', *command], after(start_s + moment),
              cwd=tmp_path).assert_quiet()


def _exists(path: Path):
    """Return a ``when`` that is true once ``path`` exists."""
    return lambda process: path.exists()


def test_ctrl_c_while_replaying(tmp_path):
    """A SIGINT in the middle of a replay: exit 130, said in the summary on stdout."""
    wrenches, out = tmp_path / 'in.mcap', tmp_path / 'out.mcap'
    synth = subprocess.run([sys.executable, '-m', 'msg_tools', 'synth', str(wrenches),
                            '--profile', 'random-walk', '--count', '20000'],
                           env=environment(), capture_output=True, text=True, timeout=300)
    assert synth.returncode == 0, synth.stderr
    ending = interrupt([sys.executable, '-m', 'msg_tools', 'replay', str(wrenches), '--out',
                        str(out), '--no-compliance', '--progress', 'never'], _exists(out),
                       cwd=tmp_path)
    ending.assert_quiet(stderr_lines=0)
    assert 'interrupted' in ending.stdout
