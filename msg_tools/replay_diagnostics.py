"""
The aggregated /diagnostics of a replay: one array a ``diagnostics_period_s`` of log time.

translator_node publishes one aggregated DiagnosticArray a period (its wrenches' and
measured poses' statuses over the period, interface.diagnostics_period); a replay writes
the same, on the log-time clock of the input: at the first message logged at or after each
multiple of the period (in log time since the epoch, so that a windowed replay's windows
write theirs at the same messages), the messages before it are answered first, then the
array is written with that message's log time (so its counts are those of the messages
logged before it); a last array closes the replay (the closing counts; the merge of a
windowed replay keeps only the last window's, ``part_merge``). One array per namespace (per
node that would have run), each on /diagnostics; a namespace's statuses are its wrench
topic's and, when it has measured poses, its estimates'.
"""

from typing import Dict, List, Mapping, Optional, Tuple, Union

from cdr_translator.interface import messages
from cdr_translator.interface.diagnostics_period import diagnostics_array
from cdr_translator.interface.pose_estimation import PoseProcessor
from cdr_translator.interface.wrench_processing import WrenchProcessor
from cdr_wire.mcap_log import McapLog
from msg_tools.replay_topics import output_topic


class ReplayDiagnostics:
    """The aggregated diagnostics of a replay's processors, due every ``period_s`` of log time."""

    def __init__(self, period_s: float, wrenches: Mapping[str, WrenchProcessor],
                 poses: Mapping[str, PoseProcessor]) -> None:
        """Sum up ``wrenches`` and ``poses`` (input topic -> processor) by namespace."""
        self.period_ns = max(int(round(period_s * 1e9)), 1)
        self._by_namespace: Dict[str, List[Union[WrenchProcessor, PoseProcessor]]] = {}
        streams: List[Tuple[str, Union[WrenchProcessor, PoseProcessor]]] = [
            *wrenches.items(), *poses.items()]
        for topic, processor in streams:
            found = self._by_namespace.setdefault(output_topic(topic, ''), [])
            if not any(known is processor for known in found):
                found.append(processor)
        self._due_ns: Optional[int] = None
        self._preceding_ns: Optional[int] = None
        self.last_ns: Optional[int] = None
        self.written = 0

    def preceding(self, log_time_ns: int) -> None:
        """
        Note a message logged before a window (a warm-up): the clock starts after it.

        So that a window whose first message is the first past a multiple of the period
        writes the array there, as the one-process replay does.
        """
        if self._preceding_ns is None or log_time_ns > self._preceding_ns:
            self._preceding_ns = log_time_ns

    def due(self, log_time_ns: int) -> bool:
        """Tell whether an array is due before the message logged at ``log_time_ns``."""
        if self._due_ns is None:
            self._due_ns = self._next_multiple(
                log_time_ns if self._preceding_ns is None else self._preceding_ns)
            for processors in self._by_namespace.values():
                for processor in processors:
                    processor.diagnostics.begin(1e-9 * log_time_ns)
        self.last_ns = log_time_ns if self.last_ns is None else max(self.last_ns, log_time_ns)
        return log_time_ns >= self._due_ns

    def write(self, log: McapLog, log_time_ns: int) -> None:
        """Write each namespace's array for the period ending at ``log_time_ns``."""
        self._due_ns = self._next_multiple(log_time_ns)
        now_s = 1e-9 * log_time_ns
        stamp = messages.stamp_from_ns(log_time_ns)
        for namespace, processors in self._by_namespace.items():
            statuses = [processor.diagnostics_status(now_s) for processor in processors]
            log.write(output_topic(namespace, messages.DIAGNOSTICS_TOPIC),
                      messages.DIAGNOSTIC_ARRAY_TYPE, diagnostics_array(stamp, statuses),
                      log_time_ns, log_time_ns)
        self.written += 1

    def _next_multiple(self, log_time_ns: int) -> int:
        """Return the first multiple of the period after ``log_time_ns``."""
        return (log_time_ns // self.period_ns + 1) * self.period_ns

    def close(self, log: McapLog) -> None:
        """Write the last arrays (the closing counts) at the last message's log time."""
        if self.last_ns is not None and log.ok:
            self.write(log, self.last_ns)
