"""
The search: Levenberg-Marquardt steps on the estimated wrench components, warm along a stream.

Each step is a forward solve with the exact compliance, within a trust radius in
length-scaled units (moments as the force that makes them at the stack height H); the
radius grows after steps the linearization predicted well and shrinks after steps that do
not lower the cost (Nocedal & Wright, Numerical Optimization, 2006, Ch. 4 and 10.3). A
stable iterate never steps past buckling. ``estimate_along`` runs a search from the
owner's last estimate, restarts once from the prior mean, and searches a moment from a
position alone from several starts.
"""

import math
import time
from typing import Any, Callable, Optional
from weakref import WeakKeyDictionary

import numpy as np

from .problem import (Curvature, estimated_name, Evaluation, Linearization, linearized,
                      Search, Target)
from .verdict import estimate_from
from .wrench_estimate import CONDITION_LIMIT, WrenchEstimate

__all__ = ['BUCKLING_RESOLUTION', 'estimate_along', 'FINISH_CHI2', 'FINISH_MISS',
           'FINISH_REACH', 'LINEAR_FINISH_CHI2', 'LOAD_LIMIT', 'MAX_SOLVES', 'search']

#: Forward solves of one estimate at most (a warm one takes 1-3; a moment from a position
#: alone, which the pose sees poorly, can take 20).
MAX_SOLVES = 40

#: Converged when the Gauss-Newton step lowers the whitened cost by at most this: the step
#: is within a tenth of a posterior standard deviation, which adds a hundredth to the
#: estimate's variance (a warm estimate along a stream then takes one forward solve).
CONVERGED_CHI2 = 1e-2

#: A remaining Gauss-Newton decrease up to this (a step of at most three posterior standard
#: deviations) may be taken from the last forward solve without another one, when the
#: linearization there is shown right over it, in one of two ways:
#:
#: * an accepted step arrived at it within FINISH_GAIN of its predicted decrease (a step of
#:   this search, or for a warm start the step that arrived at it, ``Evaluation.linear``),
#:   and the remaining step is at most one standard deviation (LINEAR_FINISH_CHI2);
#: * the accepted step that arrived at it measured the curvature (``Evaluation.curvature``,
#:   a step of this search, or for a warm start of the same measured pose the step that
#:   arrived at it): the whitened pose it missed by, scaled by the square of the remaining
#:   step's length over that step's (the miss is second order in the step), is at most
#:   FINISH_MISS.
#:
#: Either way the step is short in load (FINISH_REACH). A warm estimate along a noisy
#: stream thus takes one or two forward solves, rarely three, and the same pose again (on
#: a second topic) none.
FINISH_CHI2 = 9.0

#: The remaining decrease up to which a step shown right by its gain (FINISH_GAIN) is
#: taken to first order: a step of one standard deviation, whose second-order error is far
#: below the spread.
LINEAR_FINISH_CHI2 = 1.0

#: The largest miss, in posterior standard deviations, that the measured curvature may
#: predict for a step taken without a forward solve: half the tenth of a standard
#: deviation within which a search's answers agree (along the replay bench's walk the
#: steps so taken landed within 0.073 of the search carried to the end).
FINISH_MISS = 0.05

#: An accepted step whose decrease is within this fraction of the predicted one shows the
#: linearization right over the step.
FINISH_GAIN = 0.05

#: The last Gauss-Newton step taken without a forward solve (FINISH_CHI2) is also no longer
#: than this fraction of the load scale w* (the scaled wrench norm; w* = ``load_limit`` /
#: LOAD_LIMIT, stability.load_scale). Over a step dw the compliance changes by about
#: |dw| / w*, so the pose the step predicts misses by about |dw| / (2 w*) of the step's
#: own effect: a twentieth of a standard deviation at most for a step of one (the bound
#: on a step shown right by its gain, LINEAR_FINISH_CHI2). A standard deviation
#: alone is no bound: along the axial force, which the pose barely sees, one is 15-25 N,
#: near the 29 N buckling load, and such steps taken to first order lowered the coverage
#: of estimates from afar (0.1 mm / 0.05 deg, force: 87 % of 200 trials against 90.5 %
#: searched to the end; 91 % with this bound).
FINISH_REACH = 0.1

#: Held values (scaled norm, N) that moved at most this since the last estimate move its
#: solution to them to first order, instead of a forward solve there.
HELD_SHIFT_N = 1.0

#: A rejected step from a point whose Gauss-Newton decrease is below this has hit the
#: forward solve's rounding (1e-12 m against EXACT_POSE_SD_M): converged.
ROUNDING_CHI2 = 1.0

#: A step toward the pose that crossed buckling (a stable iterate, an unstable trial) and
#: moved the whitened fit by at most this many posterior standard deviations (its length
#: in the metric of the posterior) has located the buckling load as finely as the pose
#: tells loads apart: the best stable match lies there, and bisecting further costs a
#: forward solve past buckling each (which seeks a stable branch from the unloaded state,
#: 0.3-1 s), to place a boundary the estimate cannot resolve.
BUCKLING_RESOLUTION = 1.0

#: Trust radius after an estimate's first (damped) step, at least, and at most: scaled
#: wrench norm (N).
TRUST_RADIUS_N = 1.0

MAX_TRUST_RADIUS_N = 400.0

#: A trust radius this small relative to the wrench (scaled norm, at least 1 N) means no
#: nearby wrench lowers the cost.
STEP_TOLERANCE = 1e-10

#: Two matches further apart than this (relative, scaled wrench norm, at least 1 N) are
#: different wrenches: the forward solves converge to 1e-10, the matches to about 1e-9.
MATCH_DISTANCE = 1e-6

#: Wrenches beyond this many times the translator's load scale w* (stability.load_scale:
#: 31.4 N for the shipped one, the axial buckling load 29.3 N) are not tried: a pose that
#: only such a load could match is reported as unmatched, not solved at kilonewtons.
LOAD_LIMIT = 20.0

#: Each solver's (or robot's) last converged iterate: the next estimate's first linearization.
_STARTS: 'WeakKeyDictionary[Any, Evaluation]' = WeakKeyDictionary()


def search(evaluate: Callable[[np.ndarray], Optional[Evaluation]],
           start: Optional[Evaluation], target: Target, deadline: float,
           begin: Optional[np.ndarray] = None, solves: int = MAX_SOLVES) -> Search:
    """
    Minimize the whitened cost over the estimated components from ``start``.

    Without ``start`` (or one at other held values) from ``begin``, else from the prior
    mean. ``evaluate`` solves the forward model at a wrench (None when that solve fails);
    at most ``solves`` of them.
    """
    found = Search(None, False, '')
    free, fixed, scale = target.free_index, target.held_index, target.scale
    warm = start is not None
    shifted = False  # the start is a solved one moved to the held values to first order
    if start is not None and not _holds(start, target):
        change = np.zeros(6)
        change[fixed] = target.given[fixed] - start.wrench[fixed]
        if start.stable is True and float(np.linalg.norm(change / scale)) <= HELD_SHIFT_N:
            # held values that moved a little along a stream: the step is taken from the
            # start moved to them, so that its first forward solve is already the answer's
            start, shifted = start.moved(change), True
            start.wrench[fixed] = target.given[fixed]  # exactly, not to rounding
    if start is None or not _holds(start, target):
        wrench = target.given.copy()
        wrench[free] = target.weights.mean
        origin = start.wrench if start is not None else begin
        if origin is not None:
            wrench[free] = origin[free]
        start = evaluate(wrench)
        found.solves += 1
        if start is None:
            found.message = 'the forward solve at the starting wrench did not converge'
            return found
    # a warm start's linearization was shown right, or its curvature measured, by the step
    # that arrived at it
    current, radius, verified = start, None, warm and start.linear and not shifted
    bent = start.curvature if warm and not shifted else None
    linear = linearized(target, current)
    if not shifted:
        found.best, found.linearization = current, linear
    while True:
        cost = linear.cost
        derivative = linear.derivative
        left, values, right = derivative.left, derivative.values, derivative.right
        projected = left.T @ linear.residual
        decrease = float(projected @ projected)
        if shifted:
            pass  # a start moved to first order is no answer: step from it and solve
        elif decrease <= CONVERGED_CHI2:
            found.converged, found.message = True, 'converged'
            return found
        elif ((verified or bent is not None) and decrease <= FINISH_CHI2
              and current.stable is True):
            finish = _trust_region_step(values, right, projected, math.inf)
            size = float(np.linalg.norm(finish))
            miss = None if bent is None else bent.scaled_miss(target, size)
            if size <= FINISH_REACH * target.load_limit / LOAD_LIMIT and (
                    (verified and decrease <= LINEAR_FINISH_CHI2)
                    or (miss is not None and miss <= FINISH_MISS)):
                found.finish = np.zeros(6)
                found.finish[free] = scale[free] * finish
                found.converged = True
                found.message = ('converged (the last Gauss-Newton step from the last '
                                 'forward solve)')
                return found
        if radius is None:
            # the first radius from the damped step: the Gauss-Newton one is mostly the
            # poorly observed directions (the axial force), where the linearization from
            # far away is least trusted. A warm start takes the Gauss-Newton step when it
            # fits (along a stream it does: one forward solve per estimate); a cold one the
            # damped step.
            damped = _trust_region_step(values, right, projected, None)
            radius = max(2.0 * float(np.linalg.norm(damped)), TRUST_RADIUS_N)
            step = _trust_region_step(values, right, projected, radius) if warm else damped
        else:
            step = _trust_region_step(values, right, projected, radius)
        floor = STEP_TOLERANCE * max(float(np.linalg.norm(current.wrench / scale)), 1.0)
        if found.solves >= solves or time.perf_counter() > deadline:
            found.message = (f'no match after {found.solves} forward solves'
                             if found.solves >= solves else 'time limit reached')
            return found
        found.iterations += 1
        wrench = current.wrench.copy()
        wrench[free] += scale[free] * step
        beyond = _past_limits(wrench, target)
        trial = None if beyond else evaluate(wrench)
        found.solves += 0 if beyond else 1
        predicted = cost - float(np.sum((linear.residual + derivative.jacobian @ step) ** 2))
        if shifted and (trial is None or trial.stable is not True):
            # the step from the moved start failed: search from its wrench as from afar
            restart = search(evaluate, None, target, deadline, begin=current.wrench,
                             solves=solves - found.solves)
            restart.iterations += found.iterations
            restart.solves += found.solves
            return restart
        if trial is not None and not (trial.stable is False and current.stable is not False):
            # a stable iterate never steps past buckling: the structure rests on a stable
            # equilibrium, and the unstable side only leads the iteration to kilonewtons
            trial_linear = linearized(target, trial)
            trial_cost = trial_linear.cost
            if trial_cost < cost or shifted:   # the first solved point after a shift
                gain = (cost - trial_cost) / predicted if predicted > 0.0 else 0.0
                if gain > 0.75 and float(np.linalg.norm(step)) >= 0.99 * radius:
                    radius = min(2.0 * radius, MAX_TRUST_RADIUS_N)
                elif gain < 0.25:
                    radius = 0.5 * float(np.linalg.norm(step))
                verified = trial.linear = abs(gain - 1.0) <= FINISH_GAIN
                bent = trial.curvature = None if shifted else _curvature(
                    target, current, linear, trial_linear, step)
                current, linear, shifted = trial, trial_linear, False
                found.best, found.linearization = current, linear
                continue
        if float(projected @ projected) <= ROUNDING_CHI2:
            found.converged = True
            found.message = 'converged (to the rounding of the forward solve)'
            return found
        if (trial is not None and trial.stable is False and current.stable is not False
                and float(np.linalg.norm(values * (right @ step))) <= BUCKLING_RESOLUTION):
            found.message = ('no stable equilibrium matches the measured pose: the best '
                             'stable match lies at the buckling load (a step toward the pose '
                             'within one posterior standard deviation buckles the translator)')
            return found
        radius = 0.25 * float(np.linalg.norm(step))
        if radius <= floor:
            found.message = ('no nearby wrench lowers the pose residual: no equilibrium '
                             'matches the measured pose' + (f' within {beyond}' if beyond
                                                            else ''))
            return found


def _curvature(target: Target, current: Evaluation, linear: Linearization,
               trial: Linearization, step: np.ndarray) -> Optional[Curvature]:
    """Return what ``step`` (scaled) from ``current`` to ``trial`` measured of the curvature."""
    length = math.sqrt(float(step @ step))
    if length == 0.0:
        return None
    free = target.free_index
    predicted = current.compliance[target.block] @ (target.scale[free] * step)
    return Curvature(target.frame, target.rows, trial.error - linear.error - predicted, length)


def _past_limits(wrench: np.ndarray, target: Target) -> str:
    """Name the limit of ``target`` that ``wrench`` is past ('' when within all of them)."""
    values = wrench.tolist()
    if math.hypot(*values[:3]) > target.force_limit:
        return f'|f| <= {target.force_limit:.4g} N (max_force)'
    if math.hypot(*values[3:]) > target.moment_limit:
        return f'|m| <= {target.moment_limit:.4g} N m (max_moment)'
    if float(np.linalg.norm(wrench / target.scale)) > target.load_limit:
        return f'the load limit ({target.load_limit:.4g} N, scaled)'
    return ''


def _holds(evaluation: Evaluation, target: Target) -> bool:
    """Return True when ``evaluation`` is exactly at ``target``'s held values."""
    held = target.held_index
    return not held.size or bool(np.all(evaluation.wrench[held] == target.given[held]))


def _trust_region_step(values: np.ndarray, right: np.ndarray, projected: np.ndarray,
                       radius: Optional[float]) -> np.ndarray:
    """
    Return the Levenberg-Marquardt step within ``radius``.

    Minimizes |r + J step|^2 + lambda |step|^2 (scaled units; J = U diag(values) V^T and
    ``projected`` = U^T r) with the smallest lambda >= 0 that keeps the step within the
    radius: the Gauss-Newton step when it fits, else the step on the radius
    (``_boundary_damping``). On the radius, not inside it: the radius grows only after a
    step that reached it, and a step held inside would hold the radius too, so that a
    search along a valley of the cost (the axial force against the lateral one) would
    creep in steps of one length, a forward solve each. Without a radius (an estimate's
    first step) lambda is (values_max / CONDITION_LIMIT)^2: the poorly observable
    directions (the axial force) barely move until the others fit, since there the pose
    error is mostly the others' second-order effect (the end disk drops as it swings
    sideways) that a first-order model reads as axial load.
    """
    weights = values * projected
    if radius is None:
        return -right.T @ (weights / (values ** 2 + (values[0] / CONDITION_LIMIT) ** 2))
    squares = values ** 2
    newton = weights / squares
    size = math.sqrt(float(newton @ newton))
    if size <= radius or not math.isfinite(size):
        return -right.T @ newton
    return -right.T @ (weights / (squares + _boundary_damping(weights, squares, radius)))


#: The step's length on the radius, relative, at which _boundary_damping stops.
BOUNDARY_TOLERANCE = 1e-10

#: Newton iterations of _boundary_damping at most (it takes 1-6, rarely 10).
BOUNDARY_ITERATIONS = 50


def _boundary_damping(weights: np.ndarray, squares: np.ndarray, radius: float) -> float:
    """
    Return lambda > 0 with |p(lambda)| = ``radius``, p_i = weights_i / (squares_i + lambda).

    Newton's method on the secular equation 1/|p(lambda)| = 1/radius (Nocedal & Wright,
    Algorithm 4.3, on the SVD: |p|^2 = sum w_i^2 / (s_i^2 + lambda)^2 and the derivative
    from |q|^2 = sum w_i^2 / (s_i^2 + lambda)^3). 1/|p| is concave and increasing in
    lambda, so from a lambda left of the root (|p| > radius) each iterate stays left of
    it and approaches it quadratically. The start |weights| / radius - s_max^2 is left of
    it (|p(lambda)| >= |weights| / (s_max^2 + lambda)), which saves the iterations from
    lambda = 0 when the radius is far inside the Gauss-Newton step. Every s_i > 0 (the
    prior term): no hard case.
    """
    damping = max(math.sqrt(float(weights @ weights)) / radius - float(squares[0]), 0.0)
    for _ in range(BOUNDARY_ITERATIONS):
        shifted = squares + damping
        step = weights / shifted
        square = float(step @ step)
        size = math.sqrt(square)
        if size - radius <= BOUNDARY_TOLERANCE * radius:
            break
        damping += (square / float(step @ (step / shifted))) * (size - radius) / radius
    return damping


def _other_match(evaluate: Callable[[np.ndarray], Optional[Evaluation]], found: Search,
                 target: Target, deadline: float) -> Optional[np.ndarray]:
    """Search from the other starts of a moment (estimate_along); return a second match."""
    assert found.best is not None and found.best.compliance is not None
    scale, (rows, free) = target.scale, target.block
    block = scale[rows] * found.best.compliance[rows, free] * scale[free]
    least = np.zeros(6)
    least[target.free_index] = np.linalg.svd(block)[2][-1] * scale[target.free_index]
    reach = 0.1 * target.load_limit / LOAD_LIMIT  # a tenth of w* (scaled N)
    match = found.best.wrench
    for begin in (target.given, match + reach * least, match - reach * least):
        if time.perf_counter() > deadline:
            break
        other = search(evaluate, None, target, deadline, begin)
        found.iterations += other.iterations
        found.solves += other.solves
        if other.converged and other.best is not None and np.linalg.norm(
                (other.best.wrench - match) / scale) > MATCH_DISTANCE * max(
                float(np.linalg.norm(match / scale)), 1.0):
            return other.best.wrench.copy()
    return None


def estimate_along(owner: Any, evaluate: Callable[[np.ndarray], Optional[Evaluation]],
                   target: Target, started: float, deadline: float, warm: bool,
                   reset: Callable[[], None]) -> WrenchEstimate:
    """
    Search from ``owner``'s last estimate when ``warm`` (else cold), and build the estimate.

    A warm search that fails is repeated once from the prior mean after ``reset`` (the
    previous estimate may sit past buckling or far away), within ``deadline`` and the rest
    of MAX_SOLVES; a converged one is the next warm start. A moment from a position alone
    is searched again from no moment and from the match moved either way along its least
    observable direction (by a tenth of the load scale w*): a position sees the moment
    only through the couplings of the compliance, and several moments put the end disk at
    the same point; a second match found is ``alternative``.
    """
    start = _STARTS.get(owner) if warm else None
    found = search(evaluate, start, target, deadline)
    if (not found.converged and start is not None and time.perf_counter() < deadline
            and found.solves < MAX_SOLVES):
        reset()
        restart = search(evaluate, None, target, deadline, solves=MAX_SOLVES - found.solves)
        restart.iterations += found.iterations
        restart.solves += found.solves
        restart.message += ' (after a restart from the prior mean)'
        found = restart
    if (found.converged and found.best is not None and estimated_name(target) == 'moment'
            and len(target.rows) == 3):
        found.alternative = _other_match(evaluate, found, target, deadline)
    if found.converged and found.best is not None:
        _STARTS[owner] = found.best
    else:
        _STARTS.pop(owner, None)
    return estimate_from(found, target, started)
