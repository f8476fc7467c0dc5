"""
The launch files' argument and parameter logic, without ``launch`` / ``launch_ros``.

Neither has a PyPI wheel, so each launch file is loaded with small stand-ins for the launch
classes (fake modules in sys.modules) that record what they are given; the OpaqueFunction
is then called with a context holding resolved launch configurations, as ``ros2 launch``
does. One test also checks, with real rclpy, the namespace rule the launch files work around.
"""

import importlib.util
import os
from pathlib import Path
import random
import subprocess
import sys
from types import ModuleType, SimpleNamespace
from typing import Any, Dict, List, Optional

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'launch'
SHIPPED = ROOT / 'config' / 'translator.yaml'
NODES = {'translator.launch.py': 'translator_node', 'cdr.launch.py': 'cdr_node'}


class Recorded:
    """Stand-in for a launch class: keeps its positional and keyword arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        """Record the arguments."""
        self.args, self.kwargs = args, kwargs


class LaunchDescription(Recorded):
    """Stand-in for launch.LaunchDescription."""


class DeclareLaunchArgument(Recorded):
    """Stand-in for launch.actions.DeclareLaunchArgument."""


class OpaqueFunction(Recorded):
    """Stand-in for launch.actions.OpaqueFunction."""


class Node(Recorded):
    """Stand-in for launch_ros.actions.Node."""


def _module(name: str, **attributes: Any) -> ModuleType:
    """Return a fake module with ``attributes``."""
    module = ModuleType(name)
    module.__dict__.update(attributes)
    return module


@pytest.fixture
def fake_launch(monkeypatch, tmp_path) -> Path:
    """Install the stand-ins; return the fake share folder (holds config/translator.yaml)."""
    share = tmp_path / 'share' / 'cdr_translator'
    (share / 'config').mkdir(parents=True)
    (share / 'config' / 'translator.yaml').write_text(SHIPPED.read_text())
    modules = {
        'launch': _module('launch', LaunchDescription=LaunchDescription),
        'launch.actions': _module('launch.actions', DeclareLaunchArgument=DeclareLaunchArgument,
                                  OpaqueFunction=OpaqueFunction),
        'launch_ros': _module('launch_ros'),
        'launch_ros.actions': _module('launch_ros.actions', Node=Node),
        'ament_index_python': _module('ament_index_python'),
        'ament_index_python.packages': _module(
            'ament_index_python.packages',
            get_package_share_directory=lambda package: str(share)),
    }
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    return share


def _load(file_name: str) -> Recorded:
    """Load a launch file as ``ros2 launch`` does and return its description."""
    spec = importlib.util.spec_from_file_location('launch_file_under_test', LAUNCH / file_name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def _launch(file_name: str, given: Optional[Dict[str, str]] = None) -> List[Node]:
    """Resolve the arguments (defaults, then ``given``) and run the OpaqueFunction."""
    description = _load(file_name)
    actions = description.args[0]
    declared = {action.args[0]: action.kwargs['default_value'] for action in actions
                if isinstance(action, DeclareLaunchArgument)}
    unknown = set(given or {}) - set(declared)
    assert not unknown, f'not declared by {file_name}: {unknown}'
    context = SimpleNamespace(launch_configurations={**declared, **(given or {})})
    functions = [action for action in actions if isinstance(action, OpaqueFunction)]
    assert len(functions) == 1
    return functions[0].kwargs['function'](context)


def _user_file(tmp_path: Path, node_name: str, values: Dict[str, Any],
               key: Optional[str] = None) -> str:
    """Write a params file with ``values`` in the node's section (under ``key``)."""
    path = tmp_path / f'{node_name}_user.yaml'
    path.write_text(yaml.safe_dump({key or node_name: {'ros__parameters': values}}))
    return str(path)


@pytest.mark.parametrize('file_name', sorted(NODES))
def test_declares_the_arguments(fake_launch, file_name):
    """params_file defaults to the installed config; the rest default to '' (not given)."""
    actions = _load(file_name).args[0]
    declared = {action.args[0]: action.kwargs['default_value'] for action in actions
                if isinstance(action, DeclareLaunchArgument)}
    assert declared == {'params_file': str(fake_launch / 'config' / 'translator.yaml'),
                        'namespace': '', 'mcap_path': '', 'log_to_mcap': '', 'log_dir': ''}
    assert all(action.kwargs['description'] for action in actions
               if isinstance(action, DeclareLaunchArgument))


@pytest.mark.parametrize('file_name', sorted(NODES))
def test_defaults_give_the_shipped_section(fake_launch, file_name):
    """No arguments: exactly the node's section of the shipped file, no namespace."""
    node_name = NODES[file_name]
    nodes = _launch(file_name)
    assert len(nodes) == 1
    options = nodes[0].kwargs
    assert (options['package'], options['executable'], options['name'], options['namespace']) \
        == ('cdr_translator', node_name, node_name, '')
    shipped = yaml.safe_load(SHIPPED.read_text())[node_name]['ros__parameters']
    assert options['parameters'] == [shipped]


@pytest.mark.parametrize('file_name', sorted(NODES))
def test_params_file_wins_over_launch_defaults(fake_launch, tmp_path, file_name):
    """mcap_path, log_to_mcap, log_dir of the user's file survive when no argument is given."""
    node_name = NODES[file_name]
    mine = {'mcap_path': '/data/run.mcap', 'log_to_mcap': False, 'log_dir': '/data'}
    user = _user_file(tmp_path, node_name, mine)
    parameters = _launch(file_name, {'params_file': user})[0].kwargs['parameters']
    assert parameters == [mine]


@pytest.mark.parametrize('file_name', sorted(NODES))
def test_given_arguments_override_the_file(fake_launch, tmp_path, file_name):
    """An argument given explicitly replaces the file's value, typed like the parameter."""
    node_name = NODES[file_name]
    user = _user_file(tmp_path, node_name, {'mcap_path': '/data/run.mcap',
                                            'log_to_mcap': True, 'max_force': 50.0})
    parameters = _launch(file_name, {'params_file': user, 'mcap_path': '/tmp/other.mcap',
                                     'log_to_mcap': 'false'})[0].kwargs['parameters']
    assert parameters == [{'mcap_path': '/tmp/other.mcap', 'log_to_mcap': False,
                           'max_force': 50.0}]


def test_bad_boolean_argument_is_refused(fake_launch):
    """log_to_mcap:=maybe stops the launch with a message naming the argument."""
    with pytest.raises(ValueError, match='log_to_mcap'):
        _launch('translator.launch.py', {'log_to_mcap': 'maybe'})


@pytest.mark.parametrize('file_name', sorted(NODES))
def test_namespace_keeps_the_file_parameters(fake_launch, tmp_path, file_name):
    """In a namespace the node still gets its section (passed as values, not as the file)."""
    node_name = NODES[file_name]
    user = _user_file(tmp_path, node_name, {'max_force': 7.0})
    options = _launch(file_name, {'params_file': user, 'namespace': 'robot1'})[0].kwargs
    assert options['namespace'] == 'robot1'
    assert options['parameters'] == [{'max_force': 7.0}]


def test_sections_apply_from_wildcard_to_specific(fake_launch, tmp_path):
    """/** first, then the node's name, then its namespaced name; other nodes' sections not."""
    path = tmp_path / 'layered.yaml'
    path.write_text(yaml.safe_dump({
        '/**': {'ros__parameters': {'max_force': 1.0, 'max_moment': 1.0, 'log_dir': '/a'}},
        'translator_node': {'ros__parameters': {'max_force': 2.0, 'max_moment': 2.0}},
        '/robot1/translator_node': {'ros__parameters': {'max_force': 3.0}},
        'cdr_node': {'ros__parameters': {'max_force': 9.0}},
    }))
    parameters = _launch('translator.launch.py', {'params_file': str(path),
                                                  'namespace': '/robot1'})[0].kwargs[
        'parameters']
    assert parameters == [{'max_force': 3.0, 'max_moment': 2.0, 'log_dir': '/a'}]


def test_file_without_the_node_section_is_refused(fake_launch, tmp_path):
    """A params file for another node is an error, not a node silently on its defaults."""
    user = _user_file(tmp_path, 'cdr_node', {'max_force': 7.0})
    with pytest.raises(ValueError, match='translator_node'):
        _launch('translator.launch.py', {'params_file': user})


def test_a_plain_node_key_misses_a_namespaced_node(tmp_path):
    """Why the launch files pass values: rcl applies 'translator_node:' to /translator_node."""
    user = _user_file(tmp_path, 'translator_node', {'max_force': 5.0})
    script = (
        'import sys, rclpy\n'
        'from rclpy.node import Node\n'
        'rclpy.init(args=["--ros-args", "--params-file", sys.argv[1]])\n'
        'for namespace in ("", "robot1"):\n'
        '    node = Node("translator_node", namespace=namespace)\n'
        '    print(node.declare_parameter("max_force", 1.0).value)\n'
        '    node.destroy_node()\n'
        'rclpy.shutdown()\n')
    env = {**os.environ, 'ROS_DOMAIN_ID': str(random.randint(100, 200)),
           'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'ROS_LOG_DIR': str(tmp_path)}
    process = subprocess.run([sys.executable, '-c', script, user], capture_output=True,
                             text=True, timeout=60, env=env)
    assert process.returncode == 0, process.stderr
    assert process.stdout.split() == ['5.0', '1.0']
