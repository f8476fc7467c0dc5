"""
Compiled damped Newton iteration and load continuation shared by the reduced models.

The reduced models ('cc', 'rod') have 7-8 unknowns and exact Jacobians (closed form for
'cc', forward-mode through the RK4 shot for 'rod'), so the whole solve runs inside numba:
the Jacobian, its LU factorization (partial pivoting, no LAPACK call for a matrix this
small), a backtracking line search, and the continuation that halves the load step on
failure. The model is picked by an integer code because numba does not cache functions
that take other compiled functions as arguments.

The factorization outlives a solve: ``pivots[size]`` says whether ``lu`` holds a usable
one. Newton then starts with chord steps on it and factorizes afresh only when they stop
contracting (the residual falling by less than CHORD_CONTRACTION per step) or fail.
"""

import math

import numpy as np

from .cc_derivatives import cc_residual, cc_system
from .equivalent_rod import rod_residual
from .equivalent_rod_jacobian import rod_system
from .._jit import jit

#: Model codes.
CC = 0
ROD = 1

#: Outcome codes of ``newton`` and ``continue_to``.
CONVERGED = 0
NO_CONVERGENCE = 1
NO_DECREASE = 2
NOT_FINITE = 3
SINGULAR = 4

#: Smallest fraction of the remaining wrench change a continuation step may take.
MIN_CONTINUATION_STEP = 1e-3

#: A chord step (reused factorization) must cut the residual norm at least this much.
CHORD_CONTRACTION = 0.02

#: Step halvings of the line search.
LINE_SEARCH_HALVINGS = 12


@jit
def system(model, x, data, out, jac, want_jacobian):
    """Residual of reduced model ``model`` at x into ``out``; with the Jacobian into ``jac``."""
    if model == CC:
        cc_system(x, data, out, jac, want_jacobian)
    else:
        rod_system(x, data, out, jac, want_jacobian)


@jit
def residual(model, x, data, out):
    """Evaluate the residual of reduced model ``model`` at x into ``out``."""
    if model == CC:
        cc_residual(x, data, out)
    else:
        rod_residual(x, data, out)


@jit
def _max_abs(values):
    largest = 0.0
    for value in values:
        if not math.isfinite(value):
            return math.inf
        largest = max(largest, abs(value))
    return largest


@jit
def _norm(values):
    total = 0.0
    for value in values:
        total += value * value
    return math.sqrt(total)


@jit
def lu_factor(a, pivots):
    """Factorize square ``a`` in place (P a = L U, partial pivoting); False if singular."""
    size = a.shape[0]
    for k in range(size):
        best = k
        for i in range(k + 1, size):
            if abs(a[i, k]) > abs(a[best, k]):
                best = i
        pivots[k] = best
        if not (abs(a[best, k]) > 0.0 and math.isfinite(a[best, k])):
            return False
        if best != k:
            for j in range(size):
                a[k, j], a[best, j] = a[best, j], a[k, j]
        inverse = 1.0 / a[k, k]
        for i in range(k + 1, size):
            a[i, k] *= inverse
            factor = a[i, k]
            for j in range(k + 1, size):
                a[i, j] -= factor * a[k, j]
    return True


@jit
def lu_solve(lu, pivots, rhs, out):
    """Solve (P^T L U) out = rhs with the factors of ``lu_factor``."""
    size = lu.shape[0]
    out[:] = rhs
    for k in range(size):
        if pivots[k] != k:
            out[k], out[pivots[k]] = out[pivots[k]], out[k]
    for i in range(size):
        for j in range(i):
            out[i] -= lu[i, j] * out[j]
    for i in range(size - 1, -1, -1):
        for j in range(i + 1, size):
            out[i] -= lu[i, j] * out[j]
        out[i] /= lu[i, i]


@jit
def newton(model, x, data, tolerance, max_iterations, rs, lu, pivots):
    """
    Drive the residual below ``tolerance`` (largest component) from x, in place.

    ``lu``/``pivots`` carry the factorization between calls (see the module doc). Returns
    (iterations, outcome code); ``rs`` holds the final residual.
    """
    size = x.shape[0]
    step = np.empty(size)
    trial = np.empty(size)
    trial_rs = np.empty(size)
    residual(model, x, data, rs)
    norm = _norm(rs)
    fresh = False
    for iteration in range(max_iterations + 1):
        largest = _max_abs(rs)
        if largest <= tolerance:
            return iteration, CONVERGED
        if not math.isfinite(largest):
            return iteration, NOT_FINITE
        if iteration == max_iterations:
            break
        if pivots[size] == 0:
            system(model, x, data, rs, lu, True)
            if not lu_factor(lu, pivots):
                return iteration + 1, SINGULAR
            pivots[size] = 1
            fresh = True
        lu_solve(lu, pivots, rs, step)
        scale = 1.0
        accepted = False
        trial_norm = norm
        for _ in range(LINE_SEARCH_HALVINGS):
            for i in range(size):
                trial[i] = x[i] - scale * step[i]
            residual(model, trial, data, trial_rs)
            trial_norm = _norm(trial_rs)
            if trial_norm < (1.0 - 1e-4 * scale) * norm:
                accepted = True
                break
            scale *= 0.5
        if not accepted:
            if fresh:
                return iteration + 1, NO_DECREASE
            pivots[size] = 0  # a stale factorization pointed the wrong way
            continue
        if not fresh and trial_norm > CHORD_CONTRACTION * norm:
            pivots[size] = 0  # chord steps converge too slowly
        x[:] = trial
        rs[:] = trial_rs
        norm = trial_norm
        fresh = False
    return max_iterations, NO_CONVERGENCE


@jit
def continue_to(model, x, data, origin, wrench, tolerance, max_iterations, rs, lu, pivots):
    """
    Continue from x (solved under ``origin``) to ``wrench``; return (norm, its, code, reached).

    Newton goes straight to the wrench; a failed step is halved, down to
    MIN_CONTINUATION_STEP of the way left. x ends at the last converged state, ``reached``
    the fraction of the way it got, ``rs`` its residual under ``wrench`` and ``data[:6]``
    the wrench.
    """
    size = x.shape[0]
    trial = np.empty(size)
    done = 0.0
    step = 1.0
    iterations = 0
    while done < 1.0:
        target = min(1.0, done + step)
        if target == 1.0:
            data[:6] = wrench
        else:
            for i in range(6):
                data[i] = origin[i] + target * (wrench[i] - origin[i])
        trial[:] = x
        count, code = newton(model, trial, data, tolerance, max_iterations, rs, lu, pivots)
        iterations += count
        if code == NOT_FINITE or code == SINGULAR:
            pivots[size] = 0
        if code == CONVERGED:
            done = target
            x[:] = trial
            if count <= max_iterations // 4:
                step *= 2.0
            continue
        step = 0.5 * (target - done)
        if step < MIN_CONTINUATION_STEP:
            data[:6] = wrench
            residual(model, x, data, rs)
            return _norm(rs), iterations, code, done
    return _norm(rs), iterations, CONVERGED, 1.0
