"""
The import graph of cdr_translator and msg_tools: one-way layers and no cycles.

Every import counts, at module level or inside a function (an import hidden in a function
to dodge a cycle is still a cycle); only ``if TYPE_CHECKING:`` blocks are left out. Layers:
core <- wings (fidelity, robot, studies) <- interface <- ros / msg_tools apps; msg_tools'
MCAP core imports nothing from cdr_translator; only cdr_translator.ros imports rclpy.
"""

import ast
from pathlib import Path
import subprocess
import sys
from typing import Dict, Iterator, Set

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ('cdr_translator', 'msg_tools')

#: ROS client library and message packages: only cdr_translator.ros may import them.
ROS_PACKAGES = {'rclpy', 'rcl_interfaces', 'geometry_msgs', 'sensor_msgs', 'std_msgs',
                'visualization_msgs', 'diagnostic_msgs', 'builtin_interfaces'}

#: msg_tools modules that form its ROS-free, cdr_translator-free MCAP core.
MSG_TOOLS_CORE = {'msg_tools', 'cdr_wire.mcap_log', 'cdr_wire.reader', 'cdr_wire.msgdefs',
                  'msg_tools.info', 'msg_tools.errors', 'cdr_wire.file_lock',
                  'cdr_wire.log_status', 'cdr_wire.rosbag2_metadata'}

#: Layer of each part of cdr_translator; a module may import only its own or lower layers.
LAYERS = {'core': 0, 'fidelity': 1, 'robot': 1, 'studies': 2, 'interface': 3, 'ros': 4,
          'app': 5}


def module_names() -> Dict[str, Path]:
    """Map every module of the two packages to its file."""
    names = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob('*.py')):
            parts = list(path.relative_to(ROOT).with_suffix('').parts)
            if parts[-1] == '__init__':
                parts.pop()
            names['.'.join(parts)] = path
    return names


def imported(module: str, path: Path) -> Iterator[str]:
    """Yield the absolute names imported anywhere in ``path`` but TYPE_CHECKING blocks."""
    tree = ast.parse(path.read_text())
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    skipped: Set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and 'TYPE_CHECKING' in ast.unparse(node.test):
            skipped.update(id(child) for child in ast.walk(node))
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')
                anchor = anchor[:len(anchor) - node.level + 1]
                base = '.'.join(anchor + ([base] if base else []))
            yield base
            yield from (f'{base}.{alias.name}' for alias in node.names)


@pytest.fixture(scope='module')
def graph() -> Dict[str, Set[str]]:
    """Map each module to the project modules it imports."""
    names = module_names()
    # a module's own packages are imported before it anyway: an edge to one is no cycle
    return {module: {name for name in imported(module, path) if name in names
                     and not (module + '.').startswith(name + '.')}
            for module, path in names.items()}


def layer(module: str) -> int:
    """Return the layer of a cdr_translator module (cli and __main__ are the app)."""
    parts = module.split('.')
    if len(parts) > 1 and parts[1] in LAYERS:
        return LAYERS[parts[1]]
    if len(parts) > 1 and parts[1] in ('cli', '__main__'):
        return LAYERS['app']
    return LAYERS['core']


def test_no_import_cycles(graph):
    """Depth-first search finds no cycle, counting imports inside functions too."""
    state: Dict[str, int] = {}

    def visit(module, trail):
        state[module] = 1
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                cycle = trail[trail.index(target):] + [target]
                pytest.fail('import cycle: ' + ' -> '.join(cycle))
            if target not in state:
                visit(target, trail + [target])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])


def test_layers_point_one_way(graph):
    """Check core <- fidelity, robot <- studies <- interface <- ros <- cli."""
    wrong = [f'{module} -> {target}' for module, targets in graph.items()
             if module.startswith('cdr_translator')
             for target in targets
             if target.startswith('cdr_translator.') and layer(target) > layer(module)]
    assert not wrong, wrong


def test_msg_tools_core_is_independent_of_cdr_translator(graph):
    """The MCAP writer, reader, message definitions and info import nothing of the solver."""
    wrong = [f'{module} -> {target}' for module in MSG_TOOLS_CORE if module in graph
             for target in graph[module] if target.startswith('cdr_translator')]
    assert not wrong, wrong


def test_only_the_ros_subpackage_imports_ros():
    """Check that rclpy and message packages appear only under cdr_translator/ros."""
    wrong = []
    for module, path in module_names().items():
        if module.startswith('cdr_translator.ros'):
            continue
        wrong += [f'{module} imports {name}' for name in imported(module, path)
                  if name.split('.')[0] in ROS_PACKAGES]
    assert not wrong, wrong


def test_importing_the_libraries_loads_no_ros():
    """Importing every non-ROS module leaves rclpy unloaded (checked in a fresh process)."""
    modules = sorted(module for module in module_names()
                     if not module.startswith('cdr_translator.ros')
                     and not module.endswith('__main__'))
    code = ('import importlib, sys\n'
            f'for name in {modules!r}:\n'
            '    importlib.import_module(name)\n'
            'loaded = sorted(name for name in sys.modules if name.split(".")[0] in '
            f'{sorted(ROS_PACKAGES)!r})\n'
            'print(loaded)\n'
            'sys.exit(1 if loaded else 0)\n')
    process = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                             cwd=ROOT, timeout=300)
    assert process.returncode == 0, process.stdout + process.stderr


def test_the_tests_outside_tests_ros_need_no_ros():
    """``pytest tests --ignore=tests/ros`` collects with no ROS package importable."""
    blocked = sorted(ROS_PACKAGES | {'rosidl_runtime_py'})
    code = ('import sys\n'
            f'sys.modules.update(dict.fromkeys({blocked!r}))  # None: import fails\n'
            'import pytest\n'
            "sys.exit(pytest.main(['--collect-only', '-q', '-p', 'no:cacheprovider', 'tests',\n"
            "                      '--ignore=tests/ros']))\n")
    process = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                             cwd=ROOT, timeout=300)
    assert process.returncode == 0, process.stdout[-3000:] + process.stderr[-3000:]
    assert 'tests/ros/' not in process.stdout
