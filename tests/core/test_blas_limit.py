"""BLAS runs on one thread inside a solve (its LAPACK factorizations) and as before after it."""

from cdr_translator import _blas, _linalg
from threadpoolctl import threadpool_info, threadpool_limits


def _blas_threads():
    """Return the thread limit of every loaded BLAS library."""
    return [library['num_threads'] for library in threadpool_info()
            if library['user_api'] == 'blas']


def test_factorizations_run_on_one_blas_thread_and_the_limit_is_restored(solver, monkeypatch):
    """A cold 12 N solve factors Jacobians with one BLAS thread; two are set again after."""
    seen = []
    factor = _linalg.factorize

    def recording(*args, **kwargs):
        seen.append(_blas_threads())
        return factor(*args, **kwargs)

    monkeypatch.setattr(_linalg, 'factorize', recording)
    with threadpool_limits(limits=2, user_api='blas'):
        before = _blas_threads()
        solver.reset()
        result = solver.solve([12.0, 0.0, 0.0])
        after = _blas_threads()
    assert result.converged, result.message
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
