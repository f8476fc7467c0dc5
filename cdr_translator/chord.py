"""
Compiled Newton iterations on a stored LU factorization: the solver's inner loop.

A warm solve is a handful of chord steps (Newton steps that reuse an earlier factorization
of the shooting Jacobian), each a line search of residual shots. Run from Python, the
interpreter's bookkeeping around each 35 us shot (scaling, norms, the LAPACK wrapper, the
line search) cost about as much as the shots themselves; ``chord_iterations`` runs the
whole loop in one compiled call and returns to Python only when it needs a new
factorization (the chord steps stalled, or converge too slowly) or when it is done.

It also records the centre lines and frames of every shot into two alternating buffers,
so the shape of the accepted iterate comes for free: no extra shot for the result.

The iteration is the one TranslatorSolver._newton documents: damped Newton, backtracking
line search (at most LINE_SEARCH_HALVINGS halvings, sufficient decrease 1e-4 of the step
fraction), a chord step that shrinks the residual norm by less than ``chord_rate``
discards the factorization after it is taken.
"""

import math

import numpy as np

from ._jit import jit
from .model import translator_residual

#: How ``chord_iterations`` ended.
CONVERGED = 0
#: The factorization is stale (a chord step failed or converged too slowly): refactor, go on.
REFACTOR = 1
#: The residual became non-finite.
NOT_FINITE = 2
#: A fresh factorization gave no decrease along its step (or a non-finite step).
NO_DECREASE = 3
#: ``max_iterations`` iterations done without converging.
OUT_OF_ITERATIONS = 4
#: A fresh factorization gave a non-finite step (singular or non-finite Jacobian).
SINGULAR = 5

#: Backtracking halvings of one line search.
LINE_SEARCH_HALVINGS = 12


@jit
def lu_solve(lu, pivots, rhs, out):
    """
    Solve J out = rhs with LAPACK getrf's factors (scipy.linalg.lu_factor: lu, piv 0-based).

    The same substitutions LAPACK's getrs makes: row swaps, unit lower, then upper.
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


@jit
def _shoot(xs, wrench, x_scale, residual_scale, model_args, rs, points, frames, unknowns):
    """Nondimensional residual at ``xs`` into ``rs``; the shot's shape into the buffers."""
    pitch_radius, spacing, tube_length, spacers, steps, inv_kse, inv_kbt = model_args
    for i in range(xs.shape[0]):
        unknowns[i] = xs[i] * x_scale[i]
    translator_residual(unknowns, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                        inv_kse, inv_kbt, rs, points, frames)
    total = 0.0
    for i in range(rs.shape[0]):
        rs[i] /= residual_scale[i]
        total += rs[i] * rs[i]
    return math.sqrt(total)


@jit
def chord_iterations(xs, rs, norm, wrench, x_scale, residual_scale, model_args, lu, pivots,
                     fresh, tolerance, max_iterations, chord_rate, points, frames, slot):
    """
    Newton iterations from ``xs`` (residual ``rs``, its norm ``norm``) on the factors given.

    ``xs`` and ``rs`` are updated in place to the last accepted iterate, whose shape is in
    ``points[slot]``, ``frames[slot]`` (two buffers each; the other holds trial shots).
    ``fresh`` says the factors were made at ``xs`` (a failed line search is then final).
    Returns (status, iterations done, residual norm, slot of the accepted shape).
    """
    size = xs.shape[0]
    step = np.empty(size)
    trial = np.empty(size)
    trial_rs = np.empty(size)
    unknowns = np.empty(size)
    done = 0
    stale = False
    while True:
        if not math.isfinite(norm):
            return NOT_FINITE, done, norm, slot
        largest = 0.0
        for i in range(size):
            largest = max(largest, abs(rs[i]))
        if largest <= tolerance:
            return CONVERGED, done, norm, slot
        if done >= max_iterations:
            return OUT_OF_ITERATIONS, done, norm, slot
        if stale:
            return REFACTOR, done, norm, slot
        done += 1
        lu_solve(lu, pivots, rs, step)
        finite = True
        for i in range(size):
            step[i] = -step[i]
            if not math.isfinite(step[i]):
                finite = False
        accepted = False
        new_norm = norm
        if finite:
            scale = 1.0
            for _ in range(LINE_SEARCH_HALVINGS):
                for i in range(size):
                    trial[i] = xs[i] + scale * step[i]
                new_norm = _shoot(trial, wrench, x_scale, residual_scale, model_args,
                                  trial_rs, points[1 - slot], frames[1 - slot], unknowns)
                if new_norm < (1.0 - 1e-4 * scale) * norm:
                    accepted = True
                    break
                scale *= 0.5
        if not accepted:
            if fresh:
                return (NO_DECREASE if finite else SINGULAR), done, norm, slot
            return REFACTOR, done, norm, slot  # a stale Jacobian pointed the wrong way
        slot = 1 - slot
        for i in range(size):
            xs[i] = trial[i]
            rs[i] = trial_rs[i]
        if not fresh and new_norm > chord_rate * norm:
            stale = True  # chord steps converge too slowly: refactor before the next step
        norm = new_norm
        fresh = False
