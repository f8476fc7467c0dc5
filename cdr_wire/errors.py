"""Errors of the MCAP writer (a log file that cannot be written) and the text of any error."""

from pathlib import Path
from typing import Union

__all__ = ['error_text', 'LogFileBusyError', 'LogFileError', 'LogFileExistsError']


class LogFileError(OSError):
    """An MCAP log file cannot be opened for writing; the message says which and why."""


class LogFileBusyError(LogFileError):
    """Another writer holds the lock of the file; ``holder`` describes it (PID, command)."""

    def __init__(self, path: Union[str, Path], holder: str) -> None:
        """Name the file and its holder."""
        self.path = str(path)
        self.holder = holder
        super().__init__(f'{self.path} is being written by another writer ({holder}); '
                         'one writer per file: give each writer its own path, or leave the '
                         'path empty for an auto-named file')


class LogFileExistsError(LogFileError):
    """The file exists and the writer was not allowed to overwrite or rename."""

    def __init__(self, path: Union[str, Path]) -> None:
        """Name the file."""
        self.path = str(path)
        super().__init__(f'{self.path} already exists and is not overwritten (a finished log '
                         'of an earlier run?); remove it, choose another path, or ask for an '
                         'auto-named file')


def error_text(error: BaseException) -> str:
    """Return 'Type: message' of an exception (some mcap errors have empty messages)."""
    text = str(error)
    return f'{type(error).__name__}: {text}' if text else type(error).__name__
