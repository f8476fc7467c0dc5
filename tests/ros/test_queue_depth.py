"""Input queues as deep as their parameter says (read-only, bounded); the solver mailbox."""

from contextlib import contextmanager

from cdr_translator.ros.cdr_robot import CdrNode
from cdr_translator.ros.translator import TranslatorNode
import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data

pytestmark = pytest.mark.usefixtures('ros_env')


@pytest.fixture
def context():
    """Return an initialized rclpy context of the test's own, shut down after it."""
    context = Context()
    rclpy.init(args=[], context=context)
    yield context
    rclpy.try_shutdown(context=context)


@contextmanager
def started(factory, context, *arguments):
    """Start a node without its MCAP log, with the ROS arguments given; close it after."""
    node = factory(ros_arguments=['--ros-args', '-p', 'log_to_mcap:=false', *arguments],
                   context=context)
    try:
        yield node
    finally:
        node.close()
        node.destroy_node()


def refuses_at_run_time(node, name, value):
    """Say whether setting a read-only parameter at run time is refused as read-only."""
    result = node.set_parameters([Parameter(name, value=value)])[0]
    return not result.successful and 'read-only' in result.reason


@pytest.mark.parametrize('factory, name, default', [
    (TranslatorNode, 'wrench_queue_depth', 100),
    (CdrNode, 'input_queue_depth', 100),
], ids=['translator_node', 'cdr_node'])
def test_input_subscriptions_are_as_deep_as_the_parameter(context, factory, name, default):
    """The shipped default, then -p NAME:=7: every input's depth; sensor-data QoS otherwise."""
    for arguments, depth in (([], default), (['-p', f'{name}:=7'], 7)):
        with started(factory, context, *arguments) as node:
            assert node.get_parameter(name).value == depth
            subscriptions = list(node.subscriptions)
            assert subscriptions
            for subscription in subscriptions:
                qos = subscription.qos_profile
                assert qos.depth == depth, subscription.topic_name
                assert qos.reliability == qos_profile_sensor_data.reliability
                assert qos.history == qos_profile_sensor_data.history
            assert refuses_at_run_time(node, name, depth + 1)


def test_pending_wrenches_sets_the_solver_mailbox_and_is_read_only(context):
    """Two wrenches may wait by default, -p pending_wrenches:=1 is latest wins; start only."""
    for arguments, capacity in (([], 2), (['-p', 'pending_wrenches:=1'], 1)):
        with started(TranslatorNode, context, *arguments) as node:
            assert node.get_parameter('pending_wrenches').value == capacity
            assert node._mailbox.capacity == capacity
            assert refuses_at_run_time(node, 'pending_wrenches', 3)


def test_diagnostics_period_sets_the_timer_and_is_read_only(context):
    """-p diagnostics_period_s:=0.25 is the /diagnostics timer's period; start only."""
    for arguments, period in (([], 1.0), (['-p', 'diagnostics_period_s:=0.25'], 0.25)):
        with started(TranslatorNode, context, *arguments) as node:
            assert node.get_parameter('diagnostics_period_s').value == period
            assert node._diagnostics_timer.timer_period_ns == int(period * 1e9)
            assert refuses_at_run_time(node, 'diagnostics_period_s', 2.0)
