"""
One compiled call for the usual warm solve: predict, iterate, estimate the error.

Along a smooth wrench sequence almost every solve is the same few steps: extrapolate the
last solutions (chord.extrapolate), take Newton-Broyden steps on the stored factorization
from there (chord.chord_iterations) and, once converged, estimate the discretization error
(accuracy.estimate_kernel). Made from Python they cost more in interpreter bookkeeping
between the kernels (the continuation loop, the corrector, argument checks, small numpy reductions)
than in the kernels themselves: about 110 of 240 us of a warm solve. ``warm_step`` makes
them one compiled call and hands back only what the solver keeps.

A wrench that does not continue the path (sensor noise around a load, a jump, a path of
fewer than three solutions) is predicted to first order from the last solution, as the
general path does. It covers the usual case only and says when it does not apply, so that
the solver then takes its general path (TranslatorSolver._continuation): before any shot
when the prediction reaches too far for a whole step (TOO_FAR); after the shots when the
chord steps did not converge on the stored factorization (one of chord's codes), leaving
the last iterate for the general path to continue from.
"""

from typing import NamedTuple, Optional, Tuple

import numpy as np

from .._jit import jit_releasing_gil
from ..analysis.accuracy import ErrorEstimate, estimate_kernel
from ..bvp.chord import broyden_apply, chord_iterations, CONVERGED, extrapolate
from ..bvp.problem import Problem, RESIDUAL_KINDS

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
