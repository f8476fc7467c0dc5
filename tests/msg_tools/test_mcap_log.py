"""msg_tools message definitions, type hashes, McapLog and the output message dicts."""

import math
from pathlib import Path
import subprocess
import sys
import threading

from cdr_translator import TranslatorSolver
from cdr_translator.interface import messages
from cdr_wire import msgdefs
from cdr_wire.mcap_log import McapLog
from cdr_wire.rosbag2_metadata import offered_qos_profiles_yaml
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.reader import read_ros2_messages
import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
OUTPUT_TYPES = ('geometry_msgs/msg/WrenchStamped', 'geometry_msgs/msg/PoseStamped',
                'sensor_msgs/msg/JointState', 'std_msgs/msg/Float64MultiArray',
                'visualization_msgs/msg/MarkerArray', 'diagnostic_msgs/msg/DiagnosticArray')
STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


# ---------------------------------------------------------------------------- msgdefs
def test_every_output_type_is_shipped():
    """The six types the node and replay use have complete definitions."""
    for type_name in OUTPUT_TYPES:
        assert type_name in msgdefs.MESSAGE_DEFINITIONS


def test_field_types_follow_the_field_type_ids():
    """Arrays, bounded sequences and bounded strings get REP-2011 ids and capacities."""
    fixed = msgdefs._parse_field('float64[36] covariance', 'geometry_msgs')
    assert (fixed.type_id, fixed.capacity) == (59, 36)   # FIELD_TYPE_DOUBLE_ARRAY
    bounded = msgdefs._parse_field('string<=5[<=3] names  # comment', 'pkg')
    assert (bounded.type_id, bounded.capacity, bounded.string_capacity) == (117, 3, 5)
    nested = msgdefs._parse_field('Point[] points', 'geometry_msgs')
    assert (nested.type_id, nested.nested_type_name, nested.dependency) == (
        145, 'geometry_msgs/msg/Point', 'geometry_msgs/Point')
    assert msgdefs._strip_comment('string a "x#y" # tail') == 'string a "x#y" '


@pytest.mark.parametrize('bad', ['geometry_msgs/WrenchStamped', 'WrenchStamped', 'a/msg/',
                                 'nope_msgs/msg/Nothing', None])
def test_bad_type_names_are_value_errors(bad):
    """Unknown or malformed type names raise ValueError naming them."""
    with pytest.raises(ValueError, match='message'):
        msgdefs.type_hash(bad)


# ---------------------------------------------------------------------------- messages
def test_pose_and_joint_state_follow_the_result(solved):
    """Pose = end-disk centre and quaternion; JointState = bending angles in radians."""
    pose = messages.pose_message(solved, STAMP, 'base')
    assert pose['header'] == {'stamp': STAMP, 'frame_id': 'base'}
    assert [pose['pose']['position'][a] for a in 'xyz'] == solved.end_disk_position.tolist()
    assert [pose['pose']['orientation'][a] for a in 'xyzw'] == (
        solved.end_disk_quaternion_xyzw.tolist())
    joints = messages.joint_state_message(solved, STAMP, 'base')
    assert joints['name'] == list(messages.JOINT_NAMES)
    table = solved.to_dict()
    expected = [table['pj_bending_deg'], table['pj_direction_deg'], table['dj_bending_deg'],
                table['dj_direction_deg'], table['end_disk_rotation_deg']]
    assert np.allclose(np.degrees(joints['position']), expected, rtol=0, atol=1e-12)
    assert 22.0 < math.degrees(joints['position'][0]) < 22.6   # Table II: 22.448 deg


def test_backbone_markers_draw_the_solved_shape(solved, params):
    """Five line strips through the backbones, four disks at the frames, the rigid tube."""
    markers = messages.backbones_message(solved, params, STAMP, 'base')['markers']
    strips = [m for m in markers if m['ns'] == 'backbones']
    assert [m['type'] for m in strips] == [messages.MARKER_LINE_STRIP] * 5
    for strip, rod in zip(strips, solved.backbones):
        assert np.array_equal([[p['x'], p['y'], p['z']] for p in strip['points']], rod)
    disks = [m for m in markers if m['ns'] == 'disks']
    for disk, name in zip(disks, ('pe', 'pm', 'dm', 'de')):
        assert np.allclose([disk['pose']['position'][a] for a in 'xyz'],
                           solved.frames[name][:3, 3], atol=1e-15)
    (tube,) = [m for m in markers if m['ns'] == 'tube']
    assert tube['scale']['z'] == pytest.approx(params.tube_length, abs=1e-9)
    assert all(m['header']['frame_id'] == 'base' for m in markers)


def test_wrench_dict_round_trip():
    """wrench_message and wrench_from_message are inverse, for dicts and for objects."""
    message = messages.wrench_message([1.0, -2.0, 3.5], [0.1, 0.0, -0.2], 'base', STAMP)
    force, moment, frame_id, stamp = messages.wrench_from_message(message)
    assert force.tolist() == [1.0, -2.0, 3.5] and moment.tolist() == [0.1, 0.0, -0.2]
    assert (frame_id, stamp) == ('base', STAMP)
    assert messages.stamp_to_ns(stamp) == 1_700_000_000_123_456_789
    assert messages.stamp_from_ns(1_700_000_000_123_456_789) == STAMP


def test_diagnostics_and_output_messages(solved, params):
    """Converged: pose, angles, markers and an OK status; not converged: ERROR status only."""
    outputs = messages.output_messages(solved, STAMP, 'base', backbones_params=params,
                                       extra_values={'skipped': 3})
    topics = [topic for topic, _, _ in outputs]
    assert topics[:2] == [messages.END_DISK_POSE_TOPIC, messages.BENDING_ANGLES_TOPIC]
    assert topics[-2:] == [messages.BACKBONES_TOPIC, messages.DIAGNOSTICS_TOPIC]
    for topic, type_name, _ in outputs:
        assert messages.TOPIC_TYPES[topic] == type_name
    status = outputs[-1][2]['status'][0]
    values = {kv['key']: kv['value'] for kv in status['values']}
    assert status['level'] == messages.OK and values['converged'] == 'true'
    # the solver bounds the largest residual by 1e-10, so the norm of 90 by sqrt(90) times it
    assert values['skipped'] == '3' and float(values['residual_norm']) <= 1e-9
    failing = TranslatorSolver(params, time_limit_s=0.0).solve([20.0, 5.0, 0.0])
    assert not failing.converged
    outputs = messages.output_messages(failing, STAMP, 'base')
    assert [(topic, msg['status'][0]['level']) for topic, _, msg in outputs] == [
        (messages.DIAGNOSTICS_TOPIC, messages.ERROR)]
    assert outputs[0][2]['status'][0]['message'] == failing.message
    with pytest.raises(ValueError, match='level'):
        messages.diagnostics_message(STAMP, 7, 'x', {})
    with pytest.raises(ValueError, match='compliance'):
        messages.compliance_message(failing if getattr(failing, 'compliance', None) is None
                                    else solved)


def test_compliance_arrays_are_row_major_with_layout(params):
    """6x6 compliance: dims rows/cols, element (i, j) at 6 i + j; eigenvalues (6)."""
    solver = TranslatorSolver(params)
    result = solver.solve([12.0, 0.0, 0.0], compliance=True)
    matrix = messages.compliance_message(result)
    assert [(d['label'], d['size'], d['stride']) for d in matrix['layout']['dim']] == [
        ('rows', 6, 36), ('cols', 6, 6)]
    stored = np.array(matrix['data']).reshape(6, 6)
    assert np.array_equal(stored, result.compliance.matrix)
    eigen = messages.compliance_eigenvalues_message(result)
    assert eigen['data'] == [float(v) for v in result.compliance.eigenvalues]
    topics = [t for t, _, _ in messages.output_messages(result, STAMP, 'base')]
    assert messages.COMPLIANCE_TOPIC in topics and messages.COMPLIANCE_EIGENVALUES_TOPIC in topics


# ---------------------------------------------------------------------------- McapLog
def test_round_trip_through_mcap_ros2_with_rosbag2_metadata(tmp_path, all_outputs,
                                                            plain_message):
    """Every output decodes back to its dict; schemas, channels and metadata as rosbag2's."""
    path = tmp_path / 'run.mcap'
    written = all_outputs
    with McapLog(path, flush_every_messages=2, flush_every_s=0.0) as log:
        log.register(messages.WRENCH_TOPIC, messages.WRENCH_TYPE, qos='sensor_data')
        for index, (topic, type_name, message) in enumerate(written):
            log.write(topic, type_name, message, log_time_ns=1000 + index)
    decoded = list(read_ros2_messages(str(path)))
    assert len(decoded) == len(written)
    for (topic, type_name, message), item in zip(written, decoded):
        assert item.channel.topic == topic and item.schema.name == type_name
        assert plain_message(item.ros_msg) == message
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(written)
        assert {c.compression for c in summary.chunk_indexes} == {'zstd'}
        assert len(summary.chunk_indexes) == math.ceil(len(written) / 2)
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert (schema.encoding, channel.message_encoding) == ('ros2msg', 'cdr')
            assert schema.data.decode() == msgdefs.MESSAGE_DEFINITIONS[schema.name]
            assert channel.metadata['topic_type_hash'] == msgdefs.type_hash(schema.name)
            (qos,) = yaml.safe_load(channel.metadata['offered_qos_profiles'])
            expected = 'best_effort' if channel.topic == messages.WRENCH_TOPIC else 'reliable'
            assert qos['reliability'] == expected and qos['history'] == 'keep_last'
            assert qos['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
        metadata = {record.name: record.metadata for record in reader.iter_metadata()}
        assert metadata['rosbag2'] == {'ROS_DISTRO': 'jazzy'}


def test_close_is_idempotent_and_closed_log_rejects_writes(tmp_path):
    """close() twice is fine; writing afterwards, unknown types and type clashes are errors."""
    log = McapLog(tmp_path / 'sub' / 'x.mcap', flush_every_messages=1, flush_every_s=0.05)
    log.write('wrench', messages.WRENCH_TYPE,
              messages.wrench_message([1, 2, 3], [0, 0, 0], '', STAMP), 5)
    with pytest.raises(ValueError, match='registered with type'):
        log.write('wrench', messages.POSE_TYPE, {}, 6)
    with pytest.raises(ValueError, match='no message definition'):
        log.write('other', 'nope_msgs/msg/X', {}, 6)
    with pytest.raises(ValueError, match='qos'):
        log.register('other', messages.POSE_TYPE, qos='fast')
    with pytest.raises(ValueError, match='cannot encode'):
        log.write('pose', messages.POSE_TYPE, {'pose': {'position': {'x': 'east'}}}, 6)
    log.close()
    log.close()
    assert log.closed and log.message_counts == {'wrench': 1}
    with pytest.raises(ValueError, match='closed'):
        log.write('wrench', messages.WRENCH_TYPE, {}, 7)
    assert [m.log_time_ns for m in read_ros2_messages(str(log.path))] == [5]
    for bad in ({'flush_every_messages': -1}, {'flush_every_s': -1.0},
                {'flush_every_messages': 1.5}):
        with pytest.raises(ValueError, match='flush_every'):
            McapLog(tmp_path / 'bad.mcap', **bad)
    with pytest.raises(ValueError, match='qos'):
        offered_qos_profiles_yaml('bogus')


def test_concurrent_writers_lose_nothing(tmp_path):
    """Four threads writing at once: every message is in the file, each chunk intact."""
    path = tmp_path / 'threads.mcap'
    with McapLog(path, flush_every_messages=7, flush_every_s=0.01) as log:
        def work(worker):
            for index in range(150):
                log.write(f'w{worker}', messages.WRENCH_TYPE, messages.wrench_message(
                    [index, worker, 0], [0, 0, 0], '', STAMP), log_time_ns=index)
        threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=60)
    counts = {}
    for item in read_ros2_messages(str(path)):
        counts[item.channel.topic] = counts.get(item.channel.topic, 0) + 1
        assert item.ros_msg.wrench.force.y == int(item.channel.topic[1:])
    assert counts == {f'w{k}': 150 for k in range(4)}


KILLED_WRITER = """
import os, signal, sys, time
from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
log = McapLog(sys.argv[1], flush_every_messages=int(sys.argv[2]), flush_every_s=float(sys.argv[3]))
for index in range(int(sys.argv[4])):
    log.write('wrench', messages.WRENCH_TYPE,
              messages.wrench_message([index, 0, 0], [0, 0, 0], '', {'sec': index, 'nanosec': 0}),
              log_time_ns=index)
deadline = time.monotonic() + float(sys.argv[5])  # wait (bounded) for the flush timer
while log.status().pending and time.monotonic() < deadline:
    time.sleep(0.01)
os.kill(os.getpid(), signal.SIGKILL)
"""


def _stream_messages(path):
    """Messages of the complete chunks of an unfinished MCAP, read as a stream."""
    found = []
    try:
        for record in StreamReader(str(path), validate_crcs=True).records:
            if isinstance(record, Message):
                found.append(record.log_time)
    except EndOfFile:  # no footer: the stream just ends after the last flushed chunk
        pass
    return found


@pytest.mark.parametrize('every_n, every_s, count, wait, expected', [
    (10, 0.0, 25, 0.0, 20),      # two full chunks by count; the last 5 are lost
    (0, 0.2, 3, 30.0, 3),        # nothing by count, the timer flushed all three
])
def test_killed_writer_leaves_complete_chunks(tmp_path, every_n, every_s, count, wait,
                                              expected):
    """SIGKILL after writing: the indexed reader fails, the flushed chunks stream out."""
    path = tmp_path / 'killed.mcap'
    process = subprocess.run([sys.executable, '-c', KILLED_WRITER, str(path), str(every_n),
                              str(every_s), str(count), str(wait)], cwd=ROOT, timeout=120,
                             capture_output=True, text=True)
    assert process.returncode == -9, process.stderr
    with pytest.raises(Exception):  # noqa: B017 - no footer, no summary: any reader error
        list(read_ros2_messages(str(path)))
    assert _stream_messages(path) == list(range(expected))
