"""
The rosbag2 (Jazzy) metadata of an MCAP file: distribution, offered QoS profiles of a channel.

rosbag2 stores each channel's publishers as the YAML list ``offered_qos_profiles`` with
rmw's infinite durations spelled out; ``ros2 bag play`` re-publishes with that QoS, so a
file written here plays back like one rosbag2 recorded.
"""

from typing import Mapping

import yaml

#: ROS distribution recorded in the file's ``rosbag2`` metadata record.
ROS_DISTRO = 'jazzy'

#: rmw's infinite duration as rosbag2 serializes it.
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}

#: The QoS profiles a topic can be registered with (rclpy's default publisher profile with
#: depth 10, and qos_profile_sensor_data), as rosbag2 serializes an offered profile.
QOS_PROFILES: Mapping[str, dict] = {
    'reliable': {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
                 'durability': 'volatile'},
    'sensor_data': {'history': 'keep_last', 'depth': 5, 'reliability': 'best_effort',
                    'durability': 'volatile'},
}


def offered_qos_profiles_yaml(qos: str) -> str:
    """Return the ``offered_qos_profiles`` channel metadata of one publisher with ``qos``."""
    if qos not in QOS_PROFILES:
        raise ValueError(f'qos must be one of {sorted(QOS_PROFILES)}, got {qos!r}')
    profile = dict(QOS_PROFILES[qos])
    profile.update({'deadline': dict(_INFINITE), 'lifespan': dict(_INFINITE),
                    'liveliness': 'automatic', 'liveliness_lease_duration': dict(_INFINITE),
                    'avoid_ros_namespace_conventions': False})
    return yaml.safe_dump([profile], sort_keys=False, default_flow_style=False).rstrip('\n')
