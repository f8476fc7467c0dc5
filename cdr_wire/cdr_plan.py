"""
CDR writers and readers compiled from a message type's field layout (its plan).

A plan lists a message type's fields in order, each as (name, kind, argument, default):

* ``PRIMITIVE``: argument (``struct.Struct('<' + code)``, size), e.g. a float64;
* ``STRING``: argument None;
* ``MESSAGE``: argument the nested type's plan (default ``{}``);
* ``PRIMITIVE_ARRAY``: argument ((code, size), length), a fixed-size array;
* ``PRIMITIVE_SEQUENCE``: argument (code, size); ``BYTES_SEQUENCE`` (uint8, octet, char)
  and ``STRING_SEQUENCE``: argument None; ``MESSAGE_SEQUENCE``: argument the element's plan.

``description_plan`` reads a plan from REP-2011 type descriptions (``cdr_wire.msgdefs``
builds them from the shipped .msg texts), so no ROS is needed; a plan read from rclpy's
generated classes (``cdr_translator.ros.serialization``) has the same form. From a plan,
``plan_encoder`` and ``plan_decoder`` give the functions that write a message given as a
nested dict as little-endian XCDR1 with its encapsulation header (what rclpy and ros2 bag
write) and read one back as a dict. Each is the Python source of that type's writer or
reader, compiled once (``_Source``; rosbags' serializers are generated the same way): a
PoseStamped encodes in about 2 us and a WrenchStamped decodes in about 3 us, where
walking the plan field by field took 5-9 and 10-19 us. Fields missing from a dict take
their default; padding bytes are zeros.
"""

import abc
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

#: The kinds of a plan's field (see the module docstring for each one's argument).
PRIMITIVE, STRING, MESSAGE, PRIMITIVE_SEQUENCE, STRING_SEQUENCE = range(5)
MESSAGE_SEQUENCE, PRIMITIVE_ARRAY, BYTES_SEQUENCE = range(5, 8)

#: A message type's fields in order: (name, kind, argument, default).
Plan = List[Tuple[str, int, Any, Any]]

_UINT32 = struct.Struct('<I')
_ZEROS = tuple(bytes(count) for count in range(8))
_DESCRIBED: Dict[str, Plan] = {}


#: REP-2011 FieldType ids of the primitive types (type_description_interfaces/msg/FieldType).
DESCRIPTION_PRIMITIVES = {
    2: 'int8', 3: 'uint8', 4: 'int16', 5: 'uint16', 6: 'int32', 7: 'uint32', 8: 'int64',
    9: 'uint64', 10: 'float', 11: 'double', 13: 'char', 15: 'boolean', 16: 'octet',
}
#: REP-2011 FieldType ids of a nested type and of the (bounded) strings.
_NESTED_ID, _STRING_IDS = 1, (17, 21)
#: REP-2011 offsets of a fixed array, a bounded and an unbounded sequence of a base type.
_ARRAY_ID, _BOUNDED_SEQUENCE_ID, _SEQUENCE_ID = 48, 96, 144


def description_plan(type_name: str, descriptions: Mapping[str, Mapping[str, Any]]) -> Plan:
    """
    Return the field layout of ``type_name`` from REP-2011 individual type descriptions.

    ``descriptions`` maps 'package/msg/Name' to its description (``fields``, each with its
    ``name`` and ``type``: ``type_id``, ``capacity``, ``nested_type_name``), as a ROS 2
    MCAP's type hash is computed from: a layout without the generated rclpy classes, so
    without ROS. Fields take the zero of their type as default.
    """
    found = _DESCRIBED.get(type_name)
    if found is not None:
        return found
    fields: Plan = []
    for field in descriptions[type_name]['fields']:
        name, described = field['name'], field['type']
        type_id = described['type_id']
        base = type_id % _ARRAY_ID
        shape = type_id - base
        element: Any
        if base == _NESTED_ID:
            element = description_plan(described['nested_type_name'], descriptions)
        elif base in _STRING_IDS:
            element = None
        elif base in DESCRIPTION_PRIMITIVES:
            code, size = PRIMITIVES[DESCRIPTION_PRIMITIVES[base]]
            element = (code, size)
        else:
            raise TypeError(f'{type_name}.{name}: unsupported field type id {type_id}')
        if shape == 0:
            fields.append(_scalar_field(name, base, element))
        elif shape == _ARRAY_ID and base in DESCRIPTION_PRIMITIVES:
            zero = False if element[0] == '?' else 0
            fields.append((name, PRIMITIVE_ARRAY, (element, described['capacity']),
                           (zero,) * described['capacity']))
        elif shape in (_BOUNDED_SEQUENCE_ID, _SEQUENCE_ID):
            fields.append(_sequence_field(name, base, element))
        else:
            raise TypeError(f'{type_name}.{name}: arrays of type id {base} are not supported')
    _DESCRIBED[type_name] = fields
    return fields


def _scalar_field(name: str, base: int, element: Any) -> Tuple[str, int, Any, Any]:
    """Return the plan entry of a single (not array) field of REP-2011 base type ``base``."""
    if base == _NESTED_ID:
        return (name, MESSAGE, element, {})
    if base in _STRING_IDS:
        return (name, STRING, None, '')
    code, size = element
    return (name, PRIMITIVE, (struct.Struct('<' + code), size),
            False if code == '?' else 0.0 if code in 'fd' else 0)


def _sequence_field(name: str, base: int, element: Any) -> Tuple[str, int, Any, Any]:
    """Return the plan entry of a sequence of REP-2011 base type ``base``."""
    if base == _NESTED_ID:
        return (name, MESSAGE_SEQUENCE, element, ())
    if base in _STRING_IDS:
        return (name, STRING_SEQUENCE, None, ())
    if DESCRIPTION_PRIMITIVES[base] in ('uint8', 'octet', 'char'):
        return (name, BYTES_SEQUENCE, None, b'')
    return (name, PRIMITIVE_SEQUENCE, element, ())


#: Short strings' CDR bytes (length, UTF-8, NUL), kept once seen: the keys, names and
#: frame ids of a node's messages repeat in every message. Bounded: at most
#: ``_ENCODED_MAX`` strings of at most ``_ENCODED_LONGEST`` characters.
_ENCODED: Dict[str, bytes] = {}
_ENCODED_MAX = 4096
_ENCODED_LONGEST = 64


def _write_string(buffer: bytearray, text: str) -> None:
    """Append a CDR string: uint32 length with the NUL, the UTF-8 bytes, the NUL."""
    remainder = (len(buffer) - 4) % 4
    if remainder:
        buffer += _ZEROS[4 - remainder]
    encoded = _ENCODED.get(text)
    if encoded is None:
        data = text.encode()
        encoded = _UINT32.pack(len(data) + 1) + data + b'\x00'
        if len(text) <= _ENCODED_LONGEST and len(_ENCODED) < _ENCODED_MAX:
            _ENCODED[text] = encoded
    buffer += encoded


def _byte(value: Any) -> Any:
    """Return a byte field's value as struct packs it (rclpy gives 'byte' fields as bytes)."""
    return value[0] if isinstance(value, bytes) else value


def _ends(data: bytes, end: int) -> None:
    """Raise ValueError when ``data`` ends before byte ``end``."""
    if end > len(data):
        raise ValueError(f'CDR data ends at byte {len(data)}, {end} needed')


def _read_primitives(data: bytes, offset: int, code: str, size: int,
                     count: int) -> Tuple[list, int]:
    """Return ``count`` aligned primitives of one struct code, and the offset after them."""
    if not count:
        return [], offset
    offset += -(offset - 4) % size
    _ends(data, offset + size * count)
    return list(struct.unpack_from(f'<{count}{code}', data, offset)), offset + size * count


def _read_count(data: bytes, offset: int) -> Tuple[int, int]:
    """Return a sequence's (or string's) uint32 length, and the offset after it."""
    offset += -(offset - 4) % 4
    _ends(data, offset + 4)
    return _UINT32.unpack_from(data, offset)[0], offset + 4


def _read_string(data: bytes, offset: int) -> Tuple[str, int]:
    """Return a CDR string and the offset after it."""
    length, offset = _read_count(data, offset)
    end = offset + length
    if length == 0 or end > len(data):
        raise ValueError(f'bad CDR string length {length} at byte {offset}')
    return bytes(data[offset:end - 1]).decode(), end


def _read_bytes(data: bytes, offset: int) -> Tuple[bytes, int]:
    """Return a uint8 sequence as bytes, and the offset after it."""
    count, offset = _read_count(data, offset)
    _ends(data, offset + count)
    return bytes(data[offset:offset + count]), offset + count


class _Source(abc.ABC):
    """
    The Python source of one message type's writer or reader, built from its plan.

    Nested messages are flattened and runs of primitives whose alignment is known from the
    first of them (each no larger) become one ``struct`` call, padding bytes included: a
    PoseStamped is two packs and a string, where walking the plan field by field took nine
    aligned packs. Alignment that depends on string lengths is computed when running.
    """

    def __init__(self) -> None:
        """Start an empty body."""
        self.constants: List[Any] = []
        self.lines: List[str] = []
        self.variables = 0
        self._run: List[Tuple[str, str]] = []  # (struct code, value expression or variable)
        self._run_alignment = 0
        self._run_size = 0

    def constant(self, value: Any) -> str:
        """Return the source expression of a value the generated code refers to (in C)."""
        self.constants.append(value)
        return f'C[{len(self.constants) - 1}]'

    def variable(self) -> str:
        """Return the name of a new local variable."""
        self.variables += 1
        return f'v{self.variables}'

    def primitive(self, code: str, size: int, payload: str) -> None:
        """Add a primitive to the pending run (a new run when its alignment is unknown)."""
        if self._run and size > self._run_alignment:
            self.flush()
        if not self._run:
            self._run_alignment, self._run_size = size, 0
        padding = -self._run_size % size
        if padding:
            self._run.append((f'{padding}x', ''))
        self._run.append((code, payload))
        self._run_size += padding + size

    def flush(self) -> None:
        """Emit the pending run of primitives as one aligned struct call."""
        if self._run:
            packer = self.constant(struct.Struct('<' + ''.join(code for code, _ in self._run)))
            self.emit_run(self._run_alignment, self._run_size, packer,
                          [payload for code, payload in self._run if code[-1] != 'x'])
            self._run = []

    @abc.abstractmethod
    def emit_run(self, alignment: int, size: int, packer: str, payloads: List[str]) -> None:
        """Emit the statements of one run (the writer's or the reader's)."""

    def function(self, name: str, arguments: str, result: str) -> Callable:
        """Compile the collected lines into a function returning ``result``."""
        self.flush()
        body = '\n'.join('    ' + line for line in self.lines + [f'return {result}'])
        namespace: Dict[str, Any] = {
            'C': self.constants, 'Z': _ZEROS, 'U': _UINT32, 'S': _write_string, 'B': _byte,
            'E': {}, 'struct': struct, 'ends': _ends, 'primitives': _read_primitives,
            'count': _read_count, 'string': _read_string, 'octets': _read_bytes}
        exec(f'def {name}({arguments}):\n{body}\n', namespace)  # noqa: S102 - our own source
        return namespace[name]


class _WriterSource(_Source):
    """A writer: appends a message given as a dict to a bytearray."""

    def _pad(self, alignment: int, indent: str = '') -> None:
        if alignment > 1:
            self.lines += [f'{indent}r = (len(buffer) - 4) % {alignment}',
                           f'{indent}if r: buffer += Z[{alignment} - r]']

    def emit_run(self, alignment: int, size: int, packer: str, payloads: List[str]) -> None:
        """Pad the buffer to the run's alignment and pack its values."""
        self._pad(alignment)
        self.lines.append(f'buffer += {packer}.pack({", ".join(payloads)})')

    def message(self, fields: Plan, variable: str) -> None:
        """Add the fields of the message dict held in ``variable``."""
        for name, kind, argument, default in fields:
            if kind == MESSAGE:
                nested = self.variable()
                self.lines.append(f'{nested} = {variable}.get({name!r}, E)')
                self.message(argument, nested)
                continue
            value = f'{variable}.get({name!r}, {self.constant(default)})'
            if kind == PRIMITIVE:
                packer, size = argument
                self.primitive(packer.format[1:], size, value if size > 1 else f'B({value})')
            else:
                self.flush()
                self._sized(name, kind, argument, value)

    def _sized(self, name: str, kind: int, argument: Any, value: str) -> None:
        """Emit a string, a sequence or an array (their size is known only when writing)."""
        if kind == STRING:
            self.lines.append(f'S(buffer, {value})')
            return
        self.lines.append(f'items = {value}')
        if kind == PRIMITIVE_ARRAY:
            (code, size), length = argument
            self.lines += [f'if len(items) != {length}: raise ValueError('
                           f'"field {name!r} holds {length} values, got %d" % len(items))']
            self._pad(size)
            self.lines.append(f'buffer += {self.constant(struct.Struct(f"<{length}{code}"))}'
                              '.pack(*items)')
            return
        self._pad(4)
        self.lines.append('buffer += U.pack(len(items))')
        if kind == PRIMITIVE_SEQUENCE:
            code, size = argument
            self.lines.append('if items:')
            self._pad(size, '    ')
            self.lines.append(f'    buffer += struct.pack("<%d{code}" % len(items), *items)')
        elif kind == BYTES_SEQUENCE:
            self.lines.append('buffer += bytes(items)')
        elif kind == STRING_SEQUENCE:
            self.lines.append('for item in items: S(buffer, item)')
        else:  # MESSAGE_SEQUENCE
            self.lines.append(f'for item in items: {self.constant(_writer(argument))}'
                              '(buffer, item)')


class _ReaderSource(_Source):
    """A reader: returns a message read from CDR bytes as a dict, and the offset after it."""

    def emit_run(self, alignment: int, size: int, packer: str, payloads: List[str]) -> None:
        """Align the offset, check the bytes are there and unpack the run's variables."""
        if alignment > 1:
            self.lines.append(f'o += -(o - 4) % {alignment}')
        self.lines += [f'ends(data, o + {size})',
                       f'{", ".join(payloads)}, = {packer}.unpack_from(data, o)',
                       f'o += {size}']

    def message(self, fields: Plan) -> str:
        """Emit the reading of a message's fields; return the source of its dict."""
        items = []
        for name, kind, argument, _ in fields:
            if kind == MESSAGE:
                items.append(f'{name!r}: {self.message(argument)}')
                continue
            value = self.variable()
            items.append(f'{name!r}: {value}')
            if kind == PRIMITIVE:
                packer, size = argument
                self.primitive(packer.format[1:], size, value)
                continue
            self.flush()
            if kind == STRING:
                self.lines.append(f'{value}, o = string(data, o)')
            elif kind == PRIMITIVE_ARRAY:
                (code, size), length = argument
                self.lines.append(f'{value}, o = primitives(data, o, {code!r}, {size}, {length})')
            elif kind == BYTES_SEQUENCE:
                self.lines.append(f'{value}, o = octets(data, o)')
            else:
                self.lines.append('n, o = count(data, o)')
                if kind == PRIMITIVE_SEQUENCE:
                    code, size = argument
                    self.lines.append(f'{value}, o = primitives(data, o, {code!r}, {size}, n)')
                else:
                    read = ('string' if kind == STRING_SEQUENCE
                            else self.constant(_reader(argument)))
                    self.lines += [f'{value} = []',
                                   'for _ in range(n):',
                                   f'    item, o = {read}(data, o)',
                                   f'    {value}.append(item)']
        return '{' + ', '.join(items) + '}'


_WRITERS: Dict[int, Callable[[bytearray, Mapping[str, Any]], None]] = {}
_READERS: Dict[int, Callable[[bytes, int], Tuple[Dict[str, Any], int]]] = {}


def _writer(fields: Plan) -> Callable[[bytearray, Mapping[str, Any]], None]:
    """Return the function that appends a message of this plan to a buffer (built once)."""
    found = _WRITERS.get(id(fields))
    if found is None:
        source = _WriterSource()
        source.message(fields, 'values')
        found = _WRITERS[id(fields)] = source.function('write', 'buffer, values', 'None')
    return found


def _reader(fields: Plan) -> Callable[[bytes, int], Tuple[Dict[str, Any], int]]:
    """Return the function that reads a message of this plan at an offset (built once)."""
    found = _READERS.get(id(fields))
    if found is None:
        source = _ReaderSource()
        result = source.message(fields)
        found = _READERS[id(fields)] = source.function('read', 'data, o', f'{result}, o')
    return found


def plan_encoder(fields: Plan) -> Callable[[Mapping[str, Any]], bytes]:
    """Return the function that gives the CDR bytes of a message of this plan."""
    write = _writer(fields)

    def encode_one(values: Mapping[str, Any]) -> bytes:
        buffer = bytearray(HEADER)
        write(buffer, values)
        return bytes(buffer)
    return encode_one


def plan_decoder(fields: Plan) -> Callable[[bytes], Dict[str, Any]]:
    """Return the function that reads a message of this plan from its CDR bytes."""
    read = _reader(fields)

    def decode_one(data: bytes) -> Dict[str, Any]:
        if len(data) < 4 or data[:2] != HEADER[:2]:
            raise ValueError(f'not little-endian plain CDR: header {bytes(data[:4])!r}')
        return read(data, 4)[0]
    return decode_one
