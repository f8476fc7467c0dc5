"""
CDR encoders and decoders of the shipped message types, compiled once from their definitions.

``mcap_ros2``'s dynamic encoder walks a message's definition field by field for every
message (0.1-0.4 ms per output message); these are the generated ``struct`` writers and
readers of ``cdr_translator.ros.serialization``, laid out from the REP-2011 type
descriptions of ``msg_tools.msgdefs`` instead of the rclpy classes, so no ROS is needed.
They write the same bytes as ``mcap_ros2`` (padding zeroed) and read its bytes back as
nested dicts.
"""

from functools import lru_cache
from typing import Any, Callable, Dict, Mapping

from cdr_translator.ros.serialization import description_plan, plan_decoder, plan_encoder
from msg_tools.msgdefs import type_description


def _descriptions(type_name: str) -> Dict[str, Mapping[str, Any]]:
    """Return the individual descriptions of ``type_name`` and its nested types, by name."""
    described = type_description(type_name)
    return {item['type_name']: item for item in (described['type_description'],
                                                  *described['referenced_type_descriptions'])}


@lru_cache(maxsize=None)
def encoder(type_name: str) -> Callable[[Mapping[str, Any]], bytes]:
    """Return the CDR encoder of the shipped type ``type_name`` ('package/msg/Name')."""
    return plan_encoder(description_plan(type_name, _descriptions(type_name)))


@lru_cache(maxsize=None)
def decoder(type_name: str) -> Callable[[bytes], Dict[str, Any]]:
    """Return the CDR decoder (to nested dicts) of the shipped type ``type_name``."""
    return plan_decoder(description_plan(type_name, _descriptions(type_name)))
