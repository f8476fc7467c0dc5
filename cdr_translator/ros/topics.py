"""
The nodes' topics: output message classes, the input QoS, who subscribes, message filling.

A node builds and publishes an output only for a topic someone subscribes to
(``SubscriberCounts``); ``fill_message`` and ``type_name`` turn the plain dicts of
cdr_translator.interface.messages into generated ROS messages and name their types.
"""

from functools import lru_cache
import importlib
import math
import time
from typing import Any, Callable, Dict, FrozenSet, Mapping

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from ..interface import messages

#: The node's output topics (relative names except /diagnostics) and their message classes.
OUTPUTS = {
    messages.END_DISK_POSE_TOPIC: PoseStamped,
    messages.BENDING_ANGLES_TOPIC: JointState,
    messages.COMPLIANCE_EIGENVALUES_TOPIC: Float64MultiArray,
    messages.COMPLIANCE_TOPIC: Float64MultiArray,
    messages.BACKBONES_TOPIC: MarkerArray,
    messages.DIAGNOSTICS_TOPIC: DiagnosticArray,
    messages.SOLVE_STATUS_TOPIC: DiagnosticArray,
}

#: How long a node trusts its count of an output topic's subscribers before counting again
#: (s): a count costs 10-15 us, and a node publishes several outputs per input at 1 kHz.
SUBSCRIBERS_REFRESH_S = 0.05


class SubscriberCounts:
    """
    Which output topics have subscribers, counted again at most every ``refresh_s``.

    A node builds and publishes an output only for a topic someone subscribes to (or when
    it logs it): a subscriber that appears is served from the next count on.
    """

    def __init__(self, publishers: Mapping[str, Any], refresh_s: float = SUBSCRIBERS_REFRESH_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Watch ``publishers`` (topic -> rclpy Publisher)."""
        self._publishers = dict(publishers)
        self._refresh_s = refresh_s
        self._clock = clock
        self._next = -math.inf
        self._subscribed: FrozenSet[str] = frozenset()

    def subscribed(self) -> FrozenSet[str]:
        """Return the topics with at least one subscriber (as last counted)."""
        now = self._clock()
        if now >= self._next:
            self._subscribed = frozenset(
                topic for topic, publisher in self._publishers.items()
                if publisher.get_subscription_count() > 0)
            self._next = now + self._refresh_s
        return self._subscribed


def sensor_qos(depth: int) -> QoSProfile:
    """Return the sensor-data QoS (best effort, volatile, keep last) ``depth`` deep."""
    return QoSProfile(depth=depth, reliability=qos_profile_sensor_data.reliability,
                      durability=qos_profile_sensor_data.durability,
                      history=qos_profile_sensor_data.history)


#: Field name -> rosidl type, per generated message class (filled on first use).
_FIELD_TYPES: Dict[Any, Dict[str, Any]] = {}


def _field_types(message_class: Any) -> Dict[str, Any]:
    """Map field name -> rosidl type of a generated message class."""
    types = _FIELD_TYPES.get(message_class)
    if types is None:
        types = dict(zip(message_class.get_fields_and_field_types(), message_class.SLOT_TYPES))
        _FIELD_TYPES[message_class] = types
    return types


@lru_cache(maxsize=None)
def _message_class(namespaces: tuple, name: str) -> type:
    """Import a generated message class, e.g. (('geometry_msgs', 'msg'), 'Point')."""
    return getattr(importlib.import_module('.'.join(namespaces)), name)


def fill_message(message: Any, values: Mapping[str, Any]) -> Any:
    """
    Set the fields of a generated ROS message from a nested plain dict; return the message.

    Nested messages are dicts, sequences of messages lists of dicts, an int for a ``byte``
    field becomes that one byte, everything else is assigned as it is (the message's own
    setters check the types). KeyError names a field the message does not have.
    """
    types = _field_types(type(message))
    for name, value in values.items():
        if name not in types:
            raise KeyError(f'{type(message).__name__} has no field {name!r}')
        if isinstance(value, Mapping):
            fill_message(getattr(message, name), value)
        elif isinstance(value, (list, tuple)) and value and isinstance(value[0], Mapping):
            element = types[name].value_type
            element_class = _message_class(tuple(element.namespaces), element.name)
            setattr(message, name, [fill_message(element_class(), item) for item in value])
        elif isinstance(value, int) and isinstance(getattr(message, name), bytes):
            setattr(message, name, bytes([value]))  # a .msg 'byte' field, e.g. a level
        else:
            setattr(message, name, value)
    return message


def type_name(message_class: Any) -> str:
    """Return the ROS 2 type name of a generated message class, e.g. 'std_msgs/msg/String'."""
    package = message_class.__module__.split('.')[0]
    return f'{package}/msg/{message_class.__name__}'
