"""Batch answers of the full model (TranslatorSolver.solve_many) and deferred result fields."""

import dataclasses
import math
import pickle

from batch_checks import assert_rows_equal, sequence
from cdr_translator import BatchResult, InputError, TranslatorSolver
from cdr_translator.solve.engine import Engine
from cdr_translator.solve.result import SolveResult
import numpy as np
import pytest


def test_batch_equals_single_solves(params):
    """solve_many along a sequence equals the same solves one by one, row by row."""
    forces, moments = sequence()
    single = TranslatorSolver(params)
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    batch = TranslatorSolver(params).solve_many(forces, moments)
    assert isinstance(batch, BatchResult)
    assert batch.converged.all()
    assert batch.compliance is None
    assert batch.end_disk_position.shape == (len(forces), 3)
    assert batch.end_disk_quaternion_xyzw.shape == (len(forces), 4)
    assert batch.pj_bending.shape == batch.dj_bending.shape == (len(forces), 2)
    assert_rows_equal(batch, results)
    assert set(batch.to_dict()) == set(batch.row(0))
    assert batch.to_dict()['converged'] == [True] * len(forces)


def test_batch_with_compliance_and_default_moments(params):
    """compliance=True gives the (N, 6, 6) matrices of the single solves; moments default 0."""
    forces = sequence(6)[0]
    single = TranslatorSolver(params)
    results = [single.solve(force, compliance=True) for force in forces]
    batch = TranslatorSolver(params).solve_many(forces, compliance=True)
    assert batch.compliance is not None and batch.compliance.shape == (6, 6, 6)
    assert np.array_equal(batch.moment, np.zeros((6, 3)))
    assert_rows_equal(batch, results, compliance=True)


def test_batch_continues_a_warm_solver(params):
    """A batch on a solver that has solved before warm-starts from it, as solve() would."""
    forces, moments = sequence(12)
    single, batched = TranslatorSolver(params), TranslatorSolver(params)
    for solver in (single, batched):
        solver.solve([10.0, 1.0, 0.0])
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    assert_rows_equal(batched.solve_many(forces, moments), results)


def test_failing_row_is_flagged_and_later_rows_solve(params, monkeypatch):
    """A row whose solve raises is flagged with the error; the rows after it still solve."""
    forces = np.array([[8.0, 0.0, 0.0], [9.0, 0.0, 0.0], [9.5, 0.0, 0.0], [10.0, 0.0, 0.0],
                       [11.0, 0.0, 0.0]])
    original = Engine.correct

    def failing(self, wrench, *args, **kwargs):
        if wrench[0] == 9.5:
            raise ArithmeticError('made to fail')
        return original(self, wrench, *args, **kwargs)

    monkeypatch.setattr(Engine, 'correct', failing)
    single = TranslatorSolver(params)
    results = []
    for force in forces:
        try:
            results.append(single.solve(force))
        except ArithmeticError:
            results.append(None)
    batch = TranslatorSolver(params).solve_many(forces)
    assert batch.converged.tolist() == [True, True, False, True, True]
    assert batch.message[2] == 'ArithmeticError: made to fail'
    assert batch.stable[2] is None and batch.accuracy_met[2] is None
    assert np.isnan(batch.end_disk_position[2]).all()
    assert batch.row(2)['end_disk_position_m'] == [None, None, None]
    kept = [index for index in range(5) if index != 2]
    assert_rows_equal(BatchResult(*[column[kept] for column in dataclasses.astuple(batch)
                                    if column is not None]),
                      [results[index] for index in kept])


def test_unstable_row_is_flagged(params):
    """A row a single solve calls unstable carries that solve's message; the next row is good."""
    forces = np.array([[5.0, 0.0, 0.0], [0.0, 0.0, -400.0], [6.0, 0.0, 0.0]])
    single = TranslatorSolver(params, follow_stable_branch=False)
    results = [single.solve(force) for force in forces]
    batch = TranslatorSolver(params, follow_stable_branch=False).solve_many(forces)
    assert batch.stable[1] is False and 'unstable' in batch.message[1]
    assert batch.message[0] == batch.message[2] == ''
    assert_rows_equal(batch, results)


@pytest.mark.parametrize('forces, moments, named', [
    ([[1.0, 2.0, 3.0], [1.0, math.nan, 0.0]], None, 'forces row 1 y component is nan'),
    ([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]], [[0.0, 0.0, 0.0], [0.0, 0.0, math.inf]],
     'moments row 1 z component is inf'),
    ([[1.0, 2.0, 3.0], [1.0, 2.0]], None, 'forces row 1 must have 3 components'),
    ([1.0, 2.0, 3.0], None, 'forces row 0 must have 3 components'),
    ([[1.0, 2.0, 3.0]], [[0.0, 0.0, 0.0]] * 2, 'one row per row of forces'),
    (np.zeros((2, 4)), None, 'forces row 0 must have 3 components'),
    ('forces', None, 'forces must be an (N, 3) array'),
])
def test_bad_input_names_the_row(solver, forces, moments, named):
    """NaN, infinities, ragged rows and wrong shapes are a ValueError naming the row."""
    with pytest.raises(InputError, match=named.replace('(', r'\(').replace(')', r'\)')):
        solver.solve_many(forces, moments)
    assert issubclass(InputError, ValueError)


def test_empty_batch(solver):
    """No rows: an empty result."""
    batch = solver.solve_many(np.zeros((0, 3)))
    assert len(batch) == 0
    assert batch.to_dict()['converged'] == []


def test_deferred_fields_are_made_once_on_first_read(solved):
    """A deferred result builds a field on its first read only, with the eager value."""
    calls = []

    def maker(name, value):
        def make():
            calls.append(name)
            return value
        return make

    eager = {field.name: getattr(solved, field.name) for field in dataclasses.fields(solved)}
    lazy_names = ('frames', 'backbones', 'residual_by_type')
    lazy = SolveResult.deferred({name: maker(name, eager[name]) for name in lazy_names},
                                **{name: value for name, value in eager.items()
                                   if name not in lazy_names})
    assert calls == []
    assert lazy.end_disk_position.tolist() == solved.end_disk_position.tolist()
    assert calls == ['frames']
    assert lazy.residual_by_type == eager['residual_by_type']
    assert lazy.residual_by_type == eager['residual_by_type']
    assert calls == ['frames', 'residual_by_type']
    assert lazy.to_dict() == solved.to_dict()  # reads the backbones (max_arc_deviation)
    assert calls == ['frames', 'residual_by_type', 'backbones']
    assert lazy.backbones is eager['backbones']
    assert lazy.pj_bending == solved.pj_bending and lazy.dj_bending == solved.dj_bending
    assert lazy.max_arc_deviation == solved.max_arc_deviation
    with pytest.raises(AttributeError, match='no attribute'):
        lazy.not_a_field


def test_deferred_result_pickles_and_copies(solved):
    """Pickling or replacing a deferred result makes its fields; the copy equals it."""
    lazy = SolveResult.deferred(
        {'frames': lambda: dict(solved.frames), 'backbones': lambda: solved.backbones},
        **{field.name: getattr(solved, field.name) for field in dataclasses.fields(solved)
           if field.name not in ('frames', 'backbones')})
    copied = pickle.loads(pickle.dumps(lazy))
    assert copied.to_dict() == solved.to_dict()
    replaced = dataclasses.replace(lazy, message='changed')
    assert replaced.end_disk_position.tolist() == solved.end_disk_position.tolist()
    assert replaced.message == 'changed'
