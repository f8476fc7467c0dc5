"""
One owner per piece of state: no module reads or writes another module's private names.

A private name has one leading underscore (dunders are not private). In cdr_translator,
cdr_wire and msg_tools a module may

* read or write ``obj._name`` (``obj`` not ``self`` or ``cls``), call ``module._name(...)``
  or pass ``'_name'`` to ``getattr``/``setattr``/``hasattr``/``delattr`` only when it
  defines ``_name`` itself (a function, a class, a module-level name, a class attribute
  or a ``self._name`` attribute): objects of its own classes, not those of another
  module, a project module's or a third-party library's (numba's, mcap's);
* import a private name (``from module import _name``) only when that name is a
  module of the package (the internal modules, ``_jit``, ``_linalg``, ``_blas``), never a
  private function or constant of another module.

Parsed with ``ast``: docstrings and comments never count. Which object an attribute
belongs to is not known statically, so a name counts as owned by the module that defines
it: ``other._state`` passes in the module whose class sets ``self._state`` (another
instance of its own class), and fails anywhere else.
"""

import ast
from pathlib import Path
from typing import FrozenSet, Iterator, List, Set, Tuple

import pytest
from source_modules import module_files

ROOT = Path(__file__).resolve().parents[2]

#: Names that look private but are the public API of namedtuples.
NAMEDTUPLE_API = frozenset({'_replace', '_asdict', '_fields', '_make', '_field_defaults'})

#: Third-party private names that cannot be avoided, (file, expression) with the reason.
THIRD_PARTY: FrozenSet[Tuple[str, str]] = frozenset({
    # the standard library's documented way to exit at once, without cleanup handlers
    # (an interrupt while modules are still importing): public despite its underscore
    ('cdr_translator/console.py', 'os._exit'),
})

#: Built-ins that reach an attribute by its name.
BY_NAME = frozenset({'getattr', 'setattr', 'hasattr', 'delattr'})

#: A found access: (file relative to the root, line, what, owner module for an import).
Access = Tuple[str, int, str, str]


def is_private(name: str) -> bool:
    """Say whether ``name`` is private: one leading underscore, not a dunder."""
    return name.startswith('_') and not (name.startswith('__') and name.endswith('__'))


def owned_names(tree: ast.AST) -> Set[str]:
    """Return the private names a module defines: functions, classes, names, self attributes."""
    names: Set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
              and isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls')):
            names.add(node.attr)
        elif isinstance(node, ast.alias) and node.asname is not None:
            names.add(node.asname)
    return {name for name in names if is_private(name)}


def imported_from(module: str, path: Path, node: ast.ImportFrom) -> str:
    """Return the absolute name of the module ``node`` imports from."""
    base = node.module or ''
    if not node.level:
        return base
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    anchor = package.split('.')
    anchor = anchor[:len(anchor) - node.level + 1]
    return '.'.join(anchor + ([base] if base else []))


def private_accesses(module: str, path: Path, source: str,
                     modules: FrozenSet[str] = frozenset()) -> Iterator[Access]:
    """
    Yield the accesses to private names ``module`` (``path``) does not own, in ``source``.

    ``modules`` are the project's module names: a private name imported from a package
    that is one of its modules (``from .. import _linalg``) is that internal module.
    """
    tree = ast.parse(source)
    owned = owned_names(tree)
    where = path.relative_to(ROOT).as_posix() if path.is_absolute() else path.as_posix()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and is_private(node.attr):
            if (node.attr in owned or node.attr in NAMEDTUPLE_API
                    or (isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls'))):
                continue
            yield where, node.lineno, ast.unparse(node), ''
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in BY_NAME and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
              and is_private(node.args[1].value) and node.args[1].value not in owned
              and not (isinstance(node.args[0], ast.Name)
                       and node.args[0].id in ('self', 'cls'))):
            yield where, node.lineno, ast.unparse(node), ''
        elif isinstance(node, ast.ImportFrom):
            owner = imported_from(module, path, node)
            for alias in node.names:
                if is_private(alias.name) and f'{owner}.{alias.name}' not in modules:
                    yield where, node.lineno, f'from {owner} import {alias.name}', owner


def all_accesses() -> List[Access]:
    """Return every access to another module's private names in the packages."""
    files = module_files()
    modules = frozenset(files)
    found: List[Access] = []
    for module, path in files.items():
        found.extend(private_accesses(module, path, path.read_text(), modules))
    return found


def allowed(access: Access) -> bool:
    """Say whether ``access`` is one of the allowlisted ones."""
    where, _, what, owner = access
    return not owner and (where, what) in THIRD_PARTY


@pytest.fixture(scope='module')
def accesses() -> List[Access]:
    """Every access to another module's private names in the packages."""
    return all_accesses()


def test_no_module_touches_another_modules_private_names(accesses):
    """Outside THIRD_PARTY, no ``obj._name`` of another module and no private import."""
    unexpected = [f'{where}:{line}: {what}' for where, line, what, owner in accesses
                  if not allowed((where, line, what, owner))]
    assert not unexpected, ('private names of another module (make them public where they '
                            'are defined, or let the owner do the work):\n'
                            + '\n'.join(unexpected))


def test_allowlist_entries_are_still_needed(accesses):
    """Each third-party use allowlisted still occurs (else remove it)."""
    uses = {(where, what) for where, _, what, owner in accesses if not owner}
    assert THIRD_PARTY <= uses, THIRD_PARTY - uses


@pytest.mark.parametrize('source, found', [
    ('def f(solver):\n    return solver._state\n', ['solver._state']),
    ('def f(solver):\n    solver._verdicts = None\n', ['solver._verdicts']),
    ('from . import messages\nmessages._get({}, "a")\n', ['messages._get']),
    ('def f(robot):\n    return getattr(robot, "_continuation")\n',
     ["getattr(robot, '_continuation')"]),
    ('from .geometry import _kernel\n', ['from pkg.geometry import _kernel']),
    ('import numba\nnumba.core._private\n', ['numba.core._private']),
    # owned, self, docstrings, dunders, namedtuples and internal modules all pass
    ('class A:\n    def __init__(self):\n        self._state = 1\n\n'
     '    def take(self, other):\n        return other._state\n', []),
    ('"""solver._state is private."""\n# solver._state\nx = type(1).__name__\n', []),
    ('def f(row):\n    return row._replace(a=1)\n', []),
    ('from . import _linalg\n', []),
])
def test_the_check_finds_what_it_must(source, found):
    """The check on snippets: a foreign private access is found, owned ones are not."""
    path = Path('pkg/module.py')
    assert [what for _, _, what, _ in private_accesses(
        'pkg.module', path, source, frozenset({'pkg', 'pkg._linalg'}))] == found
