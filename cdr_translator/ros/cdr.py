"""
CDR bytes straight from (and to) the plain message dicts of cdr_translator.interface.messages.

translator_node publishes and logs serialized messages. Filling an rclpy message from a
dict and serializing it (``fill_message`` + ``serialize_message``) took 0.1-0.3 ms per
message, a third of the node's time per wrench beside the solve; ``encode`` writes the
same message's CDR (little-endian XCDR1 with its encapsulation header, what rclpy and
ros2 bag write) from the dict in 5-40 us, and ``decode`` reads one back as a dict (a
WrenchStamped in about 10 us, where ``deserialize_message`` took 0.15-0.3 ms). The layout
of each message type is read once from its generated rclpy class (``SLOT_TYPES``), so any
message type works; fields missing from a dict take their default (the .msg file's), as
``fill_message`` leaves them. Only padding bytes can differ from rclpy's output (rclpy
leaves them uninitialized and may add a few at the end): decoded, the messages are equal.
"""

import importlib
import struct
from typing import Any, Callable, Dict, List, Mapping, Tuple

#: rosidl basic type name -> (struct format character, size = alignment in bytes).
PRIMITIVES = {
    'double': ('d', 8), 'float': ('f', 4), 'int64': ('q', 8), 'uint64': ('Q', 8),
    'int32': ('i', 4), 'uint32': ('I', 4), 'int16': ('h', 2), 'uint16': ('H', 2),
    'int8': ('b', 1), 'uint8': ('B', 1), 'octet': ('B', 1), 'char': ('B', 1),
    'boolean': ('?', 1),
}

#: The encapsulation header of little-endian plain CDR.
HEADER = b'\x00\x01\x00\x00'

_UINT32 = struct.Struct('<I')
_ZEROS = tuple(bytes(count) for count in range(8))

# A field's plan: (name, kind, argument, default); kinds below.
_PRIMITIVE, _STRING, _MESSAGE, _PRIMITIVE_SEQUENCE, _STRING_SEQUENCE = range(5)
_MESSAGE_SEQUENCE, _PRIMITIVE_ARRAY, _BYTES_SEQUENCE = range(5, 8)

Plan = List[Tuple[str, int, Any, Any]]
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
            fields.append((name, _PRIMITIVE, (struct.Struct('<' + code), size), default))
        elif kind in ('UnboundedString', 'BoundedString'):
            fields.append((name, _STRING, None, default))
        elif kind == 'NamespacedType':
            fields.append((name, _MESSAGE, plan(_message_class(slot)), {}))
        elif kind in ('UnboundedSequence', 'BoundedSequence', 'Array'):
            element = slot.value_type
            element_kind = type(element).__name__
            if kind == 'Array':
                if element_kind != 'BasicType':
                    raise TypeError(f'{message_class.__name__}.{name}: arrays of '
                                    f'{element_kind} are not supported')
                fields.append((name, _PRIMITIVE_ARRAY,
                               (PRIMITIVES[element.typename], slot.size), tuple(default)))
            elif element_kind == 'BasicType' and element.typename in ('uint8', 'octet', 'char'):
                fields.append((name, _BYTES_SEQUENCE, None, bytes(default)))
            elif element_kind == 'BasicType':
                fields.append((name, _PRIMITIVE_SEQUENCE, PRIMITIVES[element.typename],
                               tuple(default)))
            elif element_kind in ('UnboundedString', 'BoundedString'):
                fields.append((name, _STRING_SEQUENCE, None, tuple(default)))
            else:
                fields.append((name, _MESSAGE_SEQUENCE, plan(_message_class(element)), ()))
        else:
            raise TypeError(f'{message_class.__name__}.{name}: unsupported type {kind}')
    _PLANS[message_class] = fields
    return fields


def _align(buffer: bytearray, size: int) -> None:
    """Pad ``buffer`` so that its body (after the 4-byte header) is ``size``-aligned."""
    remainder = (len(buffer) - 4) % size
    if remainder:
        buffer += _ZEROS[size - remainder]


def _write_string(buffer: bytearray, text: str) -> None:
    """Append a CDR string: uint32 length with the NUL, the UTF-8 bytes, the NUL."""
    remainder = (len(buffer) - 4) % 4
    if remainder:
        buffer += _ZEROS[4 - remainder]
    data = text.encode()
    buffer += _UINT32.pack(len(data) + 1)
    buffer += data
    buffer += b'\x00'


def _write(buffer: bytearray, fields: Plan, values: Mapping[str, Any]) -> None:
    """Append the fields of one message (a dict; missing fields take their default)."""
    for name, kind, argument, default in fields:
        value = values.get(name, default)
        if kind == _PRIMITIVE:
            packer, size = argument
            if size > 1:
                _align(buffer, size)
            buffer += packer.pack(value[0] if isinstance(value, bytes) else value)
        elif kind == _STRING:
            _write_string(buffer, value)
        elif kind == _MESSAGE:
            _write(buffer, argument, value)
        elif kind == _PRIMITIVE_SEQUENCE:
            code, size = argument
            _align(buffer, 4)
            buffer += _UINT32.pack(len(value))
            if len(value):
                _align(buffer, size)
                buffer += struct.pack(f'<{len(value)}{code}', *value)
        elif kind == _BYTES_SEQUENCE:
            _align(buffer, 4)
            buffer += _UINT32.pack(len(value))
            buffer += bytes(value)
        elif kind == _STRING_SEQUENCE:
            _align(buffer, 4)
            buffer += _UINT32.pack(len(value))
            for text in value:
                _write_string(buffer, text)
        elif kind == _MESSAGE_SEQUENCE:
            _align(buffer, 4)
            buffer += _UINT32.pack(len(value))
            for element in value:
                _write(buffer, argument, element)
        else:  # _PRIMITIVE_ARRAY
            (code, size), length = argument
            if len(value) != length:
                raise ValueError(f'field {name!r} holds {length} values, got {len(value)}')
            _align(buffer, size)
            buffer += struct.pack(f'<{length}{code}', *value)


def encode(message_class: type, values: Mapping[str, Any]) -> bytes:
    """Return the CDR bytes of a ``message_class`` message given as a nested dict."""
    buffer = bytearray(HEADER)
    _write(buffer, plan(message_class), values)
    return bytes(buffer)


def encoder(message_class: type) -> Callable[[Mapping[str, Any]], bytes]:
    """Return ``encode`` bound to one message class."""
    fields = plan(message_class)

    def encode_one(values: Mapping[str, Any]) -> bytes:
        buffer = bytearray(HEADER)
        _write(buffer, fields, values)
        return bytes(buffer)
    return encode_one


class _Reader:
    """A position in CDR bytes (alignment relative to the body, after the header)."""

    def __init__(self, data: bytes) -> None:
        """Start reading after the encapsulation header (ValueError unless little-endian)."""
        if len(data) < 4 or data[:2] != HEADER[:2]:
            raise ValueError(f'not little-endian plain CDR: header {bytes(data[:4])!r}')
        self.data = data
        self.offset = 4

    def take(self, code: str, size: int, count: int = 1) -> tuple:
        """Read ``count`` aligned primitives of one struct code (ValueError past the end)."""
        self.offset += (-(self.offset - 4)) % size
        end = self.offset + size * count
        if end > len(self.data):
            raise ValueError(f'CDR data ends at byte {len(self.data)}, {end} needed')
        found = struct.unpack_from(f'<{count}{code}', self.data, self.offset)
        self.offset = end
        return found

    def string(self) -> str:
        """Read a CDR string."""
        (length,) = self.take('I', 4)
        end = self.offset + length
        if length == 0 or end > len(self.data):
            raise ValueError(f'bad CDR string length {length} at byte {self.offset}')
        text = bytes(self.data[self.offset:end - 1]).decode()
        self.offset = end
        return text


def _read(reader: _Reader, fields: Plan) -> Dict[str, Any]:
    """Read one message's fields into a dict."""
    values: Dict[str, Any] = {}
    for name, kind, argument, _ in fields:
        if kind == _PRIMITIVE:
            packer, size = argument
            values[name] = reader.take(packer.format[1:], size)[0]
        elif kind == _STRING:
            values[name] = reader.string()
        elif kind == _MESSAGE:
            values[name] = _read(reader, argument)
        elif kind == _PRIMITIVE_ARRAY:
            (code, size), length = argument
            values[name] = list(reader.take(code, size, length))
        else:
            (count,) = reader.take('I', 4)
            if kind == _PRIMITIVE_SEQUENCE:
                code, size = argument
                values[name] = list(reader.take(code, size, count)) if count else []
            elif kind == _BYTES_SEQUENCE:
                values[name] = bytes(reader.take('B', 1, count))
            elif kind == _STRING_SEQUENCE:
                values[name] = [reader.string() for _ in range(count)]
            else:
                values[name] = [_read(reader, argument) for _ in range(count)]
    return values


def decode(message_class: type, data: bytes) -> Dict[str, Any]:
    """Return the nested dict of a ``message_class`` message from its CDR bytes."""
    return _read(_Reader(data), plan(message_class))
