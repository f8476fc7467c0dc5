"""Batch answers of every fidelity level (FidelitySolver.solve_many) and lazy reduced results."""

import pickle

from batch_checks import assert_rows_equal, sequence
from cdr_translator.fidelity import BatchResult, FidelitySolver, LEVEL_COST_ORDER
from cdr_translator.solve.result import FRAME_NAMES
import numpy as np
import pytest

#: FidelitySolver options per case: each fixed level, and 'auto' with a budget that mixes them.
CASES = {'full': {'fidelity': 'full'}, 'cc': {'fidelity': 'cc'}, 'rod': {'fidelity': 'rod'},
         'linear': {'fidelity': 'linear'},
         'auto': {'fidelity': 'auto', 'max_position_error': 3e-3, 'max_angle_error_deg': 1.0}}


def wrenches(count=40):
    """Return a sequence that leaves the box where 'auto' admits reduced levels and returns."""
    forces, moments = sequence(count)
    forces[count // 3: count // 2] *= 2.0
    return forces, moments


@pytest.mark.parametrize('case', list(CASES))
def test_batch_equals_single_solves(params, case):
    """Each level: solve_many equals the same solves one by one (pose to 1e-9 m)."""
    forces, moments = wrenches()
    single = FidelitySolver(params, **CASES[case])
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    batch = FidelitySolver(params, **CASES[case]).solve_many(forces, moments)
    assert isinstance(batch, BatchResult)
    assert batch.converged.all(), set(batch.message)
    assert_rows_equal(batch, results)
    assert batch.fidelity.tolist() == [result.fidelity for result in results]
    if case == 'auto':  # the budget picked several levels along the sequence
        assert len(set(batch.fidelity)) >= 2, set(batch.fidelity)


@pytest.mark.parametrize('case', ['cc', 'linear'])
def test_batch_compliance(params, case):
    """compliance=True: each row's matrix is the single solve's (and its stability)."""
    forces, moments = wrenches(5)
    single = FidelitySolver(params, **CASES[case])
    results = [single.solve(force, moment, compliance=True)
               for force, moment in zip(forces, moments)]
    batch = FidelitySolver(params, **CASES[case]).solve_many(forces, moments, compliance=True)
    assert_rows_equal(batch, results, compliance=True)


@pytest.mark.parametrize('level', ['rod'])
def test_failing_row_is_flagged_and_later_rows_solve(params, level):
    """
    A wrench the reduced model cannot reach is a flagged row; the next rows solve.

    'rod' only: the 'cc' model's Newton with its exact Jacobian converges for every finite
    wrench (its virtual-work residual has no singular branch), so no finite row fails there.
    """
    forces = np.array([[5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [0.0, 0.0, -5e4], [7.0, 0.0, 0.0],
                       [8.0, 0.0, 0.0]])
    single = FidelitySolver(params, fidelity=level, time_limit_s=1.0)
    results = [single.solve(force) for force in forces]
    batch = FidelitySolver(params, fidelity=level, time_limit_s=1.0).solve_many(forces)
    assert batch.converged.tolist() == [True, True, False, True, True]
    assert batch.message[2] and batch.fidelity[2] == level
    for index in (0, 1, 3, 4):
        assert batch.message[index] == ''
        assert np.allclose(batch.end_disk_position[index], results[index].end_disk_position,
                           rtol=0.0, atol=1e-9)


@pytest.mark.parametrize('level', ['cc', 'rod'])
def test_lazy_reduced_result_equals_eager_parts(params, level):
    """A reduced result's shape and dictionaries, read late, equal those read at once."""
    forces, moments = wrenches(6)
    eager_solver = FidelitySolver(params, fidelity=level)
    eager = eager_solver.solve(forces[2], moments[2])
    eager_parts = (eager.to_dict(), {name: frame.copy() for name, frame in eager.frames.items()},
                   eager.backbones.copy(), dict(eager.residual_by_type), eager.pj_bending,
                   eager.dj_bending, eager.end_disk_quaternion_xyzw, eager.max_arc_deviation)
    solver = FidelitySolver(params, fidelity=level)
    result = solver.solve(forces[2], moments[2])
    for force, moment in zip(forces[3:], moments[3:]):  # the model moves on before the reads
        solver.solve(force, moment)
    summary, frames, backbones, by_type, pj, dj, quaternion, deviation = eager_parts
    for name in FRAME_NAMES:
        assert np.array_equal(result.frames[name], frames[name])
    assert np.array_equal(result.backbones, backbones)
    assert result.residual_by_type == by_type
    assert (result.pj_bending, result.dj_bending) == (pj, dj)
    assert np.array_equal(result.end_disk_quaternion_xyzw, quaternion)
    assert result.max_arc_deviation == deviation
    late = result.to_dict()
    assert late.pop('solve_time_s') > 0.0 and summary.pop('solve_time_s') > 0.0
    assert late == summary
    model = solver.reduced[level]  # and the model's own shape at the solution
    x, wrench = result.unknowns / model.unknown_scale, np.r_[forces[2], moments[2]]
    assert np.array_equal(model.frames(x, wrench)[3], result.frames['de'])
    assert np.array_equal(model.points(x, wrench), result.backbones)
    assert pickle.loads(pickle.dumps(result)).to_dict()['end_disk_position_m'] == \
        summary['end_disk_position_m']


def test_bad_input_names_the_row(params):
    """The fidelity solver checks its rows as the full one does."""
    with pytest.raises(ValueError, match='forces row 1 x component is nan'):
        FidelitySolver(params, fidelity='cc').solve_many([[1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])


@pytest.mark.parametrize('budget', [(1e-3, 0.5), (3e-3, 1.0), (10e-3, 3.0), (0.1e-3, 0.05)])
def test_reach_lookup_chooses_as_the_box_by_box_rule(params, budget):
    """'auto' picks per wrench what Validation.admissible decides, box by box, would pick."""
    solver = FidelitySolver(params, max_position_error=budget[0],
                            max_angle_error_deg=budget[1])
    assert solver.validation is not None
    solver.cache_full_solution(np.array([8.0, 2.0, -1.0, 0.05, 0.0, 0.1]))
    rng = np.random.default_rng(7)
    half = np.array([20.0, 20.0, 20.0, 0.5, 0.5, 0.5])
    origin = solver.tangent.origin
    samples = np.vstack([rng.uniform(-1.2, 1.2, (300, 6)) * half,
                         origin + rng.uniform(-1.0, 1.0, (300, 6)) * half
                         * rng.choice([1 / 512, 1 / 128, 1 / 32, 1 / 8], (300, 1))])
    chosen = set()
    for wrench in samples:
        expected = 'full'
        for level in LEVEL_COST_ORDER:
            if solver.validation.admissible(level, wrench, *budget, origin=origin):
                expected = level
                break
        assert solver.choose(wrench)[0] == expected, wrench
        chosen.add(expected)
    assert len(chosen) >= 2, chosen  # both sides of some reach were sampled


@pytest.mark.parametrize('level', ['cc', 'rod', 'linear'])
def test_batch_leaves_the_solver_as_single_solves_do(params, level):
    """After solve_many, further solves and batches continue as after the single solves."""
    forces, moments = wrenches(30)
    forces[12] = [0.01, 0.0, 0.0]  # the unloaded state is nearer: a single solve starts cold
    moments[12] = 0.0
    single = FidelitySolver(params, fidelity=level)
    results = [single.solve(force, moment) for force, moment in zip(forces, moments)]
    batched = FidelitySolver(params, fidelity=level)
    first = batched.solve_many(forces[:20], moments[:20])
    second = batched.solve_many(forces[20:25], moments[20:25])
    after = [batched.solve(force, moment) for force, moment in zip(forces[25:], moments[25:])]
    assert_rows_equal(first, results[:20])
    assert_rows_equal(second, results[20:25])
    for result, expected in zip(after, results[25:]):
        assert np.array_equal(result.unknowns, expected.unknowns)
    if level != 'linear':
        assert np.array_equal(batched.levels[level].previous[0],
                              single.levels[level].previous[0])


@pytest.mark.parametrize('level', ['cc', 'rod'])
def test_reduced_runs_are_compiled(params, level, monkeypatch):
    """Without compliance a reduced run solves no row through the per-row Python solve."""
    forces, moments = wrenches(12)
    solver = FidelitySolver(params, fidelity=level)

    def refuse(*_):
        raise AssertionError('a row was solved one by one')

    monkeypatch.setattr(solver.levels[level], 'outcome', refuse)
    batch = solver.solve_many(forces, moments)
    assert batch.converged.all() and (batch.solve_time_s > 0.0).all(), set(batch.message)
