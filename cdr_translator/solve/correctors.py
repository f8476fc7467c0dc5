"""
The correctors of one continuation step: Newton, Levenberg-Marquardt, lifted Newton.

Each takes nondimensional unknowns ``xs`` near the solution at ``wrench`` and iterates on
the shooting residual until its largest entry is within the tolerance (the paper's
tolerances for Levenberg-Marquardt), the iterations run out, or the deadline passes; each
returns an ``Outcome`` saying where it ended and why.
"""

from dataclasses import dataclass, field
import math
import time
from typing import NamedTuple, Optional, Tuple

import numpy as np

from . import multiple_shooting
from .result import FRAME_NAMES, PAPER_TOLERANCES, SolveResult
from .. import _linalg
from .._linalg import residual_norm
from ..analysis.accuracy import ErrorEstimate
from ..bvp import chord
from ..bvp.problem import Problem, RESIDUAL_KINDS

#: A chord step that shrinks the residual by less than this rebuilds the Jacobian. A rebuild
#: (Jacobian, LU, stability verdict) costs about as much as a dozen Newton-Broyden steps: on
#: the node bench's 100 Hz sweep (0.19 N steps) 0.25 rebuilt 0.54 times per solve (p50
#: 1.3 ms), 0.5 0.15 times (p50 0.7 ms); at 1 kHz steps and along bench.speed_vs_error's
#: sequence the two are within noise of each other (fewer rebuilds, one more step).
CHORD_RATE = 0.5

#: (derivative of the end-disk frame, or None with jacobian='fd'; the wrench it was made at)
Pose = Tuple[Optional[np.ndarray], np.ndarray]

#: A lifted Newton state: unknowns, their nodes (SI), a factorization made on the way (or
#: None) and the node tangents of the same lifted shot (or None).
LiftedState = Tuple[np.ndarray, np.ndarray, Optional[tuple], Optional[np.ndarray]]


class Limits(NamedTuple):
    """What ends a corrector: the residual tolerance, and the time limit its message names."""

    tolerance: float
    time_limit_s: float


@dataclass
class Outcome:
    """Where an iteration ended: nondimensional unknowns and residual, and why."""

    xs: np.ndarray
    rs: np.ndarray
    iterations: int
    converged: bool
    message: str
    lu: Optional[tuple] = None
    #: the end-disk frame derivative and wrench at the point ``lu`` factorizes
    pose: Optional[Pose] = None
    #: (unknowns, wrench) of the last converged state of a stalled continuation
    reached: Optional[Tuple[np.ndarray, np.ndarray]] = None
    #: (the unknowns it belongs to, centre lines, frames) recorded by the last shot, if any
    shape: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None
    #: the error estimate and largest residuals by kind, when the iteration made them
    #: (warm_fast_path.py); None: computed from the rest
    estimate: Optional[ErrorEstimate] = None
    residual_by_kind: Optional[dict] = None
    #: whether the fallback continuation (path_following.track) found it
    tracked: bool = False

    def result(self, problem: Problem, wrench: np.ndarray, method: str) -> SolveResult:
        """Return the SolveResult of this outcome (its shape shot again if not recorded)."""
        if self.shape is not None and self.shape[0] is self.xs:
            points, frames = self.shape[1:]
        else:
            points, frames = problem.shape(self.xs, wrench)
        return SolveResult(
            converged=self.converged, message=self.message, iterations=self.iterations,
            residual_norm=residual_norm(self.rs),
            residual_by_type=(self.residual_by_kind if self.residual_by_kind is not None
                              else problem.residual_by_kind(self.rs)),
            force=wrench[:3].copy(), moment=wrench[3:].copy(),
            frames=dict(zip(FRAME_NAMES, frames)),  # views of a copy no one else keeps
            backbones=points, solve_time_s=0.0, method=method,
            unknowns=self.xs * problem.x_scale,
            steps_per_segment=problem.params.steps_per_segment)


@dataclass
class LiftedNodes:
    """
    Lifted states kept between lifted corrections (a few MB each at 9 spacer disks).

    ``converged``: of the last converged lifted correction; ``last``: of the last one at
    all; ``unloaded``: of the unloaded solution.
    """

    converged: Optional[LiftedState] = None
    last: Optional[LiftedState] = None
    unloaded: Optional[LiftedState] = field(default=None)


def newton(problem: Problem, limits: Limits, xs: np.ndarray, wrench: np.ndarray,
           deadline: float, lu: Optional[tuple], max_iterations: int,
           pose_in: Optional[Pose] = None,
           known: Optional[Tuple[np.ndarray, int]] = None) -> Outcome:
    """
    Damped Newton; given ``lu`` it starts with chord steps on that factorization.

    The iterations run compiled (chord.chord_iterations: backtracking line search, a
    chord step that shrinks the residual by less than CHORD_RATE discards the
    factorization); Python only refactors, between those calls, and checks the deadline.
    Given ``lu`` (a warm solve's usual case) the residual at ``xs`` is the first shot of
    the first compiled call. ``known`` = (residual at ``xs``, the slot of the problem's
    shape buffers that holds its shape), when a call before this one shot there.
    """
    xs = np.array(xs, dtype=float)
    shoot = lu is not None and known is None and time.perf_counter() <= deadline
    slot = 0
    if shoot:
        rs, norm = np.empty(problem.size), math.nan  # chord_newton's first shot sets both
    elif known is not None:
        rs, slot = known[0].copy(), known[1]
        norm = residual_norm(rs)
    else:
        rs = problem.residual_and_shape(xs, wrench)
        norm = residual_norm(rs)
    done, fresh, pose = 0, False, pose_in

    def ended(converged: bool, message: str) -> Outcome:
        outcome = Outcome(xs, rs, done, converged, message, lu, pose)
        outcome.shape = (xs, *problem.recorded_shape(slot))
        return outcome

    while True:
        if not shoot:
            if not math.isfinite(norm):
                return ended(False, 'residual became non-finite during the iteration')
            if np.abs(rs).max() <= limits.tolerance:
                return ended(True, 'converged')
            if done >= max_iterations:
                return ended(False, f'no convergence in {max_iterations} iterations')
            if time.perf_counter() > deadline:
                return ended(False, f'time limit of {limits.time_limit_s} s reached')
        if lu is None:
            # a singular J shows as a non-finite step
            lu = _linalg.factorize(problem.jacobian(xs, wrench, rs))
            pose = (problem.pose_jacobian, wrench.copy())
            fresh = True
        status, used, norm, slot = problem.chord_newton(
            xs, rs, wrench, lu, fresh, limits.tolerance, max_iterations - done, CHORD_RATE,
            slot, shoot)
        done += used
        fresh, shoot = False, False
        if status == chord.CONVERGED:  # the largest |residual| is within the tolerance
            return ended(True, 'converged')
        if status == chord.REFACTOR:
            lu = None
        elif status == chord.NO_DECREASE:
            return ended(False, 'line search found no decrease of the residual')
        elif status == chord.SINGULAR:
            return ended(False, 'Newton step is not finite (singular or non-finite '
                                'Jacobian)')


def levenberg_marquardt(problem: Problem, limits: Limits, xs: np.ndarray, wrench: np.ndarray,
                        deadline: float, max_iterations: int) -> Outcome:
    """
    Eq. (13) with a one-residual-per-column Jacobian, to the paper's tolerances.

    The paper's method keeps no factorization between solves: none is taken or returned.
    """
    tolerances = np.array([PAPER_TOLERANCES[kind] for kind in RESIDUAL_KINDS])
    rs = problem.residual(xs, wrench)
    damping = 1e-3
    for iteration in range(1, max_iterations + 1):
        if np.all(np.array(list(problem.residual_by_kind(rs).values())) <= tolerances):
            return Outcome(xs, rs, iteration - 1, True, "converged to the paper's tolerances")
        if time.perf_counter() > deadline:
            return Outcome(xs, rs, iteration - 1, False,
                           f'time limit of {limits.time_limit_s} s reached')
        jac = problem.jacobian(xs, wrench, rs)
        normal = jac.T @ jac
        gradient = jac.T @ rs
        while True:
            step = -np.linalg.solve(normal + damping * np.eye(problem.size), gradient)
            trial_rs = problem.residual(xs + step, wrench)
            if residual_norm(trial_rs) < residual_norm(rs):
                xs, rs = xs + step, trial_rs
                damping = max(damping / 10.0, 1e-12)
                break
            damping *= 10.0
            if damping > 1e12:
                return Outcome(xs, rs, iteration, False, 'Levenberg-Marquardt damping diverged')
    return Outcome(xs, rs, max_iterations, False,
                   f'no convergence in {max_iterations} iterations')


def lifted_newton(problem: Problem, limits: Limits, kept: LiftedNodes, xs: np.ndarray,
                  wrench: np.ndarray, deadline: float, lu: Optional[tuple],
                  max_iterations: int, pose_in: Optional[Pose] = None) -> Outcome:
    """
    Multiple shooting by lifted Newton (multiple_shooting.py) from ``xs`` and nodes to go with it.

    The nodes are those of a lifted correction that ended at ``xs``; else, if ``xs`` is
    a prediction made with the factorization ``lu`` of the last converged correction,
    that correction's nodes moved by the same first-order prediction (its node
    tangents); else the states single shooting carries at ``xs``. ``lu`` and
    ``pose_in`` are returned when no iteration was needed. ``kept`` is updated.
    """
    tangents = None  # those of ``lu``, when known
    for state in (kept.last, kept.converged):
        if state is not None and state[0] is xs:
            nodes = state[1]
            break
    else:
        state = kept.converged
        if state is not None and lu is not None and state[2] is lu and state[3] is not None:
            nodes = problem.advance_nodes(state[1], xs - state[0], 0.0, state[3])
        else:
            nodes = problem.node_states(xs, wrench)
    if state is not None and lu is not None and state[2] is lu:
        tangents = state[3]
    done = multiple_shooting.newton(problem, xs, nodes, wrench, limits.tolerance,
                                    max_iterations, deadline)
    kept.last = ((done.xs, done.nodes, done.lu, done.tangents) if done.lu is not None
                 else (done.xs, done.nodes, lu, tangents))
    if done.converged:
        kept.converged = kept.last
    if done.lu is None:
        return Outcome(done.xs, done.rs, done.iterations, done.converged, done.message,
                       lu, pose_in)
    return Outcome(done.xs, done.rs, done.iterations, done.converged, done.message,
                   done.lu, (done.pose, wrench.copy()))
