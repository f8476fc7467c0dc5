"""
The latest-wins mailbox between a node's subscription callback and its worker thread.

Testable without DDS: the callback leaves an input, the worker takes the oldest waiting;
beyond the capacity the oldest goes, counted as skipped. Another thread may take its turn
between the worker's inputs (``idle_turn``): only while nothing waits and the worker rests,
and the worker waits for it to end. The node's pose estimates take turns so, behind its
wrenches, instead of sharing the interpreter with them.
"""

from collections import deque
from contextlib import contextmanager
import threading
from typing import Any, Deque, Iterator, Optional


class LatestMailbox:
    """
    Bounded, thread-safe mailbox, first in first out: beyond ``capacity`` the oldest goes.

    ``put`` adds an item; when more than ``capacity`` items wait, the oldest waiting one is
    dropped (counted as skipped), so the newest item always waits and at most
    ``capacity - 1`` older ones before it. Capacity 1: the consumer always gets the newest
    (latest wins); 2 also keeps an item that arrived while the one before it was taken and
    being worked on, so two items arriving within one piece of work are both taken.
    """

    def __init__(self, capacity: int = 1, turn_room: int = 0) -> None:
        """
        Start empty and open; ``capacity`` >= 1 items may wait.

        ``turn_room`` more may wait from the start of another thread's turn (idle_turn)
        until the worker has caught up with them (fewer than ``capacity`` left): a turn is
        a pause of the worker, not its pace, so what arrives during it is kept.
        """
        if capacity < 1:
            raise ValueError(f'a mailbox holds at least 1 item, got capacity {capacity}')
        self._condition = threading.Condition()
        self._items: Deque[Any] = deque()
        self.capacity = capacity
        self.turn_room = turn_room
        self._room_open = False   # a turn began and the worker has not caught up since
        self._closed = False
        self._working = False   # the worker took an item and has not said it is done
        self._turn_taken = False   # another thread's turn (idle_turn) is running
        self.skipped = 0

    def put(self, item: Any) -> bool:
        """Leave ``item``; return True if it pushed out an older one nobody had taken yet."""
        with self._condition:
            self._items.append(item)
            dropped = len(self._items) > self.capacity + (
                self.turn_room if self._room_open else 0)
            if dropped:
                self._items.popleft()
                self.skipped += 1
            self._condition.notify()
            return dropped

    def take(self, timeout: Optional[float] = None) -> Any:
        """
        Wait for an item and return the oldest; None after ``timeout`` s, or once closed.

        Closed with ``drain``, the items waiting then are still handed out first.
        """
        with self._condition:
            self._condition.wait_for(
                lambda: (bool(self._items) and not self._turn_taken) or self._closed, timeout)
            if not self._items:
                return None
            self._working = True
            if len(self._items) <= self.capacity:   # caught up with what a turn kept
                self._room_open = False
            return self._items.popleft()

    def wait_for_item(self, timeout: Optional[float] = None) -> bool:
        """Wait until an item waits (True) or the mailbox is closed and empty (False)."""
        with self._condition:
            self._condition.wait_for(lambda: bool(self._items) or self._closed, timeout)
            return bool(self._items)

    def take_newest(self) -> Any:
        """Return the newest item at once (None: none); the older ones count as skipped."""
        with self._condition:
            if not self._items:
                return None
            newest = self._items.pop()
            self.skipped += len(self._items)
            self._items.clear()
            return newest

    def done(self) -> None:
        """Say the item taken last is handled: another thread may take its turn now."""
        with self._condition:
            self._working = False
            self._condition.notify_all()

    @contextmanager
    def idle_turn(self) -> Iterator[None]:
        """
        Wait until nothing waits and the worker rests, then hold the worker off meanwhile.

        The worker's items come first: a turn starts only between them (also once the
        mailbox is closed and drained), and the worker waits for at most one turn.
        """
        with self._condition:
            self._condition.wait_for(
                lambda: not (self._items or self._working or self._turn_taken))
            self._turn_taken = self._room_open = True
        try:
            yield
        finally:
            with self._condition:
                self._turn_taken = False
                self._condition.notify_all()

    def close(self, drain: bool = False) -> None:
        """Wake the consumer for good; untaken items are dropped unless ``drain``."""
        with self._condition:
            self._closed = True
            if not drain:
                self._items.clear()
            self._condition.notify_all()

    def discard(self) -> int:
        """Drop the items still waiting, count them as skipped; return how many."""
        with self._condition:
            count = len(self._items)
            self.skipped += count
            self._items.clear()
            return count
