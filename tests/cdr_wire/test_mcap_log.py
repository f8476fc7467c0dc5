"""McapLog: a ROS 2 MCAP that mcap_ros2 reads back, thread safety, a killed writer."""

import math
from pathlib import Path
import subprocess
import sys
import threading

from cdr_translator.interface import messages
from cdr_wire import msgdefs
from cdr_wire.mcap_log import McapLog
from cdr_wire.rosbag2_metadata import offered_qos_profiles_yaml
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.reader import read_ros2_messages
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


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
