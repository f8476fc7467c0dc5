"""
A node's MCAP log: the writer process, its health as diagnostics, opening the file.

Every received input and every output a node publishes goes to an MCAP file written by a
child process (cdr_wire.log_process), so that the writing takes no time from the solve.
"""

import datetime
import os
from pathlib import Path
import time
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from cdr_wire.log_process import LogProcess
from rclpy.serialization import serialize_message

from .diagnostic_log import DiagnosticLog
from ..interface import messages

#: How often a node checks its MCAP log (an ERROR diagnostic while writing fails).
LOG_CHECK_PERIOD_S = 1.0

#: Least time between two log lines of the MCAP log's status (s).
LOG_ERROR_THROTTLE_S = 10.0


class NodeLog(LogProcess):
    """
    A node's MCAP log: an McapLog in a child process (cdr_wire.log_process).

    The node's threads only hand records over (one pickled send per batch); the writing
    runs beside them instead of taking the GIL from the solve. Records may be CDR bytes or
    generated message objects, which are serialized here.
    """

    def submit_many(self, records: Sequence[Tuple[str, str, Any, int, Optional[int]]]
                    ) -> None:
        """Hand records over; message objects are serialized first."""
        super().submit_many([
            record if isinstance(record[2], bytes) else
            (record[0], record[1], serialize_message(record[2]), record[3], record[4])
            for record in records])


class LogWatch:
    """
    The MCAP log's health as diagnostics: ERROR while writing fails, WARN once it resumed.

    ``check()`` (called about once a second) returns (level, message, values) to publish,
    or None when there is nothing to say: nothing is published while the log is fine.
    """

    def __init__(self, log: NodeLog) -> None:
        """Watch ``log``."""
        self.log = log
        self._reported_lost = 0
        self._reported_errors = 0
        self._failing = False

    def report(self) -> Tuple[int, str, Dict[str, Any]]:
        """
        Return (level, message, values) of the log now: ``check``'s, or OK while it is fine.

        For the aggregated /diagnostics, which holds the log's status every period.
        """
        found = self.check()
        if found is not None:
            return found
        status = self.log.status()
        return messages.OK, f'MCAP log: writing {status.path}', {
            'mcap_file': status.path, 'records_written': status.written,
            'records_lost': status.lost + self.log.errors, 'write_errors': status.errors}

    def check(self) -> Optional[Tuple[int, str, Dict[str, Any]]]:
        """Return the diagnostic to publish now, if any (an error between two checks too)."""
        status = self.log.status()
        lost = status.lost + self.log.errors
        values: Dict[str, Any] = {'mcap_file': status.path, 'records_written': status.written,
                                  'records_lost': lost, 'write_errors': status.errors}
        if not status.ok or status.errors > self._reported_errors:
            self._failing = True
            self._reported_lost = lost
            self._reported_errors = status.errors
            return messages.ERROR, f'MCAP log: {status.message}', values
        if self._failing or lost > self._reported_lost:
            self._failing = False
            self._reported_lost = lost
            text = status.message or self.log.last_error
            return messages.WARN, f'MCAP log: {lost} records lost so far; {text}', values
        return None


def log_status_name(node_name: str) -> str:
    """Return the DiagnosticStatus name of a node's MCAP log health."""
    return f'{node_name}: mcap_log'


def node_diagnostic_log(logger: Any, node_name: str) -> DiagnosticLog:
    """
    Return the DiagnosticLog of a node: each status one line a second at most.

    The MCAP log's status gets one line in ``LOG_ERROR_THROTTLE_S``: while writing fails
    it is an ERROR at every check.
    """
    return DiagnosticLog(logger, throttle_s_by_name={
        log_status_name(node_name): LOG_ERROR_THROTTLE_S})


def log_health(watch: Optional[LogWatch], node_name: str, counts: Mapping[str, Any]
               ) -> List[Tuple[str, str, dict]]:
    """
    Check the MCAP log (a node's timer work); return the diagnostic to publish, if any.

    The status is named ``log_status_name(node_name)``; ``counts`` (the node's running
    counts) are added to its values. The node logs it as it publishes it (DiagnosticLog).
    """
    found = watch.check() if watch is not None else None
    if found is None:
        return []
    level, text, values = found
    return [(messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
             messages.diagnostics_message(messages.stamp_from_ns(time.time_ns()), level, text,
                                          {**values, **counts},
                                          name=log_status_name(node_name)))]


def log_status(watch: LogWatch, node_name: str) -> dict:
    """Return the DiagnosticStatus dict of a node's MCAP log for the aggregated array."""
    level, text, values = watch.report()
    return messages.diagnostics_message({'sec': 0, 'nanosec': 0}, level, text, values,
                                        name=log_status_name(node_name))['status'][0]


def log_lost(log: Optional[NodeLog]) -> Dict[str, int]:
    """Return ``{'log_records_lost': N}`` for a node's diagnostics ({} without a log)."""
    if log is None:
        return {}
    return {'log_records_lost': log.status().lost + log.errors}


def open_log(settings: Any, prefix: str, topics: Sequence[Tuple[str, str, str]]
             ) -> Tuple[Optional[NodeLog], str]:
    """
    Open a node's MCAP log and its writer process; (None, '') when logging is off.

    ``settings`` has log_to_mcap, mcap_path, log_dir, mcap_flush_messages and mcap_flush_s;
    an empty mcap_path names the file <log_dir>/<prefix>_<UTC time>_<pid>.mcap (another
    free name if that exists). A given mcap_path is created exclusively: an existing file
    (an earlier run's log) or one another writer holds is an OSError naming it (and the
    holder's PID), which ``run`` turns into exit code 2. ``topics`` are (resolved name, type
    name, 'sensor_data' or 'reliable') to register up front. The path returned is the file
    actually written.
    """
    if not settings.log_to_mcap:
        return None, ''
    path = Path(settings.mcap_path) if settings.mcap_path else (
        Path(settings.log_dir) / datetime.datetime.now(datetime.timezone.utc).strftime(
            f'{prefix}_%Y-%m-%d_%H-%M-%S_{os.getpid()}.mcap'))
    log = NodeLog(path, topics=topics, flush_every_messages=settings.mcap_flush_messages,
                  flush_every_s=settings.mcap_flush_s,
                  if_exists='fail' if settings.mcap_path else 'rename')
    return log, log.path
