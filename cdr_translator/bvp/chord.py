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

The iteration is the one solve/correctors.py's ``newton`` documents: damped Newton, backtracking
line search (at most LINE_SEARCH_HALVINGS halvings, sufficient decrease 1e-4 of the step
fraction), a chord step that shrinks the residual norm by less than ``chord_rate``
discards the factorization after it is taken; between factorizations, Broyden updates
(``chord_iterations``).
"""

import math

import numpy as np

from .shooting import translator_residual
from .._jit import jit
from .._linalg import lu_solve

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
def broyden_apply(lu, pivots, updates, steps, count, rhs, out):
    """
    Set out = H rhs, H the inverse Jacobian of ``lu`` after ``count`` good-Broyden updates.

    H_{i+1} r = H_i r + u_i (s_i . H_i r), with u_i = updates[i] and s_i = steps[i].
    """
    lu_solve(lu, pivots, rhs, out)
    apply_updates(updates, steps, count, out)


@jit
def apply_updates(updates, steps, count, out):
    """Set out <- H out, H after ``count`` good-Broyden updates: out += u_i (s_i . out)."""
    for i in range(count):
        dot = 0.0
        for j in range(out.shape[0]):
            dot += steps[i, j] * out[j]
        for j in range(out.shape[0]):
            out[j] += updates[i, j] * dot


#: Most solutions ``extrapolate`` uses: polynomials of degree 2 to PATH_LENGTH - 1.
PATH_LENGTH = 5


@jit
def _lagrange(positions, first, last, at, out):
    """Write the Lagrange weights at ``at`` of the nodes positions[first:last] into ``out``."""
    for j in range(first, last):
        weight = 1.0
        for k in range(first, last):
            if k != j:
                weight *= (at - positions[k]) / (positions[j] - positions[k])
        out[j] = weight


@jit
def _wrench_miss(path_wrenches, weights, first, last, wrench, wrench_scale, miss):
    """Write what the weighted path wrenches miss of ``wrench`` into ``miss``; return its size."""
    total = 0.0
    for j in range(6):
        reached = 0.0
        for i in range(first, last):
            reached += weights[i] * path_wrenches[i, j]
        miss[j] = wrench[j] - reached
        total += (miss[j] / wrench_scale[j]) ** 2
    return math.sqrt(total)


@jit
def extrapolate(path_xs, path_wrenches, count, wrench, wrench_scale, gain, rows, lu, pivots,
                updates, taken, secant_count, miss_limit, out):
    """
    Predict the unknowns at ``wrench`` from the solutions along a path; False if it is not.

    ``path_xs`` (count used rows of size) and ``path_wrenches`` (count rows of 6, SI) are
    3 to PATH_LENGTH solutions, oldest first. Unknowns and wrenches are extrapolated by the
    same polynomial in the length of the wrench path (wrenches divided by ``wrench_scale``),
    at most twice the last two steps ahead. Its degree (2 up to count - 1, the last
    degree + 1 solutions) is the one whose wrench lands nearest ``wrench``, the highest among
    equals: on a smooth path a higher degree is closer (along bench.speed_vs_error's
    sequence a guess's residual is 1e-6 at degree 2, 1e-7 at 3, 1.4e-8 at 4), where the
    wrenches scatter a lower one is. What the extrapolated wrench misses of ``wrench`` is
    added to first order, out -= H (dr/dw) miss, H as in ``broyden_apply`` and dr/dw
    nonzero on ``rows`` only (``gain``, one per wrench component). Returns False, ``out``
    unset, when one of the last two path steps is zero, ``wrench`` lies too far ahead, or
    the miss exceeds ``miss_limit`` of the step (``wrench`` does not continue the path).
    """
    positions = np.zeros(count)  # path length from the last solution (<= 0)
    for i in range(count - 2, -1, -1):
        length = 0.0
        for j in range(6):
            length += ((path_wrenches[i + 1, j] - path_wrenches[i, j]) / wrench_scale[j]) ** 2
        positions[i] = positions[i + 1] - math.sqrt(length)
    step = 0.0
    for j in range(6):
        step += ((wrench[j] - path_wrenches[count - 1, j]) / wrench_scale[j]) ** 2
    step = math.sqrt(step)
    span = -positions[count - 3]
    if not (positions[count - 2] < 0.0 and positions[count - 3] < positions[count - 2]
            and step <= 2.0 * span):
        return False
    weights = np.zeros(count)
    miss = np.zeros(6)
    best, best_miss = 2, math.inf
    for degree in range(2, count):
        first = count - 1 - degree
        if not positions[first] < positions[first + 1]:
            break  # a zero step: no higher degree through it
        _lagrange(positions, first, count, step, weights)
        missed = _wrench_miss(path_wrenches, weights, first, count, wrench, wrench_scale, miss)
        if missed <= best_miss + 1e-9 * step:  # equal within rounding: the higher degree
            best = degree
        best_miss = min(best_miss, missed)
    first = count - 1 - best
    weights[:] = 0.0
    _lagrange(positions, first, count, step, weights)
    missed = _wrench_miss(path_wrenches, weights, first, count, wrench, wrench_scale, miss)
    if not missed <= miss_limit * step:
        return False
    size = out.shape[0]
    rhs = np.zeros(size)
    for j in range(6):
        rhs[rows[j]] = gain[j] * miss[j]
    broyden_apply(lu, pivots, updates, taken, secant_count, rhs, out)
    for i in range(size):
        predicted = 0.0
        for k in range(first, count):
            predicted += weights[k] * path_xs[k, i]
        out[i] = predicted - out[i]
    return True


@jit
def chord_iterations(xs, rs, wrench, x_scale, residual_scale, model_args, lu, pivots,
                     updates, taken, count, fresh, tolerance, max_iterations, chord_rate,
                     points, frames, slot, shoot):
    """
    Newton iterations from ``xs`` (residual ``rs``) on the factors given.

    Each accepted step updates the inverse Jacobian by Broyden's good formula (Kelley,
    "Solving Nonlinear Equations with Newton's Method", SIAM 2003, Sec. 1.11 and algorithm
    brsola): H+ = H + (s - H y) s^T H / (s^T H y), s the step taken, y the residual
    change; held as rank-one factors (``updates``, ``taken``: u_i and s_i of
    ``broyden_apply``, the first ``count`` rows valid, as many as they have rows at most)
    on top of the LU factors, one substitution per step. The caller keeps them with the
    factorization: they carry over to the next solve, whose predictor and chord steps then
    start from an inverse Jacobian that already followed the solution.

    ``xs`` and ``rs`` are updated in place to the last accepted iterate, whose shape is in
    ``points[slot]``, ``frames[slot]`` (two buffers each; the other holds trial shots).
    ``fresh`` says the factors were made at ``xs`` (a failed line search is then final).
    With ``shoot`` the residual at ``xs`` is computed first (into ``rs``, its shape into
    ``slot``): one compiled call from the predicted guess on. Returns (status, iterations
    done, residual norm, slot of the accepted shape, update count).

    Nineteen arguments, no more: numba's dispatcher allocates about 400 bytes per call of
    a function with twenty or more (freed only at the next garbage-collector pass), which
    piled up between collections along a replay (tests/bvp/test_chord.py).
    """
    size = xs.shape[0]
    step = np.empty(size)
    direction = np.empty(size)
    trial = np.empty(size)
    trial_rs = np.empty(size)
    unknowns = np.empty(size)
    done = 0
    stale = False
    if shoot:
        norm = _shoot(xs, wrench, x_scale, residual_scale, model_args, rs, points[slot],
                      frames[slot], unknowns)
    else:
        total = 0.0
        for i in range(size):
            total += rs[i] * rs[i]
        norm = math.sqrt(total)
    if count >= updates.shape[0]:
        count = 0  # full: restart from the factorization (limited-memory Broyden)
    broyden_apply(lu, pivots, updates, taken, count, rs, direction)  # H rs
    while True:
        if not math.isfinite(norm):
            return NOT_FINITE, done, norm, slot, count
        largest = 0.0
        for i in range(size):
            largest = max(largest, abs(rs[i]))
        if largest <= tolerance:
            return CONVERGED, done, norm, slot, count
        if done >= max_iterations:
            return OUT_OF_ITERATIONS, done, norm, slot, count
        if stale:
            return REFACTOR, done, norm, slot, count
        done += 1
        finite = True
        for i in range(size):
            step[i] = -direction[i]
            if not math.isfinite(step[i]):
                finite = False
        accepted = False
        new_norm = norm
        scale = 1.0
        if finite:
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
                return (NO_DECREASE if finite else SINGULAR), done, norm, slot, count
            return REFACTOR, done, norm, slot, count  # a stale Jacobian pointed wrong
        slot = 1 - slot
        for i in range(size):
            xs[i] = trial[i]
            rs[i] = trial_rs[i]
        if not fresh and new_norm > chord_rate * norm:
            stale = True  # chord steps converge too slowly: refactor before the next step
        norm = new_norm
        fresh = False
        # z = H rs_new; H y = z - H rs_old = z + step; s = scale step
        broyden_apply(lu, pivots, updates, taken, count, rs, direction)
        denominator = 0.0
        length = 0.0
        for i in range(size):
            denominator += scale * step[i] * (direction[i] + step[i])
            length += (scale * step[i]) ** 2
        if count < updates.shape[0] and math.isfinite(denominator) and \
                abs(denominator) > 1e-12 * length:
            for i in range(size):
                updates[count, i] = (scale * step[i] - direction[i] - step[i]) / denominator
                taken[count, i] = scale * step[i]
            dot = 0.0
            for i in range(size):
                dot += taken[count, i] * direction[i]
            for i in range(size):
                direction[i] += updates[count, i] * dot
            count += 1
