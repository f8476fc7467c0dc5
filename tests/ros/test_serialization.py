"""
The node's CDR encoding from message dicts, and which outputs it builds and publishes.

serialization.encode must give what rclpy's fill_message + serialize_message gives
(compared after rclpy decodes both: rclpy leaves its padding bytes uninitialized),
serialization.decode must read rclpy's bytes; the node publishes only topics with
subscribers and, without a log, builds nothing else. No DDS traffic: the node test runs
in-process in its own context and domain.
"""

from cdr_translator.interface import messages
from cdr_translator.interface.diagnostics_period import diagnostics_array, StreamDiagnostics
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import node_solver
from cdr_translator.params.translator_params import DEFAULT_PARAMS_PATH
from cdr_translator.ros import serialization
from cdr_translator.ros.node_log import log_health
from cdr_translator.ros.topics import fill_message, OUTPUTS, SubscriberCounts
from cdr_wire.cdr_plan import HEADER
from geometry_msgs.msg import PoseStamped, WrenchStamped
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Float64MultiArray

STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


@pytest.fixture(scope='module')
def result():
    """Solve once with compliance; return the result and the solver's parameters."""
    settings = TranslatorSettings.from_params_files([], defaults_path=DEFAULT_PARAMS_PATH)
    solver = node_solver(settings.params, settings)
    solved = solver.solve([6.0, 2.0, -1.0], [0.05, 0.0, 0.02], compliance=True)
    assert solved.converged
    return solved, solver.params


def _same_as_rclpy(topic, values):
    """Assert that serialization.encode gives what rclpy fills and serializes from ``values``."""
    message_class = OUTPUTS[topic]
    expected = fill_message(message_class(), values)
    data = serialization.encode(message_class, values)
    assert data[:4] == HEADER
    assert deserialize_message(data, message_class) == expected
    assert deserialize_message(serialize_message(expected), message_class) == expected


def test_every_output_encodes_as_rclpy_does(result):
    """Pose, angles, both compliance arrays, the markers and the diagnostics."""
    solved, params = result
    outputs = messages.output_messages(solved, STAMP, 'translator_base',
                                       backbones_params=params,
                                       extra_values={'follower_solves': 3})
    assert {topic for topic, _, _ in outputs} == set(OUTPUTS) - {messages.DIAGNOSTICS_TOPIC}
    for topic, _, values in outputs:
        _same_as_rclpy(topic, values)
    period = StreamDiagnostics(messages.DIAGNOSTIC_NAME, 'wrenches')
    period.note(messages.WARN, 'unstable é', 1e-12, 0.002)
    status = period.status({'received': 3, 'solved': 1, 'skipped': 2}, 1.0)
    _same_as_rclpy(messages.DIAGNOSTICS_TOPIC, diagnostics_array(STAMP, [status, status]))
    for topic, _, values in messages.rejection_messages(STAMP, 'rejected: |force| é', {}):
        _same_as_rclpy(topic, values)


def test_missing_fields_take_their_defaults_and_odd_sizes_align():
    """An empty dict is the default message; strings of every length keep the alignment."""
    assert deserialize_message(serialization.encode(PoseStamped, {}), PoseStamped) == PoseStamped()
    for length in range(9):
        values = {'header': {'frame_id': 'x' * length}, 'name': ['a' * length, 'bc'],
                  'position': [0.5, -1.0], 'effort': [2.0]}
        message = deserialize_message(serialization.encode(JointState, values), JointState)
        assert message == fill_message(JointState(), values)
    layout = {'layout': {'dim': [{'label': 'l' * 3, 'size': 2, 'stride': 2}]}, 'data': [1.5]}
    encoded = serialization.encode(Float64MultiArray, layout)
    assert deserialize_message(encoded, Float64MultiArray) \
        == fill_message(Float64MultiArray(), layout)


def test_runs_of_primitives_keep_their_padding():
    """A PointField (uint32, uint8, uint32) packs with 3 padding bytes, as rclpy aligns it."""
    for name in ('', 'x', 'xyz', 'rgba'):
        values = {'header': {'stamp': STAMP, 'frame_id': name}, 'height': 1, 'width': 2,
                  'fields': [{'name': name, 'offset': 0, 'datatype': 7, 'count': 1},
                             {'name': 'yz', 'offset': 4, 'datatype': 8, 'count': 2}],
                  'is_bigendian': False, 'point_step': 12, 'row_step': 24,
                  'data': bytes(range(24)), 'is_dense': True}
        data = serialization.encode(PointCloud2, values)
        assert deserialize_message(data, PointCloud2) == fill_message(PointCloud2(), values)
        assert serialization.decode(PointCloud2, data)['fields'] == values['fields']


def test_decode_reads_rclpy_bytes_and_refuses_damaged_ones():
    """A WrenchStamped from rclpy decodes to the dict it was filled from; cut bytes do not."""
    values = messages.wrench_message([1.0, -2.5, 3.0], [0.1, 0.0, -0.2], 'translator_end_disk',
                                     STAMP)
    data = serialize_message(fill_message(WrenchStamped(), values))
    assert serialization.decode(WrenchStamped, data) == values
    encoded = serialization.encode(WrenchStamped, values)
    assert serialization.decode(WrenchStamped, encoded) == values
    with pytest.raises(ValueError, match='ends at byte'):
        serialization.decode(WrenchStamped, data[:40])
    with pytest.raises(ValueError, match='little-endian'):
        serialization.decode(WrenchStamped, b'\x00\x00' + data[2:])
    with pytest.raises(ValueError, match='string length'):
        serialization.decode(WrenchStamped, data[:12] + b'\xff\xff\x00\x00' + data[16:])


class _Publisher:
    """A stand-in for an rclpy Publisher: a settable subscriber count, counted queries."""

    def __init__(self, subscribers=0):
        self.subscribers = subscribers
        self.queries = 0

    def get_subscription_count(self):
        self.queries += 1
        return self.subscribers


def test_subscriber_counts_are_refreshed_at_most_every_period():
    """Within the period the last count stands; after it a new subscriber is seen."""
    now = [0.0]
    pose, angles = _Publisher(1), _Publisher(0)
    counts = SubscriberCounts({'pose': pose, 'angles': angles}, refresh_s=0.05,
                              clock=lambda: now[0])
    assert counts.subscribed() == {'pose'}
    angles.subscribers = 2
    now[0] = 0.04
    assert counts.subscribed() == {'pose'} and pose.queries == 1
    now[0] = 0.05
    assert counts.subscribed() == {'pose', 'angles'} and pose.queries == 2


def _outputs(node, solved, compliance, backbones, extra):
    """Serialize the outputs of ``solved`` as the node does: built lazily, the pose first."""
    return node._serialized(messages.iter_output_messages(
        solved, STAMP, node.processor.settings.base_frame, compliance=compliance,
        backbones_params=node.processor.solver.params if backbones else None,
        extra_values=extra))


def test_node_publishes_only_subscribed_topics_and_builds_nothing_else(
        node, result, monkeypatch):
    """Without a log and with only the pose subscribed, only the pose is encoded and sent."""
    solved, _ = result
    sent, encoded = [], []
    for topic, publisher in node._publishers_by_topic.items():
        monkeypatch.setattr(publisher, 'publish',
                            lambda data, topic=topic: sent.append((topic, data)))
    for topic, encode in list(node._encoders.items()):
        node._encoders[topic] = lambda values, topic=topic, encode=encode: (
            encoded.append(topic), encode(values))[1]
    pose_only = _Publisher(1)
    node._subscribers = SubscriberCounts({messages.END_DISK_POSE_TOPIC: pose_only})
    node._publish_all(_outputs(node, solved, False, False, {'received': 1}))
    assert encoded == [messages.END_DISK_POSE_TOPIC]
    assert [topic for topic, _ in sent] == [messages.END_DISK_POSE_TOPIC]
    pose = deserialize_message(sent[0][1], PoseStamped)
    assert pose.header.stamp.sec == STAMP['sec']
    assert pose.pose.position.x == pytest.approx(float(solved.end_disk_position[0]))
    node._subscribers = SubscriberCounts({})
    node._publish_all(node._serialized(log_health(None, 'n', {})))
    node._publish_all(_outputs(node, solved, True, True, {}))
    assert len(sent) == 1 and len(encoded) == 1
