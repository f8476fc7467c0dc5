"""
Parameters of both nodes on the ROS side: descriptors, and what the command line asks for.

The specs, the checks and the one settings type per node live in
cdr_translator.interface.settings (ROS-free, shared with the CLI and replay). Here they become
``ParameterDescriptor``s, and a node's ``--ros-args`` (``--params-file FILE``,
``-p name:=value``) are read so that the node applies exactly the rules the CLI applies to
the same file: an unknown key or a wrongly typed value stops the node with the same message,
where rcl alone would ignore or refuse it differently.
"""

from pathlib import Path
from typing import Any, List, Mapping, Optional, Sequence, Tuple, Union

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter
import yaml

from ..errors import ParameterError
from ..interface.settings import check_value, MODEL_KEYS, ParameterSpec, SPECS
from ..interface.settings import TranslatorSettings
from ..params.params_file import check_nesting, CommandLineValues, Layer, read_document
from ..params.translator_params import DEFAULT_PARAMS_PATH, TranslatorParams

__all__ = ['check_command_line', 'check_value', 'declare', 'default_values',
           'descriptor', 'MODEL_KEYS',
           'model_params', 'NodeSettings', 'node_arguments', 'ParameterSpec',
           'ros_parameter_sources', 'SPECS']

#: The ROS arguments that take a value, which ``ros_parameter_sources`` reads.
_PARAMS_FILE_FLAG = '--params-file'
_PARAM_FLAGS = ('-p', '--param')

#: The node-only snapshot type of earlier versions: now every key is in TranslatorSettings.
NodeSettings = TranslatorSettings


def descriptor(spec: ParameterSpec, value: Any) -> ParameterDescriptor:
    """Return the ROS descriptor of ``spec``; its range typed like ``value`` (int or float)."""
    described = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    if spec.bounds is None:
        return described
    low, high = spec.bounds
    if isinstance(value, int):
        described.integer_range = [IntegerRange(from_value=int(low), to_value=int(high),
                                                step=1)]
    else:
        described.floating_point_range = [FloatingPointRange(
            from_value=float(low), to_value=float(high), step=0.0)]
    return described


def declare(node: Any, spec: ParameterSpec, value: Any) -> Any:
    """
    Declare ``spec``'s parameter on ``node`` with the default ``value``; return its value.

    An empty list is declared as an empty double array: rclpy would type ``[]`` a byte
    array (and refuse doubles later), and rcl reads ``[]`` in a file as not set, which would
    leave the parameter uninitialized (``ros2 param dump`` then returns nothing).
    """
    described = descriptor(spec, value)
    if isinstance(value, (list, tuple)) and not value:
        node.declare_parameter(spec.name, Parameter.Type.DOUBLE_ARRAY, described)
        node.set_parameters([Parameter(spec.name, Parameter.Type.DOUBLE_ARRAY, [])])
        return []
    return node.declare_parameter(spec.name, value, described).value


def ros_parameter_sources(arguments: Sequence[str]) -> List[Layer]:
    """
    Return the ``--params-file`` paths and ``-p name:=value`` values of a command line.

    In their order, which is the order rcl applies them in (the last value of a key wins):
    a path for each file, a CommandLineValues for each ``-p``. Only what stands between
    ``--ros-args`` and ``--`` (or the end) counts, as rcl reads it; ``-p`` values are YAML,
    as rcl parses them. ParameterError for a malformed ``-p``.
    """
    layers: List[Layer] = []
    for token, following in _ros_pairs(arguments):
        if token in (_PARAMS_FILE_FLAG, *_PARAM_FLAGS) and following is None:
            raise ParameterError(f'{token} at the end of the command line: it needs a value')
        if token == _PARAMS_FILE_FLAG:
            layers.append(str(following))
        elif token in _PARAM_FLAGS:
            name, separator, text = str(following).partition(':=')
            if not separator or not name:
                raise ParameterError(f'-p {following!r}: expected name:=value')
            if ':' in name:  # node:name targets one node by name
                continue
            try:
                check_nesting(text, f'-p {name}')
                layers.append(CommandLineValues({name: yaml.safe_load(text)}))
            except yaml.YAMLError as error:
                raise ParameterError(f'-p {name}: {text!r} is not a YAML value ('
                                     f'{" ".join(str(error).split())})') from error
    return layers


def _ros_pairs(arguments: Sequence[str]) -> List[Tuple[str, Optional[str]]]:
    """Return each ROS argument (between ``--ros-args`` and ``--``) with the next token."""
    pairs: List[Tuple[str, Optional[str]]] = []
    inside = False
    tokens = list(arguments)
    for index, token in enumerate(tokens):
        if token == '--ros-args':
            inside = True
        elif token == '--':
            inside = False
        elif inside:
            pairs.append((token, tokens[index + 1] if index + 1 < len(tokens) else None))
    return pairs


def node_arguments(arguments: Sequence[str]) -> List[str]:
    """Return the arguments that are not ROS's (outside ``--ros-args`` ... ``--``)."""
    ours: List[str] = []
    inside = False
    for token in arguments:
        if token == '--ros-args':
            inside = True
        elif token == '--' and inside:
            inside = False
        elif not inside:
            ours.append(token)
    return ours


def check_command_line(arguments: Sequence[str]) -> None:
    """
    Check the ``--params-file`` and ``-p`` of a node's command line before rcl reads them.

    Every file must be a readable params file (the checks the CLI applies to ``--params``)
    and every ``-p`` a ``name:=value`` with a YAML value: ParameterError naming the file or
    parameter otherwise, where rcl would fail to initialize with a traceback. Which keys a
    file may hold is judged later, with the node's namespace known.
    """
    for layer in ros_parameter_sources(arguments):
        if not isinstance(layer, CommandLineValues):
            read_document(str(layer))


def default_values(path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> dict:
    """Return every translator_node parameter of ``path`` over the shipped defaults."""
    return TranslatorSettings.from_params_file(path).values()


def model_params(values: Mapping[str, Any]) -> TranslatorParams:
    """Build the validated model parameters out of all parameter values."""
    return TranslatorParams.from_mapping({key: values[key] for key in MODEL_KEYS})
