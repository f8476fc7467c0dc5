"""BLAS runs on one thread inside a solve (its LAPACK factorizations) and as before after it."""

from cdr_translator import _blas, _linalg
from cdr_translator.fidelity import FidelitySolver
import pytest
from threadpoolctl import threadpool_info, threadpool_limits


def _blas_threads():
    """Return the thread limit of every loaded BLAS library."""
    return [library['num_threads'] for library in threadpool_info()
            if library['user_api'] == 'blas']


def _solve_alone(solver):
    """Solve 12 N cold by ``solve``."""
    solver.reset()
    return solver.solve([12.0, 0.0, 0.0])


def _solve_in_a_batch(solver):
    """Solve 12 N cold as the one row of ``solve_many`` (a full-level FidelitySolver)."""
    solver.reset()
    return solver.solve_many([[12.0, 0.0, 0.0]]).row(0)


@pytest.mark.parametrize('how', ['solve', 'solve_many'])
def test_factorizations_run_on_one_blas_thread_and_the_limit_is_restored(solver, params, how,
                                                                         monkeypatch):
    """A cold 12 N solve factors Jacobians with one BLAS thread; two are set again after."""
    seen = []
    factor = _linalg.factorize

    def recording(*args, **kwargs):
        seen.append(_blas_threads())
        return factor(*args, **kwargs)

    batched = FidelitySolver(params, 'full') if how == 'solve_many' else None
    monkeypatch.setattr(_linalg, 'factorize', recording)
    with threadpool_limits(limits=2, user_api='blas'):
        before = _blas_threads()
        if how == 'solve':
            result = _solve_alone(solver)
            converged, message = result.converged, result.message
        else:
            row = _solve_in_a_batch(batched)
            converged, message = row['converged'], row['message']
        after = _blas_threads()
    assert converged, message
    assert seen, 'the solve made no factorization: the test checks nothing'
    assert all(threads == [1] * len(before) for threads in seen), seen
    assert before and after == before == [2] * len(before)


def test_a_library_already_at_one_thread_is_left_alone(monkeypatch):
    """Nested or OPENBLAS_NUM_THREADS=1: no library is set (nor restored to anything)."""
    calls = []
    libraries = _blas._BLAS_LIBRARIES
    assert libraries, 'threadpoolctl found no BLAS library (numpy and scipy ship OpenBLAS)'
    for library in libraries:
        monkeypatch.setattr(library, 'set_num_threads',
                            lambda threads, library=library: calls.append((library, threads)))
        monkeypatch.setattr(library, 'get_num_threads', lambda: 1)

    @_blas.one_blas_thread
    def inner():
        return 'done'

    assert inner() == 'done'
    assert calls == []
