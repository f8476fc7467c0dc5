"""
The chain's continuation: from the previous solution to the requested sliders and payload.

Predictor-corrector, as the leg solver walks one translator along its load: each step
predicts the solution (to first order with the stored factorization, by extrapolating a
steadily followed path, or, along equal input steps from solutions linearized exactly, from
the tangents and curvatures of the solves before: robot/grid_predictor.py) and the coupled
Newton corrects it; a failed step is halved, a good one doubled. ``ChainContinuation`` keeps
the path state between solves: the previous solution, the last factorization and the last
solves' steps.
"""

from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import numpy as np

from .chain import ChainState, difference
from .coupled_newton import CoupledNewton, Outcome
from .grid_predictor import GridPredictor
from .linearization import Factorization
from ..solve.continuation import MIN_CONTINUATION_STEP

#: Largest change of the scaled unknowns (platform and legs) a continuation step of the
#: coupled Newton may predict; a step predicting more is shortened. Ten times the leg
#: solver's PREDICTOR_REACH, which bounds one leg's nondimensional unknowns alone: with 0.3
#: warm jumps to random sliders and payloads took 67 iterations and 37 leg Jacobians a
#: solve against 25 and 20 (twice the time); the slider circle's solves were the same.
PREDICTOR_REACH = 3.0

#: The polynomial predictor (extrapolate) is used when the input change it does not
#: extrapolate makes at most this fraction of the residual change of the whole.
EXTRAPOLATE_WITHIN = 0.5

#: Highest degree of the polynomial predictor: the last PREDICTOR_DEGREE solves' steps.
#: Along bench.delta_statics' slider circle (interleaved in one process) degree 3 took
#: 3.96 iterations per warm solve against 4.91 for the quadratic; degree 4 took 5.62: the
#: solves converge to about 1e-8, and its weights (sum 15, against 7) amplify that.
PREDICTOR_DEGREE = 3

#: A solve whose input change makes at most this fraction of the residual change of the
#: path's last step refines that step's end rather than starting a step (``_recorded``).
REFINEMENT = 0.01


@dataclass
class PathStep:
    """One converged coupled solve: from ``start`` to ``end`` for an input change."""

    start: ChainState
    end: ChainState
    inputs_change: np.ndarray  # du (12)
    step: np.ndarray  # end - start, flat and scaled (chain.difference)


class ChainContinuation:
    """Walks the chain to new inputs with ``newton``, warm-started by the solves before."""

    def __init__(self, newton: CoupledNewton) -> None:
        """Continue with ``newton``'s chain and legs; no previous solution yet."""
        self.newton = newton
        #: the last converged solution and its inputs, where the next walk starts
        self.previous: Optional[Tuple[ChainState, np.ndarray]] = None
        #: the last factorization, which the next walk predicts and iterates with
        self.factorization: Optional[Factorization] = None
        #: the last (up to PREDICTOR_DEGREE) coupled solves' steps, latest last
        #: (extrapolate); emptied by a solve that is not one
        self.path: List[PathStep] = []
        #: the tangents of the solves that started at an exact factorization
        self.grid = GridPredictor(newton.chain.x_scale)

    def reset(self) -> None:
        """Forget the previous solution, its factorization and the path."""
        self.previous = None
        self.factorization = None
        self.path = []
        self.grid.reset()

    def walk(self, inputs: np.ndarray, coupled: bool) -> Outcome:
        """
        Walk from the previous solution to ``inputs`` (sliders, payload).

        Each step predicts the solution to first order with the stored factorization,
        dx = -J^-1 (dr/du) du (coupled, a whole step along a steadily followed path: to
        higher order, ``extrapolate``), and Newton corrects it (``coupled``: leg unknowns
        and platform together; else every iterate's legs solved in full); a failed step is
        halved, a good one doubled. A step the nested iterates fail is taken again coupled,
        and so is the rest of the walk: past a leg's free-end buckling load a nested
        iterate is ill posed (legs.NESTED_COMPRESSION), a coupled one is not.
        """
        if self.previous is None:
            raise RuntimeError('continuation needs a previous solution')
        newton = self.newton
        chain = newton.chain
        state, start = self.previous
        factorization = self.factorization
        if factorization is not None:
            factorization.secants.count = 0  # a solve's Broyden updates are its own
        done, step, iterations = 0.0, 1.0, 0
        coupling = coupled  # the iterates' kind: nested ones hand over when they fail
        current = start
        outcome: Optional[Outcome] = None
        first = chain.input_sensitivity(state, start)
        while done < 1.0:
            target = min(1.0, done + step)
            goal = start + target * (inputs - start)
            guess, along_grid = state, False
            if factorization is not None:
                sensitivity = first if done == 0.0 else chain.input_sensitivity(state, current)
                change = sensitivity @ (goal - current)
                predicted = None
                if coupled and target == 1.0 and done == 0.0:
                    if factorization.state is state:  # exact there: its tangent is kept
                        predicted = self.grid.predict(
                            state, start, inputs - start,
                            newton.correction(change, None, factorization, True))
                    along_grid = predicted is not None
                    if not along_grid:
                        predicted = self.extrapolate(state, inputs - start, first,
                                                     factorization)
                if predicted is None:
                    predicted = newton.correction(change, None, factorization, coupling)
                reach = float(np.abs(predicted).max())
                if coupling and reach > PREDICTOR_REACH and not along_grid:
                    # beyond the linear regime of the legs' shooting: a shorter step
                    fraction = max(PREDICTOR_REACH / reach,
                                   MIN_CONTINUATION_STEP / (target - done))
                    target = done + fraction * (target - done)
                    goal = start + target * (inputs - start)
                    predicted = fraction * newton.correction(change, None, factorization,
                                                             coupling)
                guess = state.moved(predicted, chain.x_scale)
            # along the grid the legs' Jacobians at the last solution are too far off for
            # chord steps (at 12 mm steps the first contracted by 0.4, then a rebuild; at
            # 20 mm it failed its line search, thirty leg shots): made at the guess at once
            outcome = newton.correct(guess, goal, None if along_grid else factorization,
                                     coupling)
            iterations += outcome.iterations
            if outcome.converged:
                done, state, current = target, outcome.state, goal
                factorization = outcome.factorization
                step *= 2.0
                continue
            if not coupling and not newton.legs.out_of_time():
                # the same step coupled, from the last solution: a leg compressed past its
                # free-end buckling load has no nested iterate (or a leg solve failed)
                coupling = True
                continue
            step = 0.5 * (target - done)
            if step < MIN_CONTINUATION_STEP or newton.legs.out_of_time():
                self.grid.abandon()
                if not outcome.state.leg_error <= newton.limits.leg_tolerance:
                    outcome.state = state  # the last solution every leg converged at
                    outcome.factorization = factorization
                outcome.residual = chain.residual(outcome.state, inputs)
                outcome.iterations = iterations
                outcome.message = (f'continuation stalled at {done:.1%} of the way to the '
                                   f'sliders and payload: {outcome.message}')
                return outcome
        self.factorization = factorization
        if outcome is None:  # cannot happen: the loop runs at least once
            raise RuntimeError('continuation made no step')
        if coupled and outcome.converged:  # this solve's step, for the next ones' predictor
            self.path = self._recorded(outcome.state, inputs - start, first)
            self.grid.reached(outcome.state)
        else:
            self.path = []
        outcome.iterations = iterations
        return outcome

    def _recorded(self, end: ChainState, inputs_change: np.ndarray,
                  sensitivity: np.ndarray) -> List[PathStep]:
        """
        Return the path with the solve from ``self.previous`` to ``end`` added, latest last.

        ``sensitivity``: the residual's input sensitivity at ``self.previous``.

        A refinement (an input change within REFINEMENT of the last step's, in the residual
        change it makes: the inverse statics' corrections after its predicted sliders) joins
        that step: the path keeps the points of a steadily followed path, which the
        predictor extrapolates, instead of a short step that no polynomial fits.
        """
        if self.previous is None:
            raise RuntimeError('a path step needs a previous solution')
        chain = self.newton.chain
        start = self.previous[0]
        path = self.path
        if path and path[-1].end is start:
            last = path[-1]
            size = np.linalg.norm(sensitivity @ inputs_change / chain.r_scale)
            if size <= REFINEMENT * np.linalg.norm(sensitivity @ last.inputs_change
                                                   / chain.r_scale):
                merged = PathStep(last.start, end, last.inputs_change + inputs_change,
                                  difference(end, last.start, chain.x_scale))
                return [*path[:-1], merged]
        record = PathStep(start, end, inputs_change, difference(end, start, chain.x_scale))
        return [*path[1 - PREDICTOR_DEGREE:], record]

    def extrapolate(self, state: ChainState, inputs_change: np.ndarray,
                    sensitivity: np.ndarray, factorization: Factorization
                    ) -> Optional[np.ndarray]:
        """
        Polynomial predictor (flat, scaled) along a path followed at a steady rate.

        With the last m solves' steps s_k, s_(k-1), ... (consecutive, coupled) the solution
        extrapolated by the polynomial of degree m through them is x_k + sum_j w_j s_(k-j),
        at inputs u_k + sum_j w_j du_(k-j), with the backward-difference weights
        w_j = (-1)^j C(m, j + 1) (m = 2: x_k + 2 s_k - s_(k-1)); the rest of the input
        change is predicted to first order. The degree, 2 to PREDICTOR_DEGREE, is the one
        whose inputs leave the smallest rest (the highest among equals): along a smooth
        path the highest, where the inputs scatter a lower one. The first-order
        predictor's error is the path's curvature and the stored Jacobian's age; this one's
        is of order m + 1 along the path. None (the first-order predictor is used) when
        there are no two such steps, or the inputs do not follow them: the rest's residual
        change is more than EXTRAPOLATE_WITHIN of the whole input change's.
        """
        path = self.path
        r_scale = self.newton.chain.r_scale
        chained = 0  # steps of the path that end, one after the other, at ``state``
        end = state
        for record in reversed(path):
            if record.end is not end:
                break
            chained, end = chained + 1, record.start
        if chained < 2:
            return None
        smallest, chosen = math.inf, (0.0, [0], np.zeros(0))
        for degree in range(2, min(chained, PREDICTOR_DEGREE) + 1):
            weights = [(-1) ** j * math.comb(degree, j + 1) for j in range(degree)]
            rest = sensitivity @ (inputs_change - sum(
                weight * path[-1 - j].inputs_change for j, weight in enumerate(weights)))
            size = float(np.linalg.norm(rest / r_scale))
            if size <= smallest * (1.0 + 1e-9):  # equal within rounding: the higher degree
                chosen = (size, weights, rest)
            smallest = min(smallest, size)
        size, weights, rest = chosen
        whole = sensitivity @ inputs_change
        if size > EXTRAPOLATE_WITHIN * np.linalg.norm(whole / r_scale):
            return None
        return (sum(weight * path[-1 - j].step for j, weight in enumerate(weights))
                + self.newton.correction(rest, None, factorization, True))
