"""Diagnostics are logged at their own level, by the one path both nodes publish through."""

import time

from cdr_translator.interface import messages
from cdr_translator.ros import diagnostic_log, node_log
from cdr_translator.ros.diagnostic_log import DiagnosticLog

STAMP = {'sec': 5, 'nanosec': 6}


class _Logger:
    """Records (level method, text) like an rclpy logger named ``name``."""

    def __init__(self, name='my_node'):
        self.name = name
        self.lines = []

    def debug(self, text):
        self.lines.append(('debug', text))

    def warning(self, text):
        self.lines.append(('warning', text))

    def error(self, text):
        self.lines.append(('error', text))


def _diagnostic(level, text, name='my_node: stage'):
    return (messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
            messages.diagnostics_message(STAMP, level, text, {}, name=name))


def test_each_level_logs_at_its_own_level_with_the_stage():
    """ERROR as error, WARN and STALE as warning, OK as debug; other outputs pass untouched."""
    logger = _Logger()
    log = DiagnosticLog(logger)
    pose = ('pose', 'geometry_msgs/msg/PoseStamped', {'pose': {}})
    built = [pose, _diagnostic(messages.ERROR, 'bad'), _diagnostic(messages.WARN, 'odd', 'a: b'),
             _diagnostic(messages.STALE, 'old', 'my_node: other'), _diagnostic(messages.OK, 'ok')]
    assert list(log.logged(built)) == built
    assert logger.lines == [('error', 'stage: bad'), ('warning', 'a: b: odd'),
                            ('warning', 'other: old'), ('debug', 'stage: ok')]


def test_throttled_per_status_and_level_and_the_count_given_later():
    """One line per (name, level) per throttle time; the lines not logged are counted."""
    now = [0.0]
    logger = _Logger()
    log = DiagnosticLog(logger, throttle_s=1.0, throttle_s_by_name={'my_node: slow': 10.0},
                        clock=lambda: now[0])
    for _ in range(3):
        list(log.logged([_diagnostic(messages.ERROR, 'bad')]))
    list(log.logged([_diagnostic(messages.WARN, 'odd'),
                     _diagnostic(messages.ERROR, 'other stage', 'my_node: other'),
                     _diagnostic(messages.ERROR, 'slow', 'my_node: slow')]))
    now[0] = 1.5
    list(log.logged([_diagnostic(messages.ERROR, 'bad again'),
                     _diagnostic(messages.ERROR, 'slow', 'my_node: slow')]))
    for _ in range(4):
        list(log.logged([_diagnostic(messages.OK, 'ok')]))
    assert logger.lines == [
        ('error', 'stage: bad'), ('warning', 'stage: odd'), ('error', 'other: other stage'),
        ('error', 'slow: slow'),
        ('error', 'stage: bad again (2 more since the last line, not logged)')] + [
        ('debug', 'stage: ok')] * 4


def test_mcap_log_status_gets_its_own_throttle():
    """The MCAP log's status, an ERROR at every check while failing, logs every 10 s."""
    logger = _Logger('n')
    log = node_log.node_diagnostic_log(logger, 'n')
    for _ in range(2):
        list(log.logged([_diagnostic(messages.ERROR, 'disk full', node_log.log_status_name('n')),
                         _diagnostic(messages.ERROR, 'no equilibrium', 'n: solve')]))
        time.sleep(1.05 * diagnostic_log.THROTTLE_S)
    assert logger.lines == [('error', 'mcap_log: disk full'), ('error', 'solve: no equilibrium'),
                            ('error', 'solve: no equilibrium')]
    assert node_log.log_health(None, 'n', {}) == []


def test_translator_node_logs_a_rejection_at_the_diagnostics_level(node, capfd):
    """
    A rejected wrench makes its period's aggregated status an ERROR, logged as one (no WARN).

    Its own status (solve_status) is not logged: one line a period, not one a wrench.
    """
    capfd.readouterr()
    node._reject(STAMP, 'force x component is nan')
    assert 'force x component is nan' not in capfd.readouterr().err
    node._publish_diagnostics()
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if 'force x component is nan' in line]
    assert len(lines) == 1 and lines[0].startswith('[ERROR]'), err
    assert ']: kinestatics: ' in lines[0] and 'wrenches failed or rejected' in lines[0]
    assert lines[0].endswith('last: rejected: force x component is nan')
