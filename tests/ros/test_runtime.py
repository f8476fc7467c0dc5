"""translator_node's parts that need no DDS: parameters, input checks, mailbox, filler, log."""

import threading
import time

from cdr_translator.interface import messages
from cdr_translator.interface.processing import check_magnitude, in_end_disk_frame
from cdr_translator.params import ParameterError
from cdr_translator.ros.parameters import default_values, descriptor, ros_parameter_sources
from cdr_translator.ros.parameters import SPECS
from cdr_translator.ros.runtime import fill_message, LatestMailbox, LogThread, type_name
from diagnostic_msgs.msg import DiagnosticArray
from mcap_ros2.reader import read_ros2_messages
from msg_tools.mcap_log import McapLog
import pytest
from rclpy.serialization import deserialize_message, serialize_message
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
    files, overrides = ros_parameter_sources(
        ['node', '--params-file', 'not_ros.yaml', '--ros-args', '--params-file', 'a.yaml',
         '-p', 'max_force:=50.0', '--param', 'log_dir:=/tmp/x', '-r', '__ns:=/leg1', '--',
         '-p', 'ignored:=1', '--ros-args', '--params-file', 'b.yaml'])
    assert files == ['a.yaml', 'b.yaml']
    assert overrides == {'max_force': 50.0, 'log_dir': '/tmp/x'}
    with pytest.raises(ParameterError, match='expected name:=value'):
        ros_parameter_sources(['--ros-args', '-p', 'max_force=50'])


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


def test_log_thread_writes_bytes_and_messages_in_order(tmp_path):
    """Raw CDR and message objects both land in the MCAP, decodable, in submission order."""
    path = tmp_path / 'log.mcap'
    log = LogThread(McapLog(path, flush_every_messages=2, flush_every_s=0.0))
    stamp = {'sec': 1, 'nanosec': 2}
    first = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 0, 'a', {}))
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, serialize_message(first), 10)
    second = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 2, 'b', {}))
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, second, 20, 15)
    log.close()
    log.close()
    decoded = list(read_ros2_messages(str(path)))
    assert [message.ros_msg.status[0].message for message in decoded] == ['a', 'b']
    assert [message.log_time_ns for message in decoded] == [10, 20]
    assert decoded[1].publish_time_ns == 15
    assert log.written == 2 and log.errors == 0
    assert deserialize_message(serialize_message(second), DiagnosticArray) == second


def _wait(condition, timeout_s=10.0):
    """Wait (bounded) until ``condition()`` holds; return whether it did."""
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.005)
    return condition()


def test_log_thread_writes_while_the_solver_waits(tmp_path):
    """A record waits while the solver works (mailbox not idle) and is written once it waits."""
    mailbox = LatestMailbox()
    assert not mailbox.idle.is_set()
    log = LogThread(McapLog(tmp_path / 'log.mcap', flush_every_s=0.0), idle=mailbox.idle,
                    hold_s=600.0)
    stamp = {'sec': 1, 'nanosec': 2}
    record = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 0, 'a', {}))
    mailbox.put('wrench')
    log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, record, 10)
    assert _wait(lambda: log.held == 1)
    assert log.written == 0  # held: hold_s is 10 minutes
    assert mailbox.take() == 'wrench' and not mailbox.idle.is_set()  # the solver works
    assert mailbox.take(timeout=0.05) is None and mailbox.idle.is_set()  # then waits
    assert _wait(lambda: log.written == 1)
    mailbox.put('next')
    assert not mailbox.idle.is_set()
    mailbox.close()
    assert mailbox.idle.is_set()
    log.close()


@pytest.mark.parametrize('hold_s, hold_records', [(0.0, 1000), (600.0, 2)],
                         ids=['held long enough', 'too many held'])
def test_log_thread_stops_holding_back(tmp_path, hold_s, hold_records):
    """While the solver works: written after hold_s, or once hold_records are queued."""
    busy = threading.Event()  # never set: the solver never waits
    log = LogThread(McapLog(tmp_path / 'log.mcap', flush_every_s=0.0), idle=busy,
                    hold_s=hold_s, hold_records=hold_records)
    stamp = {'sec': 1, 'nanosec': 2}
    record = fill_message(DiagnosticArray(), messages.diagnostics_message(stamp, 0, 'a', {}))
    for index in range(3):
        log.submit('/diagnostics', messages.DIAGNOSTIC_ARRAY_TYPE, record, 10 + index)
    assert _wait(lambda: log.written >= 2)
    log.close()
    assert log.written == 3
