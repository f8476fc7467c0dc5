"""translator_node's parts that need no DDS: parameters, input checks, mailbox, filler, log."""

import threading

from cdr_translator import TranslatorParams
from cdr_translator.node_io import fill_message, LatestMailbox, LogThread, type_name
from cdr_translator.node_params import check_value, default_values, model_params
from cdr_translator.node_params import NodeSettings, SPECS
from cdr_translator.params import ACCURACY_KEYS, DEFAULT_PARAMS_PATH, FIDELITY_KEYS, NODE_NAME
from cdr_translator.params import NODE_ONLY_KEYS
from cdr_translator.params import ParameterError, read_params_file
from diagnostic_msgs.msg import DiagnosticArray
from mcap_ros2.reader import read_ros2_messages
from msg_tools import messages
from msg_tools.mcap_log import McapLog
from msg_tools.processing import check_magnitude, in_end_disk_frame
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import MarkerArray
import yaml


def test_every_yaml_key_is_declared_and_node_keys_match_the_library():
    """The one YAML, the node's specs and params.NODE_ONLY_KEYS name the same parameters."""
    values = read_params_file()
    assert set(values) == set(SPECS)
    model_keys = set(TranslatorParams.__dataclass_fields__)
    assert set(SPECS) - model_keys == NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS
    assert set(NodeSettings.__dataclass_fields__) == \
        NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS
    assert model_params(values) == TranslatorParams.from_yaml()
    assert all(SPECS[key].read_only for key in model_keys)


def test_default_values_name_missing_and_unknown_keys(tmp_path):
    """A params file the node cannot take fully is an error naming the keys."""
    document = yaml.safe_load(DEFAULT_PARAMS_PATH.read_text())
    section = document[NODE_NAME]['ros__parameters']
    del section['max_force']
    section['max_forse'] = 1.0
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) \['max_forse'\], "
                                             r"missing \['max_force'\]"):
        default_values(path)


def test_descriptors_carry_description_range_and_read_only():
    """Integer and float ranges follow the value's type; geometry is read-only."""
    values = default_values()
    steps = SPECS['steps_per_segment'].descriptor(values['steps_per_segment'])
    assert steps.read_only and steps.integer_range[0].from_value == 1
    force = SPECS['max_force'].descriptor(values['max_force'])
    assert not force.read_only and force.floating_point_range[0].from_value == 0.0
    assert 'N' in force.description
    frame = SPECS['base_frame'].descriptor(values['base_frame'])
    assert not frame.integer_range and not frame.floating_point_range


@pytest.mark.parametrize('name, value, others, reason', [
    ('base_frame', '', {'end_disk_frame': 'e'}, 'must not be empty'),
    ('base_frame', 'a b', {'end_disk_frame': 'e'}, 'white space'),
    ('end_disk_frame', 'b', {'base_frame': 'b'}, 'must differ'),
])
def test_check_value_gives_reasons(name, value, others, reason):
    """Run-time values the descriptors cannot catch are refused with a reason."""
    assert reason in check_value(name, value, others)


def test_check_value_accepts_good_values():
    """Valid frames and limits pass."""
    assert check_value('base_frame', 'world', {'end_disk_frame': 'tool'}) is None
    assert check_value('max_force', 5.0, {}) is None


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
