"""
What translator.launch.py and cdr.launch.py share: their arguments and a node's parameters.

No ``launch`` import here (the launch files load this file by path): plain logic that the
tests call directly. The rule: the node gets the parameters of its section in the user's
params file; a launch argument overrides one of them only when it is given (non-empty).
The section is passed on as values rather than as the file, so that it still applies when
the node runs in a namespace (a params file's ``translator_node:`` key matches the node
``/translator_node`` only, not ``/robot1/translator_node``).
"""

from typing import Any, Dict, List, Mapping, Tuple

import yaml

#: Launch arguments that override the parameter of the same name when given: type, help.
OVERRIDES: Mapping[str, Tuple[type, str]] = {
    'mcap_path': (str, 'MCAP log file (default: from the params file, where empty means an '
                       'auto-named file under log_dir)'),
    'log_to_mcap': (bool, 'true or false: log every input and output to MCAP (default: from '
                          'the params file)'),
    'log_dir': (str, 'folder of auto-named MCAP logs (default: from the params file)'),
}

_TRUE, _FALSE = ('true', 'yes', '1', 'on'), ('false', 'no', '0', 'off')


def arguments(shipped_params: str) -> List[Tuple[str, str, str]]:
    """Return (name, default, description) of every launch argument."""
    return [('params_file', shipped_params,
             'ROS 2 params file; the node takes its section (node name, /name, /** keys)'),
            ('namespace', '', 'namespace of the node and so of its relative topics'),
            *[(name, '', description) for name, (_, description) in OVERRIDES.items()]]


def parse_override(name: str, text: str) -> Any:
    """Convert a launch argument's text to the type of its parameter (ValueError if it is not)."""
    kind = OVERRIDES[name][0]
    if kind is bool:
        if text.strip().lower() in _TRUE:
            return True
        if text.strip().lower() in _FALSE:
            return False
        raise ValueError(f'launch argument {name}:={text!r}: expected true or false')
    return kind(text)


def _section_keys(node_name: str, namespace: str) -> List[str]:
    """Return the params-file keys that address the node, least specific first."""
    namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
    return ['/**', f'/**/{node_name}', node_name, f'/{node_name}',
            f'{namespace}/{node_name}'.lstrip('/'), f'{namespace}/{node_name}']


def file_parameters(params_file: str, node_name: str, namespace: str = '') -> Dict[str, Any]:
    """
    Return the parameters ``params_file`` sets for ``node_name`` in ``namespace``.

    Sections apply from the least to the most specific key (``/**`` first); ValueError if
    the file has none for the node.
    """
    with open(params_file) as stream:
        document = yaml.safe_load(stream) or {}
    if not isinstance(document, Mapping):
        raise ValueError(f'{params_file}: not a ROS 2 params file')
    values: Dict[str, Any] = {}
    found = False
    for key in dict.fromkeys(_section_keys(node_name, namespace)):
        section = document.get(key)
        if isinstance(section, Mapping) and isinstance(section.get('ros__parameters'),
                                                       Mapping):
            values.update(section['ros__parameters'])
            found = True
    if not found:
        raise ValueError(f'{params_file} has no ros__parameters section for {node_name}')
    return values


def node_parameters(configuration: Mapping[str, str], node_name: str) -> Dict[str, Any]:
    """Return the node's parameters: its params-file section, then the given overrides."""
    values = file_parameters(configuration['params_file'], node_name,
                             configuration.get('namespace', ''))
    values.update({name: parse_override(name, configuration[name]) for name in OVERRIDES
                   if configuration.get(name, '') != ''})
    return values


def node_options(configuration: Mapping[str, str], node_name: str) -> Dict[str, Any]:
    """Return the keyword arguments of launch_ros' Node for the executable ``node_name``."""
    return {'package': 'cdr_translator', 'executable': node_name, 'name': node_name,
            'namespace': configuration.get('namespace', ''), 'output': 'screen',
            'emulate_tty': True, 'parameters': [node_parameters(configuration, node_name)]}


def launch_description(node_name: str, shipped_params: str, launch_description_class: Any,
                       declare_argument: Any, opaque_function: Any, node_class: Any) -> Any:
    """
    Build a launch file's description from the launch classes it passes in.

    The arguments are declared; the node is built by an OpaqueFunction once they are
    resolved (so that an argument left empty can leave the file's value alone).
    """
    def node(context: Any) -> list:
        return [node_class(**node_options(context.launch_configurations, node_name))]

    return launch_description_class([
        *[declare_argument(name, default_value=default, description=description)
          for name, default, description in arguments(shipped_params)],
        opaque_function(function=node),
    ])
