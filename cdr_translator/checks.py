"""
Validators for numbers and vectors: one place for the checks every entry point makes.

Each ``check_*`` returns the value in the form the caller stores (float, int or array) or
raises the given ``ValueError`` subclass with a message that names the value, in the manner
of pytransform3d's ``check_*`` functions.
"""

import math
from typing import Any, Optional, Type

import numpy as np
from numpy.typing import ArrayLike

from .errors import InputError

__all__ = ['check_covariance', 'check_integer', 'check_number', 'check_unit_quaternion',
           'check_vector']


def check_number(name: str, value: Any, *, low: Optional[float] = None,
                 high: Optional[float] = None, low_open: bool = False,
                 high_open: bool = False, error: Type[ValueError] = ValueError) -> float:
    """
    Return ``value`` as a float if it is a finite real number within the bounds given.

    ``low``/``high`` are inclusive unless ``low_open``/``high_open``; a bool is not a
    number here (YAML's ``true`` must not pass as 1.0).
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise error(f'{name} must be a number, got {value!r}')
    number = float(value)
    if not math.isfinite(number):
        raise error(f'{name} must be finite, got {value!r}')
    below = low is not None and (number <= low if low_open else number < low)
    above = high is not None and (number >= high if high_open else number > high)
    if below or above:
        raise error(f'{name} must {_range_text(low, high, low_open, high_open)}, got {value!r}')
    return number


def _range_text(low: Optional[float], high: Optional[float], low_open: bool,
                high_open: bool) -> str:
    """Say the allowed range in words: 'be positive', 'lie in (-1, 0.5)', 'be >= 0'."""
    if low is not None and high is not None:
        return f'lie in {"(" if low_open else "["}{low:g}, {high:g}{")" if high_open else "]"}'
    if low is not None:
        if low == 0.0 and low_open:
            return 'be positive'
        return f'be {">" if low_open else ">="} {low:g}'
    return f'be {"<" if high_open else "<="} {high:g}'


def check_integer(name: str, value: Any, *, low: Optional[int] = None,
                  high: Optional[int] = None, error: Type[ValueError] = ValueError) -> int:
    """Return ``value`` as an int if it is an integer (not a bool) within [low, high]."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise error(f'{name} must be an integer, got {value!r}')
    if (low is not None and value < low) or (high is not None and value > high):
        bounds = ' and '.join(part for part in (f'>= {low}' if low is not None else '',
                                                f'<= {high}' if high is not None else '')
                              if part)
        raise error(f'{name} must be an integer {bounds}, got {value!r}')
    return int(value)


def check_vector(name: str, values: ArrayLike, size: int = 3,
                 error: Type[ValueError] = InputError) -> np.ndarray:
    """Return ``values`` as a float array of ``size`` finite components (x, y, z named)."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise error(f'{name} must be {size} numbers, got {values!r}') from None
    if array.shape != (size,):
        raise error(f'{name} must have {size} components, got shape {array.shape}')
    labels = 'xyz' if size == 3 else [str(index) for index in range(size)]
    for label, value in zip(labels, array):
        if not math.isfinite(value):
            raise error(f'{name} {label} component is {value}: it must be finite')
    return array


def check_unit_quaternion(name: str, values: ArrayLike, tolerance: float = 1e-6,
                          error: Type[ValueError] = InputError) -> np.ndarray:
    """
    Return ``values`` as a normalized (x, y, z, w) quaternion of norm 1 within ``tolerance``.

    A tracker's quaternion, normalized in single precision, is off by about 1e-7: it passes
    and is renormalized here; a zero or clearly unnormalized one is named.
    """
    quaternion = check_vector(name, values, 4, error)
    norm = float(np.linalg.norm(quaternion))
    if abs(norm - 1.0) > tolerance:
        raise error(f'{name} must be a unit quaternion (x, y, z, w), got norm {norm:.9g}')
    return quaternion / norm


def check_covariance(name: str, values: ArrayLike, size: int,
                     error: Type[ValueError] = InputError) -> np.ndarray:
    """
    Return ``values`` as a finite, symmetric, positive semidefinite ``size`` x ``size`` array.

    Symmetry and the eigenvalues are judged relative to the largest entry (1e-9 and -1e-12 of
    it: a covariance written with rounding passes); the returned array is symmetrized.
    """
    try:
        matrix = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise error(f'{name} must be a {size}x{size} matrix of numbers, got {values!r}') from None
    if matrix.shape != (size, size):
        raise error(f'{name} must be {size}x{size}, got shape {matrix.shape}')
    if not np.all(np.isfinite(matrix)):
        raise error(f'{name} must be finite, got {matrix.tolist()}')
    largest = float(np.abs(matrix).max())
    if float(np.abs(matrix - matrix.T).max()) > 1e-9 * largest:
        raise error(f'{name} must be symmetric, got {matrix.tolist()}')
    matrix = 0.5 * (matrix + matrix.T)
    smallest = float(np.linalg.eigvalsh(matrix)[0])
    if smallest < -1e-12 * largest:
        raise error(f'{name} must be positive semidefinite, has eigenvalue {smallest:.3g}')
    return matrix
