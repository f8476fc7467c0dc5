"""
The part of an input a windowed replay solves: messages by log time, warmed up on the ones before.

A replay split across processes (``msg_tools.replay_windows``) gives each process one
``LogTimeWindow``. Every message of the input is still read in file order, so message
indices, the read report and the duplicate filter are those of a whole replay; only the
messages whose log time falls in the window are replayed. Before a topic's first message
in the window, its last ``warm_up_messages`` messages before the window are solved and
their outputs discarded: the warm-started solver then starts the window from about the
state a sequential replay reaches there, instead of from the straight rod.
"""

from collections import deque
from dataclasses import dataclass
from typing import Callable, Deque, Dict, Iterable, Iterator, Optional, Set, Tuple

from cdr_translator.interface import messages
from cdr_translator.interface.wrench_processing import WrenchProcessor
from cdr_wire.reader import Decoders, RawMessage

#: Messages solved per topic before a window to warm its solver up (outputs discarded).
WARM_UP_MESSAGES = 10


@dataclass(frozen=True)
class LogTimeWindow:
    """Log times ``start_ns`` <= t < ``stop_ns`` (None: open on that side)."""

    start_ns: Optional[int] = None
    stop_ns: Optional[int] = None
    warm_up_messages: int = WARM_UP_MESSAGES

    def holds(self, log_time_ns: int) -> bool:
        """Tell whether a message logged at ``log_time_ns`` is replayed in this window."""
        return ((self.start_ns is None or log_time_ns >= self.start_ns)
                and (self.stop_ns is None or log_time_ns < self.stop_ns))


def window_messages(source: Iterable[RawMessage], window: Optional[LogTimeWindow],
                    warm_up: Callable[[RawMessage], None]) -> Iterator[Tuple[int, RawMessage]]:
    """
    Yield (index in the input, message) of the messages in ``window`` (all when None).

    ``warm_up`` is called on each topic's last ``window.warm_up_messages`` messages before
    the window, just before that topic's first message in it.
    """
    if window is None:
        yield from enumerate(source)
        return
    before: Dict[str, Deque[RawMessage]] = {}
    started: Set[str] = set()
    for index, raw in enumerate(source):
        if not window.holds(raw.log_time_ns):
            if (raw.topic not in started and window.start_ns is not None
                    and raw.log_time_ns < window.start_ns):
                before.setdefault(raw.topic, deque(maxlen=window.warm_up_messages)).append(raw)
            continue
        if raw.topic not in started:
            started.add(raw.topic)
            for earlier in before.pop(raw.topic, ()):
                warm_up(earlier)
        yield index, raw


def warm_up(processor: WrenchProcessor, decoders: Decoders, raw: RawMessage) -> None:
    """Solve ``raw`` to warm ``processor`` up: its outputs, counts and notes are left out."""
    counts = dict(processor.counts)
    try:
        force, moment, frame_id, stamp = messages.wrench_from_message(decoders.decode(raw))
    except (ValueError, AttributeError, TypeError):
        return
    processor.process(force, moment, frame_id, stamp)
    processor.counts.update(counts)
    processor.diagnostics.discard_notes()
