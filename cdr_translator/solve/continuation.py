"""
Load continuation of one translator: from the previous (or unloaded) solution to a wrench.

``continue_to`` is the predictor-corrector walk with step halving and doubling;
``warm_step`` the usual warm case in one compiled call; ``track`` and ``track_only`` the
fallback (path_following.track) for a walk that stalled. What they carry from one solve to
the next (previous solution, factorization, the path of warm solves, lifted nodes) is a
``PathState``, owned by the solver and passed in.
"""

from dataclasses import dataclass, field
import math
import time
from typing import Callable, Optional, Tuple

import numpy as np

from . import path_following
from .correctors import CHORD_RATE, LiftedNodes, LiftedState, Limits, Outcome, Pose
from .warm_fast_path import settings_array as warm_step_settings, warm_step as warm_step_kernel
from .warm_fast_path import WarmStep
from .. import _linalg
from .._linalg import residual_norm
from ..bvp import chord
from ..bvp.problem import Problem

#: Largest nondimensional change of the unknowns a first continuation step may predict:
#: past it the linear prediction has left its regime (see ``first_step``).
PREDICTOR_REACH = 0.3

#: Smallest fraction of the remaining wrench change a continuation step may take: below it
#: the walk has stalled (a thousand halvings' worth of steps would not finish in time).
MIN_CONTINUATION_STEP = 1e-3

#: Largest nondimensional residual at which a corrector out of iterations gets another
#: round on the same step instead of a halved step (it is converging, only slowly).
NEARLY_CONVERGED = 1e-6

#: A warm solve's whole-step predictor extrapolates the last solutions of a sequence (three
#: to chord.PATH_LENGTH) when their wrenches' polynomial reaches the new wrench within this
#: fraction of the step (else: the first-order predictor alone). Along
#: bench.speed_vs_error's sequence the quadratic cut the corrector iterations from 5.06 to
#: 3.31 per solve.
EXTRAPOLATION_MISS = 0.5

#: Cold continuations of translators with at least this many spacer disks per joint correct
#: by the lifted Newton method (multiple_shooting.newton) instead of single shooting;
#: None: never. At one spacer disk single shooting is the faster corrector
#: (docs/explanation/solution_quality.md).
LIFT_FROM_SPACERS: Optional[int] = 2

#: A corrector of one continuation step: (guess, wrench, deadline, factorization or None,
#: max_iterations, its pose) -> Outcome.
Corrector = Callable[..., Outcome]


@dataclass
class PathState:
    """What a solver carries from one solve to the next (unknowns nondimensional)."""

    size: int
    #: (unknowns, wrench) of the last converged solve
    previous: Optional[Tuple[np.ndarray, np.ndarray]] = None
    #: the stored factorization, its pose, and the unknowns it is exact at (once known)
    lu: Optional[tuple] = None
    pose: Optional[Pose] = None
    exact_at: Optional[np.ndarray] = None
    #: the last solutions of consecutive warm solves, oldest first (unknowns, wrenches),
    #: how many (at most chord.PATH_LENGTH) and the unknowns of the last (``previous``'s
    #: while the chain holds): the whole-step predictor extrapolates them
    path_xs: np.ndarray = field(init=False)
    path_wrenches: np.ndarray = field(init=False)
    path_count: int = 0
    path_last: Optional[np.ndarray] = None
    lifted: LiftedNodes = field(default_factory=LiftedNodes)
    unloaded_lu: Optional[tuple] = None
    unloaded_pose: Optional[Pose] = None
    #: a warm step already taken at the next wrench, (wrench, step, unknowns, residual) as
    #: warm_fast_path.warm_step returns them (a batch's compiled run stopped there): the next
    #: ``warm_step`` at that wrench goes on from it instead of taking it again
    handed_over: Optional[Tuple[np.ndarray, WarmStep, np.ndarray, np.ndarray]] = None
    #: warm_step's settings array and the (tolerance, max_iterations, judge) it was made for
    warm_settings: np.ndarray = field(default_factory=lambda: np.empty(0))
    warm_settings_for: Optional[Tuple[float, int, bool]] = None

    def __post_init__(self) -> None:
        """Allocate the path of warm solves."""
        self.path_xs = np.empty((chord.PATH_LENGTH, self.size))
        self.path_wrenches = np.empty((chord.PATH_LENGTH, 6))


def unloaded(problem: Problem, state: PathState) -> Tuple[Tuple[np.ndarray, np.ndarray], tuple]:
    """Return the straight unloaded solution and its LU factorization (computed once)."""
    if state.unloaded_lu is None:
        zero = np.zeros(6)
        xs = problem.straight_guess(zero)
        state.unloaded_lu = _linalg.factorize(
            problem.jacobian(xs, zero, problem.residual(xs, zero)))
        state.unloaded_pose = (problem.pose_jacobian, zero)
    return (problem.straight_guess(np.zeros(6)), np.zeros(6)), state.unloaded_lu


def unloaded_lifted(problem: Problem, state: PathState, xs: np.ndarray) -> LiftedState:
    """
    Return the lifted state of the unloaded solution ``xs`` (its nodes made once).

    Its factorization is the unloaded one (at zero defects the lifted Jacobian is the
    single-shooting one), with the node tangents of a lifted shot there.
    """
    if state.lifted.unloaded is None:
        zero = np.zeros(6)
        nodes = problem.node_states(xs, zero)
        problem.lifted_jacobian(xs, nodes, zero)
        state.lifted.unloaded = (xs, nodes, unloaded(problem, state)[1], problem.node_tangents)
    _, nodes, lu, tangents = state.lifted.unloaded
    return xs, nodes, lu, tangents


def continue_to(problem: Problem, state: PathState, limits: Limits, max_iterations: int,
                wrench: np.ndarray, warm_start: bool, deadline: float, corrector: Corrector,
                cold_corrector: Optional[Corrector] = None) -> Outcome:
    """
    Predictor-corrector continuation from the previous solution (or the unloaded one).

    Each step predicts the solution at a larger wrench to first order with the stored LU
    factorization, dx = -J^-1 (dr/dw) dw (without one, the last solution is the guess),
    and the corrector (Newton, or the paper's Levenberg-Marquardt) refines it. A failed
    step is halved; a step is doubled after one that converged in at most half the
    allowed iterations, but never right after a failure (halving then doubling again
    would retry the step that just failed); a corrector that ran out of iterations within
    NEARLY_CONVERGED of the solution continues instead. A warm start is the same walk,
    usually one step. A cold start from the unloaded state corrects by ``cold_corrector``
    when given (lifted Newton). If it stalls, the outcome is the best state found, its
    residual taken at the requested wrench.
    """
    if not (warm_start and state.previous is not None):
        state.previous, state.lu = unloaded(problem, state)
        state.pose = state.unloaded_pose
        if cold_corrector is not None:
            corrector = cold_corrector
            state.lifted.converged = unloaded_lifted(problem, state, state.previous[0])
    xs, start = state.previous
    lu, pose = state.lu, state.pose
    # the whole step's prediction: sizes the first step, is its guess if whole
    predicted = None if lu is None else extrapolated(problem, state, xs, wrench, lu)
    if predicted is not None:
        whole: Optional[np.ndarray] = xs - predicted
    elif lu is not None:
        whole = problem.wrench_response(lu, wrench - start)
        predicted = xs - whole
    else:
        whole = None
    done, step, iterations = 0.0, first_step(whole), 0
    current = start
    outcome: Optional[Outcome] = None
    grow = 2.0
    while done < 1.0:
        target = min(1.0, done + step)
        goal = start + target * (wrench - start)
        if lu is None:
            guess = xs
        elif predicted is not None and target == 1.0 and done == 0.0:
            guess = predicted
        else:
            guess = xs - problem.wrench_response(lu, goal - current)
        outcome = corrector(guess, goal, deadline, lu, max_iterations, pose)
        iterations += outcome.iterations
        if (not outcome.converged and np.abs(outcome.rs).max() < NEARLY_CONVERGED
                and time.perf_counter() < deadline):
            # out of iterations but inside the basin: keep correcting, don't halve
            outcome = corrector(outcome.xs, goal, deadline, outcome.lu, max_iterations,
                                outcome.pose)
            iterations += outcome.iterations
        if outcome.converged:
            done, xs, current, lu, pose = target, outcome.xs, goal, outcome.lu, outcome.pose
            if outcome.iterations <= max_iterations // 2:
                step *= grow
            grow = 2.0
            continue
        grow = 1.0
        step = 0.5 * (target - done)
        if step < MIN_CONTINUATION_STEP or time.perf_counter() > deadline:
            ended = stalled(problem, limits, xs, outcome, wrench, done, iterations, deadline)
            ended.reached = (xs, current)
            return ended
    state.lu, state.pose = lu, pose
    if outcome is None:  # cannot happen: the loop runs at least once
        raise RuntimeError('continuation made no step')
    outcome.iterations = iterations
    return outcome


def first_step(predicted: Optional[np.ndarray]) -> float:
    """
    Fraction of the wrench change to try first: whole if its linear prediction is small.

    ``predicted`` is the predicted change of the unknowns for the whole step (None without
    a factorization). A first step whose predicted change exceeds PREDICTOR_REACH
    (nondimensional) left the linear regime; trying it anyway cost a failed corrector and a
    halving (cold 12 N: 30 ms with the whole step, 9 ms sized this way).
    """
    if predicted is None:
        return 1.0
    largest = np.abs(predicted).max()
    if largest <= PREDICTOR_REACH:
        return 1.0
    return max(PREDICTOR_REACH / largest, MIN_CONTINUATION_STEP)


def stalled(problem: Problem, limits: Limits, xs: np.ndarray, failed: Outcome,
            wrench: np.ndarray, done: float, iterations: int, deadline: float) -> Outcome:
    """Best of the last converged state and the failed iterate, judged at ``wrench``."""
    candidates = [(candidate, problem.residual(candidate, wrench))
                  for candidate in (xs, failed.xs)]
    best, rs = min(candidates, key=lambda pair: residual_norm(pair[1])
                   if math.isfinite(residual_norm(pair[1])) else math.inf)
    reason = failed.message
    if 'time limit' not in reason and time.perf_counter() > deadline:
        reason = f'time limit of {limits.time_limit_s} s reached after: {reason}'
    return Outcome(best, rs, iterations, False,
                   f'continuation stalled at {done:.1%} of the way to the wrench: {reason}')


def warm_step(problem: Problem, state: PathState, max_iterations: int, settings: np.ndarray,
              wrench: np.ndarray, deadline: float,
              newton: Corrector) -> Tuple[Optional[Outcome], int]:
    """
    Solve the usual warm case in one compiled call (warm_fast_path.py); None if not usual.

    Applies when the previous solution has a stored exact factorization: then the
    prediction (the path's extrapolation, else first order), the chord steps on that
    factorization and the error estimate are one call. When the chord steps stall it
    goes on as ``newton`` would (a fresh Jacobian at the iterate); when that fails too,
    or the prediction reaches too far for one step, it returns None with the iterations
    spent, and ``continue_to`` solves from the previous solution, as it would have
    without this call.
    """
    previous, lu, pose = state.previous, state.lu, state.pose
    handed, state.handed_over = state.handed_over, None
    if previous is None or lu is None or pose is None or pose[0] is None:
        return None, 0
    if handed is not None and np.array_equal(handed[0], wrench):
        step, xs, rs = handed[1:]
    else:
        count = state.path_count if state.path_last is previous[0] else 0
        step, xs, rs = warm_step_kernel(problem, previous,
                                        (state.path_xs, state.path_wrenches, count),
                                        wrench, lu, pose[0], settings)
    if step.status == chord.CONVERGED:
        outcome = Outcome(xs, rs, step.iterations, True, 'converged', lu, pose,
                          estimate=step.estimate, residual_by_kind=step.residual_by_kind)
        outcome.shape = (xs, *problem.recorded_shape(step.slot))
        return outcome, 0
    if step.status == chord.REFACTOR and time.perf_counter() <= deadline:
        with np.errstate(over='ignore', invalid='ignore'):  # rejected trial steps overflow
            outcome = newton(xs, wrench, deadline, None, max_iterations - step.iterations,
                             pose, known=(rs, step.slot))
        if outcome.converged:
            state.lu, state.pose = outcome.lu, outcome.pose
            outcome.iterations += step.iterations
            return outcome, 0
        return None, step.iterations + outcome.iterations
    return None, step.iterations


def warm_settings(state: PathState, tolerance: float, max_iterations: int,
                  judge: bool) -> np.ndarray:
    """Return the settings warm_step takes (made again when one it depends on changes)."""
    key = (tolerance, max_iterations, judge)
    if state.warm_settings_for != key:
        state.warm_settings = warm_step_settings(
            tolerance, max_iterations, CHORD_RATE, EXTRAPOLATION_MISS, PREDICTOR_REACH,
            estimate=judge)
        state.warm_settings_for = key
    return state.warm_settings


def extend_path(state: PathState, xs: np.ndarray, wrench: np.ndarray, chained: bool) -> None:
    """Append a solution to the path of warm solves; without ``chained`` start a new one."""
    count = state.path_count if chained else 0
    if count == chord.PATH_LENGTH:
        state.path_xs[:-1] = state.path_xs[1:]
        state.path_wrenches[:-1] = state.path_wrenches[1:]
        count -= 1
    state.path_xs[count] = xs
    state.path_wrenches[count] = wrench
    state.path_count, state.path_last = count + 1, xs


def extrapolated(problem: Problem, state: PathState, xs: np.ndarray, wrench: np.ndarray,
                 lu: tuple) -> Optional[np.ndarray]:
    """
    Predict the solution at ``wrench`` from the last solutions of a warm sequence, or None.

    Problem.extrapolate (chord.extrapolate) from the path of warm solves when it holds
    three solutions or more and ends at ``xs``; None else or when ``wrench`` does not
    continue the path (its polynomial misses ``wrench`` by more than EXTRAPOLATION_MISS
    of the step).
    """
    if state.path_count < 3 or state.path_last is not xs:
        return None
    return problem.extrapolate(lu, state.path_xs, state.path_wrenches, state.path_count,
                               wrench, EXTRAPOLATION_MISS)


def track(problem: Problem, state: PathState, limits: Limits, stalled_at: Outcome,
          wrench: np.ndarray, deadline: float) -> Outcome:
    """
    Continue a stalled continuation by path_following.track from where it stopped.

    Returns the tracked outcome, converged with an exact factorization (also stored for
    the next solve), or the stalled one with the fallback's failure added to its message.
    """
    assert stalled_at.reached is not None
    xs, start = stalled_at.reached
    tracked = path_following.track(problem, xs, start, wrench, limits.tolerance, deadline)
    iterations = stalled_at.iterations + tracked.iterations
    if not tracked.converged:
        stalled_at.iterations = iterations
        stalled_at.message += (f'; the fallback continuation failed: {tracked.message}'
                               if stalled_at.message else
                               f'the tracking continuation failed: {tracked.message}')
        if residual_norm(tracked.rs) < residual_norm(stalled_at.rs):
            stalled_at.xs, stalled_at.rs = tracked.xs, tracked.rs
        return stalled_at
    message = (f'converged by the fallback continuation ({tracked.steps} steps with a '
               'Hermite predictor on exact tangents)')
    if stalled_at.message:
        message += f' after: {stalled_at.message}'
    elif tracked.floor <= 0.0:
        message = 'converged'  # path='tracking' at the tolerance
    if tracked.floor > 0.0:
        message += (f'; residual {np.abs(tracked.rs).max():.2g} at the rounding floor '
                    f'{tracked.floor:.2g} of the shot, above the tolerance '
                    f'{limits.tolerance:.2g}')
    pose = (tracked.pose, wrench.copy())
    state.lu, state.pose = tracked.lu, pose
    state.exact_at = tracked.xs
    return Outcome(tracked.xs, tracked.rs, iterations, True, message, tracked.lu, pose,
                   tracked=True)


def track_only(problem: Problem, state: PathState, limits: Limits, wrench: np.ndarray,
               warm: bool, deadline: float) -> Outcome:
    """Solve by path_following.track alone: from the previous solution, else unloaded."""
    starts = [state.previous] if warm and state.previous is not None else []
    starts.append(unloaded(problem, state)[0])
    outcome: Optional[Outcome] = None
    iterations = 0
    for xs, start in starts:
        begin = Outcome(xs, problem.residual(xs, wrench), iterations, False, '',
                        reached=(xs, start))
        outcome = track(problem, state, limits, begin, wrench, deadline)
        iterations = outcome.iterations
        if outcome.converged or time.perf_counter() > deadline:
            break
    assert outcome is not None
    return outcome
