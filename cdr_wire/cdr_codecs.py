"""
CDR encoders and decoders of the shipped message types, compiled once from their definitions.

``mcap_ros2``'s dynamic encoder walks a message's definition field by field for every
message (0.1-0.4 ms per output message); these are the generated ``struct`` writers and
readers of ``cdr_wire.cdr_plan``, laid out from the REP-2011 type descriptions of
``cdr_wire.msgdefs``, so no ROS is needed. They write the same bytes as ``mcap_ros2``
(padding zeroed) and read its bytes back as nested dicts. ``McapLog`` encodes with them;
``ShippedDecoders`` reads a file's messages with them where the file's schema is the
shipped definition. The /diagnostics array, written once per replayed wrench with some 35
strings, has a writer of its own (``encode_diagnostic_array``) that keeps the CDR of the
key strings it has met: the same bytes in about half the time.
"""

from functools import lru_cache
import struct
from typing import Any, Callable, Dict, Mapping, Tuple

from cdr_wire.cdr_plan import description_plan, HEADER, plan_decoder, plan_encoder
from cdr_wire.msgdefs import MESSAGE_DEFINITIONS, type_description
from cdr_wire.reader import Decoders, RawMessage


def _descriptions(type_name: str) -> Dict[str, Mapping[str, Any]]:
    """Return the individual descriptions of ``type_name`` and its nested types, by name."""
    described = type_description(type_name)
    items = [described['type_description'], *described['referenced_type_descriptions']]
    return {item['type_name']: item for item in items}


#: The DiagnosticArray type, whose encoder is ``encode_diagnostic_array``.
DIAGNOSTIC_ARRAY_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'

#: Strings kept as CDR (length, UTF-8, NUL) at most: a node's keys, status names, hardware ids.
MAX_KEPT_KEYS = 1024

_UINT32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
_LEVEL = struct.Struct('<B')
#: zero bytes that pad a buffer to 4-byte alignment, by ``len(buffer) % 4`` (HEADER is 4)
_PADDING = (b'', b'\x00\x00\x00', b'\x00\x00', b'\x00')
_EMPTY: Mapping[str, Any] = {}
_kept_keys: Dict[str, bytes] = {}


def _cdr_string(text: str) -> bytes:
    """Return the CDR of a string after its alignment: uint32 length with the NUL, bytes, NUL."""
    data = text.encode()
    return _UINT32.pack(len(data) + 1) + data + b'\x00'


def _key_string(text: str) -> bytes:
    """Return ``_cdr_string(text)``, kept for the next message (keys repeat, values do not)."""
    found = _kept_keys.get(text)
    if found is None:
        found = _cdr_string(text)
        if len(_kept_keys) < MAX_KEPT_KEYS:
            _kept_keys[text] = found
    return found


def encode_diagnostic_array(message: Mapping[str, Any]) -> bytes:
    """
    Return the CDR bytes of a diagnostic_msgs/DiagnosticArray given as a nested dict.

    The bytes and the defaults of missing fields are those of the generated writer
    (``plan_encoder``); a value that does not fit its field raises struct.error as there.
    """
    head = message.get('header', _EMPTY)
    stamp = head.get('stamp', _EMPTY)
    buffer = bytearray(HEADER)
    buffer += _STAMP.pack(stamp.get('sec', 0), stamp.get('nanosec', 0))
    buffer += _cdr_string(head.get('frame_id', ''))
    statuses = message.get('status', ())
    buffer += _PADDING[len(buffer) % 4]
    buffer += _UINT32.pack(len(statuses))
    for status in statuses:
        level = status.get('level', 0)   # rclpy gives a 'byte' field as bytes
        buffer += _LEVEL.pack(level[0] if isinstance(level, bytes) else level)
        buffer += _PADDING[len(buffer) % 4]
        buffer += _key_string(status.get('name', ''))
        buffer += _PADDING[len(buffer) % 4]
        buffer += _cdr_string(status.get('message', ''))
        buffer += _PADDING[len(buffer) % 4]
        buffer += _key_string(status.get('hardware_id', ''))
        values = status.get('values', ())
        buffer += _PADDING[len(buffer) % 4]
        buffer += _UINT32.pack(len(values))
        for pair in values:
            buffer += _PADDING[len(buffer) % 4]
            buffer += _key_string(pair.get('key', ''))
            buffer += _PADDING[len(buffer) % 4]
            buffer += _cdr_string(pair.get('value', ''))
    return bytes(buffer)


@lru_cache(maxsize=None)
def encoder(type_name: str) -> Callable[[Mapping[str, Any]], bytes]:
    """Return the CDR encoder of the shipped type ``type_name`` ('package/msg/Name')."""
    if type_name == DIAGNOSTIC_ARRAY_TYPE:
        return encode_diagnostic_array
    return plan_encoder(description_plan(type_name, _descriptions(type_name)))


@lru_cache(maxsize=None)
def decoder(type_name: str) -> Callable[[bytes], Dict[str, Any]]:
    """Return the function that reads a shipped type's CDR bytes as nested dicts."""
    return plan_decoder(description_plan(type_name, _descriptions(type_name)))


class ShippedDecoders(Decoders):
    """
    ``Decoders`` that read a shipped type with its compiled reader (as dicts, 10x faster).

    Only on a CDR channel whose ros2msg schema is the shipped definition text; any other
    message, and one the compiled reader refuses, goes to the file's own decoder, so a
    message that cannot be read fails with the same ValueError as there.
    """

    def __init__(self) -> None:
        """Start with no schema checked."""
        super().__init__()
        self._shipped: Dict[Tuple[int, int], bool] = {}

    def decode(self, message: RawMessage) -> object:
        """Decode ``message``; ValueError saying why it cannot be."""
        schema = message.schema
        if schema is not None and self._is_shipped(message):
            try:
                return decoder(schema.name)(message.data)
            except (ValueError, struct.error):
                pass   # let the file's decoder say why
        return super().decode(message)

    def _is_shipped(self, message: RawMessage) -> bool:
        """Tell whether the message's channel carries a shipped type as shipped (cached)."""
        channel, schema = message.channel, message.schema
        key = (channel.id, channel.schema_id)
        known = self._shipped.get(key)
        if known is None:
            known = self._shipped[key] = bool(
                schema is not None and channel.message_encoding == 'cdr'
                and schema.encoding == 'ros2msg' and schema.name in MESSAGE_DEFINITIONS
                and schema.data == MESSAGE_DEFINITIONS[schema.name].encode())
        return known
