"""
The chain's three legs as its Newton evaluates them: shots, full solves, results, budget.

A coupled iterate shoots each leg once at its own unknowns; a nested one solves each leg
in full under its wrench (warm-started). ``ChainLegs`` also keeps a solve's work counts
and time limit, which every leg evaluation charges and checks.
"""

import functools
import math
import time
from typing import Dict, List, Optional, Protocol, Sequence, Tuple

import numpy as np

from .chain import ChainState
from .held_leg import euler_critical_load
from .kernels import leg_frames, shoot_legs
from .result import DeltaResult, LegResults
from ..geometry import bending_between
from ..params.translator_params import Accuracy, TranslatorParams
from ..solve.result import SolveResult
from ..solve.solver import TranslatorSolver

#: The work counters of a solve (DeltaResult fields of the same names).
COUNTS = ('leg_solves', 'leg_shots', 'leg_jacobians')

#: A nested iterate solves each leg under its end-disk wrench alone (load control). Past
#: the leg's free-end buckling load (held_leg.euler_critical_load, 29.6 N for the shipped
#: translator) that wrench no longer fixes the leg's shape: strongly bent shapes carry it
#: too, a leg solve walking the wrench there lands on one of them (55-66 deg of bending,
#: where the chain's legs bend 9 deg), and the chain's Newton on the wrenches stalls. Legs
#: compressed beyond this fraction of that load are therefore never solved nested; the
#: continuation goes on coupled (robot/continuation.py), where the legs' unknowns iterate
#: with the platform's and each leg is held at both ends, well posed up to the held buckling
#: load (37 times higher). Cold solves under 1 kg stay far below it.
NESTED_COMPRESSION = 0.8


class LegFactors(Protocol):
    """A leg's linearization at a state as TranslatorSolver.result_at takes it."""

    @property
    def lu(self) -> tuple:
        """Return the LU factorization of the leg's shooting Jacobian (nondimensional)."""

    @property
    def pose(self) -> np.ndarray:
        """Return d(end-disk frame)/d(unknowns), (12, n)."""

    @property
    def wrench(self) -> np.ndarray:
        """Return the wrench it was made at."""


class ChainFactors(Protocol):
    """The three legs' linearizations at a state (robot.linearization.Factorization)."""

    @property
    def legs(self) -> Sequence[LegFactors]:
        """Return one per leg, in order."""


class Deadline(Exception):
    """The time limit passed during a leg solve."""


class ChainLegs:
    """The three leg solvers, a solve's work counts and deadline, and where legs restart."""

    def __init__(self, params: TranslatorParams, time_limit_s: float) -> None:
        """Three leg solvers for ``params``; no solve under way."""
        # a leg is one link of the closed chain: its discretization stays fixed across the
        # robot's Newton iterations (no automatic refinement) and its equilibrium is not
        # judged alone (a leg's stability under a dead tip load is not the chain's)
        # the leg solves of the nested iteration converge, nothing more (judge=False): only
        # the legs of the result are judged, when read (results)
        self.solvers = tuple(TranslatorSolver(params, time_limit_s=time_limit_s,
                                              accuracy=Accuracy(0.0, 0.0),
                                              follow_stable_branch=False, judge=False)
                             for _ in range(3))
        #: the largest nondimensional leg residual a converged chain may leave
        self.tolerance = min(solver.tolerance for solver in self.solvers)
        problem = self.solvers[0].problem
        #: the compiled shots' leg arguments (kernels.shoot_legs, coupled_iterations)
        self.scales = (problem.x_scale, problem.residual_scale, problem.model_args)
        #: leg residuals of none (a correction moving the legs by their wrench response only)
        self.no_residuals = np.zeros((3, problem.size))
        self.counts: Dict[str, int] = dict.fromkeys(COUNTS, 0)
        self.deadline = math.inf
        self.time_limit_s = time_limit_s
        #: start_at arguments of each leg solver, applied before the next full leg solve
        self.starts: Optional[Tuple[tuple, ...]] = None
        #: the largest compression (N) a leg is solved under in a nested iterate
        self.nested_compression_n = NESTED_COMPRESSION * euler_critical_load(params)

    def begin(self, started: float, time_limit_s: float) -> None:
        """Start a solve at ``started`` (time.perf_counter) with a fresh count and deadline."""
        self.time_limit_s = time_limit_s
        self.deadline = started + time_limit_s
        self.counts = dict.fromkeys(COUNTS, 0)

    def out_of_time(self) -> bool:
        """Whether the solve's deadline has passed."""
        return time.perf_counter() > self.deadline

    def reset(self) -> None:
        """Forget every leg's warm start."""
        self.starts = None
        for solver in self.solvers:
            solver.reset()

    def count_into(self, result: DeltaResult) -> None:
        """Copy the solve's work counts into ``result``."""
        result.leg_solves = self.counts['leg_solves']
        result.leg_shots = self.counts['leg_shots']
        result.leg_jacobians = self.counts['leg_jacobians']

    def home_state(self, position: np.ndarray) -> ChainState:
        """Straight legs, no load, platform at ``position``: the solution for q = 0, no payload."""
        state = ChainState(position.copy(), np.eye(3), np.zeros((3, 6)),
                           np.zeros((3, self.solvers[0].problem.size)))
        self.store(state, [solver.solve(np.zeros(3)) for solver in self.solvers])
        self.counts['leg_solves'] += 3
        return state

    def evaluate(self, state: ChainState, coupled: bool) -> bool:
        """
        Give ``state`` its legs' end-disk frames; False if a leg cannot be evaluated there.

        ``coupled``: one residual shot per leg at the state's leg unknowns. Else each leg
        is solved under its wrench (warm-started), its unknowns replaced by the solution;
        False, none solved, when a leg is compressed past ``nested_compression_n``.
        """
        if not coupled:
            if not self.load_controlled(state.wrenches):
                return False
            legs = [self._solve(k, state.wrenches[k]) for k in range(3)]
            self.store(state, legs)
            return all(leg.converged for leg in legs)
        residuals = np.empty_like(state.unknowns)
        frames = np.empty((3, 4, 4))
        state.leg_error = shoot_legs(state.unknowns, state.wrenches, *self.scales,
                                     residuals, frames)
        self.counts['leg_shots'] += 3
        state.leg_residuals, state.frames = residuals, frames
        return math.isfinite(state.leg_error)

    def load_controlled(self, wrenches: np.ndarray) -> bool:
        """Whether every leg's wrench (3, 6; {pe_i}) leaves it for a nested solve."""
        return bool(np.all(-wrenches[:, 2] <= self.nested_compression_n))

    def store(self, state: ChainState, legs: List[SolveResult]) -> None:
        """Set ``state``'s leg unknowns, frames and residual size from solved legs."""
        state.legs = legs
        state.frames = np.stack([leg.frames['de'] for leg in legs])
        state.unknowns = np.stack([leg.unknowns / solver.problem.x_scale
                                   for leg, solver in zip(legs, self.solvers)])
        state.leg_residuals = None
        # a converged leg met its solver's tolerance on the largest residual component
        state.leg_error = 0.0 if all(leg.converged for leg in legs) else math.inf

    def _solve(self, k: int, wrench: np.ndarray) -> SolveResult:
        remaining = self.deadline - time.perf_counter()
        if remaining <= 0.0:
            raise Deadline(f'time limit of {self.time_limit_s} s reached')
        if self.starts is not None:  # the last coupled solution: each leg starts there
            for solver, start in zip(self.solvers, self.starts):
                solver.start_at(*start)
            self.starts = None
        self.counts['leg_solves'] += 1
        return self.solvers[k].solve(wrench[:3], wrench[3:], time_limit_s=remaining)

    def results(self, state: ChainState,
                factorization: Optional[ChainFactors]) -> Sequence[SolveResult]:
        """
        Return the legs' SolveResults at ``state`` (shape, stability, error estimate).

        A LegResults builds each on first access from the state's leg unknowns
        (TranslatorSolver.result_at: one shot and the verdicts, what a leg solve started
        there gives): with the leg's factorization after a coupled iteration, with an exact
        Jacobian there after a nested one (whose leg solves are not judged). After a
        coupled iteration the next full leg solve (nested iteration) starts each leg there
        (TranslatorSolver.start_at).
        """
        coupled = state.legs is None
        starts = []
        for k in range(3):
            leg = factorization.legs[k] if factorization is not None and coupled else None
            starts.append((state.unknowns[k].copy(), state.wrenches[k].copy(),
                           None if leg is None else (leg.lu, leg.pose, leg.wrench)))
        if coupled:
            self.starts = tuple(starts)
        return LegResults((functools.partial(solver.result_at, *start)
                           for solver, start in zip(self.solvers, starts)),
                          functools.partial(self.bending, state.unknowns.copy(),
                                            state.wrenches.copy()))

    def bending(self, unknowns: np.ndarray, wrenches: np.ndarray) -> np.ndarray:
        """(3, 2): the legs' PJ and DJ bending angles at ``unknowns`` under ``wrenches``."""
        frames = np.empty((3, 4, 4, 4))
        leg_frames(unknowns, wrenches, self.scales[0], self.scales[2], frames)
        return np.array([[bending_between(leg[0], leg[1])[0], bending_between(leg[2], leg[3])[0]]
                         for leg in frames])
