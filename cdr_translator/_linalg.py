"""
Dense linear algebra of the solvers: LU factorization and solves, small SVDs, residual norms.

``factorize``, ``solve_lu`` and ``thin_svd`` call LAPACK (getrf, getrs, gesdd) directly
from Python; ``lu_solve`` and ``norm`` are compiled and are also called from other kernels
(chord.py, accuracy.py, warm_fast_path.py, robot/kernels.py), so they stay numba
functions; ``residual_norm`` is ``norm`` for Python callers.
"""

import math
from typing import Tuple

import numpy as np
from scipy.linalg.lapack import dgesdd, dgetrf, dgetrs

from ._jit import jit


def factorize(matrix: np.ndarray) -> tuple:
    """
    LU factorization (lu, piv) of a square matrix by LAPACK getrf directly.

    scipy.linalg.lu_factor's form and arithmetic (piv 0-based) without its argument handling,
    which cost a third as much as factoring these 90x90 Jacobians (95 against 66 us). Nothing
    is checked: a non-finite entry gives non-finite factors, an exactly singular matrix a zero
    pivot (determinant_sign 0, non-finite solves), which the callers' finiteness checks catch.
    """
    lu, pivots, info = dgetrf(matrix)
    if info < 0:
        raise ValueError(f'getrf: illegal argument {-info}')
    return lu, pivots


def solve_lu(lu: tuple, rhs: np.ndarray) -> np.ndarray:
    """
    Solve J x = rhs with scipy's LU factorization (lu, piv) by LAPACK getrs directly.

    Same arithmetic as scipy.linalg.lu_solve without its argument checking, which cost
    ten times the solve itself for these 90x90 systems (0.46 ms against 0.04 ms measured
    on the loaded machine).
    """
    solution, info = dgetrs(lu[0], lu[1], rhs)
    if info != 0:
        raise ValueError(f'getrs: illegal argument {-info}')
    return solution


def thin_svd(matrix: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the thin SVD (U, s, V^T) of a small matrix, as numpy.linalg.svd(full_matrices=False).

    LAPACK's gesdd called directly: numpy's wrapping costs as much again as decomposing the
    12 x 6 derivative of an estimate (two or three per pose), and numpy.linalg.svd of a 6 x 6
    compliance block right after a forward solve took 62-65 us against 18 us this way
    (medians along a stream of estimates). LinAlgError when it fails.
    """
    left, values, right, info = dgesdd(matrix, full_matrices=0)
    if info != 0:
        raise np.linalg.LinAlgError(f'gesdd: the SVD did not converge ({info})')
    return left, values, right


@jit
def norm(vector):
    """
    Return the Euclidean norm of a flat vector (inf on overflow, NaN with a NaN entry).

    Compiled: numpy's ``sqrt(v @ v)`` inside the ``errstate`` that silences its overflow
    warning took 6 us for 90 entries; this call takes well under one.
    """
    total = 0.0
    for i in range(vector.shape[0]):
        total += vector[i] * vector[i]
    return math.sqrt(total)


def residual_norm(values: np.ndarray) -> float:
    """Return the Euclidean norm of a residual vector as a float (``norm``: no warnings)."""
    return float(norm(values))


@jit
def lu_solve(lu, pivots, rhs, out):
    """
    Solve J out = rhs with LAPACK getrf's factors (scipy.linalg.lu_factor: lu, piv 0-based).

    The same substitutions LAPACK's getrs makes: row swaps, unit lower, then upper. Factors
    stored by columns (lu_factor's Fortran order) are swept column by column, contiguous
    and independent updates (half the time of row sweeps there: 6.5 against 12 us at
    90x90); factors stored by rows (robot/delta.py stacks them so) row by row.
    """
    size = rhs.shape[0]
    for i in range(size):
        out[i] = rhs[i]
    for i in range(size):
        j = pivots[i]
        if j != i:
            swap = out[i]
            out[i] = out[j]
            out[j] = swap
    if lu.strides[0] < lu.strides[1]:  # column-major
        for j in range(size):
            value = out[j]
            for i in range(j + 1, size):
                out[i] -= lu[i, j] * value
        for j in range(size - 1, -1, -1):
            value = out[j] / lu[j, j]
            out[j] = value
            for i in range(j):
                out[i] -= lu[i, j] * value
        return
    for i in range(size):
        acc = out[i]
        for j in range(i):
            acc -= lu[i, j] * out[j]
        out[i] = acc
    for i in range(size - 1, -1, -1):
        acc = out[i]
        for j in range(i + 1, size):
            acc -= lu[i, j] * out[j]
        out[i] = acc / lu[i, i]
