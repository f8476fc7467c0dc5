"""
Cosserat-rod kinestatics of the dual-continuum-joint translator (one CDR leg).

The exported names load on first use: the command lines (``python -m cdr_translator``, the
nodes) import this package before anything else, and numpy, numba and scipy take seconds to
load, so they make Ctrl-C quiet (cdr_translator.console) before those imports start.
"""

import importlib
from typing import Any, List, TYPE_CHECKING

if TYPE_CHECKING:
    from .errors import InputError, ParameterError, PlausibilityWarning, SolveError
    from .estimation.wrench_estimate import WrenchEstimate
    from .params.translator_params import TranslatorParams
    from .solve.batch import BatchResult
    from .solve.result import SolveResult
    from .solve.solver import TranslatorSolver

__all__ = ['BatchResult', 'InputError', 'ParameterError', 'PlausibilityWarning', 'SolveError',
           'SolveResult', 'TranslatorParams', 'TranslatorSolver', 'WrenchEstimate']

#: The module that defines each exported name.
_HOMES = {'BatchResult': 'solve.batch', 'InputError': 'errors', 'ParameterError': 'errors',
          'PlausibilityWarning': 'errors', 'SolveError': 'errors',
          'SolveResult': 'solve.result', 'TranslatorParams': 'params.translator_params',
          'TranslatorSolver': 'solve.solver',
          'WrenchEstimate': 'estimation.wrench_estimate'}


def __getattr__(name: str) -> Any:
    """Load an exported name from its module on first use (PEP 562)."""
    if name not in _HOMES:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{_HOMES[name]}'), name)
    globals()[name] = value
    return value


def __dir__() -> List[str]:
    """List the module's names, the exported ones included before they load."""
    return sorted(set(globals()) | set(__all__))
