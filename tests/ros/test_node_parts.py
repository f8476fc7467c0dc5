"""translator_node's parts that need no DDS: parameters, checks, mailbox, filler, log, spin."""

import gc
import os
import sys
import threading
import time
import weakref

from cdr_translator.interface import messages
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import check_magnitude, in_end_disk_frame
from cdr_translator.params.params_file import CommandLineValues
from cdr_translator.params.translator_params import ParameterError
from cdr_translator.ros import spin
from cdr_translator.ros.client import isolated_ros_env
from cdr_translator.ros.latest_mailbox import LatestMailbox
from cdr_translator.ros.node_log import log_lost, LogWatch, NodeLog
from cdr_translator.ros.parameters import default_values, descriptor, ros_parameter_sources
from cdr_translator.ros.parameters import SPECS
from cdr_translator.ros.topics import fill_message, type_name
from cdr_wire.errors import LogFileBusyError, LogFileExistsError
from cdr_wire.reader import McapSource
from diagnostic_msgs.msg import DiagnosticArray
from mcap_ros2.reader import read_ros2_messages
import pytest
import rclpy
from rclpy.node import Node
from rclpy.serialization import serialize_message
from visualization_msgs.msg import MarkerArray


def test_descriptors_carry_description_range_and_read_only():
    """Integer and float ranges follow the value's type; geometry is read-only."""
    values = default_values()
    steps = descriptor(SPECS['steps_per_segment'], values['steps_per_segment'])
    assert steps.read_only and steps.integer_range[0].from_value == 1
    force = descriptor(SPECS['max_force'], values['max_force'])
    assert not force.read_only and force.floating_point_range[0].from_value == 0.0
    assert 'N' in force.description
    frame = descriptor(SPECS['base_frame'], values['base_frame'])
    assert not frame.integer_range and not frame.floating_point_range


def test_command_line_parameter_sources():
    """--params-file and -p count inside --ros-args only; -p values are YAML."""
    layers = ros_parameter_sources(
        ['node', '--params-file', 'not_ros.yaml', '--ros-args', '--params-file', 'a.yaml',
         '-p', 'max_force:=50.0', '--param', 'log_dir:=/tmp/x', '-r', '__ns:=/leg1', '--',
         '-p', 'ignored:=1', '--ros-args', '--params-file', 'b.yaml'])
    assert layers == ['a.yaml', CommandLineValues({'max_force': 50.0}),
                      CommandLineValues({'log_dir': '/tmp/x'}), 'b.yaml']
    with pytest.raises(ParameterError, match='expected name:=value'):
        ros_parameter_sources(['--ros-args', '-p', 'max_force=50'])


@pytest.mark.parametrize('order, expected', [
    ('file -p', 1.0), ('-p file', 2.0), ('wildcard -p', 1.0), ('-p wildcard', 3.0),
    ('file wildcard', 3.0), ('wildcard file', 2.0)])
def test_params_files_and_p_apply_in_rcl_order(tmp_path, order, expected):
    """The last --params-file or -p naming a key wins, as rcl (rclpy checked) applies them."""
    (tmp_path / 'file.yaml').write_text(
        'translator_node:\n  ros__parameters:\n    max_force: 2.0\n')
    (tmp_path / 'wildcard.yaml').write_text('/**:\n  ros__parameters:\n    max_force: 3.0\n')
    arguments = ['--ros-args']
    for word in order.split():
        arguments += ['-p', 'max_force:=1.0'] if word == '-p' else [
            '--params-file', str(tmp_path / f'{word}.yaml')]
    settings = TranslatorSettings.from_params_files(ros_parameter_sources(arguments))
    assert settings.max_force == expected


def test_input_checks_name_the_problem():
    """Magnitude limits and frame ids: ValueError with the magnitude or the frame."""
    check_magnitude((3.0, 4.0, 0.0), (0.0, 0.0, 0.0), 5.0, 1.0)
    with pytest.raises(ValueError, match=r'\|force\| = 5\.09902 N exceeds max_force = 5 N'):
        check_magnitude((3.0, 4.0, 1.0), (0.0, 0.0, 0.0), 5.0, 1.0)
    with pytest.raises(ValueError, match=r'\|moment\| = 2 N m exceeds max_moment'):
        check_magnitude((0.0, 0.0, 0.0), (0.0, 0.0, 2.0), 5.0, 1.0)
    assert in_end_disk_frame('', 'base', 'tip') is False
    assert in_end_disk_frame('base', 'base', 'tip') is False
    assert in_end_disk_frame('tip', 'base', 'tip') is True
    with pytest.raises(ValueError, match="unknown frame_id 'world'"):
        in_end_disk_frame('world', 'base', 'tip')


def test_mailbox_keeps_the_newest_and_counts_the_rest():
    """Latest wins; every replaced item is counted; close wakes a waiting consumer."""
    mailbox = LatestMailbox()
    assert mailbox.put(1) is False
    assert mailbox.put(2) is True
    assert mailbox.put(3) is True
    assert mailbox.take() == 3 and mailbox.skipped == 2
    assert mailbox.take(timeout=0.01) is None
    got = []
    consumer = threading.Thread(target=lambda: got.append(mailbox.take()))
    consumer.start()
    mailbox.close()
    consumer.join(5.0)
    assert not consumer.is_alive() and got == [None]


def test_fill_message_nested_sequences_and_bytes():
    """Nested dicts, lists of message dicts and int levels of byte fields are filled."""
    stamp = {'sec': 3, 'nanosec': 4}
    diagnostics = fill_message(DiagnosticArray(), messages.diagnostics_message(
        stamp, messages.WARN, 'careful', {'skipped': 7}))
    assert diagnostics.header.stamp.sec == 3
    assert diagnostics.status[0].level == bytes([messages.WARN])
    assert diagnostics.status[0].values[0].key == 'skipped'
    assert diagnostics.status[0].values[0].value == '7'
    markers = fill_message(MarkerArray(), {'markers': [
        {'ns': 'a', 'points': [{'x': 1.0, 'y': 2.0, 'z': 3.0}, {'x': 4.0}]}]})
    assert markers.markers[0].points[1].x == 4.0 and markers.markers[0].points[0].z == 3.0
    with pytest.raises(KeyError, match="no field 'colour'"):
        fill_message(MarkerArray(), {'markers': [{'colour': {}}]})
    assert type_name(MarkerArray) == 'visualization_msgs/msg/MarkerArray'


def test_log_process_writes_bytes_and_messages_in_order(tmp_path):
    """Raw CDR and message objects both land in the MCAP, decodable, in submission order."""
    path = tmp_path / 'log.mcap'
    log = NodeLog(path, flush_every_messages=2, flush_every_s=0.0,
                  topics=[('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, 'reliable')])
    stamp = {'sec': 1, 'nanosec': 2}
    first = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 0, 'a', {}))
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, serialize_message(first), 10)
    second = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 2, 'b', {}))
    log.submit_many([('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, second, 20, 15)])
    status = log.close()
    assert log.close() == status and status.ok and (status.written, status.lost) == (2, 0)
    decoded = list(read_ros2_messages(str(path)))
    assert [message.ros_msg.status[0].message for message in decoded] == ['a', 'b']
    assert [message.log_time_ns for message in decoded] == [10, 20]
    assert decoded[1].publish_time_ns == 15
    assert log.written == 2 and log.errors == 0 and log.submitted == 2
    assert log.closing_line() == (True, f'MCAP log closed: 2 records written, 0 lost (0 not '
                                        f'written, 0 not serializable) in {path}')


def _wait(condition, timeout_s=10.0):
    """Wait (bounded) until ``condition()`` holds; return whether it did."""
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.005)
    return condition()


def test_log_process_holds_the_file_for_its_caller(tmp_path):
    """The file is locked in the caller's name: a second writer fails naming the caller."""
    path = tmp_path / 'log.mcap'
    log = NodeLog(path, flush_every_s=0.0)
    try:
        with pytest.raises(LogFileBusyError, match=f'PID {os.getpid()}'):
            NodeLog(path)
    finally:
        log.close()
    with pytest.raises(LogFileExistsError):
        NodeLog(path)


def test_a_dead_log_process_is_an_error_with_the_records_counted_lost(tmp_path):
    """Killing the writer: status not ok, every unconfirmed record lost, ERROR diagnostic."""
    path = tmp_path / 'log.mcap'
    log = NodeLog(path, flush_every_messages=1, flush_every_s=0.0)
    watch = LogWatch(log)
    data = serialize_message(fill_message(DiagnosticArray(), messages.diagnostics_message(
        {'sec': 1, 'nanosec': 2}, 0, 'a', {})))
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, data, 10)
    assert _wait(lambda: log.status().written == 1)
    assert watch.check() is None
    log._process.kill()
    assert _wait(lambda: not log.status().ok)
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, data, 20)
    status = log.status()
    assert (status.written, status.lost + log.errors) == (1, 1)
    assert 'exited with code -9' in status.message
    level, text, values = watch.check()
    assert level == messages.ERROR and 'writer process' in text
    assert values['records_lost'] == 1
    assert log_lost(log) == {'log_records_lost': 1}
    assert log.close().lost + log.errors == 1
    assert log.closing_line()[0] is False
    assert [raw.log_time_ns for raw in McapSource(path).messages()] == [10]  # salvaged


def test_freeze_heap_keeps_later_garbage_collectable():
    """What is alive is frozen (no full-collection pauses); later cycles are still freed."""
    class Cycle:
        """An object in a reference cycle with itself."""

    try:
        assert spin.freeze_heap() > 10_000  # solver, numba, rclpy already imported
        later = Cycle()
        later.self = later
        probe = weakref.ref(later)
        del later
        gc.collect()
        assert probe() is None
    finally:
        gc.unfreeze()


def test_run_spins_with_a_short_gil_switch_interval(monkeypatch):
    """
    run() lowers CPython's GIL switch interval (5 ms) before it spins.

    Behind a busy solver thread the executor's wrench callback waits that long for the GIL.
    """
    seen = []

    class Executor:
        """Records the interval at the first spin, then ends the run as SIGINT would."""

        def add_node(self, node):
            pass

        def spin_once(self, timeout_sec):
            seen.append(sys.getswitchinterval())
            rclpy.try_shutdown()

        def shutdown(self):
            pass

    class QuietNode(Node):
        """A node with the close() that run() calls."""

        def close(self):
            pass

    monkeypatch.setattr(spin, 'EventsExecutor', Executor)
    monkeypatch.setattr(spin, 'freeze_heap', lambda: None)
    monkeypatch.setattr(spin.signal, 'signal', lambda *_: None)
    before = sys.getswitchinterval()
    try:
        code = spin.run(lambda ros_arguments: QuietNode('switch_interval_probe'), 'probe', [])
    finally:
        sys.setswitchinterval(before)
    assert code == 0
    assert seen == [pytest.approx(spin.GIL_SWITCH_INTERVAL_S)]
    assert spin.GIL_SWITCH_INTERVAL_S < before


def test_mailbox_with_room_for_two_answers_a_burst_and_drops_the_oldest_beyond():
    """FIFO within the capacity; one more item pushes out the oldest waiting, counted."""
    mailbox = LatestMailbox(capacity=2)
    assert mailbox.put(1) is False and mailbox.put(2) is False
    assert mailbox.take() == 1  # a burst of two: both are taken, oldest first
    assert mailbox.put(3) is False
    assert mailbox.put(4) is True  # 2 goes: the newest always waits
    assert [mailbox.take(), mailbox.take()] == [3, 4] and mailbox.skipped == 1
    assert mailbox.take(timeout=0.01) is None
    with pytest.raises(ValueError, match='capacity 0'):
        LatestMailbox(capacity=0)


def test_an_isolated_environment_picks_a_domain_ros_recommends():
    """Domains 1-101 (Linux's recommended range, not the default 0), localhost discovery."""
    domains = set()
    for _ in range(300):
        env = isolated_ros_env()
        domains.add(int(env['ROS_DOMAIN_ID']))
        assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert min(domains) >= 1 and max(domains) <= 101 and len(domains) > 50
    assert isolated_ros_env(7)['ROS_DOMAIN_ID'] == '7'


def test_an_idle_turn_waits_for_the_workers_items_and_holds_the_worker_off():
    """A turn starts only when nothing waits and the worker rests; the worker waits for it."""
    mailbox = LatestMailbox(capacity=2)
    mailbox.put('wrench 1')
    events = []

    def other() -> None:
        with mailbox.idle_turn():
            events.append('turn begins')
            time.sleep(0.05)
            events.append('turn ends')

    assert mailbox.take() == 'wrench 1'   # the worker is busy with it
    thread = threading.Thread(target=other)
    thread.start()
    time.sleep(0.05)
    assert events == []   # not while the worker works
    mailbox.done()
    time.sleep(0.01)
    mailbox.put('wrench 2')   # arrives during the turn: waits for its end
    assert mailbox.take(timeout=1.0) == 'wrench 2' and events == ['turn begins', 'turn ends']
    thread.join(1.0)
    mailbox.done()
    mailbox.put('wrench 3')   # a waiting item comes before a turn
    begun = []
    late = threading.Thread(target=lambda: begun.append(mailbox.idle_turn().__enter__()))
    late.start()
    time.sleep(0.05)
    assert begun == []
    assert mailbox.take() == 'wrench 3'
    mailbox.done()
    late.join(1.0)
    assert begun == [None]


def test_take_newest_counts_the_older_items_as_skipped():
    """Taking the newest drops the older waiting items, counted as skipped."""
    mailbox = LatestMailbox(capacity=3)
    for item in ('pose 1', 'pose 2', 'pose 3'):
        mailbox.put(item)
    assert mailbox.wait_for_item(0.1) and mailbox.take_newest() == 'pose 3'
    assert mailbox.skipped == 2 and mailbox.take_newest() is None
    mailbox.close()
    assert not mailbox.wait_for_item(0.1)


def test_what_arrives_during_a_turn_is_kept_until_the_worker_catches_up():
    """Turn room: items arriving in a turn wait beyond the capacity, then the usual limit."""
    mailbox = LatestMailbox(capacity=2, turn_room=5)
    with mailbox.idle_turn():
        for item in range(6):
            mailbox.put(item)
    assert mailbox.skipped == 0
    mailbox.put(6)   # still catching up: kept
    assert mailbox.skipped == 0
    taken = []
    while len(taken) < 6:
        taken.append(mailbox.take())
        mailbox.done()
    assert taken == [0, 1, 2, 3, 4, 5]   # caught up: the usual capacity again
    mailbox.put(7)
    mailbox.put(8)
    assert mailbox.skipped == 1 and [mailbox.take(), mailbox.take()] == [7, 8]
    mailbox.done()
    with mailbox.idle_turn():   # beyond the room, the oldest goes
        for item in range(9, 17):
            mailbox.put(item)
    assert mailbox.skipped == 2
