"""
The import graph of cdr_translator, cdr_wire and msg_tools: one-way layers and no cycles.

Every import counts, at module level, inside a function (an import hidden in a function to
dodge a cycle is still a cycle) or under ``if TYPE_CHECKING:`` (a type-only import ties the
two modules together as much as any other). Layers: core <- wings (fidelity, robot,
studies) <- interface <- ros / msg_tools apps; the wire (cdr_wire: CDR, MCAP files) imports
nothing of cdr_translator or msg_tools, and only the edges (cdr_translator.ros, msg_tools)
import it; only cdr_translator.ros imports rclpy.

cdr_translator's layers, each a folder (LAYERS): the ground helpers at the root, params,
bvp (the boundary-value problem), analysis, estimation (the search over any forward
model), solve (the engine), calibration, fidelity, robot, studies, interface, ros, and
the command line.
"""

import ast
from pathlib import Path
import subprocess
import sys
from typing import Dict, FrozenSet, Iterator, List, Set

import pytest
from source_modules import module_files

ROOT = Path(__file__).resolve().parents[2]

#: ROS client library and message packages: only cdr_translator.ros may import them.
ROS_PACKAGES = {'rclpy', 'rcl_interfaces', 'geometry_msgs', 'sensor_msgs', 'std_msgs',
                'visualization_msgs', 'diagnostic_msgs', 'builtin_interfaces'}

#: The wire package: it imports only itself; these edges import it.
WIRE = 'cdr_wire'
WIRE_USERS = ('cdr_translator.ros', 'msg_tools')

#: Layer of each part of cdr_translator; a module may import only its own or lower layers.
#: The root's modules (but cli and __main__) are the ground. estimation sits below the
#: engine: it searches over a forward model given as callables, and the engine's
#: ``TranslatorSolver.estimate_wrench`` hands it the translator's.
LAYERS = {'ground': 0, 'params': 1, 'bvp': 2, 'analysis': 3, 'estimation': 4, 'solve': 5,
          'calibration': 6, 'fidelity': 6, 'robot': 7, 'studies': 8, 'interface': 9,
          'ros': 10, 'app': 11}


def imported(module: str, path: Path) -> Iterator[str]:
    """Yield the absolute names imported anywhere in ``path``, type-only imports included."""
    tree = ast.parse(path.read_text())
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    for node in ast.walk(tree):
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
    names = module_files()
    # a module's own packages are imported before it anyway: an edge to one is no cycle
    return {module: {name for name in imported(module, path) if name in names
                     and not (module + '.').startswith(name + '.')}
            for module, path in names.items()}


def cycle_groups(graph: Dict[str, Set[str]]) -> List[FrozenSet[str]]:
    """Return the groups of modules that import each other (strongly connected, Tarjan)."""
    order: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    groups: List[FrozenSet[str]] = []

    def visit(module: str) -> None:
        order[module] = low[module] = len(order)
        stack.append(module)
        for target in sorted(graph[module]):
            if target not in order:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in stack:
                low[module] = min(low[module], order[target])
        if low[module] == order[module]:
            group = set()
            while True:
                member = stack.pop()
                group.add(member)
                if member == module:
                    break
            if len(group) > 1 or module in graph[module]:
                groups.append(frozenset(group))

    for module in sorted(graph):
        if module not in order:
            visit(module)
    return groups


def one_cycle(graph: Dict[str, Set[str]], group: FrozenSet[str]) -> List[str]:
    """Return one import cycle through the modules of ``group``, as a path back to its start."""
    start = min(group)
    trail = [start]
    seen = {start}
    while True:
        # within a group every module reaches every other: walk until a module repeats
        target = min(name for name in graph[trail[-1]] if name in group)
        if target in seen:
            return trail[trail.index(target):] + [target]
        trail.append(target)
        seen.add(target)


def layer(module: str) -> int:
    """Return the layer of a cdr_translator module (cli and __main__ are the app)."""
    parts = module.split('.')
    if len(parts) == 1:  # the package's face: it exports names of every layer
        return LAYERS['app']
    if len(parts) > 1 and parts[1] in LAYERS:
        return LAYERS[parts[1]]
    if len(parts) > 1 and parts[1] in ('cli', '__main__'):
        return LAYERS['app']
    return LAYERS['ground']


def test_no_import_cycles(graph):
    """No group of modules imports each other, type-only and function-level imports counted."""
    groups = cycle_groups(graph)
    assert not groups, 'import cycles: ' + '; '.join(
        ' -> '.join(one_cycle(graph, group)) for group in groups)


def test_cycle_groups_find_type_only_and_function_level_cycles(tmp_path):
    """The cycle search sees a cycle closed by a TYPE_CHECKING import, and by a function's."""
    (tmp_path / 'a.py').write_text('from typing import TYPE_CHECKING\nimport c\n'
                                   'if TYPE_CHECKING:\n    import b\n')
    (tmp_path / 'b.py').write_text('def f():\n    import a\n')
    (tmp_path / 'c.py').write_text('X = 1\n')
    names = {name: tmp_path / f'{name}.py' for name in 'abc'}
    small = {module: {name for name in imported(module, path) if name in names}
             for module, path in names.items()}
    assert cycle_groups(small) == [frozenset({'a', 'b'})]
    assert one_cycle(small, frozenset({'a', 'b'})) == ['a', 'b', 'a']


def test_layers_point_one_way(graph):
    """Check that each layer imports only its own and lower layers (LAYERS)."""
    wrong = [f'{module} -> {target}' for module, targets in graph.items()
             if module.startswith('cdr_translator')
             for target in targets
             if target.startswith('cdr_translator.') and layer(target) > layer(module)]
    assert not wrong, wrong


def test_the_wire_imports_only_itself(graph):
    """cdr_wire (CDR codecs, MCAP writer and reader) imports nothing of the solver or apps."""
    wrong = [f'{module} -> {target}' for module, targets in graph.items()
             if module.split('.')[0] == WIRE
             for target in targets if target.split('.')[0] != WIRE]
    assert not wrong, wrong


def test_only_the_edges_import_the_wire(graph):
    """cdr_wire is used by the ROS nodes and the msg_tools apps, not by the layers below."""
    wrong = [f'{module} -> {target}' for module, targets in graph.items()
             if module.split('.')[0] != WIRE
             and not module.startswith(tuple(user + '.' for user in WIRE_USERS))
             and module not in WIRE_USERS
             for target in targets if target.split('.')[0] == WIRE]
    assert not wrong, wrong


def test_the_two_edges_import_nothing_of_each_other(graph):
    """The ROS nodes and the msg_tools apps share the layers below them, not each other."""
    wrong = [f'{module} -> {target}' for module, targets in graph.items()
             for target in targets
             if (module.startswith('cdr_translator') and target.startswith('msg_tools'))
             or (module.startswith('msg_tools') and target.startswith('cdr_translator.ros'))]
    assert not wrong, wrong


def test_only_the_ros_subpackage_imports_ros():
    """Check that rclpy and message packages appear only under cdr_translator/ros."""
    wrong = []
    for module, path in module_files().items():
        if module.startswith('cdr_translator.ros'):
            continue
        wrong += [f'{module} imports {name}' for name in imported(module, path)
                  if name.split('.')[0] in ROS_PACKAGES]
    assert not wrong, wrong


def test_importing_the_libraries_loads_no_ros():
    """Importing every non-ROS module leaves rclpy unloaded (checked in a fresh process)."""
    modules = sorted(module for module in module_files()
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
