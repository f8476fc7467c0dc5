"""
One writer per MCAP file: create it exclusively and hold an exclusive ``flock`` on it.

``open_exclusive`` creates the file (failing, overwriting or picking a new name when it
exists) and locks it before anything is written, so a second writer on the same path fails
at once (``LogFileBusyError`` naming the holder's PID) instead of interleaving records.
"""

import fcntl
import os
from pathlib import Path
from typing import Iterator, Optional, Tuple, Union

from cdr_wire.errors import LogFileBusyError, LogFileExistsError

#: What a writer does when its path exists: fail (the default), overwrite it, or pick a
IF_EXISTS = ('fail', 'overwrite', 'rename')

#: Highest ``n`` tried for a new name.
_MAX_RENAME = 9999


def _flock_holder(path: Union[str, Path]) -> Optional[str]:
    """
    Return who holds a ``flock`` on ``path`` ('PID 123: command line'), None if nobody.

    Read from /proc/locks (Linux) without taking any lock, so looking never makes a real
    writer fail; without /proc/locks, a shared lock is tried for an instant instead.
    """
    try:
        status = os.stat(path)
        with open('/proc/locks') as locks:
            lines = locks.read().splitlines()
    except FileNotFoundError:
        return _probe(path)
    except OSError:
        return None
    device = f'{os.major(status.st_dev):02x}:{os.minor(status.st_dev):02x}:{status.st_ino}'
    for line in lines:
        fields = line.split()
        if '->' in fields or 'FLOCK' not in fields or len(fields) < 6:
            continue
        if fields[5] != device and fields[5].rsplit(':', 1)[-1] != str(status.st_ino):
            continue
        pid = fields[4]
        if pid == str(os.getpid()):
            return f'PID {pid}, this process'
        try:
            with open(f'/proc/{pid}/cmdline', 'rb') as command:
                text = command.read().replace(b'\0', b' ').decode(errors='replace').strip()
        except OSError:
            text = ''
        return f'PID {pid}: {text[:160]}' if text else f'PID {pid}'
    return None


def lock_holder(path: Union[str, Path]) -> str:
    """Describe the holder of the lock on ``path`` ('holder unknown' when it cannot tell)."""
    return _flock_holder(path) or 'holder unknown'


def _probe(path: Union[str, Path]) -> Optional[str]:
    """Try a shared lock on ``path`` for an instant: 'holder unknown' if it is held."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return 'holder unknown'
    finally:
        os.close(fd)
    return None


def _names(path: Path) -> Iterator[Path]:
    """Yield ``path`` then ``<stem>_1<suffix>``, ``<stem>_2<suffix>``, ..."""
    yield path
    for number in range(1, _MAX_RENAME + 1):
        yield path.with_name(f'{path.stem}_{number}{path.suffix}')


def open_exclusive(path: Union[str, Path], if_exists: str = 'fail') -> Tuple[int, Path]:
    """
    Create ``path`` (and its folders) for writing under an exclusive flock; return (fd, path).

    ``if_exists``: 'fail' raises LogFileExistsError for an existing file (LogFileBusyError
    when a writer holds it); 'overwrite' truncates it once the lock is held; 'rename' takes
    the first free ``<stem>_<n><suffix>``. A file locked by another writer is never opened
    for writing: LogFileBusyError names it and its holder. Other OSErrors (no permission, a
    file where a folder should be) propagate.
    """
    if if_exists not in IF_EXISTS:
        raise ValueError(f'if_exists must be one of {IF_EXISTS}, got {if_exists!r}')
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if if_exists == 'overwrite':
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise LogFileBusyError(path, lock_holder(path)) from None
        os.ftruncate(fd, 0)
        return fd, path
    for candidate in _names(path) if if_exists == 'rename' else [path]:
        try:
            fd = os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
        except FileExistsError:
            if if_exists == 'fail':
                holder = _flock_holder(candidate)
                if holder is not None:
                    raise LogFileBusyError(candidate, holder) from None
                raise LogFileExistsError(candidate) from None
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:   # an overwriting writer took the new file first
            os.close(fd)
            if if_exists == 'fail':
                raise LogFileBusyError(candidate, lock_holder(candidate)) from None
            continue
        return fd, candidate
    raise LogFileExistsError(path.with_name(f'{path.stem}_{_MAX_RENAME}{path.suffix}'))
