"""
Accuracy of a converged solve: its error estimate, and refinement until the target is met.

docs/explanation/solution_quality.md.

A solve whose estimate (accuracy.py) misses the target is re-solved at more steps per
segment, each re-solve warm-started from the previous one: ``refine`` is that policy (the
steps, when to stop, the message), the re-solves a callable. The engine (engine.py) owns
the refined solvers and the steps a warm sequence keeps.
"""

import math
import time
from typing import Callable, Optional, Tuple

import numpy as np

from .correctors import Outcome
from .result import FRAME_NAMES, SolveResult
from ..analysis.accuracy import ErrorEstimate, estimate as estimate_error, MAX_GROWTH, meets
from ..analysis.accuracy import refined_steps
from ..bvp.problem import Problem
from ..params.translator_params import Accuracy, MAX_REFINED_STEPS

#: Refined re-solves at most. Each aims at the target from the error's law, but the steps
#: grow at most MAX_GROWTH times per re-solve: from 8 steps a result that needs about 1000
#: (the 200 N out, 400 N down hard case) takes five of them.
MAX_REFINEMENTS = 8

#: Order of the rods' integrator (RK4): the error falls as N^-4 in the asymptotic range.
RK4_ORDER = 4.0


#: One refined solve: (steps per segment, from the unloaded state?, time limit in s) -> its
#: result and, when it converged, its error estimate.
Attempt = Callable[[int, bool, float], Tuple[SolveResult, Optional[ErrorEstimate]]]


def estimate_at(problem: Problem, outcome: Outcome, result: SolveResult,
                wrench: np.ndarray) -> ErrorEstimate:
    """Estimate the error of a converged outcome (accuracy.estimate)."""
    pose = outcome.pose[0] if outcome.pose is not None else None
    frames = (outcome.shape[2] if outcome.shape is not None and outcome.shape[0] is outcome.xs
              else np.stack([result.frames[name] for name in FRAME_NAMES]))
    return estimate_error(problem, outcome.xs, wrench, outcome.rs, frames, outcome.lu, pose)


def set_estimate(result: SolveResult, estimate: ErrorEstimate, target: Accuracy) -> None:
    """Set the result's discretization-error estimate and whether it meets ``target``."""
    result.error_estimate_m = estimate.position_m
    result.error_estimate_deg = estimate.angle_deg
    result.accuracy_met = meets(estimate, target.position_m, target.angle_deg)


def accuracy_shortfall(result: SolveResult) -> str:
    """Return the message tail of a result whose error estimate misses the accuracy target."""
    return (f'; accuracy target not met: estimated error {result.error_estimate_m:.2g} m, '
            f'{result.error_estimate_deg:.2g} deg at {result.steps_per_segment} steps per '
            'segment')


def refine(result: SolveResult, estimate: ErrorEstimate, target: Accuracy, deadline: float,
           time_limit_s: float, attempt: Attempt, tracked: bool = False) -> Optional[SolveResult]:
    """
    Re-solve with more steps per segment until the accuracy ``target`` is met.

    ``result`` (with its ``estimate``) is the solve to refine; ``attempt(steps, cold,
    time_limit_s)`` solves again at ``steps`` steps per segment, warm from the last
    converged solve (the unknowns mean the same at any discretization, and the Jacobians
    differ by the discretization error: its chord steps converge) or, with ``cold``, from
    the unloaded state. A result the fallback continuation found (``tracked``) is refined
    by that continuation alone, cold while the estimates are not yet falling with the
    steps (a coarse solution of so sensitive a shot is no warm start for a finer grid),
    then from the last refined solution. The steps follow ``next_steps``; each refined
    solve gets the time left before ``deadline`` (of a solve limited to ``time_limit_s``),
    and the message says why refinement stopped short of the target. Returns the last
    converged refined result (its message says whether the target was met), or None when
    no refinement converged.
    """
    refined = None
    coarser: Optional[ErrorEstimate] = None
    cold = tracked
    stop = ''
    for _ in range(MAX_REFINEMENTS):
        steps = next_steps(coarser if tracked else None, estimate, target)
        remaining = deadline - time.perf_counter()
        if steps <= estimate.steps:
            break
        if remaining <= 0.0:
            stop = (f'; the time limit of {time_limit_s} s was reached before the '
                    f'refinement to {steps} steps per segment')
            break
        tried, finer = attempt(steps, cold, remaining)
        if not tried.converged:
            stop = (f'; the refinement to {steps} steps per segment did not converge: '
                    f'{tried.message}')
            break
        refined = tried
        assert finer is not None
        coarser, estimate = estimate, finer
        cold = cold and not _error_ratio(estimate, target) < _error_ratio(coarser, target)
        refined.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
        if refined.accuracy_met:
            break
    else:
        stop = f'; refinement stopped after {MAX_REFINEMENTS} re-solves (MAX_REFINEMENTS)'
    if refined is None:
        if stop:
            result.message += stop
        return None
    refined.iterations += result.iterations
    extra = '' if refined.message == 'converged' else f' ({refined.message})'
    refined.message = result.message + extra
    refined.message += (f'; refined to {refined.steps_per_segment} steps per segment '
                        f'(estimated error at {result.steps_per_segment}: '
                        f'{result.error_estimate_m:.2g} m, '
                        f'{result.error_estimate_deg:.2g} deg)')
    if not refined.accuracy_met:
        refined.message += accuracy_shortfall(refined) + stop
    return refined


def _error_ratio(estimate: ErrorEstimate, target: Accuracy) -> float:
    """Return the larger of estimate / target over both kinds (0 when both are off)."""
    ratio = 0.0
    if target.position_m > 0.0:
        ratio = max(ratio, estimate.position_m / target.position_m)
    if target.angle_deg > 0.0:
        ratio = max(ratio, estimate.angle_deg / target.angle_deg)
    return ratio


def next_steps(coarser: Optional[ErrorEstimate], current: ErrorEstimate,
               target: Accuracy) -> int:
    """
    Return the steps per segment of the next refinement (at most MAX_REFINED_STEPS).

    accuracy.refined_steps' N^-4 law (RK4's order, 25 % margin, at most MAX_GROWTH times
    the steps), with the order the last two estimates show instead when they fall more
    slowly than N^-4 (still above the asymptotic range): their ratio over the ratio of
    the steps, at least 1. ``refine`` passes ``coarser`` for the fallback's states only:
    elsewhere the estimates at 8 steps are already asymptotic, and accuracy.kept_steps'
    hysteresis counts on the N^-4 law's margin.
    """
    steps = refined_steps(current, target.position_m, target.angle_deg, MAX_REFINED_STEPS)
    if coarser is None or steps <= current.steps:
        return steps
    before, now = _error_ratio(coarser, target), _error_ratio(current, target)
    if not 0.0 < now < before < math.inf:
        return steps
    order = max(1.0, math.log(before / now) / math.log(current.steps / coarser.steps))
    if order >= RK4_ORDER:
        return steps
    wanted = min(MAX_GROWTH, 1.25 * now ** (1.0 / order))
    return min(MAX_REFINED_STEPS, max(steps, math.ceil(wanted * current.steps)))
