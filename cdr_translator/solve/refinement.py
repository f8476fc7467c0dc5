"""
Accuracy of a converged solve: its error estimate, and refinement until the target is met.

docs/explanation/solution_quality.md.

A solve whose estimate (accuracy.py) misses the target is re-solved by solvers of the same
structure at more steps per segment, each warm-started from the previous one (``refine``);
a warm sequence then keeps the refined steps (``solve_kept``). The refined solvers and the
kept steps are a ``Refinements``, owned by the solver.
"""

from dataclasses import dataclass, field
import math
import time
from typing import Dict, Optional, TYPE_CHECKING

import numpy as np

from .branch import STALE_WRENCH
from .correctors import Outcome
from .result import FRAME_NAMES, SolveResult
from ..analysis.accuracy import (ErrorEstimate, estimate as estimate_error, kept_steps, MAX_GROWTH,
                                 meets)
from ..analysis.accuracy import refined_steps
from ..bvp.problem import Problem
from ..params.translator_params import Accuracy, MAX_REFINED_STEPS

if TYPE_CHECKING:
    from .solver import TranslatorSolver

#: Refined re-solves at most. Each aims at the target from the error's law, but the steps
#: grow at most MAX_GROWTH times per re-solve: from 8 steps a result that needs about 1000
#: (the 200 N out, 400 N down hard case) takes five of them.
MAX_REFINEMENTS = 8

#: Order of the rods' integrator (RK4): the error falls as N^-4 in the asymptotic range.
RK4_ORDER = 4.0


@dataclass
class Refinements:
    """
    The solvers at other steps per segment and what the next warm solve starts at.

    ``solvers`` are the owner's solvers at other steps per segment; ``kept`` is the
    steps per segment the next warm solve starts at (a key of ``solvers``), kept from the
    refinement of an earlier one, None: the owner's own; ``last_estimate`` the estimate
    of the owner's last judged solve.
    """

    solvers: Dict[int, 'TranslatorSolver'] = field(default_factory=dict)
    kept: Optional[int] = None
    last_estimate: Optional[ErrorEstimate] = None

    def solver(self, owner: 'TranslatorSolver', steps: int) -> 'TranslatorSolver':
        """Return ``owner``'s solver at ``steps`` steps per segment, without a target."""
        made = self.solvers.get(steps)
        if made is None:
            made = self.solvers[steps] = type(owner)(
                owner.params.with_changes(steps_per_segment=steps), tolerance=owner.tolerance,
                max_iterations=owner.max_iterations, jacobian=owner.jacobian,
                accuracy=Accuracy(0.0, 0.0), follow_stable_branch=owner.follow_stable_branch)
        return made


def take_over(solver: 'TranslatorSolver', source: 'TranslatorSolver') -> None:
    """
    Warm-start ``solver``'s next solve from ``source``'s last solution and factorization.

    ``source`` solves the same structure at other steps per segment: the unknowns mean
    the same, and its factorization (the Jacobian differs by the discretization error)
    serves the chord steps and the stability verdict as a stale one would.
    """
    state, other = solver._state, source._state
    state.previous, state.lu, state.pose = other.previous, other.lu, other.pose
    solver._refinements.kept = None


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


def refine(owner: 'TranslatorSolver', result: SolveResult, estimate: ErrorEstimate,
           source: 'TranslatorSolver', wrench: np.ndarray, deadline: float,
           compliance: bool, verify: bool, compliance_options: dict,
           tracked: bool = False) -> Optional[SolveResult]:
    """
    Re-solve with more steps per segment until ``owner``'s accuracy target is met.

    ``result`` (with its ``estimate``) is the solve of ``source`` (``owner``, or a
    refined solver of a kept solve). Each refined solve starts from the previous one's
    solution and factorization (the unknowns mean the same at any discretization, and
    the Jacobians differ by the discretization error: its chord steps converge). A result
    the fallback continuation found (``tracked``) is refined by that continuation alone
    (path='tracking'), from the unloaded state while the estimates are not yet falling
    with the steps (a coarse solution of so sensitive a shot is no warm start for a finer
    grid), then from the last refined solution. The steps follow ``next_steps``; each
    refined solve gets the time left, and the message says why refinement stopped short
    of the target. Returns the last converged refined result (its message says whether
    the target was met), or None when no refinement converged; the next warm solve starts
    at its steps.
    """
    refinements = owner._refinements
    refined = None
    target = owner.accuracy
    coarser: Optional[ErrorEstimate] = None
    cold = tracked
    stop = ''
    for _ in range(MAX_REFINEMENTS):
        steps = next_steps(coarser if tracked else None, estimate, target)
        remaining = deadline - time.perf_counter()
        if steps <= estimate.steps:
            break
        if remaining <= 0.0:
            stop = (f'; the time limit of {owner.time_limit_s} s was reached before the '
                    f'refinement to {steps} steps per segment')
            break
        solver = refinements.solver(owner, steps)
        solver.time_limit_s = remaining
        take_over(solver, source)
        solver.path = 'tracking' if tracked else 'default'
        try:
            attempt = solver.solve(wrench[:3], wrench[3:], warm_start=not cold,
                                   compliance=compliance, verify=verify, **compliance_options)
        finally:
            solver.path = 'default'
        if not attempt.converged:
            stop = (f'; the refinement to {steps} steps per segment did not converge: '
                    f'{attempt.message}')
            break
        refined = attempt
        source = solver
        assert solver._refinements.last_estimate is not None
        coarser, estimate = estimate, solver._refinements.last_estimate
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
    refinements.kept = refined.steps_per_segment
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


def solve_kept(owner: 'TranslatorSolver', wrench: np.ndarray, started: float,
               compliance: bool, verify: bool,
               compliance_options: dict) -> Optional[SolveResult]:
    """
    Warm solve at the steps per segment kept from an earlier refinement.

    A warm sequence that needed refinement usually needs it again: solving at the kept
    steps directly skips ``owner``'s own solve and the refined one after it. The solve is
    judged at those steps: refined further when its estimate misses the target
    (``refine``), and the next solve steps down (accuracy.kept_steps) when it has room.
    Returns None, forgetting the kept steps, when that solve did not converge or the
    wrench moved by more than STALE_WRENCH (relative) since the last one (a long
    continuation, cheaper at the owner's steps): the owner then solves as usual, from
    the last solution.
    """
    refinements = owner._refinements
    steps = refinements.kept
    assert steps is not None
    solver = refinements.solvers[steps]
    refinements.kept = None
    previous = solver._state.previous
    if previous is None or float(np.linalg.norm(wrench - previous[1])) > \
            STALE_WRENCH * float(np.linalg.norm(wrench)):
        return None  # not a warm sequence: a long continuation is cheaper at fewer steps
    solver.time_limit_s = owner.time_limit_s
    attempt = solver.solve(wrench[:3], wrench[3:], compliance=compliance, verify=verify,
                           **compliance_options)
    if not attempt.converged:
        return None
    estimate = solver._refinements.last_estimate
    assert solver._state.previous is not None and estimate is not None
    owner._state.previous = solver._state.previous
    refinements.last_estimate = estimate
    target = owner.accuracy
    attempt.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
    extra = '' if attempt.message == 'converged' else f' ({attempt.message})'
    attempt.message = (f'converged{extra} at {steps} steps per segment, kept from the '
                       'refinement of an earlier solve')
    result = attempt
    if not attempt.accuracy_met:
        refined = refine(owner, attempt, estimate, solver, wrench,
                         started + owner.time_limit_s, compliance, verify, compliance_options)
        if refined is not None:
            result = refined
        else:
            refinements.kept = steps
            result.message += accuracy_shortfall(result)
    else:
        fewer = kept_steps(estimate, target.position_m, target.angle_deg,
                           owner.params.steps_per_segment)
        if fewer == steps:
            refinements.kept = steps
        elif fewer > owner.params.steps_per_segment:
            refinements.kept = fewer
            take_over(refinements.solver(owner, fewer), solver)
        else:
            take_over(owner, solver)
    result.solve_time_s = time.perf_counter() - started
    return result
