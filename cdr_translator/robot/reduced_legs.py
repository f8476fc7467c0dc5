"""
A DeltaRobot's legs at the reduced levels ('cc', 'rod', or 'auto' over both): its solves.

A warm 'cc' solve runs the coupled Newton (robot/reduced_coupled_kernels.py: the legs' unknowns and
the platform's in one compiled call, Jacobians kept across solves); a cold one, a 'rod'
one, or a warm one that does not converge that way, walks from the previous solution by
damped continuation (ReducedChain.walk, the legs solved in full at every iterate). The
result records each leg's level and its validated error bound (robot/levels.py); 'auto'
takes the first level whose bounds meet the budget. The atlas's compiled loop over
samples is robot/reduced_batch.py.
"""

import time
from typing import Callable, Dict, Optional, Tuple

import numpy as np

from .chain import Chain, SIZE
from .held_leg import HeldReference
from .levels import BoundTable, REDUCED_LEVELS, within_budget
from .reduced_chain import ReducedChain, ReducedOutcome
from .result import DeltaResult
from ..fidelity import Validation
from ..fidelity.reduced import ROD_STEPS
from ..params.translator_params import TranslatorParams


class ReducedLegs:
    """The reduced chains of a robot's level(s), with their validation data; warm-started."""

    def __init__(self, chain: Chain, params: TranslatorParams, fidelity: str,
                 max_position_error: float, max_angle_error: float, max_iterations: int,
                 home_position: np.ndarray) -> None:
        """Chains of the reduced levels ``fidelity`` uses ('auto': those a budget allows)."""
        if fidelity == 'auto':
            levels = REDUCED_LEVELS if max_position_error > 0.0 and max_angle_error > 0.0 \
                else ()
        else:
            levels = (fidelity,) if fidelity != 'full' else ()
        self.fidelity = fidelity
        self.budget = (max_position_error, max_angle_error)
        self.home_position = home_position
        self.chains: Dict[str, ReducedChain] = {
            level: ReducedChain(chain, params, level, max_iterations) for level in levels}
        validation = Validation.load() if self.chains else None
        validation = (validation if validation is not None
                      and validation.matches(params, ROD_STEPS) else None)
        #: each level's validated leg errors (robot/levels.py)
        self.bound_tables = {level: BoundTable(validation, level) for level in self.chains}
        self._last: Optional[Tuple[DeltaResult, ReducedChain, ReducedOutcome, np.ndarray,
                                   np.ndarray]] = None

    def __bool__(self) -> bool:
        """Whether any level is reduced (else the robot's legs are all full)."""
        return bool(self.chains)

    def reset(self) -> None:
        """Forget every chain's previous solution."""
        for chain in self.chains.values():
            chain.reset()

    def solve(self, inputs: np.ndarray, warm_start: bool, tolerances: np.ndarray,
              held: Optional[HeldReference], started: float,
              time_limit_s: float) -> Optional[DeltaResult]:
        """
        Solve with reduced legs; None: 'auto' needs full legs.

        'auto' takes the first level in REDUCED_LEVELS that converges with every leg's
        validated error inside the budget; a level that does not leaves its legs at their
        last solution (the next solve at that level starts there). ``held``: add the
        linearization (compliance, verdicts) against that reference.
        """
        linearized = held is not None
        for level, chain in self.chains.items():
            outcome = chain.coupled(inputs, tolerances, linearized) if warm_start else None
            if outcome is None:
                deadline = started + time_limit_s
                if not (warm_start and chain.previous is not None):
                    chain.reset()
                    chain.previous = (chain.home(self.home_position), np.zeros(12))
                start, origin = chain.previous
                with np.errstate(over='ignore', invalid='ignore'):
                    outcome = chain.walk(start, origin, inputs, tolerances,
                                         lambda: time.perf_counter() > deadline, linearized)
            bounds = self.bound_tables[level].bounds(outcome.state.wrenches).tolist()
            if outcome.converged:
                chain.accept(outcome, inputs)
            if self.fidelity == 'auto' and not (outcome.converged and within_budget(
                    bounds, *self.budget)):
                continue
            result = self._result(level, chain, outcome, inputs, bounds)
            if held is not None and outcome.converged:
                with np.errstate(over='ignore', invalid='ignore'):
                    chain.linearize(result, outcome, inputs, held.critical_load_n)
            result.solve_time_s = time.perf_counter() - started
            self._last = (result, chain, outcome, inputs, tolerances)
            return result
        return None

    def deferred_linearization(self, result: DeltaResult,
                               held: Callable[[], HeldReference]) -> Callable[[], None]:
        """DeltaRobot.deferred_linearization of a solve with reduced legs."""
        last = self._last
        if not result.converged or last is None or last[0] is not result:
            raise RuntimeError('only a converged solve can be linearized later')
        _, chain, outcome, inputs, tolerances = last

        def add() -> None:
            reference = held()
            started = time.perf_counter()
            with np.errstate(over='ignore', invalid='ignore'):
                # a walk from the solution to itself: the legs' compliances and the platform
                # Jacobian made there, as a compliance solve makes them
                there = chain.walk(outcome.state, inputs, inputs, tolerances, lambda: False, True)
                chain.linearize(result, there, inputs, reference.critical_load_n)
            result.solve_time_s += time.perf_counter() - started

        return add

    def _result(self, level: str, chain: ReducedChain, outcome: ReducedOutcome,
                inputs: np.ndarray, bounds: list) -> DeltaResult:
        """Return the DeltaResult of ``outcome`` (its legs' SolveResults built on first read)."""
        residual = outcome.residual if outcome.converged or np.all(
            np.isfinite(outcome.residual)) else np.full(SIZE, np.nan)
        state = outcome.state
        # the state's arrays are the outcome's own; the chain keeps it as the next walk's
        # start, which a walk copies before it moves
        return DeltaResult(
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, sliders=inputs[:3], payload_force=inputs[3:6],
            payload_moment=inputs[6:9], payload_offset=inputs[9:],
            platform_position=state.position, platform_rotation=state.rotation,
            home_position=self.home_position.copy(), leg_results=chain.leg_results(outcome),
            leg_tip_wrenches=state.wrenches, equilibrium_residual=residual[18:],
            compatibility_residual=residual[:18].reshape(3, 6), solve_time_s=0.0,
            leg_solves=0, leg_jacobians=outcome.leg_jacobians, leg_fidelity=(level,) * 3,
            leg_error_bound_m=tuple(bound[0] for bound in bounds),
            leg_error_bound_deg=tuple(bound[1] for bound in bounds))
