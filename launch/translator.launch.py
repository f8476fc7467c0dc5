"""
Launch translator_node on a ROS 2 workstation (``launch``, ``launch_ros`` have no wheels).

    ros2 launch cdr_translator translator.launch.py [params_file:=FILE] [namespace:=NS]
        [mcap_path:=FILE] [log_to_mcap:=true|false] [log_dir:=DIR]

The node gets the ``translator_node`` section of ``params_file`` (default: the shipped
config/translator.yaml); ``mcap_path``, ``log_to_mcap`` and ``log_dir`` replace the
file's value only when given (launch_common.py). The pip-wheel venv has no ``ros2 launch``:
run ``.venv/bin/translator_node`` there (docs/howto/run_nodes.md).
"""

import importlib.util
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments; the node is built once they are resolved."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'launch_common.py')
    spec = importlib.util.spec_from_file_location('cdr_translator_launch_common', path)
    common = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(common)  # launch files are no package: load it by path
    shipped = os.path.join(get_package_share_directory('cdr_translator'), 'config',
                           'translator.yaml')
    return common.launch_description('translator_node', shipped, LaunchDescription,
                                     DeclareLaunchArgument, OpaqueFunction, Node)
