"""
Ctrl-C for a command run as a process: SIGINT to its process group, then how it ended.

The command runs in its own session (``start_new_session``), as a shell runs a foreground
job: ``os.killpg`` reaches it and every process it started, as Ctrl-C in a terminal does.
Every wait is bounded; whatever is left of the group is killed before the test judges it.
"""

from dataclasses import dataclass
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Callable, List, Mapping, Optional, Sequence

from cdr_translator.interface.wrench_processing import WrenchProcessor

ROOT = Path(__file__).resolve().parents[1]

#: How long a command may take to end after SIGINT (a loaded CI machine; seconds usually).
END_TIMEOUT_S = 120.0
#: How long processes of the group may take to exit after the command ended.
GROUP_GRACE_S = 10.0


@dataclass
class Ending:
    """How an interrupted command ended: exit code, output, processes it left behind."""

    returncode: int
    stdout: str
    stderr: str
    leftovers: List[int]

    def assert_quiet(self, stderr_lines: int = 1) -> None:
        """Exit code 130, ``stderr_lines`` on stderr, no traceback, no process left."""
        lines = self.stderr.strip().splitlines()
        assert self.returncode == 130, (self.returncode, self.stderr[-3000:])
        assert 'Traceback' not in self.stderr, self.stderr[-3000:]
        assert len(lines) == stderr_lines, self.stderr[-3000:]
        assert not self.leftovers, f'left behind: {self.leftovers}'


def environment(extra: Optional[Mapping[str, str]] = None) -> dict:
    """Return os.environ with this checkout first on PYTHONPATH (and ``extra``)."""
    env = dict(os.environ, **(extra or {}))
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')]).rstrip(
        os.pathsep)
    return env


def interpreter_start_s() -> float:
    """
    Return how long this machine takes to start Python (its site import included).

    Until then no line of the project runs: a SIGINT there is the interpreter's to report.
    The moments "during the imports" are counted from this.
    """
    times = []
    for _ in range(2):
        started = time.monotonic()
        subprocess.run([sys.executable, '-c', 'pass'], check=True, timeout=60)
        times.append(time.monotonic() - started)
    return min(times)


def group_members(group: int) -> List[int]:
    """Return the live processes of process group ``group`` (a /proc scan)."""
    members = []
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            fields = Path(f'/proc/{entry}/stat').read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if fields[2] == str(group) and fields[0] != 'Z':
            members.append(int(entry))
    return members


def _ignore_sigint() -> None:
    """Ignore SIGINT (in a child before its exec), as a script's background job inherits it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def interrupt(command: Sequence[str], when: Callable[[subprocess.Popen], bool],
              env: Optional[Mapping[str, str]] = None, cwd: Optional[Path] = None,
              wait_s: float = 240.0, inherit_ignored: bool = False,
              end_timeout_s: float = END_TIMEOUT_S) -> Ending:
    """
    Start ``command``, send SIGINT to its group once ``when(process)``, return the ending.

    ``when`` is polled every 10 ms for at most ``wait_s`` (an AssertionError after); a
    command that ends before it is an AssertionError too. ``inherit_ignored`` starts the
    command with SIGINT ignored, as ``command &`` in a non-interactive shell does. A
    command still running ``end_timeout_s`` after the SIGINT is an AssertionError.
    """
    process = subprocess.Popen(list(command), env=dict(env or environment()), cwd=cwd,
                               start_new_session=True, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               preexec_fn=_ignore_sigint if inherit_ignored else None)
    try:
        deadline = time.monotonic() + wait_s
        while not when(process):
            assert process.poll() is None, f'ended before the interrupt: {process.stderr.read()}'
            assert time.monotonic() < deadline, f'no moment to interrupt in {wait_s} s'
            time.sleep(0.01)
        os.killpg(process.pid, signal.SIGINT)
        try:
            stdout, stderr = process.communicate(timeout=end_timeout_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(f'still running {end_timeout_s} s after SIGINT') from None
        deadline = time.monotonic() + GROUP_GRACE_S
        while group_members(process.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        return Ending(process.returncode, stdout, stderr, group_members(process.pid))
    finally:
        if process.poll() is None or group_members(process.pid):
            try:
                os.killpg(process.pid, signal.SIGKILL)
            except ProcessLookupError:  # the last of them exited meanwhile
                pass
        process.wait(timeout=30)


def after(seconds: float) -> Callable[[subprocess.Popen], bool]:
    """Return a ``when`` that is true ``seconds`` after its first call (the start)."""
    started: List[float] = []

    def elapsed(process: subprocess.Popen) -> bool:
        if not started:
            started.append(time.monotonic())
        return time.monotonic() - started[0] >= seconds

    return elapsed


def interrupt_processing_at(monkeypatch, call: int) -> None:
    """Make the ``call``-th WrenchProcessor.process raise KeyboardInterrupt (a Ctrl-C there)."""
    original, calls = WrenchProcessor.process, []

    def interrupted(self, *args):
        calls.append(1)
        if len(calls) == call:
            raise KeyboardInterrupt
        return original(self, *args)

    monkeypatch.setattr(WrenchProcessor, 'process', interrupted)
