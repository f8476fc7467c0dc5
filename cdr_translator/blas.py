"""
BLAS on one thread for the LAPACK work of the solvers: per call, or for a whole application.

The factorizations and eigenproblems here are 90x90 or smaller: extra BLAS threads cannot
speed them up, and on a busy machine their spin-waiting made a compliance computation 10x
slower (1.8 -> 10 ms median). ``one_blas_thread`` (a decorator) limits BLAS to one thread
for one call and restores the previous limits after it; ``single_blas_thread()`` (a context)
does the same for a whole run of an application: translator_node and cdr_node, the CLI,
the replay and the benchmarks use it. Inside it the per-call limit has nothing to do: the
libraries are already at one thread. That matters: setting and restoring OpenBLAS's thread
count costs 0.1-0.2 ms on this shared machine when work runs in between (a warm solve took
0.42 ms with the limit set and restored around it, 0.25 ms with BLAS left at one thread;
bench/results/targets.md), most of a warm solve that itself needs no BLAS at all.

The limits are read and set on the libraries directly (threadpoolctl's ``limit()`` context,
which first gathers every library's info, took 30-40 us). threadpoolctl is optional: rosdep
has no key for it (so package.xml cannot declare it), pip installs get it (setup.py).
Without it BLAS keeps its own thread count, which ``OPENBLAS_NUM_THREADS=1`` in the
environment sets to one.
"""

import functools
from types import TracebackType
from typing import Any, Callable, List, Optional, Tuple, Type

try:
    from threadpoolctl import ThreadpoolController
except ImportError:  # optional (see above)
    ThreadpoolController = None

__all__ = ['BLAS_LIBRARIES', 'BlasThreadLimit', 'one_blas_thread', 'single_blas_thread']

#: The BLAS libraries' controllers (threadpoolctl.LibController: get_num_threads,
#: set_num_threads) loaded in this process (numpy's and scipy's OpenBLAS); none without
#: threadpoolctl
BLAS_LIBRARIES: List[Any] = (
    [] if ThreadpoolController is None else
    [library for library in ThreadpoolController().lib_controllers if library.user_api == 'blas'])


class BlasThreadLimit:
    """
    Context: every BLAS library at one thread inside, its previous limit restored at exit.

    Libraries already at one thread (``OPENBLAS_NUM_THREADS=1``, or inside another such
    context) are left alone, and so nothing is set or restored when contexts nest.
    """

    __slots__ = ('_changed',)

    def __init__(self) -> None:
        """Change nothing yet."""
        self._changed: List[Tuple[Any, int]] = []

    def __enter__(self) -> 'BlasThreadLimit':
        """Set every library above one thread to one."""
        self._changed = [(library, threads) for library in BLAS_LIBRARIES
                         for threads in (library.get_num_threads(),)
                         if threads is not None and threads != 1]
        for library, _ in self._changed:
            library.set_num_threads(1)
        return self

    def __exit__(self, kind: Optional[Type[BaseException]], error: Optional[BaseException],
                 trace: Optional[TracebackType]) -> None:
        """Restore the limits changed on entry."""
        changed, self._changed = self._changed, []
        for library, threads in changed:
            library.set_num_threads(threads)


def single_blas_thread() -> BlasThreadLimit:
    """
    Return a context that keeps BLAS at one thread for everything run inside it.

    For an application's whole run (a node, the CLI, a replay, a benchmark): the solves
    inside it then skip their own per-call limit (see the module docstring). A script that
    solves a sequence can do the same (or use ``threadpoolctl.threadpool_limits(1)``).
    """
    return BlasThreadLimit()


def one_blas_thread(method: Callable[..., Any]) -> Callable[..., Any]:
    """Run ``method`` with BLAS limited to one thread, the previous limits restored after."""
    if not BLAS_LIBRARIES:
        return method

    @functools.wraps(method)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with BlasThreadLimit():
            return method(*args, **kwargs)
    return wrapper
