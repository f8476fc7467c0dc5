"""
Ctrl-C at a safe point: a SIGINT taken as a request, honoured between two records.

Python raises KeyboardInterrupt wherever the interpreter happens to be when SIGINT arrives:
inside the MCAP writer that can be halfway through a chunk, and the file finished after it
then holds a record that does not parse (seen in CI: "chunk at byte 119: a record does not
parse"). ``deferred_sigint`` replaces the handler for the length of a ``with`` block: the
first SIGINT only sets ``requested``, which the loop checks between messages; a second one
raises KeyboardInterrupt at once, for a user who wants out whatever it costs.
"""

from contextlib import contextmanager
import signal
import threading
from types import FrameType
from typing import Iterator, Optional

__all__ = ['InterruptRequest', 'deferred_sigint']


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
