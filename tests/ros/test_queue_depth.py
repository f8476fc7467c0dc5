"""Input queues as deep as their parameter says (read-only, bounded); the solver mailbox."""

from cdr_translator.ros.cdr_node import CdrNode
from cdr_translator.ros.translator_node import TranslatorNode
import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data

pytestmark = pytest.mark.usefixtures('ros_env')


@pytest.mark.parametrize('factory, name, default', [
    (TranslatorNode, 'wrench_queue_depth', 100),
    (CdrNode, 'input_queue_depth', 100),
], ids=['translator_node', 'cdr_node'])
def test_input_subscriptions_are_as_deep_as_the_parameter(factory, name, default):
    """The shipped default, then -p NAME:=7: every input's depth; sensor-data QoS otherwise."""
    context = Context()
    rclpy.init(args=[], context=context)
    try:
        for arguments, depth in (([], default), (['-p', f'{name}:=7'], 7)):
            node = factory(ros_arguments=['--ros-args', '-p', 'log_to_mcap:=false',
                                          *arguments], context=context)
            try:
                assert node.get_parameter(name).value == depth
                subscriptions = list(node.subscriptions)
                assert subscriptions
                for subscription in subscriptions:
                    qos = subscription.qos_profile
                    assert qos.depth == depth, subscription.topic_name
                    assert qos.reliability == qos_profile_sensor_data.reliability
                    assert qos.history == qos_profile_sensor_data.history
                result = node.set_parameters([Parameter(name, value=depth + 1)])[0]
                assert not result.successful and 'read-only' in result.reason
            finally:
                node.close()
                node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_pending_wrenches_sets_the_solver_mailbox_and_is_read_only():
    """Two wrenches may wait by default, -p pending_wrenches:=1 is latest wins; start only."""
    context = Context()
    rclpy.init(args=[], context=context)
    try:
        for arguments, capacity in (([], 2), (['-p', 'pending_wrenches:=1'], 1)):
            node = TranslatorNode(ros_arguments=['--ros-args', '-p', 'log_to_mcap:=false',
                                                 *arguments], context=context)
            try:
                assert node.get_parameter('pending_wrenches').value == capacity
                assert node._mailbox.capacity == capacity
                result = node.set_parameters([Parameter('pending_wrenches', value=3)])[0]
                assert not result.successful and 'read-only' in result.reason
            finally:
                node.close()
                node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
