"""
package.xml resolves with rosdep and declares exactly what the sources import.

The rosdep keys are checked against ``rosdep_keys.yaml`` beside this file: the entries of
rosdistro's rosdep/python.yaml and rosdep/base.yaml for the declared keys, at the rosdistro
commit it names (scripts/refresh_rosdep_keys.py rewrites it). With ``CDR_ROSDEP_DIR`` set to
a folder holding the two full files, the keys are checked against those instead, and the
snapshot against them. ROS packages are keys by their own names: the ones the pip wheels
install are found in the venv's ament index, ``launch`` / ``launch_ros`` (no wheels) are
listed below. The imports are found by walking the sources with ``ast``.
"""

import ast
import os
from pathlib import Path
import subprocess
import sys
from typing import Dict, Iterator, List, Optional, Set, Tuple
import xml.etree.ElementTree as ElementTree

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

#: Installed code (exec dependencies) and test code (test or exec dependencies).
INSTALLED_SOURCES = ('cdr_translator', 'cdr_wire', 'msg_tools', 'launch')
TEST_SOURCES = ('tests',)

#: This repository's own top-level modules (not dependencies).
OWN_MODULES = {'cdr_translator', 'cdr_wire', 'msg_tools', 'bench', 'scripts', 'tests'}

#: Top-level import name -> the rosdep key that provides it.
IMPORT_KEYS: Dict[str, str] = {
    'rclpy': 'rclpy',
    'rcl_interfaces': 'rcl_interfaces',
    'geometry_msgs': 'geometry_msgs',
    'sensor_msgs': 'sensor_msgs',
    'std_msgs': 'std_msgs',
    'visualization_msgs': 'visualization_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'ament_index_python': 'ament_index_python',
    'launch': 'launch',
    'launch_ros': 'launch_ros',
    'numba': 'python3-numba',
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib',
    # mcap-ros2-support is a pip key; pip installs mcap with it, and mcap zstandard and lz4
    'mcap_ros2': 'mcap-ros2-support',
    'mcap': 'mcap-ros2-support',
    'zstandard': 'mcap-ros2-support',
    'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis',
    'ament_flake8': 'ament_flake8',
    'ament_pep257': 'ament_pep257',
}

#: Imports the package.xml does not declare, and why: the code must import them lazily
#: (inside a function) or inside try/except ImportError, so that the package and the nodes
#: work without them. pip installs them (setup.py install_requires / extras_require).
OPTIONAL_IMPORTS = {
    'threadpoolctl': 'BLAS thread limit of the solver; rosdep has no key',
    # the workspace atlas (extras_require['atlas']): rosdep has no dask, distributed,
    # xarray or zarr key, and tqdm alone would not make the atlas work
    'dask': 'atlas', 'distributed': 'atlas', 'xarray': 'atlas', 'zarr': 'atlas',
    'tqdm': 'atlas',
}

#: ROS 2 Jazzy packages that have no PyPI wheel (so are not in the venv's ament index).
ROS_PACKAGES_WITHOUT_WHEELS = {'launch', 'launch_ros'}

#: The rosdistro platform of ROS 2 Jazzy: a key must resolve there.
PLATFORM = 'ubuntu'


#: The declared keys' entries of rosdistro's key files (scripts/refresh_rosdep_keys.py).
SNAPSHOT = Path(__file__).with_name('rosdep_keys.yaml')
REFRESH_SCRIPT = ROOT / 'scripts' / 'refresh_rosdep_keys.py'

#: rosdistro's key files, merged in this order.
ROSDEP_FILES = ('python.yaml', 'base.yaml')


def load_yaml(path: Path) -> dict:
    """Return the parsed YAML file (libyaml's loader when there is one: the files are big)."""
    with open(path) as stream:
        return yaml.load(stream, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))


def full_copy() -> Optional[Dict[str, dict]]:
    """Return file name -> keys of the full rosdistro files in CDR_ROSDEP_DIR, if it is set."""
    folder = os.environ.get('CDR_ROSDEP_DIR')
    if not folder:
        return None
    return {name: load_yaml(Path(folder) / name) for name in ROSDEP_FILES}


def rosdep_keys() -> Dict[str, dict]:
    """Return every key (of the full copy, else of the snapshot) with its rules."""
    files = full_copy() or load_yaml(SNAPSHOT)['files']
    keys: Dict[str, dict] = {}
    for name in ROSDEP_FILES:
        keys.update(files[name])
    return keys


def ament_packages() -> Set[str]:
    """Return the ROS packages the venv's wheels registered in the ament index."""
    index = Path(sys.prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
    return {path.name for path in index.iterdir()} if index.is_dir() else set()


def declared(path: Path = ROOT / 'package.xml') -> Dict[str, List[str]]:
    """Return tag -> keys of package.xml's dependency tags."""
    root = ElementTree.parse(path).getroot()
    tags = ('depend', 'build_depend', 'buildtool_depend', 'exec_depend', 'test_depend')
    return {tag: [element.text.strip() for element in root.iter(tag)] for tag in tags}


def _is_guarded(node: ast.AST, parents: Dict[ast.AST, ast.AST]) -> bool:
    """Say whether an import node sits in a ``try`` whose handlers catch ImportError."""
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.Try) and any(
                isinstance(handler.type, ast.Name)
                and handler.type.id in ('ImportError', 'ModuleNotFoundError')
                for handler in node.handlers):
            return True
    return False


def _is_lazy(node: ast.AST, parents: Dict[ast.AST, ast.AST]) -> bool:
    """Say whether an import node sits inside a function (runs only when that is called)."""
    while node in parents:
        node = parents[node]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            return True
    return False


def imports(folders: Tuple[str, ...]) -> Iterator[Tuple[str, Path, bool]]:
    """
    Yield (top-level module, file, optional) of every absolute import.

    Optional: inside try/except ImportError, or inside a function.
    """
    for folder in folders:
        for path in sorted((ROOT / folder).rglob('*.py')):
            tree = ast.parse(path.read_text(), str(path))
            parents = {child: node for node in ast.walk(tree)
                       for child in ast.iter_child_nodes(node)}
            for node in ast.walk(tree):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                optional = _is_guarded(node, parents) or _is_lazy(node, parents)
                for name in names:
                    yield name.split('.')[0], path, optional


def third_party(folders: Tuple[str, ...]) -> Dict[str, List[Tuple[Path, bool]]]:
    """Map every non-stdlib, non-own import of ``folders`` to where it occurs."""
    # helper modules beside the tests (e.g. tests/msg_tools/chunked.py) are imported by name
    local = {path.stem for folder in folders for path in (ROOT / folder).rglob('*.py')}
    found: Dict[str, List[Tuple[Path, bool]]] = {}
    for name, path, guarded in imports(folders):
        if name not in sys.stdlib_module_names and name not in OWN_MODULES | local:
            found.setdefault(name, []).append((path, guarded))
    return found


def _key_problem(key: str, keys: Dict[str, dict], ros: Set[str]) -> Optional[str]:
    """Return why ``key`` would not resolve on Ubuntu (None if it does)."""
    if key in ros or key in ROS_PACKAGES_WITHOUT_WHEELS:
        return None
    if key not in keys:
        return (f'{key}: neither a rosdep key nor a ROS package (a new key of rosdistro: '
                f'add it to {SNAPSHOT.name} with {REFRESH_SCRIPT.name})')
    rules = keys[key]
    if not isinstance(rules, dict) or not rules.get(PLATFORM):
        return f'{key}: no {PLATFORM} rule'
    return None


def test_every_declared_dependency_is_a_resolvable_key():
    """Each dependency is a ROS package or a rosdep key with an Ubuntu rule."""
    keys, ros = rosdep_keys(), ament_packages()
    assert 'rclpy' in ros, 'the venv has no ament index of the ROS wheels'
    everything = [key for tag_keys in declared().values() for key in tag_keys]
    assert everything, 'package.xml declares nothing'
    problems = [problem for key in everything
                if (problem := _key_problem(key, keys, ros)) is not None]
    assert not problems, problems
    assert len(everything) == len(set(everything)), 'a dependency is declared twice'


def test_the_key_check_can_fail():
    """The old python3-threadpoolctl and a made-up name are rejected."""
    keys, ros = rosdep_keys(), ament_packages()
    assert _key_problem('python3-threadpoolctl', keys, ros) is not None
    assert _key_problem('cdr_no_such_package', keys, ros) is not None
    assert _key_problem('python3-numba', keys, ros) is None


def test_the_snapshot_is_what_the_refresh_script_writes(tmp_path):
    """The script rebuilds the snapshot from full files: declared keys only, entries kept."""
    committed = load_yaml(SNAPSHOT)
    folder = tmp_path / 'rosdep'
    folder.mkdir()
    for name in ROSDEP_FILES:
        entries = {**committed['files'][name], f'cdr_undeclared_{name[:-5]}': {'ubuntu': ['x']}}
        (folder / name).write_text(yaml.safe_dump(entries))
    (folder / 'README.md').write_text(f'Copied at commit {committed["rosdistro_commit"]}.\n')
    written = tmp_path / 'rosdep_keys.yaml'
    process = subprocess.run([sys.executable, str(REFRESH_SCRIPT), str(folder),
                              '--output', str(written)],
                             capture_output=True, text=True, timeout=60)
    assert process.returncode == 0, process.stdout + process.stderr
    assert written.read_text() == SNAPSHOT.read_text()


@pytest.mark.skipif(not os.environ.get('CDR_ROSDEP_DIR'),
                    reason='CDR_ROSDEP_DIR names no full copy of the rosdistro files')
def test_the_snapshot_matches_the_full_copy():
    """Every declared key of the full files is in the snapshot with the same rules."""
    files, everything = full_copy(), {key for keys in declared().values() for key in keys}
    assert files is not None
    snapshot = load_yaml(SNAPSHOT)['files']
    stale = [name for name in ROSDEP_FILES
             if snapshot[name] != {key: rules for key, rules in files[name].items()
                                   if key in everything}]
    assert not stale, f'{SNAPSHOT.name} differs from {stale}: run {REFRESH_SCRIPT.name}'


def test_installed_code_imports_only_declared_exec_dependencies():
    """Every third-party import of the installed code maps to an exec dependency."""
    tags = declared()
    runtime = set(tags['depend'] + tags['exec_depend'])
    for name, places in third_party(INSTALLED_SOURCES).items():
        where = sorted({str(path.relative_to(ROOT)) for path, _ in places})
        if name in OPTIONAL_IMPORTS:
            assert all(optional for _, optional in places), \
                f'{name} is not declared ({OPTIONAL_IMPORTS[name]}): import it in a function ' \
                f'or inside try/except ImportError ({where})'
            continue
        assert name in IMPORT_KEYS, f'{name} ({where}): add it to IMPORT_KEYS and package.xml'
        assert IMPORT_KEYS[name] in runtime, \
            f'{name} ({where}) needs <exec_depend>{IMPORT_KEYS[name]}</exec_depend>'


def test_tests_import_only_declared_dependencies():
    """Every third-party import of the tests maps to a test or exec dependency."""
    tags = declared()
    available = set(tags['depend'] + tags['exec_depend'] + tags['test_depend'])
    for name, places in third_party(TEST_SOURCES).items():
        if name in OPTIONAL_IMPORTS:
            continue
        where = sorted({str(path.relative_to(ROOT)) for path, _ in places})
        assert name in IMPORT_KEYS, f'{name} ({where}): add it to IMPORT_KEYS and package.xml'
        assert IMPORT_KEYS[name] in available, \
            f'{name} ({where}) needs <test_depend>{IMPORT_KEYS[name]}</test_depend>'


def test_nothing_unneeded_is_declared():
    """Every declared key provides something the sources import."""
    tags = declared()
    installed_keys = {IMPORT_KEYS[name] for name in third_party(INSTALLED_SOURCES)
                      if name in IMPORT_KEYS}
    test_keys = {IMPORT_KEYS[name] for name in third_party(TEST_SOURCES)
                 if name in IMPORT_KEYS}
    unneeded_exec = set(tags['depend'] + tags['exec_depend']) - installed_keys
    unneeded_test = set(tags['test_depend']) - test_keys
    assert not unneeded_exec, f'exec dependencies nothing imports: {sorted(unneeded_exec)}'
    assert not unneeded_test, f'test dependencies no test imports: {sorted(unneeded_test)}'


def test_optional_import_detection(tmp_path):
    """The guard detection tells a guarded or a function's import from a bare one."""
    guarded = ast.parse('try:\n    import a\nexcept ImportError:\n    a = None\n')
    bare = ast.parse('try:\n    import a\nexcept ValueError:\n    pass\n')
    for tree, expected in ((guarded, True), (bare, False)):
        parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
        node = next(node for node in ast.walk(tree) if isinstance(node, ast.Import))
        assert _is_guarded(node, parents) is expected
    lazy = ast.parse('def f():\n    import a\n')
    parents = {child: node for node in ast.walk(lazy) for child in ast.iter_child_nodes(node)}
    node = next(node for node in ast.walk(lazy) if isinstance(node, ast.Import))
    assert _is_lazy(node, parents) and not _is_guarded(node, parents)
