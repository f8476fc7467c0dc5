"""
Stability verdict of a converged solve, and stable-branch following past a bifurcation.

``judge`` gives the verdict (stability.py) from the factorization the solve ended with,
redone on an exact Jacobian when that one is stale or the verdict is close;
``follow_stable_branch`` perturbs an unstable solution along its critical mode and
re-converges (Riks' way). The cached verdict and the unloaded reference live in a
``Verdicts``, owned by the solver and passed in.
"""

from dataclasses import dataclass
from typing import Callable, Optional, Tuple

import numpy as np

from .continuation import PathState, unloaded
from .correctors import Outcome
from .result import SolveResult
from .. import _linalg
from ..analysis import stability
from ..bvp.problem import Problem

#: A factorization made at a wrench further than this (relative to |w|, SI components)
#: from the solved one is not trusted for the stability verdict.
STALE_WRENCH = 0.2

#: Smallest load (a fraction of stability.load_scale, w*) that a wrench's drift since its
#: factorization is measured against for the stability verdict: at w* / 2 a drift within half
#: the margin (the rule) moves the margin by at most about a quarter of it near no load.
#: Measuring against |w| alone, a translator at rest under 0.05 N of sensor noise rebuilt the
#: exact Jacobian on every solve (1.73 ms median; 0.56 ms at a 5 N offset).
LOAD_FLOOR = 0.5

#: Perturb-and-reconverge attempts past a bifurcation (a symmetric structure may first
#: land on a saddle branch, e.g. buckled along x when the stable one is diagonal).
BRANCH_ATTEMPTS = 3

#: Size of the critical-mode imperfection that steers past a bifurcation, relative to the
#: wrench (stability margin < 0): large enough to leave the unstable branch's basin.
IMPERFECTION = 0.02


@dataclass
class Verdicts:
    """The unloaded reference (made once) and the last verdict with its factorization."""

    origin: Optional[stability.Reference] = None
    verdict: Optional[stability.Stability] = None
    verdict_lu: Optional[tuple] = None


def origin(problem: Problem, state: PathState, verdicts: Verdicts) -> stability.Reference:
    """Return the unloaded state's stiffness and det J sign (stability.py), made once."""
    if verdicts.origin is None:
        (xs, zero), lu = unloaded(problem, state)
        pose = state.unloaded_pose[0] if state.unloaded_pose is not None else None
        if pose is None:  # jacobian='fd': the tangent shot gives the pose derivative
            pose = problem.exact_jacobian(xs, zero)[2]
        _, frames = problem.shape(xs, zero)
        verdicts.origin = stability.reference(lu, pose, frames[3][:3, :3],
                                              problem.wrench_sensitivity,
                                              problem.params.stack_height)
    return verdicts.origin


def judge(problem: Problem, state: PathState, verdicts: Verdicts, outcome: Outcome,
          wrench: np.ndarray, rotation: Optional[np.ndarray] = None) -> stability.Stability:
    """
    Verdict at a converged outcome from the factorization its iteration ended with.

    That factorization may be from an earlier iterate or solve (chord steps); when it was
    made at a wrench further (relative to |w|, or to LOAD_FLOOR of the load scale when
    |w| is smaller; sizes by stability.wrench_size) than STALE_WRENCH or half the margin
    it gives, or the verdict is unstable or its margin below CLOSE_BRANCH_MARGIN, the verdict is
    redone on an exact Jacobian at the solution itself, which then also becomes the
    stored factorization.
    """
    lu = outcome.lu
    pose, lu_wrench = outcome.pose if outcome.pose is not None else (None, None)
    if rotation is None:
        rotation = problem.residual_and_end_frame(outcome.xs, wrench)[1][:3, :3]
    reference = origin(problem, state, verdicts)
    if lu is not None and pose is not None and lu_wrench is not None:
        if verdicts.verdict_lu is lu and verdicts.verdict is not None:
            verdict = verdicts.verdict  # chord steps keep a factorization over many solves
        else:
            verdict = stability.assess(lu, pose, rotation, problem.wrench_sensitivity,
                                       reference)
            verdicts.verdict_lu, verdicts.verdict = lu, verdict
        # the margin moves about as fast as the load, relative to the load: a verdict
        # from a factorization made at a wrench more than half the margin away (or
        # STALE_WRENCH) could already be on the other side of zero. Near no load it
        # moves by about |dw| / w* (stability.load_scale): measured against a load of
        # at least LOAD_FLOOR w*, sensor noise around zero keeps the verdict
        length = reference.length
        drift = stability.wrench_size(wrench - lu_wrench, length) / max(
            stability.wrench_size(wrench, length), LOAD_FLOOR * stability.load_scale(reference))
        if verdict.stable and verdict.margin >= stability.CLOSE_BRANCH_MARGIN and \
                drift <= min(STALE_WRENCH, 0.5 * verdict.margin):
            return verdict
    _, jac, pose = problem.exact_jacobian(outcome.xs, wrench)
    lu = _linalg.factorize(jac)
    outcome.lu, outcome.pose = lu, (pose.copy(), wrench.copy())
    outcome.estimate = None  # made on the stale factorization: redone on this one
    state.lu, state.pose = outcome.lu, outcome.pose
    state.exact_at = outcome.xs
    return stability.assess(lu, pose, rotation, problem.wrench_sensitivity, reference)


def follow_stable_branch(state: PathState, length: float,
                         solve_from: Callable[[np.ndarray, bool, float], Outcome],
                         judged: Callable[[Outcome, np.ndarray], stability.Stability],
                         outcome: Outcome, verdict: stability.Stability, wrench: np.ndarray,
                         deadline: float) -> Tuple[Outcome, stability.Stability]:
    """
    Past a bifurcation: perturb along the critical mode and re-converge (Riks' way).

    The wrench is given an imperfection along the critical mode (IMPERFECTION of the
    wrench's size, stability.critical_wrench; ``length`` the stack height), solved from
    the unloaded state by ``solve_from(wrench, warm_start, deadline)``, which follows the
    imperfect, stable path; the imperfection is then removed by a warm continuation that
    stays on the branch it reached, each judged by ``judged``. Returns the new outcome
    when it converged stably, else the original one with its verdict.
    """
    saved = (state.previous, state.lu, state.pose)
    size = np.linalg.norm(wrench[:3]) + np.linalg.norm(wrench[3:]) / length
    current_verdict = verdict
    iterations = outcome.iterations
    direction = np.zeros(6)
    for attempt in range(BRANCH_ATTEMPTS):
        # a later attempt adds the critical mode of the unstable branch it reached to
        # the earlier imperfection (x-buckled saddle + its y mode: the diagonal)
        direction = direction + stability.critical_wrench(current_verdict, length)
        direction /= np.linalg.norm(direction[:3]) + np.linalg.norm(direction[3:]) / length
        perturbed = wrench + IMPERFECTION * size * direction
        first = solve_from(perturbed, False, deadline)
        iterations += first.iterations
        if not first.converged:
            break
        judged(first, perturbed)  # the exact factorization there: a stale one's
        # predictor led the way back to the unstable branch
        state.previous = (first.xs, perturbed)
        second = solve_from(wrench, True, deadline)
        iterations += second.iterations
        if not second.converged:
            break
        new_verdict = judged(second, wrench)
        if new_verdict.stable:
            state.previous = (second.xs, wrench)
            second.iterations = iterations
            second.message = ('converged on the stable branch: the first solution was '
                              f'unstable (margin {verdict.margin:.3g}); perturbed along '
                              f'the critical mode and re-converged ({attempt + 1} '
                              'perturbation(s))')
            return second, new_verdict
        current_verdict = new_verdict
    state.previous, state.lu, state.pose = saved
    return outcome, verdict


def apply_verdict(result: SolveResult, verdict: stability.Stability) -> None:
    """Set the result's stability verdict and margin; an unstable one joins the message."""
    result.stable = verdict.stable
    result.stability_margin = verdict.margin
    if not verdict.stable:
        result.message += f'; {verdict.message}'
