"""
ROS 2 params files read the way rcl reads them, for the library, the CLI and replay alike.

A params file maps node-name patterns to ``ros__parameters`` mappings. A pattern applies to
a node when it matches the node's fully qualified name (``/namespace/name``): a pattern
without a leading slash is taken from the root (``translator_node`` is
``/translator_node``), ``**`` stands for any number of name segments (``/**`` applies to
every node) and ``*`` for one segment. Every section that applies is used, in file order,
later values winning, as rcl_yaml_param_parser does.

On top of rcl, three rules the nodes and the offline tools share (so a file gives the same
outcome everywhere):

* the shipped config/translator.yaml gives every key its default and its ROS type; a file
  overrides it key by key (a partial file is fine);
* a key the shipped file does not declare for that node is an error naming it (ROS would
  ignore it silently);
* a value must have the declared ROS type: an integer where a double is declared is refused,
  as rclpy refuses it, with a message saying how to write it (``100.0``, not ``100``).

A file none of whose sections applies to the node, while one names the node in another
namespace, is an error too: that is the usual mistake of a namespaced launch.
"""

from dataclasses import dataclass
import difflib
from fnmatch import fnmatchcase
import os
from pathlib import Path
import stat
from typing import Any, Dict, FrozenSet, Iterable, List, Mapping, Optional, Tuple, Union

import yaml

from ..errors import ParameterError

__all__ = ['applicable_sections', 'check_known', 'check_nesting', 'check_value_type',
           'CommandLineValues', 'declared_type', 'every_key', 'fully_qualified_name', 'Layer',
           'layered_values', 'read_document', 'section_applies', 'section_values']

PathLike = Union[str, Path]


@dataclass(frozen=True)
class CommandLineValues:
    """
    ``-p name:=value`` values of a node's command line, as one layer among its params files.

    rcl applies ``--params-file`` and ``-p`` in the order they appear, the last value of a
    key winning, so a ``-p`` stands in its place among the files.
    """

    values: Mapping[str, Any]


#: A params file, a node's command-line values in their place, or None (no file).
Layer = Union[None, PathLike, CommandLineValues]

#: The key under a node-name pattern that holds its parameters.
PARAMETERS_KEY = 'ros__parameters'
#: Largest params file read (bytes): the shipped one is a few kB, and a device or a huge
#: file given by mistake must not be read without bound.
MAX_PARAMS_BYTES = 1 << 20
#: Deepest nesting of mappings and lists read. The shipped file nests 4 deep (the file's
#: mapping, a node's, its ros__parameters, a list); YAML's composer (and rcl's parser)
#: recurse once per level, so a file nested thousands deep would end in a RecursionError
#: (a traceback) instead of a message.
MAX_PARAMS_DEPTH = 32


def fully_qualified_name(node_name: str, namespace: str = '/') -> str:
    """Return ``/namespace/node_name`` (the root namespace is ``/``)."""
    namespace = '/' + namespace.strip('/')
    return f'{namespace.rstrip("/")}/{node_name}'


def section_applies(pattern: str, fqn: str) -> bool:
    """Tell whether a params-file node pattern (``/**``, ``name``, ``/ns/*``) matches ``fqn``."""
    wanted = [part for part in ('/' + pattern.lstrip('/')).split('/') if part]
    segments = [part for part in fqn.split('/') if part]
    return _match(wanted, segments)


def _match(pattern: List[str], segments: List[str]) -> bool:
    if not pattern:
        return not segments
    head, rest = pattern[0], pattern[1:]
    if head == '**':
        return any(_match(rest, segments[skip:]) for skip in range(len(segments) + 1))
    return bool(segments) and fnmatchcase(segments[0], head) and _match(rest, segments[1:])


def _bounded_text(path: Path) -> str:
    """Return the text of ``path``; ParameterError unless a regular file of bounded size."""
    # O_NONBLOCK: a FIFO given by mistake must not block the open.
    descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    with open(descriptor, 'rb') as stream:
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            raise ParameterError(f'cannot read parameter file {path}: not a regular file')
        data = stream.read(MAX_PARAMS_BYTES + 1)
    if len(data) > MAX_PARAMS_BYTES:
        raise ParameterError(f'cannot read parameter file {path}: larger than '
                             f'{MAX_PARAMS_BYTES} bytes, so not a params file')
    return data.decode('utf-8')


def check_nesting(text: str, where: Union[str, Path]) -> None:
    """
    Raise ParameterError if the YAML ``text`` nests beyond MAX_PARAMS_DEPTH (``where``: whose).

    YAMLError when ``text`` is not YAML at all (as ``yaml.safe_load`` would raise).
    """
    depth = 0
    # The event stream is produced by a state machine without recursion, unlike composing.
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_PARAMS_DEPTH:
                line = f' (line {event.start_mark.line + 1})' if event.start_mark else ''
                raise ParameterError(f'{where} nests mappings and lists more than '
                                     f'{MAX_PARAMS_DEPTH} deep{line}, so it is not a params file')
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1


def read_document(path: PathLike) -> Mapping[str, Any]:
    """Load a params file; ParameterError if it cannot be read or is not one."""
    path = Path(path)
    try:
        text = _bounded_text(path)
        check_nesting(text, path)
        document = yaml.safe_load(text)
    except OSError as error:
        raise ParameterError(f'cannot read parameter file {path}: {error}') from error
    except UnicodeDecodeError as error:
        raise ParameterError(f'{path} is not a text file: {error}') from error
    except yaml.YAMLError as error:
        raise ParameterError(f'{path} is not valid YAML: {error}') from error
    if not isinstance(document, Mapping) or not document:
        raise ParameterError(f'{path} is not a ROS 2 params file (node name: '
                             f'{PARAMETERS_KEY}: {{...}})')
    for pattern, section in document.items():
        if not isinstance(section, Mapping) or not isinstance(
                section.get(PARAMETERS_KEY), Mapping):
            raise ParameterError(f'{path}: {pattern}: has no {PARAMETERS_KEY}: mapping')
    return document


def applicable_sections(path: PathLike, node_name: str,
                        namespace: str = '/') -> List[Tuple[str, Dict[str, Any]]]:
    """
    Return (pattern, ros__parameters) of every section of ``path`` that applies, in order.

    ParameterError when the file cannot be read, or when no section applies and one names
    the node under another namespace. A file with sections for other nodes only gives [].
    """
    document = read_document(path)
    fqn = fully_qualified_name(node_name, namespace)
    sections = [(str(pattern), dict(section[PARAMETERS_KEY]))
                for pattern, section in document.items()
                if section_applies(str(pattern), fqn)]
    if not sections:
        misplaced = [str(pattern) for pattern in document
                     if str(pattern).rstrip('/').split('/')[-1] == node_name]
        if misplaced:
            raise ParameterError(
                f'{path}: section {misplaced[0]!r} does not apply to {fqn} (ROS 2 matches '
                f'fully qualified names): key it {fqn!r} or "/**/{node_name}" or "/**"')
    return sections


def section_values(path: PathLike, node_name: str, namespace: str = '/') -> Dict[str, Any]:
    """Merge the ``ros__parameters`` of every section of ``path`` that applies to the node."""
    values: Dict[str, Any] = {}
    for _, section in applicable_sections(path, node_name, namespace):
        values.update(section)
    return values


def every_key(path: PathLike) -> FrozenSet[str]:
    """Return the keys of every section of ``path`` (what some node of the package takes)."""
    return frozenset(key for section in read_document(path).values()
                     for key in section[PARAMETERS_KEY])


def declared_type(value: Any) -> str:
    """Return the ROS 2 parameter type a YAML value declares: 'double', 'integer_array', ..."""
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'integer'
    if isinstance(value, float):
        return 'double'
    if isinstance(value, str):
        return 'string'
    if isinstance(value, (list, tuple)):
        kinds = {declared_type(item) for item in value}
        if len(kinds) == 1 and next(iter(kinds)) in ('bool', 'integer', 'double', 'string'):
            return f'{next(iter(kinds))}_array'
        return 'mixed list' if kinds else 'empty list'
    return type(value).__name__


def check_value_type(name: str, value: Any, default: Any, where: str = '') -> None:
    """Raise ParameterError unless ``value`` has the ROS type of ``default``."""
    expected, got = declared_type(default), declared_type(value)
    if got == expected or (expected == 'empty list' and got.endswith('_array')):
        return  # an empty default declares no element type: the key's own check judges them
    article = 'an' if expected[0] in 'aeiou' else 'a'
    hint = ''
    if expected == 'double' and got == 'integer':
        hint = f' (write {float(value)!r})'
    elif expected == 'double_array' and got in ('integer_array', 'mixed list'):
        hint = f' (write {[float(item) for item in value]!r})'
    raise ParameterError(f'{where}{name} must be {article} {expected}, got {got} {value!r}{hint}')


def check_known(values: Mapping[str, Any], declared: Iterable[str], node_name: str,
                where: str = '') -> None:
    """Raise ParameterError naming each key the node does not declare (and a close match)."""
    declared = sorted(declared)
    unknown = sorted(set(values) - set(declared))
    if not unknown:
        return
    hints = []
    for key in unknown:
        close = difflib.get_close_matches(key, declared, n=1)
        hints.append(f'{key} (did you mean {close[0]}?)' if close else key)
    raise ParameterError(f'{where}unknown {node_name} parameter(s): {", ".join(hints)}')


def layered_values(node_name: str, paths: Iterable[Layer],
                   defaults_path: PathLike, namespace: str = '/',
                   defaults: Optional[Mapping[str, Any]] = None,
                   overrides: Optional[Mapping[str, Any]] = None,
                   defaults_section: Optional[str] = None,
                   required: bool = True) -> Dict[str, Any]:
    """
    Return every parameter of the node: the shipped defaults, then each file key by key.

    ``defaults`` (default: the ``defaults_section`` of ``defaults_path``, ``node_name``'s by
    default) declares the keys and their types. A section naming the node may use only
    those keys; a wildcard section (``/**``) applies to every node, so it may also hold keys
    another node of the package declares (they are left to that node) but no key none
    declares. ``-p name:=value`` values of a node's command line stand among ``paths`` as
    CommandLineValues, in their place; ``overrides`` come after every file. Both may name
    only declared keys. Values must have the declared ROS types. A file none of whose
    sections applies is an error unless not ``required``: it would be ignored silently.
    """
    if defaults is None:
        defaults = section_values(defaults_path, defaults_section or node_name)
    values = dict(defaults)
    package_keys = every_key(defaults_path) | set(values)
    for path in paths:
        if isinstance(path, CommandLineValues):
            _apply_command_line(path.values, values, node_name)
            continue
        if path is None or Path(path).resolve() == Path(defaults_path).resolve():
            continue
        where = f'{path}: '
        sections = applicable_sections(path, node_name, namespace)
        if not sections and required:
            raise ParameterError(f'{path} has no section for '
                                 f'{fully_qualified_name(node_name, namespace)} ({node_name}:, '
                                 '/**: or its fully qualified name, with ros__parameters:)')
        for pattern, section in sections:
            check_known(section, package_keys if '*' in pattern else values, node_name,
                        where)
            for key, value in section.items():
                if key in values:
                    check_value_type(key, value, values[key], where)
                    values[key] = value
    _apply_command_line(overrides or {}, values, node_name)
    return values


def _apply_command_line(overrides: Mapping[str, Any], values: Dict[str, Any],
                        node_name: str) -> None:
    """Set ``values``' keys to ``-p`` values, which may name only declared keys."""
    check_known(overrides, values, node_name, 'command line: ')
    for key, value in overrides.items():
        check_value_type(key, value, values[key], 'command line: ')
        values[key] = value
