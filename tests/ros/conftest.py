"""Fixtures of the node tests."""

import os

from cdr_translator.ros.client import isolated_ros_env
from cdr_translator.ros.translator import TranslatorNode
import pytest
import rclpy
from rclpy.context import Context


@pytest.fixture(scope='module')
def ros_env():
    """Give the requesting test module its own DDS domain, limited to this machine."""
    env = isolated_ros_env()
    keys = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')
    saved = {key: os.environ.get(key) for key in keys}
    os.environ.update({key: env[key] for key in keys})
    yield env
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture
def node(ros_env):
    """Run a translator_node in this process (own context, no log); close it afterwards."""
    context = Context()
    rclpy.init(args=[], context=context)
    made = TranslatorNode(context=context,
                          ros_arguments=['--ros-args', '-p', 'log_to_mcap:=false'])
    try:
        yield made
    finally:
        made.close()
        made.destroy_node()
        rclpy.try_shutdown(context=context)
