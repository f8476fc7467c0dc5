"""
What every command line of the project prints and how it ends at the console's edges.

* ``json_text``: strict JSON (RFC 8259 has no NaN or Infinity): a non-finite number is
  written as null, so any JSON reader accepts what ``--json`` prints.
* ``run_command``: a closed standard output (``| head -1``) ends quietly with
  ``EXIT_BROKEN_PIPE``, Ctrl-C with one line and ``EXIT_INTERRUPTED``, never a traceback;
  a warning (an implausible parameter) is one line, ``warning: ...``, on stderr.
* ``quiet_sigint``: the same for a Ctrl-C while an entry point still imports (numpy,
  numba, scipy, rclpy take seconds), until ``run_command`` takes over.
* ``deferred_sigint``: Ctrl-C at a safe point. Python raises KeyboardInterrupt wherever the
  interpreter is when SIGINT arrives: inside an MCAP writer halfway through a chunk (the
  file finished after it then holds a record that does not parse), or inside a Zarr write
  whose asynchronous tasks are then abandoned. In the block the first SIGINT only sets
  ``requested``, which the caller checks between records; a second one raises at once,
  for a user who wants out whatever it costs.
* ``unwritable_reason``: whether an output path can be written, asked before any work.
* ``CommandParser`` and ``add_command``: the argument parsing of every command line with
  subcommands: a subcommand's own usage on an option error, a description line of its own.
"""

import argparse
from contextlib import contextmanager
import json
import math
import os
from pathlib import Path
import signal
import sys
import tempfile
import threading
from types import FrameType
from typing import Any, Callable, Iterator, List, Optional, TextIO, Tuple, Type, Union
import warnings

#: Ctrl-C (128 + SIGINT), as a shell reports a process SIGINT ended.
EXIT_INTERRUPTED = 130
#: Standard output closed early (128 + SIGPIPE), as a shell reports a process SIGPIPE ended.
EXIT_BROKEN_PIPE = 141

#: What a command prints on stderr when Ctrl-C ends it.
INTERRUPTED_LINE = 'interrupted (Ctrl-C)'

__all__ = ['add_command', 'CommandParser', 'deferred_sigint', 'EXIT_BROKEN_PIPE',
           'EXIT_INTERRUPTED', 'finite_or_none', 'InterruptRequest', 'INTERRUPTED_LINE',
           'json_text', 'one_line_warning',
           'quiet_sigint', 'run_command', 'SubcommandParser', 'unwritable_reason']


def finite_or_none(data: Any) -> Any:
    """Return ``data`` with every non-finite float (in dicts, lists, tuples) made None."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {key: finite_or_none(value) for key, value in data.items()}
    if isinstance(data, (list, tuple)):
        return [finite_or_none(value) for value in data]
    return data


def json_text(data: Any) -> str:
    """Return ``data`` as strict JSON text: NaN and infinities become null."""
    return json.dumps(finite_or_none(data), allow_nan=False)


def _exit_interrupted(number: int, frame: Optional[FrameType]) -> None:
    """
    SIGINT handler of an entry point that is still importing: one line, exit 130 at once.

    No exception: raised inside an extension module's import (numpy's), it comes out as
    that module's ImportError, a traceback again. Nothing needs cleaning up yet.
    """
    sys.stdout.flush()
    print(INTERRUPTED_LINE, file=sys.stderr, flush=True)
    os._exit(EXIT_INTERRUPTED)


def quiet_sigint(even_if_ignored: bool = False) -> None:
    """
    Make Ctrl-C print one line and exit EXIT_INTERRUPTED, until ``run_command`` starts.

    An entry point calls it before its heavy imports: a KeyboardInterrupt raised inside
    them would print the import chain as a traceback. Only the main thread's default
    handler is replaced (another one is someone's choice); ``run_command`` puts the
    default back, so the command itself sees KeyboardInterrupt, which its cleanup expects.

    A process started in the background by a non-interactive shell inherits SIGINT
    ignored. A command line keeps it so (the shell's choice), but a node stops on SIGINT
    once running whatever it inherited, so ``even_if_ignored`` (the nodes) replaces an
    ignored SIGINT too: one sent during start-up would otherwise be lost, and the node
    would run on where ``kill -INT`` expected it to end.
    """
    handler = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is threading.main_thread() and (
            handler is signal.default_int_handler
            or (even_if_ignored and handler == signal.SIG_IGN)):
        signal.signal(signal.SIGINT, _exit_interrupted)


def run_command(command: Callable[[], int]) -> int:
    """
    Run a command-line ``command``; return its exit code, or the console's own.

    A BrokenPipeError (the reader of stdout went away) returns EXIT_BROKEN_PIPE after
    pointing stdout at /dev/null, so the interpreter's final flush cannot raise again; a
    KeyboardInterrupt prints 'interrupted' on stderr and returns EXIT_INTERRUPTED. A
    ``quiet_sigint`` handler gives way to Python's default one for the command. Warnings
    print as one line each (``one_line_warning``).
    """
    try:
        if signal.getsignal(signal.SIGINT) is _exit_interrupted:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        with warnings.catch_warnings():
            warnings.showwarning = one_line_warning
            return command()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        print(INTERRUPTED_LINE, file=sys.stderr)
        return EXIT_INTERRUPTED


def one_line_warning(message: Union[Warning, str], category: Type[Warning], filename: str,
                     lineno: int, file: Optional[TextIO] = None,
                     line: Optional[str] = None) -> None:
    """Print a warning as ``warning: <message>`` (a ``warnings.showwarning`` replacement)."""
    print(f'warning: {message}', file=sys.stderr if file is None else file)


def unwritable_reason(path: Union[str, Path], folder_ok: bool = False) -> Optional[str]:
    """
    Return why ``path`` cannot be written, or None when it can.

    Creates the missing folders (as the writers would) and a probe file next to ``path``,
    so a read-only folder, a file in the way or /proc are found before any work is done.
    A folder at ``path`` is a reason unless ``folder_ok`` (a store that is a folder).
    """
    target = Path(path)
    if target.is_dir() and not folder_ok:
        return 'it is a folder'
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=target.parent):
            pass
        if target.exists() and not os.access(target, os.W_OK):
            return 'it is not writable'
    except OSError as error:
        reason = error.strerror or str(error)
        return reason + (f' ({error.filename})' if getattr(error, 'filename', None) else '')
    return None


class CommandParser(argparse.ArgumentParser):
    """
    The parser of a command line with subcommands (``python -m cdr_translator``, ``msg_tools``).

    Its subcommands' parsers are ``SubcommandParser``: an option a subcommand does not know
    is reported with that subcommand's usage (argparse reports it with the top-level usage,
    which does not show the options that were meant).
    """

    def add_subparsers(self, **kwargs: Any) -> Any:
        """Add the subcommands' action; their parsers are ``SubcommandParser``."""
        kwargs.setdefault('parser_class', SubcommandParser)
        return super().add_subparsers(**kwargs)


class SubcommandParser(CommandParser):
    """A subcommand's parser: an argument it does not take is an error with its own usage."""

    def parse_known_args(self, args: Any = None, namespace: Any = None
                         ) -> Tuple[Any, List[str]]:
        """Parse ``args``; exit 2 with this subcommand's usage on an unrecognized argument."""
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f'unrecognized arguments: {" ".join(extras)}')
        return parsed, extras


def add_command(commands: Any, name: str, summary: str, details: str = '',
                **options: Any) -> argparse.ArgumentParser:
    """
    Add subcommand ``name`` to ``commands`` (what ``add_subparsers`` returned); return it.

    ``summary`` (one line) is its entry in the command list and the first line of its own
    ``--help``, followed by ``details`` when given; ``options`` go to its parser (a
    ``usage`` argparse cannot write, such as one of two options required).
    """
    description = summary[:1].upper() + summary[1:] + ('.' if not summary.endswith('.') else '')
    if details:
        description += '\n\n' + details
    return commands.add_parser(name, help=summary, description=description, **options)


class InterruptRequest:
    """Whether Ctrl-C was pressed inside a ``deferred_sigint`` block."""

    def __init__(self) -> None:
        self.requested = False

    def handle(self, number: int, frame: Optional[FrameType]) -> None:
        """Signal handler: the first SIGINT is a request, a second one interrupts at once."""
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True


@contextmanager
def deferred_sigint() -> Iterator[InterruptRequest]:
    """
    Take SIGINT as a request for the block (main thread, default Python handler only).

    Elsewhere (a worker thread, where handlers cannot be set, or a SIGINT that is ignored or
    handled by someone else) the disposition is left alone and ``requested`` stays False:
    a KeyboardInterrupt, if any, arrives as it always did.
    """
    request = InterruptRequest()
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield request
        return
    signal.signal(signal.SIGINT, request.handle)
    try:
        yield request
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
