"""
One compiled call for a run of usual warm rows of a batch (``TranslatorSolver.solve_many``).

A usual warm row of a sequence is the warm step (warm_step.py), a stability verdict that
the row may keep from the stored factorization (branch.judge: the same factorization, made
at a wrench close enough), an error estimate within the accuracy target, and the pose and
joint bending read from the recorded frames. ``warm_rows`` runs those rows one after the
other in one compiled loop, extending the path of warm solves as the solver would
(continuation.extend_path), and stops before the first row that is not usual: the warm
step did not converge, the wrench moved too far from the factorization for its verdict,
the estimate misses the target, the previous wrench is zero (a cold solve), or the
end-disk rotation is too far from one for the compiled quaternion. The warm step taken
at that row is handed back, so that the solver's own solve goes on from it (as from its
own warm step) and gives that row from the state the rows before it left.
"""

import math
from typing import Callable, NamedTuple, Optional, Tuple

import numpy as np

from .warm_step import _ANGLE, _MAX_ITERATIONS, _OTHER_STEPS, _POSITION, _REPORT_SIZE
from .warm_step import _warm_step
from .warm_step import described, WarmStep
from .._jit import jit, jit_releasing_gil
from ..bvp.chord import CONVERGED, PATH_LENGTH
from ..bvp.problem import Problem
from ..geometry import _bending_between_frames, _quaternion_of_rotation

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
    if not _quaternion_of_rotation(rotation, quaternion):
        return False  # too far from a rotation: geometry.quaternion_xyzw's fallback
    out[QUATERNION:QUATERNION + 4] = quaternion
    theta, delta = _bending_between_frames(shape[0], shape[1])
    out[PJ] = theta
    out[PJ + 1] = delta
    theta, delta = _bending_between_frames(shape[2], shape[3])
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
    #: the warm step taken at the row that stopped the run, as warm_step.warm_step returns
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
    ``pose`` and ``settings`` as warm_step.warm_step takes them; the path arrays are
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
