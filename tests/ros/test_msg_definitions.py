"""
msg_tools' message definitions and CDR against ROS itself: the installed interfaces and rclpy.

msg_tools needs no ROS; these tests use the pinned ROS wheels as the oracle (the .msg and
.json files rosidl installed, rclpy's serializer), so they live with the ROS tests.
"""

import importlib
import json
from pathlib import Path
import sys

from cdr_wire import msgdefs
from cdr_wire.mcap_log import McapLog
from mcap_ros2.reader import read_ros2_messages
import pytest
from rclpy.serialization import deserialize_message, serialize_message

#: The interface files installed by the ROS wheels: the oracle for texts and hashes.
ROS_SHARE = Path(sys.prefix) / 'share'


def _installed(type_name: str, suffix: str) -> Path:
    package, _, name = type_name.split('/')
    path = ROS_SHARE / package / 'msg' / f'{name}{suffix}'
    # the pinned ROS wheels ship these files: they are the oracle, so their absence fails
    assert path.is_file(), f'{path} is not installed'
    return path


@pytest.mark.parametrize('type_name', msgdefs.shipped_types())
def test_shipped_text_and_hash_equal_the_installed_interfaces(type_name):
    """Each shipped .msg equals ROS's file; each RIHS01 equals the hash rosidl generated."""
    assert (msgdefs.MSG_DIR / type_name.split('/')[0] / (type_name.split('/')[2] + '.msg')
            ).read_text() == _installed(type_name, '.msg').read_text()
    official = json.loads(_installed(type_name, '.json').read_text())
    hashes = {entry['type_name']: entry['hash_string'] for entry in official['type_hashes']}
    assert msgdefs.type_hash(type_name) == hashes[type_name]
    assert msgdefs.TYPE_HASHES[type_name] == hashes[type_name]
    # every referenced type the official description lists, and only those
    referenced = [entry['type_name'] for entry
                  in official['type_description_msg']['referenced_type_descriptions']]
    assert [entry['type_name'] for entry in
            msgdefs.type_description(type_name)['referenced_type_descriptions']] == referenced


def test_full_definition_has_each_dependency_once_in_rosbag2_order():
    """Own text first, then each transitive dependency once, depth first, sorted per level."""
    text = msgdefs.MESSAGE_DEFINITIONS['geometry_msgs/msg/WrenchStamped']
    blocks = text.split('\n' + '=' * 80 + '\n')
    assert blocks[0] == _installed('geometry_msgs/msg/WrenchStamped', '.msg').read_text()
    assert [block.splitlines()[0] for block in blocks[1:]] == [
        'MSG: geometry_msgs/Wrench', 'MSG: geometry_msgs/Vector3', 'MSG: std_msgs/Header',
        'MSG: builtin_interfaces/Time']
    marker_array = msgdefs.MESSAGE_DEFINITIONS['visualization_msgs/msg/MarkerArray']
    names = [line for line in marker_array.splitlines() if line.startswith('MSG: ')]
    referenced = msgdefs.type_description('visualization_msgs/msg/MarkerArray')[
        'referenced_type_descriptions']
    assert sorted(names) == sorted('MSG: ' + entry['type_name'].replace('/msg/', '/')
                                   for entry in referenced)


def _rclpy_dict(message):
    """Turn an rclpy message into nested dicts/lists (byte fields as ints)."""
    if hasattr(message, 'get_fields_and_field_types'):
        return {name: _rclpy_dict(getattr(message, name))
                for name in message.get_fields_and_field_types()}
    if isinstance(message, bytes) and len(message) == 1:
        return message[0]
    if getattr(message, 'typecode', None) == 'B':  # uint8[] as array.array
        return bytes(message)
    if isinstance(message, (list, tuple)) or type(message).__name__ in ('ndarray', 'array'):
        return [_rclpy_dict(item) for item in message]
    return message


def test_cdr_agrees_with_rclpy_both_ways(tmp_path, all_outputs, plain_message):
    """Our CDR deserializes in rclpy to the same values; rclpy's bytes log and decode back."""

    def get_message(type_name):
        package, _, name = type_name.split('/')
        return getattr(importlib.import_module(f'{package}.msg'), name)

    path = tmp_path / 'cdr.mcap'
    written = all_outputs
    with McapLog(path, flush_every_messages=0, flush_every_s=0.0) as log:
        for topic, type_name, message in written:
            log.write(topic, type_name, message, log_time_ns=1)
            ros_message = deserialize_message(
                log._encoder(type_name)(message), get_message(type_name))
            assert _rclpy_dict(ros_message) == message
            log.write_serialized('rclpy/' + topic.lstrip('/'), type_name,
                                 serialize_message(ros_message), log_time_ns=2)
    decoded = {}
    for item in read_ros2_messages(str(path)):
        decoded.setdefault(item.channel.topic.replace('rclpy/', '').lstrip('/'), []).append(
            plain_message(item.ros_msg))
    for first, second in decoded.values():
        assert first == second
