"""
Launch translator_node with the shipped parameter file (ROS 2 workstations only).

    ros2 launch cdr_translator translator.launch.py [params_file:=FILE] [mcap_path:=FILE]
        [namespace:=NS]

``launch`` and ``launch_ros`` come with a ROS 2 desktop install; the pip-wheel venv of this
repository does not have them (run ``.venv/bin/translator_node`` there instead).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments and the node."""
    shipped = os.path.join(get_package_share_directory('cdr_translator'), 'config',
                           'translator.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=shipped,
                              description='ROS 2 params file with a translator_node section'),
        DeclareLaunchArgument('mcap_path', default_value='',
                              description='MCAP log file; empty: auto-named under log_dir'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the node and its relative topics'),
        Node(package='cdr_translator', executable='translator_node', name='translator_node',
             namespace=LaunchConfiguration('namespace'), output='screen', emulate_tty=True,
             parameters=[LaunchConfiguration('params_file'),
                         {'mcap_path': ParameterValue(LaunchConfiguration('mcap_path'),
                                                      value_type=str)}]),
    ])
