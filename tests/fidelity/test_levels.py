"""
The levels behind one protocol (cdr_translator.fidelity.level) and who owns what.

Each level answers through ``solve``, ``solve_many`` and ``compliance``; 'auto' is a policy
over them. No fidelity module reads or writes another's private names, and no two import
each other, type-only imports counted.
"""

import ast
from pathlib import Path

from cdr_translator import fidelity
from cdr_translator.fidelity import FidelitySolver, LEVELS
import numpy as np
import pytest

PACKAGE = Path(fidelity.__file__).parent

#: Methods of the level protocol (fidelity.level.Level).
PROTOCOL = ('solve', 'solve_many', 'compliance', 'reset')


def _modules():
    """Return {module name: parsed tree} of the fidelity package."""
    return {path.stem: ast.parse(path.read_text()) for path in sorted(PACKAGE.glob('*.py'))}


def test_no_module_touches_another_objects_private_names():
    """``obj._name`` only for ``self`` and ``cls``; no private name imported from a sibling."""
    offences = []
    for name, tree in _modules().items():
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and node.attr.startswith('_')
                    and not node.attr.startswith('__')
                    and not (isinstance(node.value, ast.Name)
                             and node.value.id in ('self', 'cls'))):
                offences.append(f'{name}:{node.lineno} .{node.attr}')
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                offences += [f'{name}:{node.lineno} import {alias.name}'
                             for alias in node.names if alias.name.startswith('_')]
    assert not offences, offences


def test_no_import_cycle_among_the_fidelity_modules():
    """The modules import one another one way, imports under TYPE_CHECKING counted."""
    trees = _modules()
    graph = {}
    for name, tree in trees.items():
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                imported |= ({node.module.split('.')[0]} if node.module
                             else {alias.name for alias in node.names})
        graph[name] = imported & set(trees) - {name}
    done, path = set(), []

    def visit(module):
        assert module not in path, ' -> '.join(path[path.index(module):] + [module])
        if module in done:
            return
        path.append(module)
        for other in sorted(graph[module]):
            visit(other)
        path.pop()
        done.add(module)

    for module in sorted(graph):
        visit(module)


@pytest.fixture(scope='module')
def solvers(params):
    """Return a solver per level, fixed at it."""
    return {level: FidelitySolver(params, fidelity=level) for level in LEVELS}


def test_each_level_is_behind_the_protocol(solvers):
    """Every level offers the protocol's methods and answers under its own name."""
    wrench = np.array([6.0, 1.0, -0.5, 0.02, 0.0, 0.01])
    for level, solver in solvers.items():
        assert set(solver.levels) == set(LEVELS)
        for name, implementation in solver.levels.items():
            assert implementation.name == name
            assert all(callable(getattr(implementation, method)) for method in PROTOCOL)
        solver.reset()
        first = solver.solve(wrench[:3], wrench[3:])
        again = solver.solve(wrench[:3], wrench[3:])
        # 'linear' makes its expansion by a full answer first
        assert (first.fidelity, again.fidelity) == (
            ('full', 'linear') if level == 'linear' else (level, level))


@pytest.mark.parametrize('level', LEVELS)
def test_compliance_of_an_answer_is_the_solves(solvers, level):
    """``FidelitySolver.compliance`` (the level's) equals what ``solve`` computed with it."""
    solver = solvers[level]
    solver.reset()
    wrench = np.array([8.0, -2.0, 1.0, 0.03, -0.01, 0.02])
    if level == 'linear':
        solver.solve(wrench[:3], wrench[3:])  # the expansion
    with_compliance = solver.solve(wrench[:3], wrench[3:], compliance=True)
    assert with_compliance.fidelity == level and with_compliance.converged
    later = solver.compliance(with_compliance)
    assert np.allclose(later.matrix, with_compliance.compliance.matrix, rtol=1e-6,
                       atol=1e-12)


def test_levels_forget_only_on_reset(solvers):
    """A reduced level keeps its warm start between answers; reset forgets every level's."""
    solver = solvers['cc']
    solver.reset()
    solver.solve([3.0, 0.0, 0.0])
    assert solver.levels['cc'].previous is not None
    solver.reset()
    assert solver.levels['cc'].previous is None
    assert solver.auto.last_wrench is None and not solver.tangent.ready
