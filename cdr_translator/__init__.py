"""Cosserat-rod kinestatics of the dual-continuum-joint translator (one CDR leg)."""

from .errors import InputError, ParameterError, PlausibilityWarning, SolveError
from .params import TranslatorParams
from .result import SolveResult
from .solver import TranslatorSolver

__all__ = ['InputError', 'ParameterError', 'PlausibilityWarning', 'SolveError', 'SolveResult',
           'TranslatorParams', 'TranslatorSolver']
