"""
CDR bytes straight from (and to) the plain message dicts of cdr_translator.interface.messages.

translator_node publishes and logs serialized messages. Filling an rclpy message from a
dict and serializing it (``fill_message`` + ``serialize_message``) took 0.1-0.3 ms per
message, a third of the node's time per wrench beside the solve; ``encode`` writes the
same message's CDR (little-endian XCDR1 with its encapsulation header, what rclpy and
ros2 bag write) from the dict, and ``decode`` reads one back as a dict (rclpy's
``deserialize_message`` took 0.15-0.3 ms). The layout of each message type is read once
from its generated rclpy class (``SLOT_TYPES``), so any message type works, as a plan of
``cdr_wire.cdr_plan``, which compiles its writer and reader. Fields missing from a dict
take their default (the .msg file's), as ``fill_message`` leaves them. Only padding bytes
can differ from rclpy's output (rclpy leaves them uninitialized and may add a few at the
end): decoded, the messages are equal.
"""

import importlib
import struct
from typing import Any, Callable, Dict, Mapping

from cdr_wire.cdr_plan import (BYTES_SEQUENCE, MESSAGE, MESSAGE_SEQUENCE, Plan, plan_decoder,
                               plan_encoder, PRIMITIVE, PRIMITIVE_ARRAY, PRIMITIVE_SEQUENCE,
                               PRIMITIVES, STRING, STRING_SEQUENCE)

_PLANS: Dict[type, Plan] = {}


def _message_class(namespaced: Any) -> type:
    """Return the generated class of a rosidl NamespacedType (e.g. geometry_msgs/Point)."""
    module = importlib.import_module('.'.join(namespaced.namespaces))
    return getattr(module, namespaced.name)


def plan(message_class: type) -> Plan:
    """Return the field layout of a generated message class (built once per class)."""
    found = _PLANS.get(message_class)
    if found is not None:
        return found
    fields: Plan = []
    slot_types = message_class.SLOT_TYPES  # type: ignore[attr-defined]
    names = message_class.get_fields_and_field_types()  # type: ignore[attr-defined]
    defaults = message_class()  # the .msg file's default values
    for name, slot in zip(names, slot_types):
        kind = type(slot).__name__
        default = getattr(defaults, name)
        if kind == 'BasicType':
            code, size = PRIMITIVES[slot.typename]
            fields.append((name, PRIMITIVE, (struct.Struct('<' + code), size), default))
        elif kind in ('UnboundedString', 'BoundedString'):
            fields.append((name, STRING, None, default))
        elif kind == 'NamespacedType':
            fields.append((name, MESSAGE, plan(_message_class(slot)), {}))
        elif kind in ('UnboundedSequence', 'BoundedSequence', 'Array'):
            element = slot.value_type
            element_kind = type(element).__name__
            if kind == 'Array':
                if element_kind != 'BasicType':
                    raise TypeError(f'{message_class.__name__}.{name}: arrays of '
                                    f'{element_kind} are not supported')
                fields.append((name, PRIMITIVE_ARRAY,
                               (PRIMITIVES[element.typename], slot.size), tuple(default)))
            elif element_kind == 'BasicType' and element.typename in ('uint8', 'octet', 'char'):
                fields.append((name, BYTES_SEQUENCE, None, bytes(default)))
            elif element_kind == 'BasicType':
                fields.append((name, PRIMITIVE_SEQUENCE, PRIMITIVES[element.typename],
                               tuple(default)))
            elif element_kind in ('UnboundedString', 'BoundedString'):
                fields.append((name, STRING_SEQUENCE, None, tuple(default)))
            else:
                fields.append((name, MESSAGE_SEQUENCE, plan(_message_class(element)), ()))
        else:
            raise TypeError(f'{message_class.__name__}.{name}: unsupported type {kind}')
    _PLANS[message_class] = fields
    return fields


def encoder(message_class: type) -> Callable[[Mapping[str, Any]], bytes]:
    """Return the function that gives the CDR bytes of a ``message_class`` message dict."""
    return plan_encoder(plan(message_class))


def encode(message_class: type, values: Mapping[str, Any]) -> bytes:
    """Return the CDR bytes of a ``message_class`` message given as a nested dict."""
    return encoder(message_class)(values)


def decoder(message_class: type) -> Callable[[bytes], Dict[str, Any]]:
    """Return ``decode`` bound to one message class (its layout read and its reader built now)."""
    return plan_decoder(plan(message_class))


def decode(message_class: type, data: bytes) -> Dict[str, Any]:
    """Return the nested dict of a ``message_class`` message from its CDR bytes."""
    return decoder(message_class)(data)
