"""BLAS runs on one thread inside a solve (its LAPACK factorizations) and as before after it."""

from cdr_translator import blas, solver as solver_module
from threadpoolctl import threadpool_info, threadpool_limits


def _blas_threads():
    """Return the thread limit of every loaded BLAS library."""
    return [library['num_threads'] for library in threadpool_info()
            if library['user_api'] == 'blas']


def test_lu_factor_runs_on_one_blas_thread_and_the_limit_is_restored(solver, monkeypatch):
    """A cold 12 N solve factors Jacobians with one BLAS thread; two are set again after."""
    seen = []
    factor = solver_module.lu_factor

    def recording(*args, **kwargs):
        seen.append(_blas_threads())
        return factor(*args, **kwargs)

    monkeypatch.setattr(solver_module, 'lu_factor', recording)
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
    libraries = blas.BLAS_LIBRARIES
    assert libraries, 'threadpoolctl found no BLAS library (numpy and scipy ship OpenBLAS)'
    for library in libraries:
        monkeypatch.setattr(library, 'set_num_threads',
                            lambda threads, library=library: calls.append((library, threads)))
        monkeypatch.setattr(library, 'get_num_threads', lambda: 1)

    @solver_module.one_blas_thread
    def inner():
        return 'done'

    assert inner() == 'done'
    assert calls == []


def _count_sets(monkeypatch):
    """Record every set_num_threads call of every BLAS library (and still make it)."""
    calls = []
    for library in blas.BLAS_LIBRARIES:
        original = library.set_num_threads

        def recording(threads, library=library, original=original):
            calls.append((library, threads))
            return original(threads)
        monkeypatch.setattr(library, 'set_num_threads', recording)
    return calls


def test_single_blas_thread_holds_one_thread_and_solves_inside_set_nothing(solver,
                                                                           monkeypatch):
    """
    Inside single_blas_thread() every library is at one thread and solves touch no limit.

    Warm solves inside set nothing (each used to set and restore the limit: 0.1-0.2 ms);
    the previous limit is back after the context, and only the context set anything.
    """
    calls = _count_sets(monkeypatch)
    with threadpool_limits(limits=2, user_api='blas'):
        calls.clear()
        with blas.single_blas_thread():
            assert _blas_threads() == [1] * len(blas.BLAS_LIBRARIES)
            entered = len(calls)
            solver.reset()
            for force in (12.0, 12.5, 13.0):
                assert solver.solve([force, 0.0, 0.0]).converged
            assert len(calls) == entered  # the solves set nothing
        made = [threads for _, threads in calls]
        assert _blas_threads() == [2] * len(blas.BLAS_LIBRARIES)
    assert entered == len(blas.BLAS_LIBRARIES)
    assert made == [1] * entered + [2] * entered  # the context's own limit and restore


def test_solves_outside_set_and_restore_the_limit_each(solver, monkeypatch):
    """Without the context each solve limits BLAS and restores it (what the context saves)."""
    calls = _count_sets(monkeypatch)
    with threadpool_limits(limits=2, user_api='blas'):
        calls.clear()
        solver.reset()
        for force in (12.0, 12.5, 13.0):
            assert solver.solve([force, 0.0, 0.0]).converged
    assert len(calls) >= 3 * 2 * len(blas.BLAS_LIBRARIES)
