"""
ROS 2 message definitions shipped with cdr_wire, without any ROS package installed.

The ``.msg`` texts of every type the translator reads or writes (and their dependencies) are
shipped verbatim in ``cdr_wire/msg/<package>/<Name>.msg`` (ROS 2 Jazzy, common_interfaces
5.3). From them this module builds

* the complete ``ros2msg`` definition text of a type the way rosbag2 writes it into an MCAP
  schema: the type's own text, then for every dependency, depth first and in sorted order at
  each level, a line of 80 ``=``, a ``MSG: package/Name`` line and that type's text;
* the type description of REP-2011 and its ``RIHS01_<sha256>`` hash, which rosbag2 stores as
  the channel metadata ``topic_type_hash`` and DDS uses to match types.
"""

import hashlib
import json
from pathlib import Path
import re
from types import MappingProxyType
from typing import Dict, List, Mapping, NamedTuple, Optional, Tuple

#: Where the shipped .msg texts live: msg/<package>/<Name>.msg beside this module.
MSG_DIR = Path(__file__).resolve().parent / 'msg'

#: The line rosbag2 puts between the definitions of a type and of each dependency.
SEPARATOR = '=' * 80

#: Field type ids of type_description_interfaces/msg/FieldType for .msg primitive types
#: (a .msg ``char`` is an IDL ``uint8``, a .msg ``byte`` an IDL ``octet``).
_PRIMITIVE_TYPE_IDS = {
    'int8': 2, 'uint8': 3, 'char': 3, 'int16': 4, 'uint16': 5, 'int32': 6, 'uint32': 7,
    'int64': 8, 'uint64': 9, 'float32': 10, 'float64': 11, 'bool': 15, 'byte': 16,
    'string': 17, 'wstring': 18,
}
_NESTED_TYPE_ID = 1
_BOUNDED_STRING_TYPE_IDS = {'string': 21, 'wstring': 22}
#: Offsets added to a scalar type id for a fixed array, a bounded and an unbounded sequence.
_ARRAY_OFFSET, _BOUNDED_SEQUENCE_OFFSET, _UNBOUNDED_SEQUENCE_OFFSET = 48, 96, 144

_TYPE_NAME_RE = re.compile(r'^([A-Za-z][A-Za-z0-9_]*)/msg/([A-Za-z][A-Za-z0-9_]*)$')
_FIELD_TYPE_RE = re.compile(
    r'^(?P<base>[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*)?)'
    r'(?:<=(?P<string_bound>\d+))?'
    r'(?:\[(?P<array>(?:<=)?\d*)\])?$')
_CONSTANT_RE = re.compile(r'^\S+\s+[A-Za-z][A-Za-z0-9_]*\s*=')


class Field(NamedTuple):
    """One field of a .msg definition, as REP-2011 describes it."""

    name: str
    type_id: int
    capacity: int
    string_capacity: int
    nested_type_name: str  # 'pkg/msg/Name' or ''
    dependency: str  # 'pkg/Name' as rosbag2 names it in a MSG: line, or ''


def _split_type_name(type_name: str) -> Tuple[str, str]:
    """Return (package, Name) of 'package/msg/Name'; ValueError naming any other form."""
    match = _TYPE_NAME_RE.match(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise ValueError(
            f'message type name must look like "package/msg/Name", got {type_name!r}')
    return match.group(1), match.group(2)


def _msg_text(type_name: str) -> str:
    """Return the shipped .msg text of 'package/msg/Name'."""
    package, name = _split_type_name(type_name)
    path = MSG_DIR / package / f'{name}.msg'
    if not path.is_file():
        raise ValueError(f'no message definition for {type_name!r} is shipped in {MSG_DIR}')
    return path.read_text(encoding='utf-8')


def _strip_comment(line: str) -> str:
    """Remove a trailing ``#`` comment, leaving ``#`` inside quoted string values alone."""
    quote: Optional[str] = None
    for index, char in enumerate(line):
        if quote:
            if char == quote:
                quote = None
        elif char in '"\'':
            quote = char
        elif char == '#':
            return line[:index]
    return line


def _parse_field(line: str, package: str) -> Field:
    """Parse one field line (``type name [default]``) of a .msg text of ``package``."""
    type_token, name = line.split()[:2]
    match = _FIELD_TYPE_RE.match(type_token)
    if match is None:
        raise ValueError(f'cannot parse the field type {type_token!r} in {line!r}')
    base, string_bound, array = match.group('base', 'string_bound', 'array')
    string_capacity = int(string_bound) if string_bound else 0
    nested_type_name = dependency = ''
    if base in _PRIMITIVE_TYPE_IDS:
        type_id = (_BOUNDED_STRING_TYPE_IDS[base] if string_bound
                   else _PRIMITIVE_TYPE_IDS[base])
    else:
        dep_package, _, dep_name = base.rpartition('/')
        dependency = f'{dep_package or package}/{dep_name}'
        nested_type_name = f'{dep_package or package}/msg/{dep_name}'
        type_id = _NESTED_TYPE_ID
    capacity = 0
    if array is not None:
        if array == '':
            type_id += _UNBOUNDED_SEQUENCE_OFFSET
        elif array.startswith('<='):
            type_id += _BOUNDED_SEQUENCE_OFFSET
            capacity = int(array[2:])
        else:
            type_id += _ARRAY_OFFSET
            capacity = int(array)
    return Field(name, type_id, capacity, string_capacity, nested_type_name, dependency)


def fields(type_name: str) -> List[Field]:
    """Return the fields of a shipped type in definition order (constants are not fields)."""
    package, _ = _split_type_name(type_name)
    result = []
    for raw_line in _msg_text(type_name).splitlines():
        line = _strip_comment(raw_line).strip()
        if line and not _CONSTANT_RE.match(line):
            result.append(_parse_field(line, package))
    if not result:
        # An empty message gets this member in its IDL, hence in its type description.
        result.append(Field('structure_needs_at_least_one_member',
                            _PRIMITIVE_TYPE_IDS['uint8'], 0, 0, '', ''))
    return result


def message_definition(type_name: str) -> str:
    """
    Return the complete ros2msg definition of ``type_name`` ('package/msg/Name').

    The text is what rosbag2 stores as the schema of a ROS 2 MCAP channel: the type's .msg
    text, then each dependency once (depth first, dependencies of one type in sorted order)
    after a separator line and a ``MSG: package/Name`` line.
    """
    _split_type_name(type_name)
    seen = set()

    def append(current: str) -> str:
        text = _msg_text(current)
        for dependency in sorted({field.dependency for field in fields(current)} - {''}):
            if dependency not in seen:
                seen.add(dependency)
                package, _, name = dependency.partition('/')
                text += f'\n{SEPARATOR}\nMSG: {dependency}\n' + append(f'{package}/msg/{name}')
        return text

    return append(type_name)


def _individual_description(type_name: str) -> dict:
    """Return the REP-2011 individual type description (without default values)."""
    return {
        'type_name': type_name,
        'fields': [{'name': field.name,
                    'type': {'type_id': field.type_id, 'capacity': field.capacity,
                             'string_capacity': field.string_capacity,
                             'nested_type_name': field.nested_type_name}}
                   for field in fields(type_name)],
    }


def type_description(type_name: str) -> dict:
    """
    Return the REP-2011 type description of ``type_name`` in the form that is hashed.

    ``{'type_description': ..., 'referenced_type_descriptions': [...]}``, the referenced
    types being every nested type, transitively, once each, sorted by name. Field default
    values are left out, as they are not part of the hash.
    """
    referenced: Dict[str, dict] = {}
    pending = [type_name]
    while pending:
        for field in fields(pending.pop()):
            nested = field.nested_type_name
            if nested and nested not in referenced:
                referenced[nested] = _individual_description(nested)
                pending.append(nested)
    return {
        'type_description': _individual_description(type_name),
        'referenced_type_descriptions': [referenced[name] for name in sorted(referenced)],
    }


def type_hash(type_name: str) -> str:
    """
    Return the RIHS01 type hash of ``type_name`` ('package/msg/Name'), REP-2011.

    SHA-256 of the compact JSON of ``type_description(type_name)`` (separators ', ' and
    ': ', keys in the order of the description message), as 'RIHS01_' + 64 hex digits.
    """
    serialized = json.dumps(type_description(type_name), ensure_ascii=True, allow_nan=False,
                            separators=(', ', ': '), sort_keys=False)
    return 'RIHS01_' + hashlib.sha256(serialized.encode('utf-8')).hexdigest()


def shipped_types() -> Tuple[str, ...]:
    """Return every type name ('package/msg/Name') whose .msg text is shipped, sorted."""
    return tuple(sorted(f'{path.parent.name}/msg/{path.stem}'
                        for path in MSG_DIR.glob('*/*.msg')))


#: Complete ros2msg definition text of every shipped type, keyed by 'package/msg/Name'.
MESSAGE_DEFINITIONS: Mapping[str, str] = MappingProxyType(
    {name: message_definition(name) for name in shipped_types()})

#: RIHS01 hash of every shipped type, keyed by 'package/msg/Name'.
TYPE_HASHES: Mapping[str, str] = MappingProxyType(
    {name: type_hash(name) for name in shipped_types()})
