"""
Compilation switch for the numerical kernels (rod.py, model.py).

The kernels are written once. Normally they are compiled with numba; the paper's
baseline method runs the very same source interpreted (``interpreted_kernels``), so
the baseline differs from the fast path in implementation speed only, never in model.
"""

import importlib
import sys
from types import ModuleType
from typing import Callable, Dict

import numba

_interpreting = False
_KERNEL_MODULES = ('cdr_translator.rod', 'cdr_translator.model')
_interpreted_cache: Dict[str, ModuleType] = {}


def jit(func: Callable) -> Callable:
    """Compile ``func`` with numba (cached on disk), or leave it as Python while copying."""
    if _interpreting:
        return func
    return numba.njit(cache=True, error_model='numpy')(func)


def interpreted_kernels() -> Dict[str, ModuleType]:
    """
    Return fresh, uncompiled copies of the kernel modules, keyed by short name.

    The copies are imported with the switch off and then taken out of ``sys.modules``
    again, so the compiled modules that the rest of the package uses stay untouched.
    """
    global _interpreting
    if _interpreted_cache:
        return _interpreted_cache
    originals = {name: sys.modules.pop(name, None) for name in _KERNEL_MODULES}
    _interpreting = True
    try:
        for name in _KERNEL_MODULES:
            _interpreted_cache[name.rsplit('.', 1)[1]] = importlib.import_module(name)
    finally:
        _interpreting = False
        package = sys.modules['cdr_translator']
        for name, module in originals.items():
            short = name.rsplit('.', 1)[1]
            if module is None:
                sys.modules.pop(name, None)
                package.__dict__.pop(short, None)
            else:
                sys.modules[name] = module
                setattr(package, short, module)
    return _interpreted_cache
