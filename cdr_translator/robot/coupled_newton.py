"""
The chain's Newton correction: from a predicted state to a solution for fixed inputs.

Damped by Deuflhard's natural monotonicity test, on chord steps while they contract fast
enough. Coupled (warm solves): the legs' shooting unknowns join the platform's, each
iterate one residual shot per leg, mostly in one compiled call
(kernels.coupled_iterations); nested (from home, and the fallback of a stalled coupled
solve): every iterate solves each leg in full under its wrench.
"""

from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np

from .chain import Chain, ChainState, SIZE
from .kernels import chord_verdict, coupled_iterations, coupled_step, FAR, NO_STEP
from .kernels import REBUILD, within
from .legs import ChainLegs, Deadline
from .linearization import Factorization, factorize

#: Chord steps whose contractions of the Newton correction have a geometric mean above
#: this, or one step contracting by less than SLOW_CHORD, rebuild the factorization (three
#: exact leg Jacobians and the platform LU). Stricter than the leg solver's CHORD_RATE (0.5,
#: on one step's shrink of the residual): along bench.delta_statics' slider circle 0.25 took
#: 4.1 iterations and 0.83 leg Jacobians a warm solve, 0.5 took 5.4 and 0.53, in the same
#: median time (0.57 and 0.60 ms); on warm jumps to random sliders and payloads 25 against
#: 38 iterations a solve.
CHORD_RATE = 0.25
SLOW_CHORD = 0.5

#: Chord steps on one factorization within one Newton correction at most: a correction
#: still not converged after these rebuilds (it converges, but too slowly to finish).
CHORD_LIMIT = 8

#: A slow chord step whose next correction is below this (flat scaled unknowns) rebuilds
#: nothing: so close to the solution (converged at about 1e-8) the contractions are the
#: shots' rounding more than the Jacobian's age (0.5 at 1e-7 along the slider circle), and
#: a rebuild (about 15 iterations' worth) would buy one or two iterations.
CHORD_FLOOR = 1e-6

#: A nested (cold) iterate whose next step is below this (the norm of the scaled platform
#: unknowns' step: m / stack height, rad, wrench / bending force) finishes coupled: so near
#: the solution the legs' shooting is nearly linear, and an iterate costs three shots
#: instead of three leg solves. Not finely tuned: on 16 random cold solves (sliders within
#: 25 mm, payloads within 8 N of 1 kg) 0.1 took 10.1 leg solves and 3.9 leg Jacobians a
#: solve, 0.01 took 11.8 and 3.9, 1.0 took 6.8 and 4.5 (times within the shared machine's
#: noise): handing over earlier trades leg solves for rebuilds.
COUPLE_WITHIN = 0.1


@dataclass(frozen=True)
class Limits:
    """What a Newton correction must reach, and in how many iterations at most."""

    equilibrium_tolerance: float  # N, N m
    position_tolerance: float  # m
    rotation_tolerance: float  # rad
    leg_tolerance: float  # the legs' largest nondimensional shooting residual
    max_iterations: int


@dataclass
class Outcome:
    """Where a Newton correction ended."""

    state: ChainState
    residual: np.ndarray
    iterations: int
    converged: bool
    message: str
    factorization: Optional[Factorization] = None


@dataclass
class CoupledRun:
    """Where ``kernels.coupled_iterations`` stopped, and what ``correct`` carries on with."""

    status: int  # kernels' CONVERGED_AT_TOP, OUT_OF_BUDGET, REBUILD, NO_STEP or FAR
    iterations: int  # iterations it did (a failed line search counts)
    state: ChainState
    residual: np.ndarray
    step: Optional[np.ndarray]  # the pending correction, if any
    fresh: bool
    chord_steps: int
    chord_log: float


def norm(step: np.ndarray, coupled: bool) -> float:
    """Norm of a flat scaled step (the legs' part counts only when ``coupled``)."""
    counted = step if coupled else step[:SIZE]
    return math.sqrt(float(counted @ counted))


class CoupledNewton:
    """Newton corrections of the chain with ``legs``, to the ``limits`` of the solve."""

    def __init__(self, chain: Chain, legs: ChainLegs, limits: Limits) -> None:
        """Correct states of ``chain`` evaluated by ``legs``; ``limits`` may change by solve."""
        self.chain = chain
        self.legs = legs
        self.limits = limits

    def converged(self, residual: np.ndarray, state: ChainState) -> bool:
        """Whether ``state`` with ``residual`` meets the limits' tolerances."""
        limits = self.limits
        return bool(state.leg_error <= limits.leg_tolerance
                    and within(residual, limits.equilibrium_tolerance,
                               limits.position_tolerance, limits.rotation_tolerance))

    def correct(self, state: ChainState, inputs: np.ndarray,
                factorization: Optional[Factorization], coupled: bool) -> Outcome:
        """
        Damped Newton with the natural monotonicity test; given a factorization, chord steps.

        ``coupled``: the unknowns are the platform's and the legs' own shooting unknowns
        together, each iterate one residual shot per leg; the Newton system is reduced to
        the platform's 24 by eliminating each leg's unknowns with its LU (the legs enter
        through their compliances, as in the nested form, plus the twist each leg's own
        Newton correction makes), and every accepted step updates the inverse Jacobian by
        Broyden's good formula (``Secants``, kept with the factorization). Else every
        iterate solves the legs in full.
        A step is judged in the unknowns, not in the residual: the trial point must shrink
        the simplified Newton correction J^-1 r (same factorization) relative to the step
        (Deuflhard's restricted monotonicity test). That needs no weighting of metres
        against newtons, and it accepts the full step of the force-stiff leg axes that a
        residual-norm test rejects far from the solution. The simplified correction of an
        accepted trial is the next step (after its Broyden update). A chord step
        contracting by less than CHORD_RATE, or failing, rebuilds the factorization.
        """
        max_iterations = self.limits.max_iterations
        try:
            evaluated = self.legs.evaluate(state, coupled)
            residual = self.chain.residual(state, inputs) if evaluated else None
        except (Deadline, ArithmeticError) as error:
            return Outcome(state, np.full(SIZE, np.inf), 0, False, str(error), factorization)
        if residual is None:
            return Outcome(state, np.full(SIZE, np.inf), 0, False,
                           'a leg did not converge at the predicted wrenches'
                           if coupled or self.legs.load_controlled(state.wrenches)
                           else 'a leg is compressed past its free-end buckling load, where '
                                'its wrench alone does not fix its shape', factorization)
        fresh, chord_steps, chord_log = False, 0, 0.0
        step: Optional[np.ndarray] = None  # the next correction, once an iteration made it
        far = False  # the compiled iterations left the current one to this loop
        iteration = 1
        while iteration <= max_iterations:
            if self.converged(residual, state):
                return Outcome(state, residual, iteration - 1, True, 'converged',
                               factorization)
            if self.legs.out_of_time():
                return Outcome(state, residual, iteration - 1, False,
                               f'time limit of {self.legs.time_limit_s} s reached',
                               factorization)
            try:
                if factorization is None:
                    factorization = factorize(self.chain, self.legs, state, inputs)
                    fresh, step = True, None
                if coupled and not far:
                    run = self.coupled_iterations(state, residual, step, inputs,
                                                  factorization, fresh, chord_steps,
                                                  chord_log, max_iterations - iteration + 1)
                    state, residual, step = run.state, run.residual, run.step
                    fresh, chord_steps, chord_log = run.fresh, run.chord_steps, run.chord_log
                    iteration += run.iterations
                    if run.status == NO_STEP:
                        return Outcome(state, residual, iteration - 1, False,
                                       'damping found no contracting Newton step',
                                       factorization)
                    if run.status == REBUILD:
                        factorization, step = None, None
                    far = run.status == FAR
                    continue
                far = False
                if step is None:
                    step = self.correction(residual, state.leg_residuals if coupled else None,
                                           factorization, coupled)
                step_size = norm(step, coupled)
                trial = self._line_search(state, step, inputs, factorization, coupled)
            except (Deadline, ArithmeticError) as error:
                return Outcome(state, residual, iteration, False, str(error), factorization)
            if trial is None:
                if fresh:
                    return Outcome(state, residual, iteration, False,
                                   'damping found no contracting Newton step', factorization)
                factorization, step = None, None  # a stale Jacobian pointed the wrong way
                iteration += 1
                continue
            state, residual, contraction, step = trial
            chord_steps, chord_log, rebuild = chord_verdict(
                fresh, contraction, step_size, chord_steps, chord_log, SLOW_CHORD, CHORD_RATE,
                CHORD_FLOOR, CHORD_LIMIT)
            if rebuild:
                factorization, step = None, None  # chord steps converge too slowly
            fresh = False
            if not coupled and step_size * contraction < COUPLE_WITHIN \
                    and not self.converged(residual, state):
                # near the solution the legs' shooting is nearly linear: finish coupled,
                # three shots per iterate instead of three leg solves
                finish = self.correct(state, inputs, factorization, True)
                finish.iterations += iteration
                if finish.converged:
                    return finish
            iteration += 1
        converged = self.converged(residual, state)
        return Outcome(state, residual, max_iterations, converged,
                       'converged' if converged
                       else f'no convergence in {max_iterations} iterations',
                       factorization)

    def coupled_iterations(self, state: ChainState, residual: np.ndarray,
                           step: Optional[np.ndarray], inputs: np.ndarray,
                           factorization: Factorization, fresh: bool, chord_steps: int,
                           chord_log: float, allowed: int) -> CoupledRun:
        """
        Run up to ``allowed`` coupled chord iterations in one compiled call.

        kernels.coupled_iterations does what the loop of ``correct`` does for them (one
        compiled call instead of about 0.1 ms of Python per iteration); the state it
        reaches is a new ChainState (``state`` itself when no trial was accepted).
        """
        if state.frames is None or state.leg_residuals is None:
            raise RuntimeError('the legs have not been shot at this state')
        limits = self.limits
        reached = (state.position.copy(), state.rotation.copy(), state.wrenches.copy(),
                   state.unknowns.copy(), state.frames.copy(), state.leg_residuals.copy(),
                   residual.copy())
        scratch = tuple(np.empty_like(array) for array in reached)
        flat = step.copy() if step is not None else np.empty(SIZE + state.unknowns.size)
        secants = factorization.secants
        (status, iterations, shots, leg_error, secants.count, chord_steps, chord_log,
         has_step, fresh, moved) = coupled_iterations(
            reached, scratch, flat, step is not None, inputs, self.legs.scales,
            self.chain.platform,
            (factorization.factors, factorization.pivots, factorization.twists,
             factorization.gains, factorization.platform_inverse),
            secants.updates, secants.steps, int(secants.count),
            (float(limits.equilibrium_tolerance), float(limits.position_tolerance),
             float(limits.rotation_tolerance), float(limits.leg_tolerance)),
            (SLOW_CHORD, CHORD_RATE, CHORD_FLOOR, CHORD_LIMIT, int(allowed)), bool(fresh),
            int(chord_steps), float(chord_log), float(state.leg_error))
        self.legs.counts['leg_shots'] += shots
        if moved:
            state = ChainState(*reached[:4], frames=reached[4], leg_residuals=reached[5],
                               leg_error=leg_error)
            residual = reached[6]
        return CoupledRun(status, iterations, state, residual, flat if has_step else None,
                          fresh, chord_steps, chord_log)

    def correction(self, residual: np.ndarray, leg_residuals: Optional[np.ndarray],
                   factorization: Factorization, coupled: bool) -> np.ndarray:
        """
        Newton step for the given residuals, flat and scaled (kernels.coupled_step).

        [platform step / x_scale (24); leg steps (3 x n, nondimensional)]. Leg k's unknowns
        move by -J_k^-1 (r_k + dr_k/dw dw_k): its own Newton correction a_k = J_k^-1 r_k,
        which turns its end disk by the twist -T_k a_k, and the response to the wrench
        change. The platform step absorbs those twists into its compatibility residual (the
        twist enters the rotation error through the inverse left Jacobian of SO(3), the
        identity to first order in that small error: a change of the Newton matrix only,
        which leaves the solution where it is). Without ``leg_residuals`` (legs solved in
        full, or the continuation predictor) only the wrench response moves the legs.
        ``coupled``: with the factorization's Broyden updates (``Secants``).
        """
        gains = factorization.gains
        out = np.empty(SIZE + gains.shape[0] * gains.shape[1])
        secants = factorization.secants
        coupled_step(residual,
                     leg_residuals if leg_residuals is not None else self.legs.no_residuals,
                     leg_residuals is not None, self.chain.r_scale, self.chain.x_scale,
                     factorization.factors, factorization.pivots, factorization.twists, gains,
                     factorization.platform_inverse, secants.updates, secants.steps,
                     secants.count if coupled else 0, out)
        return out

    def _line_search(self, state: ChainState, step: np.ndarray, inputs: np.ndarray,
                     factorization: Factorization, coupled: bool
                     ) -> Optional[Tuple[ChainState, np.ndarray, float, Optional[np.ndarray]]]:
        """
        Halve the Newton ``step`` (flat, scaled) until a trial passes the monotonicity test.

        Return (state, residual, contraction ||J^-1 r_trial|| / ||step||, the next step), or
        None. A converged trial is taken at once (contraction 0, no next step); ``coupled``,
        an accepted one updates the inverse Jacobian (``Secants``), which makes the next
        step from its simplified correction.
        """
        size = norm(step, coupled)
        scale = 1.0
        for _ in range(10):
            trial = state.moved(scale * step, self.chain.x_scale)
            if self.legs.evaluate(trial, coupled):
                residual = self.chain.residual(trial, inputs)
                if self.converged(residual, trial):
                    return trial, residual, 0.0, None
                simplified = self.correction(residual, trial.leg_residuals if coupled else None,
                                             factorization, coupled)
                contraction = norm(simplified, coupled) / size
                if contraction < 1.0 - 0.25 * scale:
                    if coupled:  # H y = H r_trial - H r = step - simplified
                        simplified = factorization.secants.add(scale * step, step - simplified,
                                                               simplified)
                    return trial, residual, contraction, simplified
            scale *= 0.5
        return None
