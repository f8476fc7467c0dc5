"""
The exceptions cdr_translator raises, in one place.

Bad input is always a ``ValueError`` subclass whose message names the key or the component;
a computation that cannot give an answer the caller asked to have (rather than one that
reports failure in its result) is an ``ArithmeticError`` subclass.
"""

__all__ = ['InputError', 'ParameterError', 'PlausibilityWarning', 'SolveError']


class ParameterError(ValueError):
    """A parameter is missing, unknown or has an impossible value (the message names it)."""


class InputError(ValueError):
    """An input to a solve (a wrench, slider positions) is malformed or out of range."""


class SolveError(ArithmeticError):
    """A computation that must produce a value (e.g. a compliance matrix) could not."""


class PlausibilityWarning(UserWarning):
    """A parameter is legal but far outside the translator's scale (the message names it)."""
