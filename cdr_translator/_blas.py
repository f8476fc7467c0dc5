"""BLAS thread control: the solvers' small factorizations run on one BLAS thread."""

import functools
from typing import Any, Callable, List, Optional

try:  # optional: rosdep has no key for it (so package.xml cannot declare it); pip has it
    from threadpoolctl import ThreadpoolController
except ImportError:
    ThreadpoolController = None


def _blas_controller() -> Optional[Any]:
    """
    Return a threadpoolctl controller of the loaded BLAS libraries; None without threadpoolctl.

    Without threadpoolctl BLAS keeps its own thread count, which ``OPENBLAS_NUM_THREADS=1``
    in the environment sets to one.
    """
    return None if ThreadpoolController is None else ThreadpoolController()


#: The BLAS libraries loaded in this process (numpy's and scipy's OpenBLAS), or None
_BLAS = _blas_controller()


#: The BLAS libraries' controllers (threadpoolctl.LibController: get_num_threads,
#: set_num_threads), none without threadpoolctl
_BLAS_LIBRARIES: List[Any] = (
    [] if _BLAS is None else
    [library for library in _BLAS.lib_controllers if library.user_api == 'blas'])


def one_blas_thread(method: Callable) -> Callable:
    """
    Run ``method`` with BLAS limited to one thread, the previous limits restored after.

    The factorizations here are 90x90: extra BLAS threads cannot speed them up, and on a busy
    machine their spin-waiting made a compliance computation 10x slower (1.8 -> 10 ms median).
    The limits are read and set on the libraries directly (a few us; threadpoolctl's
    ``limit()`` context, which first gathers every library's info, took 30-40 us, a tenth of
    a warm solve); libraries already at one thread (``OPENBLAS_NUM_THREADS=1``, or a call
    nested in another limited one) are left alone. Without threadpoolctl ``method`` is
    returned unchanged.
    """
    if not _BLAS_LIBRARIES:
        return method

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        changed = [(library, threads) for library in _BLAS_LIBRARIES
                   for threads in (library.get_num_threads(),)
                   if threads is not None and threads != 1]
        for library, _ in changed:
            library.set_num_threads(1)
        try:
            return method(*args, **kwargs)
        finally:
            for library, threads in changed:
                library.set_num_threads(threads)
    return wrapper
