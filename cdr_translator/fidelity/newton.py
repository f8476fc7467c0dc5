"""
Compiled damped Newton iteration shared by the reduced models ('cc' and 'rod').

The reduced models have 7-8 unknowns, so the whole iteration (forward-difference Jacobian,
dense solve, backtracking line search) runs inside numba; the model is picked by an integer
code because numba does not cache functions that take other compiled functions as arguments.
"""

import math

import numpy as np

from .cc import cc_residual
from .equivalent_rod import rod_residual
from .._jit import jit

#: Model codes.
CC = 0
ROD = 1

#: Outcome codes of ``newton``.
CONVERGED = 0
NO_CONVERGENCE = 1
NO_DECREASE = 2
NOT_FINITE = 3

#: Forward-difference step of the Newton Jacobian (nondimensional unknowns).
JACOBIAN_STEP = 1e-6


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
def newton(model, x, data, tolerance, max_iterations, rs, jac, have_jacobian):
    """
    Drive the residual below ``tolerance`` (largest component) from x, in place.

    With ``have_jacobian`` the iteration starts with chord steps on ``jac`` (a Jacobian
    from an earlier solve) and rebuilds it only when those slow down or fail; ``jac``
    returns the last Jacobian used. Returns (iterations, outcome code); ``rs`` holds the
    final residual.
    """
    size = x.shape[0]
    column = np.empty(size)
    trial = np.empty(size)
    trial_rs = np.empty(size)
    residual(model, x, data, rs)
    norm = math.sqrt(np.sum(rs * rs))
    fresh = False
    for iteration in range(max_iterations + 1):
        largest = _max_abs(rs)
        if largest <= tolerance:
            return iteration, CONVERGED
        if not math.isfinite(largest):
            return iteration, NOT_FINITE
        if iteration == max_iterations:
            break
        if not have_jacobian:
            for j in range(size):
                saved = x[j]
                x[j] = saved + JACOBIAN_STEP
                residual(model, x, data, column)
                x[j] = saved
                for i in range(size):
                    jac[i, j] = (column[i] - rs[i]) / JACOBIAN_STEP
            have_jacobian = True
            fresh = True
        step = np.linalg.solve(jac, -rs)
        scale = 1.0
        accepted = False
        for _ in range(12):
            for i in range(size):
                trial[i] = x[i] + scale * step[i]
            residual(model, trial, data, trial_rs)
            trial_norm = math.sqrt(np.sum(trial_rs * trial_rs))
            if trial_norm < (1.0 - 1e-4 * scale) * norm:
                accepted = True
                break
            scale *= 0.5
        if not accepted:
            if fresh:
                return iteration + 1, NO_DECREASE
            have_jacobian = False  # a stale Jacobian pointed the wrong way
            continue
        if not fresh and trial_norm > 0.25 * norm:
            have_jacobian = False  # chord steps converge too slowly
        x[:] = trial
        rs[:] = trial_rs
        norm = trial_norm
        fresh = False
    return max_iterations, NO_CONVERGENCE
