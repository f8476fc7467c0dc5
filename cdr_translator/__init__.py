"""Cosserat-rod kinestatics of the dual-continuum-joint translator (one CDR leg)."""

from .params import ParameterError, TranslatorParams
from .result import SolveResult
from .solver import TranslatorSolver

__all__ = ['ParameterError', 'SolveResult', 'TranslatorParams', 'TranslatorSolver']
