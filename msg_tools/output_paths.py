"""
The output paths of a replay, checked before any input is read.

Each output must be writable (its folders are created as the writers would) and be
neither the input nor another output: opening it for writing truncates it.
"""

import os
from pathlib import Path
from typing import Sequence, Tuple, Union

from cdr_translator.console import unwritable_reason
from msg_tools.errors import OutputError


def check_output(path: Union[str, Path], what: str) -> None:
    """
    Make sure ``path`` can be written before any input is read; OutputError if not.

    Creates the missing folders (as the writers would) and a probe file next to ``path``,
    so a read-only folder, a file in the way or a folder given as ``path`` are found.
    """
    reason = unwritable_reason(path)
    if reason is not None:
        raise OutputError(f'cannot write the {what} {path}: {reason}')


def _same_file(first: Path, second: Path) -> bool:
    """Tell whether two paths name one file: the same path, a symbolic or a hard link."""
    if first.resolve() == second.resolve():
        return True
    try:
        return os.path.samefile(first, second)
    except OSError:   # one of them does not exist (yet): then they are not one file
        return False


def check_distinct(input_path: Union[str, Path],
                   outputs: Sequence[Tuple[str, Union[str, Path, None]]]) -> None:
    """
    Raise OutputError when an output is the input file or another output (links included).

    ``outputs``: (what, path) pairs, a None or empty path being no output. Opening an
    output for writing truncates it: the input would be destroyed before it is read, two
    outputs would overwrite each other.
    """
    named = [('input', Path(input_path))]
    named += [(what, Path(path)) for what, path in outputs if path]
    for position, (what, path) in enumerate(named):
        for other_what, other in named[:position]:
            if _same_file(path, other):
                raise OutputError(f'the {what} {path} is the same file as the {other_what} '
                                  f'{other}: give each output its own path')
