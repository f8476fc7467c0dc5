"""
A node's diagnostics, logged at their own level on their way out: one path, so they agree.

Both nodes hand the diagnostics they publish on /diagnostics (translator_node its aggregated
array once a period, cdr_node every message's) through ``DiagnosticLog.logged``, which
logs each DiagnosticStatus it sees at the status' level (ERROR as error, WARN and STALE as
warning, OK as debug) with the status name's stage, e.g. ``inverse statics: target
rejected: ...`` on cdr_node's logger. No other code logs a diagnostic's content, so a log
line can never say WARN where the diagnostic says ERROR.
"""

import math
import threading
import time
from typing import Any, Callable, Dict, Iterable, Iterator, Mapping, Optional, Tuple

from ..interface import messages

#: At most one log line per status name and level in this many seconds (the rest are
#: counted and the count is given with the next line): a bad input stream may come at 1 kHz.
THROTTLE_S = 1.0

#: rclpy logs a call site at one severity only, hence one call site per level here.
_LOG_AT: Dict[int, Callable[[Any, str], Any]] = {
    messages.OK: lambda logger, text: logger.debug(text),
    messages.WARN: lambda logger, text: logger.warning(text),
    messages.ERROR: lambda logger, text: logger.error(text),
    messages.STALE: lambda logger, text: logger.warning(text),
}


class DiagnosticLog:
    """
    Log the diagnostics among a node's outputs at their level, throttled per status.

    ``throttle_s`` is the least time between two lines of one (status name, level); OK
    statuses (one per solve) are not throttled, they go to the debug level. A status name
    in ``throttle_s_by_name`` uses its own time (e.g. the MCAP log's, checked every second).
    """

    def __init__(self, logger: Any, throttle_s: float = THROTTLE_S,
                 throttle_s_by_name: Optional[Mapping[str, float]] = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Log to ``logger`` (an rclpy logger, or anything with debug, warning and error)."""
        self._logger = logger
        self._throttle_s = throttle_s
        self._throttle_s_by_name = dict(throttle_s_by_name or {})
        self._clock = clock
        # (status name, level) -> (time of its last line, lines suppressed since)
        self._last: Dict[Tuple[str, int], Tuple[float, int]] = {}
        self._lock = threading.Lock()  # the executor, solver and timer threads all publish
        name = str(getattr(logger, 'name', '') or '')
        self._prefix = f'{name}: ' if name else ''

    def logged(self, built: Iterable[Tuple[str, str, dict]]
               ) -> Iterator[Tuple[str, str, dict]]:
        """Yield each of ``built``, a diagnostic once its statuses have been logged."""
        for item in built:
            if item[0] == messages.DIAGNOSTICS_TOPIC:
                for status in item[2]['status']:
                    self.log(status)
            yield item

    def log(self, status: Mapping[str, Any]) -> bool:
        """Log one DiagnosticStatus dict at its level; return False if throttled."""
        level, name = int(status['level']), str(status['name'])
        text = str(status['message'])
        if level != messages.OK:
            with self._lock:
                now = self._clock()
                last, suppressed = self._last.get((name, level), (-math.inf, 0))
                if now - last < self._throttle_s_by_name.get(name, self._throttle_s):
                    self._last[(name, level)] = (last, suppressed + 1)
                    return False
                self._last[(name, level)] = (now, 0)
            if suppressed:
                text = f'{text} ({suppressed} more since the last line, not logged)'
        stage = name[len(self._prefix):] if name.startswith(self._prefix) else name
        _LOG_AT[level](self._logger, f'{stage}: {text}')
        return True
