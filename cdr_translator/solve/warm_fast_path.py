"""
The warm fast path: one compiled call for a usual warm solve, or for a run of batch rows.

Along a smooth wrench sequence almost every solve is the same few steps: extrapolate the
last solutions (chord.extrapolate), take Newton-Broyden steps on the stored factorization
from there (chord.chord_iterations) and, once converged, estimate the discretization error
(accuracy.estimate_kernel). Made from Python they cost more in interpreter bookkeeping
between the kernels (the continuation loop, the corrector, argument checks, small numpy
reductions) than in the kernels themselves: about 110 of 240 us of a warm solve.
``warm_step`` makes them one compiled call and hands back only what the engine keeps.

A wrench that does not continue the path (sensor noise around a load, a jump, a path of
fewer than three solutions) is predicted to first order from the last solution, as the
general path does. It covers the usual case only and says when it does not apply, so that
the engine then takes its general path (continuation.continue_to): before any shot
when the prediction reaches too far for a whole step (TOO_FAR); after the shots when the
chord steps did not converge on the stored factorization (one of chord's codes), leaving
the last iterate for the general path to continue from.

A usual warm row of a sequence is the warm step (``warm_step``), a stability verdict that
the row may keep from the stored factorization (branch.judge: the same factorization, made
at a wrench close enough), an error estimate within the accuracy target, and the pose and
joint bending read from the recorded frames. ``warm_rows`` runs those rows one after the
other in one compiled loop, extending the path of warm solves as the engine would
(continuation.extend_path), and stops before the first row that is not usual: the warm
step did not converge, the wrench moved too far from the factorization for its verdict,
the estimate misses the target, the previous wrench is zero (a cold solve), or the
end-disk rotation is too far from one for the compiled quaternion. The warm step taken
at that row is handed back, so that the engine's own solve goes on from it (as from its
own warm step) and gives that row from the state the rows before it left.
"""

import math
from typing import Callable, NamedTuple, Optional, Tuple

import numpy as np

from .._jit import jit, jit_releasing_gil
from ..analysis.accuracy import ErrorEstimate, estimate_kernel
from ..bvp.chord import broyden_apply, chord_iterations, CONVERGED, extrapolate, PATH_LENGTH
from ..bvp.problem import Problem, RESIDUAL_KINDS
from ..geometry import bending_between_frames, quaternion_of_rotation

#: ``warm_step`` status: the prediction moves an unknown by more than the reach allowed for
#: a whole step (no shot made): the general continuation sizes smaller steps.
TOO_FAR = -2

#: Layout of ``warm_step``'s report array: the residual norm, the error estimate (position,
#: angle, comparison steps) and the largest residual of each of RESIDUAL_KINDS (SI).
_NORM, _POSITION, _ANGLE, _OTHER_STEPS, _BY_KIND = 0, 1, 2, 3, 4
_REPORT_SIZE = _BY_KIND + len(RESIDUAL_KINDS)

#: Layout of ``warm_step``'s settings array.
_TOLERANCE, _MAX_ITERATIONS, _CHORD_RATE, _MISS_LIMIT, _REACH, _ESTIMATE = 0, 1, 2, 3, 4, 5


class WarmStep(NamedTuple):
    """What ``warm_step`` did; the estimate and residuals by kind only when it converged."""

    status: int
    iterations: int
    #: slot of the accepted iterate's shape in the problem's shape buffers
    slot: int
    residual_norm: float
    estimate: Optional[ErrorEstimate]
    residual_by_kind: Optional[dict]


@jit_releasing_gil
def _warm_step(path_xs, path_wrenches, count, wrenches, scales, wrench_factors, kind,
               model_args, lu, pivots, updates, taken, secant_count, settings, pose, points,
               frames, state, report):
    """
    Predict, iterate and estimate (``warm_step``) in one call: 19 arguments, no more.

    ``wrenches`` stacks the wrench to solve at and the previous solution's; ``scales`` stacks
    x_scale and residual_scale, ``wrench_factors`` the wrench scale and
    the wrench's gain on its residual rows (the last six), ``state`` the unknowns the
    previous solution ends at (row 0; the iterate on return) and the residual (row 1).
    Returns (status, iterations, slot, Broyden update count); ``report`` gets _NORM and,
    when converged and the settings ask for it (_ESTIMATE), the estimate and the residuals
    by kind.
    """
    size = state.shape[1]
    xs = state[0]
    rs = state[1]
    wrench = wrenches[0]
    rows = np.arange(size - 6, size)
    guess = np.empty(size)
    if not (count >= 3 and extrapolate(path_xs, path_wrenches, count, wrench,
                                       wrench_factors[0], wrench_factors[1], rows, lu, pivots,
                                       updates, taken, secant_count, settings[_MISS_LIMIT],
                                       guess)):
        # first order: x - J^-1 (dr/dw) dw (TranslatorSolver._continuation's predictor)
        change = np.zeros(size)
        for j in range(6):
            change[rows[j]] = wrench_factors[1, j] * (wrench[j] - wrenches[1, j])
        broyden_apply(lu, pivots, updates, taken, secant_count, change, guess)
        for i in range(size):
            guess[i] = xs[i] - guess[i]
    for i in range(size):  # continuation.first_step: a whole step within the reach
        if not abs(xs[i] - guess[i]) <= settings[_REACH]:
            return TOO_FAR, 0, 0, secant_count
    for i in range(size):
        xs[i] = guess[i]
    status, done, norm, slot, secant_count = chord_iterations(
        xs, rs, wrench, scales[0], scales[1], model_args, lu, pivots, updates, taken,
        secant_count, False, settings[_TOLERANCE], int(settings[_MAX_ITERATIONS]),
        settings[_CHORD_RATE], points, frames, 0, True)
    report[_NORM] = norm
    if status != CONVERGED or settings[_ESTIMATE] == 0.0:
        return status, done, slot, secant_count
    position, angle, other = estimate_kernel(xs, wrench, scales[0], scales[1], kind,
                                             model_args, rs, frames[slot], lu, pivots, pose,
                                             True)
    report[_POSITION] = position
    report[_ANGLE] = angle
    report[_OTHER_STEPS] = other
    for k in range(_REPORT_SIZE - _BY_KIND):
        report[_BY_KIND + k] = 0.0
    for i in range(size):
        at = _BY_KIND + kind[i]
        report[at] = max(report[at], abs(rs[i] * scales[1, i]))
    return status, done, slot, secant_count


def warm_step(problem: Problem, previous: Tuple[np.ndarray, np.ndarray],
              path: Tuple[np.ndarray, np.ndarray, int], wrench: np.ndarray, lu: tuple,
              pose: np.ndarray,
              settings: np.ndarray) -> Tuple[WarmStep, np.ndarray, np.ndarray]:
    """
    Solve at ``wrench`` from the last solution of a warm sequence, if it is usual.

    ``previous`` = (unknowns, wrench) of that solution; ``path`` = (unknowns, wrenches,
    count) of the sequence's last solutions, oldest first, the last being ``previous``'s
    (count 0: no path, a first-order prediction); ``lu`` the stored factorization (and the
    Broyden updates the problem keeps on it), ``pose`` its end-disk pose derivative;
    ``settings`` from ``settings_array``. Returns what happened, the unknowns and the
    residual: the solution when converged, else the last iterate (TOO_FAR: the previous
    unknowns).
    """
    state = np.empty((2, problem.size))
    state[0] = previous[0]
    wrenches = np.empty((2, 6))  # np.stack took several times as long
    wrenches[0] = wrench
    wrenches[1] = previous[1]
    report = np.empty(_REPORT_SIZE)
    count = problem.secant_count(lu)
    status, done, slot, count = _warm_step(
        path[0], path[1], path[2], wrenches, problem.scales, problem.wrench_factors,
        problem.residual_kind, problem.model_args, lu[0], lu[1], problem.secant_updates,
        problem.secant_steps, count, settings, pose, problem.shape_points,
        problem.shape_frames, state, report)
    problem.keep_secant_count(lu, int(count))
    return described(problem, status, done, slot, report, settings), state[0], state[1]


def described(problem: Problem, status: int, done: int, slot: int, report: np.ndarray,
              settings: np.ndarray) -> WarmStep:
    """Return the WarmStep of what ``_warm_step`` returned and reported."""
    estimate = by_kind = None
    values = report.tolist()  # plain floats in one call, not one numpy scalar each
    if status == CONVERGED and settings[_ESTIMATE] != 0.0:
        estimate = ErrorEstimate(values[_POSITION], values[_ANGLE],
                                 problem.params.steps_per_segment, int(values[_OTHER_STEPS]))
        by_kind = dict(zip(RESIDUAL_KINDS, values[_BY_KIND:]))
    return WarmStep(int(status), int(done), int(slot), values[_NORM], estimate, by_kind)


def residual_by_kind(report: np.ndarray) -> dict:
    """Return the largest residual of each of RESIDUAL_KINDS (SI) a converged step reported."""
    return dict(zip(RESIDUAL_KINDS, report[_BY_KIND:].tolist()))


def settings_array(tolerance: float, max_iterations: int, chord_rate: float,
                   miss_limit: float, reach: float, estimate: bool = True) -> np.ndarray:
    """
    Return the solver settings ``warm_step`` takes, as its compiled part reads them.

    Without ``estimate`` a converged step makes no error estimate (nor residuals by kind):
    for a solver that does not judge its solves (TranslatorSolver(judge=False)).
    """
    settings = np.empty(6)
    settings[_TOLERANCE] = tolerance
    settings[_MAX_ITERATIONS] = max_iterations
    settings[_CHORD_RATE] = chord_rate
    settings[_MISS_LIMIT] = miss_limit
    settings[_REACH] = reach
    settings[_ESTIMATE] = 1.0 if estimate else 0.0
    return settings


#: Layout of a row of ``warm_rows``' output: end-disk position and quaternion (x, y, z, w),
#: PJ and DJ bending (angle, direction; rad), error estimate (m, deg, rad).
POSITION, QUATERNION, PJ, DJ, ERROR_M, ERROR_DEG, ERROR_RAD, ROW_SIZE = 0, 3, 7, 9, 11, 12, 13, 14

#: Layout of ``warm_rows``' checks array: the wrench the stored factorization was made at
#: (6), the stack height, the load the drift is measured against at least (N), the largest
#: drift the kept verdict allows, and the accuracy targets (m, deg; 0: none).
_LU_WRENCH, _LENGTH, _LOAD_FLOOR, _DRIFT_LIMIT, _TARGET_M, _TARGET_DEG = 0, 6, 7, 8, 9, 10
_CHECKS_SIZE = 11

#: Layout of ``warm_rows``' counts array: the path of warm solves' count (chained on the
#: previous solution, else 0), the Broyden updates on the factorization, the comparison
#: steps of the last row's estimate; then what the last warm step returned (status,
#: iterations, shape slot, Broyden updates), NO_STEP when none was taken.
_PATH_COUNT, _SECANT_COUNT, _OTHER = 0, 1, 2
_STEP_STATUS, _STEP_ITERATIONS, _STEP_SLOT, _STEP_SECANT_COUNT, _COUNTS_SIZE = 3, 4, 5, 6, 7

#: No warm step was taken at the row that stopped the run (its previous wrench is zero).
NO_STEP = -100


class Checks(NamedTuple):
    """What makes a row usual beyond a converged warm step (branch.judge, meets)."""

    #: the wrench the stored factorization was made at (SI)
    lu_wrench: np.ndarray
    #: stability.wrench_size's length (the stack height)
    length: float
    #: the smallest load a wrench's drift is measured against (N)
    load_floor: float
    #: the largest relative drift the stored verdict allows
    drift_limit: float
    #: accuracy targets (m, deg; 0: none)
    position_m: float
    angle_deg: float


@jit
def _wrench_size(fx, fy, fz, mx, my, mz, length):
    """stability.wrench_size of one wrench."""
    return math.sqrt(fx * fx + fy * fy + fz * fz + (mx * mx + my * my + mz * mz) / length ** 2)


@jit_releasing_gil
def _warm_rows(wrenches, previous, path_xs, path_wrenches, counts, scales, wrench_factors,
               kind, model_args, lu, pivots, updates, taken, settings, pose, points, frames,
               checks, out, state, report, saved):
    """
    Solve rows of ``wrenches`` from ``previous`` until one is unusual; return how many.

    ``previous`` holds the unknowns of the last solution (row 0) and its wrench (row 1,
    first six entries); on return, like the path and ``counts``, those of the last row
    solved. Row i of ``out`` (ROW_SIZE) gets row i's answer. The row that is not usual
    leaves its warm step, if it took one, in ``state`` (unknowns, residual), ``report`` and
    ``counts`` (_STEP_STATUS on: status, iterations, shape slot, Broyden update count);
    ``saved`` (2, k, size) then holds the first k Broyden updates as they were before it
    when that step may have overwritten them (it began with fewer than k rows free: the
    updates restart at the first row when full, chord.py), for ``Run.undo``.
    """
    pair = np.empty((2, 6))
    rotation = np.empty((3, 3))
    quaternion = np.empty(4)
    for row in range(wrenches.shape[0]):
        counts[_STEP_STATUS] = NO_STEP
        if not previous[1, :6].any():
            return row  # not a warm solve: the previous wrench is zero
        if counts[_SECANT_COUNT] + saved.shape[1] > updates.shape[0]:
            saved[0] = updates[:saved.shape[1]]
            saved[1] = taken[:saved.shape[1]]
        if not _usual_row(wrenches[row], previous, path_xs, path_wrenches, counts, scales,
                          wrench_factors, kind, model_args, lu, pivots, updates, taken,
                          settings, pose, points, frames, checks, out[row], state, pair,
                          report, rotation, quaternion):
            return row
    return wrenches.shape[0]


@jit
def _usual_row(wrench, previous, path_xs, path_wrenches, counts, scales, wrench_factors,
               kind, model_args, lu, pivots, updates, taken, settings, pose, points, frames,
               checks, out, state, pair, report, rotation, quaternion):
    """
    Solve one row of ``_warm_rows`` into ``out``; False (nothing kept) when it is not usual.

    ``pair``, ``rotation`` and ``quaternion`` are scratch space; ``state`` and ``report``
    hold the row's warm step (``_warm_rows``).
    """
    state[0] = previous[0]
    pair[0] = wrench
    pair[1] = previous[1, :6]
    status, done, slot, secant_count = _warm_step(
        path_xs, path_wrenches, counts[_PATH_COUNT], pair, scales, wrench_factors, kind,
        model_args, lu, pivots, updates, taken, counts[_SECANT_COUNT], settings, pose,
        points, frames, state, report)
    counts[_STEP_STATUS] = status
    counts[_STEP_ITERATIONS] = done
    counts[_STEP_SLOT] = slot
    counts[_STEP_SECANT_COUNT] = secant_count
    if status != CONVERGED:
        return False
    length = checks[_LENGTH]
    load = max(_wrench_size(wrench[0], wrench[1], wrench[2], wrench[3], wrench[4],
                            wrench[5], length), checks[_LOAD_FLOOR])
    change = wrench - checks[_LU_WRENCH:_LU_WRENCH + 6]
    drift = _wrench_size(change[0], change[1], change[2], change[3], change[4], change[5],
                         length) / load
    error_deg = math.degrees(report[_ANGLE])
    if not (drift <= checks[_DRIFT_LIMIT]
            and (checks[_TARGET_M] <= 0.0 or report[_POSITION] <= checks[_TARGET_M])
            and (checks[_TARGET_DEG] <= 0.0 or error_deg <= checks[_TARGET_DEG])):
        return False
    shape = frames[slot]
    for k in range(3):
        out[POSITION + k] = shape[3, k, 3]
        for j in range(3):
            rotation[k, j] = shape[3, k, j]
    if not quaternion_of_rotation(rotation, quaternion):
        return False  # too far from a rotation: geometry.quaternion_xyzw's fallback
    out[QUATERNION:QUATERNION + 4] = quaternion
    theta, delta = bending_between_frames(shape[0], shape[1])
    out[PJ] = theta
    out[PJ + 1] = delta
    theta, delta = bending_between_frames(shape[2], shape[3])
    out[DJ] = theta
    out[DJ + 1] = delta
    out[ERROR_M] = report[_POSITION]
    out[ERROR_DEG] = error_deg
    out[ERROR_RAD] = report[_ANGLE]
    counts[_SECANT_COUNT] = secant_count
    counts[_OTHER] = int(report[_OTHER_STEPS])
    count = counts[_PATH_COUNT]  # continuation.extend_path, chained
    if count == PATH_LENGTH:
        for k in range(PATH_LENGTH - 1):
            path_xs[k] = path_xs[k + 1]
            path_wrenches[k] = path_wrenches[k + 1]
        count -= 1
    path_xs[count] = state[0]
    path_wrenches[count] = wrench
    counts[_PATH_COUNT] = count + 1
    previous[0] = state[0]
    previous[1, :6] = wrench
    return True


class Run(NamedTuple):
    """What ``warm_rows`` solved: rows, answers, the last solution, path and estimate."""

    #: how many rows, from the first, were solved
    rows: int
    #: their answers, rows of ROW_SIZE
    answers: np.ndarray
    #: (unknowns, wrench) of the last row solved, the previous solution when none
    previous: Tuple[np.ndarray, np.ndarray]
    #: the count of the path of warm solves
    path_count: int
    #: the comparison steps of the last row's error estimate
    coarse_steps: int
    #: the warm step taken at the row that stopped the run, as ``warm_step`` returns
    #: it (the step, the unknowns, the residual); None: none taken, or no row stopped it
    stopped_at: Optional[Tuple[WarmStep, np.ndarray, np.ndarray]]
    #: puts the Broyden updates back as they were before that step, for a solve of the row
    #: that does not go on from it (None with ``stopped_at``)
    undo: Optional[Callable[[], None]]
    #: the last warm step taken (that of the last row solved when no row stopped the run):
    #: its iterations, shape slot, residual and ``warm_step`` report
    last_step: Tuple[int, int, np.ndarray, np.ndarray]


def warm_rows(problem: Problem, previous: Tuple[np.ndarray, np.ndarray],
              path: Tuple[np.ndarray, np.ndarray, int], wrenches: np.ndarray, lu: tuple,
              pose: np.ndarray, settings: np.ndarray, checks: Checks) -> Run:
    """
    Solve the usual warm rows at the head of ``wrenches`` (N, 6) in one compiled call.

    ``previous``, ``path`` (its count 0 unless the path ends at ``previous``), ``lu``,
    ``pose`` and ``settings`` as ``warm_step`` takes them; the path arrays are
    extended in place and the Broyden updates kept on ``lu``, also those of the step
    taken at the row that stopped the run (``Run.stopped_at``).
    """
    last = np.zeros((2, problem.size))
    last[0] = previous[0]
    last[1, :6] = previous[1]
    out = np.empty((len(wrenches), ROW_SIZE))
    counts = np.zeros(_COUNTS_SIZE, dtype=np.int64)
    counts[_PATH_COUNT] = path[2]
    counts[_SECANT_COUNT] = problem.secant_count(lu)
    counts[_STEP_STATUS] = NO_STEP
    values = np.empty(_CHECKS_SIZE)
    values[_LU_WRENCH:_LU_WRENCH + 6] = checks.lu_wrench
    values[_LENGTH:] = (checks.length, checks.load_floor, checks.drift_limit,
                        checks.position_m, checks.angle_deg)
    state = np.empty((2, problem.size))
    report = np.empty(_REPORT_SIZE)
    updates, taken = problem.secant_updates, problem.secant_steps
    # a warm step adds at most one Broyden update per iteration
    saved = np.empty((2, min(len(updates), int(settings[_MAX_ITERATIONS]) + 1), problem.size))
    done = int(_warm_rows(wrenches, last, path[0], path[1], counts, problem.scales,
                          problem.wrench_factors, problem.residual_kind, problem.model_args,
                          lu[0], lu[1], updates, taken, settings, pose, problem.shape_points,
                          problem.shape_frames, values, out, state, report, saved))
    before = int(counts[_SECANT_COUNT])
    stopped_at = None
    undo: Optional[Callable[[], None]] = None
    if done < len(wrenches) and counts[_STEP_STATUS] != NO_STEP:
        problem.keep_secant_count(lu, int(counts[_STEP_SECANT_COUNT]))
        step = described(problem, int(counts[_STEP_STATUS]), int(counts[_STEP_ITERATIONS]),
                         int(counts[_STEP_SLOT]), report, settings)
        stopped_at = (step, state[0], state[1])
        overwritten = before + saved.shape[1] > len(updates)

        def put_back() -> None:
            """Put the Broyden updates back as they were before the step."""
            if overwritten:
                updates[:saved.shape[1]] = saved[0]
                taken[:saved.shape[1]] = saved[1]
            problem.keep_secant_count(lu, before)
        undo = put_back
    else:
        problem.keep_secant_count(lu, before)
    return Run(done, out[:done], (last[0], last[1, :6].copy()), int(counts[_PATH_COUNT]),
               int(counts[_OTHER]), stopped_at, undo,
               (int(counts[_STEP_ITERATIONS]), int(counts[_STEP_SLOT]), state[1], report))
