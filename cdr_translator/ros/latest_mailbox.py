"""
The latest-wins mailbox between a node's subscription callback and its worker thread.

Testable without DDS: the callback leaves an input, the worker takes the oldest waiting;
beyond the capacity the oldest goes, counted as skipped.
"""

from collections import deque
import threading
from typing import Any, Deque, Optional


class LatestMailbox:
    """
    Bounded, thread-safe mailbox, first in first out: beyond ``capacity`` the oldest goes.

    ``put`` adds an item; when more than ``capacity`` items wait, the oldest waiting one is
    dropped (counted as skipped), so the newest item always waits and at most
    ``capacity - 1`` older ones before it. Capacity 1: the consumer always gets the newest
    (latest wins); 2 also keeps an item that arrived while the one before it was taken and
    being worked on, so two items arriving within one piece of work are both taken.
    """

    def __init__(self, capacity: int = 1) -> None:
        """Start empty and open; ``capacity`` >= 1 items may wait."""
        if capacity < 1:
            raise ValueError(f'a mailbox holds at least 1 item, got capacity {capacity}')
        self._condition = threading.Condition()
        self._items: Deque[Any] = deque()
        self.capacity = capacity
        self._closed = False
        self.skipped = 0

    def put(self, item: Any) -> bool:
        """Leave ``item``; return True if it pushed out an older one nobody had taken yet."""
        with self._condition:
            self._items.append(item)
            dropped = len(self._items) > self.capacity
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
            self._condition.wait_for(lambda: bool(self._items) or self._closed, timeout)
            if not self._items:
                return None
            return self._items.popleft()

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
