"""
The CDR's forward statics with reduced legs ('cc', 'rod'): its iterations and linearization.

Each leg is the reduced model of cdr_translator/fidelity (``ReducedModel``) instead of a
full TranslatorSolver. A warm 'cc' solve is one coupled Newton over the legs' unknowns and
the platform's (robot/reduced_coupled_kernels.coupled_newton, Jacobians kept across solves). A walk
(cold solves, 'rod' legs, and warm ones the coupled Newton did not converge) runs the
chain's Newton over the platform's 24 unknowns (robot/reduced_kernels.chain_newton), each iterate
solving every leg's reduced model in full, and halves a failed step, as
robot/continuation.py does for full legs. Each leg enters through its end-disk pose and its
6x6 compliance from implicit differentiation of the reduced model. This module also gives
the linearization at a solution (platform compliance, input sensitivity, the legs'
verdicts held at both ends) and the legs' SolveResults.
"""

from dataclasses import dataclass
from functools import partial
from typing import Callable, Optional, Tuple

import numpy as np

from .chain import Chain, ChainState, SIZE
from .chain_path import DEGREE, point_width, push
from .held_leg import held_reference, held_verdict, HeldReference
from .linearization import chain_verdict
from .reduced_bordered import bordered_newton, BorderedState, NO_DESCENT as BORDERED_NO_DESCENT
from .reduced_bordered import SINGULAR, SOLVED as BORDERED_SOLVED
from .reduced_coupled_kernels import follow, linearize_solution, SOLVED as COUPLED_SOLVED
from .reduced_kernels import chain_newton, leg_compliance, LEG_FAILED, NO_DESCENT
from .reduced_kernels import platform_jacobian, SOLVED
from .result import DeltaResult, LegResults
from ..fidelity import cc, equivalent_rod
from ..fidelity.reduced import ReducedModel, ROD_STEPS
from ..params.translator_params import TranslatorParams
from ..solve.continuation import MIN_CONTINUATION_STEP
from ..solve.result import FRAME_NAMES, SolveResult

#: Why a compiled Newton correction failed, by its outcome code.
_FAILURES = {LEG_FAILED: "a leg's reduced model did not converge under its wrench",
             NO_DESCENT: 'damping found no decrease of the residual'}

#: Why a Newton correction with the legs held in the system failed, by its outcome code.
_BORDERED_FAILURES = {BORDERED_NO_DESCENT: 'damping found no decrease of the residual with '
                                           'the legs held in the Newton system',
                      SINGULAR: "the chain's Newton Jacobian (legs held in it) is singular"}


@dataclass
class ReducedState:
    """A chain state with reduced legs: platform pose, leg wrenches, the legs' unknowns."""

    position: np.ndarray
    rotation: np.ndarray
    wrenches: np.ndarray
    leg_x: np.ndarray  # (3, n): each leg's nondimensional reduced unknowns

    def copy(self) -> 'ReducedState':
        """Return an independent copy."""
        return ReducedState(self.position.copy(), self.rotation.copy(), self.wrenches.copy(),
                            self.leg_x.copy())

    def chain_state(self) -> ChainState:
        """Return the platform part as robot/chain.py's ChainState (reduced leg unknowns)."""
        return ChainState(self.position, self.rotation, self.wrenches, self.leg_x)


@dataclass
class ReducedOutcome:
    """Where a walk ended: state, residual, Jacobian and the legs' linearization there."""

    state: ReducedState
    converged: bool
    message: str
    iterations: int
    residual: np.ndarray
    jacobian: np.ndarray  # (24, 24) SI platform Jacobian at the state
    frames: np.ndarray  # (3, 4, 4) end disks in {pe_i}
    compliances: np.ndarray  # (3, 6, 6)
    leg_jacobians: int = 0  # legs linearized anew by a coupled Newton
    on_path: bool = False  # already among the path's points (a coupled solve's)


def model_data(params: TranslatorParams, level: str) -> np.ndarray:
    """Return the compiled model's data vector of ``level`` ('cc' or 'rod') for ``params``."""
    if level == 'cc':
        return cc.model_data(params)
    return equivalent_rod.model_data(params, ROD_STEPS)


class ReducedChain:
    """Forward statics of the chain with three reduced legs of one level; warm-started."""

    def __init__(self, chain: Chain, params: TranslatorParams, level: str,
                 max_iterations: int) -> None:
        """Legs of ``level`` ('cc' or 'rod') for ``params``; no solution yet."""
        self.chain = chain
        self.level = level
        self.model = (ReducedModel.constant_curvature(params) if level == 'cc'
                      else ReducedModel.equivalent_rod(params))
        self.data = model_data(params, level)
        #: whether warm solves take the coupled Newton: 'cc', whose wrench derivatives are
        #: in closed form; a 'rod' leg's differenced ones (about 40 shots a linearization)
        #: made it slower than solving the legs in full at every iterate
        self.couples = level == 'cc'
        self.max_iterations = max_iterations
        self.params = params
        size = self.model.size
        self.lu = np.zeros((3, size, size))
        self.pivots = np.zeros((3, size + 1), dtype=np.int64)
        #: the scaled platform Jacobian's LU, kept for chord steps across solves
        self.factors = np.zeros((SIZE, SIZE))
        self.factor_pivots = np.zeros(SIZE + 1, dtype=np.int64)
        self.previous: Optional[Tuple[ReducedState, np.ndarray]] = None
        #: the end disks (3, 4, 4) of the previous solution
        self.previous_frames = np.zeros((3, 4, 4))
        #: what the coupled Newton keeps across solves: each leg's H LU, dx/dw and
        #: compliance, and the scaled platform Jacobian's LU
        #: (reduced_coupled_kernels.coupled_newton)
        self.kept = (np.zeros((3, size, size)), np.zeros((3, size + 1), dtype=np.int64),
                     np.zeros((3, size, 6)), np.zeros((3, 6, 6)), np.zeros((SIZE, SIZE)),
                     np.zeros(SIZE + 1, dtype=np.int64))
        #: an outcome's Jacobian and compliances when not linearized (NaN, never written)
        self._not_linearized = (np.full((SIZE, SIZE), np.nan), np.full((3, 6, 6), np.nan))
        self._held: Optional[HeldReference] = None
        #: the last solutions, which a warm coupled solve starts from (chain_path.py)
        self.points = np.zeros((DEGREE + 1, point_width(size)))
        self.seen = np.zeros((DEGREE + 1, SIZE // 2))
        self.count = np.zeros(1, dtype=np.int64)
        #: whether ``kept`` was made at the last point (a coupled solve linearized there)
        self.kept_at_last = False
        r_scale, x_scale = chain.platform[4], chain.platform[5]
        #: the inputs' scales for the predictor: sliders and offset as positions, payload
        #: force and moment as the equilibrium residual's
        self.input_scale = np.concatenate([np.full(3, x_scale[0]), r_scale[18:24],
                                           np.full(3, x_scale[0])])

    def reset(self) -> None:
        """Forget the previous solution and the legs' factorizations."""
        self.previous = None
        self.pivots[:, -1] = 0
        self.factor_pivots[-1] = 0
        self.kept[1][:, -1] = 0
        self.kept[5][-1] = 0
        self.count[0] = 0
        self.kept_at_last = False

    def accept(self, outcome: 'ReducedOutcome', inputs: np.ndarray) -> None:
        """Keep a converged outcome as the next solve's start."""
        self.previous = (outcome.state, inputs)
        self.previous_frames = outcome.frames
        if not outcome.on_path:
            self.kept_at_last = False
            state = outcome.state
            push(self.points, self.seen, self.count, state.position, state.rotation,
                 state.wrenches, state.leg_x, outcome.frames, inputs)

    def coupled(self, inputs: np.ndarray, tolerances: np.ndarray,
                linearized: bool) -> Optional['ReducedOutcome']:
        """
        Solve ``inputs`` by the coupled Newton from the previous solution; None if it fails.

        ``linearized``: the legs' compliances and the platform Jacobian at the solution too
        (made exact there, the next solve's chord steps start from them).
        """
        if self.count[0] == 0 or not self.couples:
            return None
        size = self.model.size
        state = ReducedState(np.empty(3), np.empty((3, 3)), np.empty((3, 6)),
                             np.empty((3, size)))
        frames = np.empty((3, 4, 4))
        residual = np.empty(SIZE)
        code, iterations, refreshes = follow(
            self.model.code, self.data, self.model.tolerance, state.leg_x, state.wrenches,
            state.position, state.rotation, frames, inputs, self.chain.platform, tolerances,
            self.max_iterations, *self.kept, residual, self.points, self.seen, self.count,
            self.input_scale, not self.kept_at_last)
        self.kept_at_last = False
        if code != COUPLED_SOLVED:  # what it kept may be made far off: make it anew next time
            self.kept[1][:, -1] = 0
            self.kept[5][-1] = 0
            return None
        if not linearized:
            return ReducedOutcome(state, True, 'converged', iterations, residual,
                                  self._not_linearized[0], frames, self._not_linearized[1],
                                  refreshes, True)
        jacobian = np.full((SIZE, SIZE), np.nan)
        linearize_solution(self.model.code, self.data, state.leg_x, state.wrenches,
                           state.rotation, inputs, self.chain.platform, residual, *self.kept,
                           np.zeros(3, dtype=np.int64), jacobian)
        self.kept_at_last = True
        return ReducedOutcome(state, True, 'converged', iterations, residual, jacobian, frames,
                              self.kept[3].copy(), refreshes + 3, True)

    def home(self, position: np.ndarray) -> ReducedState:
        """Straight legs, no load, platform at ``position``."""
        return ReducedState(position.copy(), np.eye(3), np.zeros((3, 6)),
                            np.zeros((3, self.model.size)))

    def walk(self, start: ReducedState, origin: np.ndarray, inputs: np.ndarray,
             tolerances: np.ndarray, out_of_time: Callable[[], bool],
             linearized: bool) -> ReducedOutcome:
        """
        Continue from ``start`` (solved for inputs ``origin``) to ``inputs``.

        Newton goes straight to the inputs; a failed step is halved down to
        continuation.MIN_CONTINUATION_STEP of the way left. The outcome holds the last
        converged state when the walk stalls. ``linearized``: the legs' compliances and
        the platform Jacobian at the solution too (else the outcome's are NaN).
        """
        state, done, step, iterations = start, 0.0, 1.0, 0
        leg_origin = state.wrenches
        frames = np.empty((3, 4, 4))
        compliances = np.full((3, 6, 6), np.nan)
        signs = np.zeros(3, dtype=np.int64)
        residual = np.full(SIZE, np.inf)
        jacobian = np.full((SIZE, SIZE), np.nan)
        bordered = False  # the legs held in the Newton system (reduced_bordered.py)
        while done < 1.0:
            target = min(1.0, done + step)
            goal = inputs if target == 1.0 else origin + target * (inputs - origin)
            trial = state.copy()
            trial_origin = leg_origin.copy()
            if bordered:
                code, count = self._bordered_step(trial, goal, tolerances, frames, residual)
                iterations += count
                if code == BORDERED_SOLVED:
                    done, state = target, trial
                    step *= 2.0
                    continue
                step = 0.5 * (target - done)
                if step < MIN_CONTINUATION_STEP or out_of_time():
                    return self._stalled(state, inputs, done, iterations,
                                         _BORDERED_FAILURES.get(code, 'no convergence in '
                                                                f'{self.max_iterations} '
                                                                'iterations'))
                continue
            code, count = chain_newton(
                self.model.code, self.data, self.model.tolerance, self.model.max_iterations,
                trial.leg_x, trial_origin, self.lu, self.pivots, trial.position,
                trial.rotation, trial.wrenches, goal, self.chain.platform, tolerances,
                self.max_iterations, self.factors, self.factor_pivots,
                linearized and target == 1.0, frames, compliances, signs, residual, jacobian)
            iterations += count
            if code == SOLVED:
                done, state, leg_origin = target, trial, trial_origin
                step *= 2.0
                continue
            self.pivots[:, -1] = 0
            self.factor_pivots[-1] = 0
            if self.couples and not out_of_time():
                # the same step with the legs held in the system, and so the rest of the
                # walk: past a leg's free-end buckling load its wrench alone does not fix
                # its shape (H_k singular there), the chain held at both ends does
                bordered = True
                continue
            step = 0.5 * (target - done)
            if step < MIN_CONTINUATION_STEP or out_of_time():
                return self._stalled(state, inputs, done, iterations,
                                     _FAILURES.get(code, f'no convergence in '
                                                         f'{self.max_iterations} iterations'))
        if bordered and linearized:
            # the legs' compliances and the platform Jacobian at the solution, as
            # chain_newton makes them (a leg past its free-end buckling load has a
            # regular H_k again, its determinant's sign negative: its held verdict's)
            for k in range(3):
                made = self.leg_linearization(state.leg_x[k], state.wrenches[k])
                compliances[k] = made[1]
            platform_jacobian(state.rotation, state.wrenches, residual, inputs,
                              self.chain.platform[0], self.chain.platform[1], compliances,
                              jacobian)
        return ReducedOutcome(state, True, 'converged', iterations, residual, jacobian, frames,
                              compliances)

    def _bordered_step(self, trial: ReducedState, goal: np.ndarray, tolerances: np.ndarray,
                       frames: np.ndarray, residual: np.ndarray) -> Tuple[int, int]:
        """
        Solve ``goal`` from ``trial`` (moved in place) by reduced_bordered's Newton.

        ``frames`` and ``residual`` receive the end disks and the SI residual reached.
        """
        held = BorderedState(trial.position, trial.rotation, trial.wrenches, trial.leg_x)
        code, count, reached, disks = bordered_newton(
            self.model.code, self.data, self.model.tolerance, held, goal, self.chain.platform,
            tolerances, self.max_iterations)
        trial.position[:], trial.rotation[:], trial.wrenches[:] = (held.position, held.rotation,
                                                                   held.wrenches)
        trial.leg_x[:] = held.leg_x
        frames[:] = disks
        residual[:] = reached
        return code, count

    def _stalled(self, state: ReducedState, inputs: np.ndarray, done: float, iterations: int,
                 message: str) -> 'ReducedOutcome':
        """Return a walk's outcome stalled at ``state``, ``done`` of the way, with why."""
        last = self.evaluate(state, inputs)
        return ReducedOutcome(state, False, f'continuation stalled at {done:.1%} of the way '
                              f'to the sliders and payload: {message}', iterations,
                              last.residual, last.jacobian, last.frames, last.compliances)

    def evaluate(self, state: ReducedState, inputs: np.ndarray) -> ReducedOutcome:
        """Return the residual and legs of ``state`` as it is (no iteration, no Jacobian)."""
        frames = np.empty((3, 4, 4))
        compliances = np.empty((3, 6, 6))
        for k in range(3):
            frames[k], compliances[k], _ = self.leg_linearization(state.leg_x[k],
                                                                  state.wrenches[k])
        chain_state = state.chain_state()
        chain_state.frames = frames
        residual = self.chain.residual(chain_state, inputs)
        return ReducedOutcome(state, False, '', 0, residual, np.full((SIZE, SIZE), np.nan),
                              frames, compliances)

    def leg_linearization(self, x: np.ndarray, wrench: np.ndarray
                          ) -> Tuple[np.ndarray, np.ndarray, tuple]:
        """Return the end-disk frame, 6x6 compliance and LU of H (stability.determinant_sign)."""
        size = self.model.size
        frame = np.empty((4, 4))
        compliance = np.empty((6, 6))
        lu = np.empty((size, size))
        pivots = np.zeros(size, dtype=np.int64)
        sign = leg_compliance(self.model.code, np.ascontiguousarray(x), self.data,
                              np.ascontiguousarray(wrench, dtype=float), frame, compliance,
                              lu, pivots, np.empty((size, 6)))
        if sign == 0:
            compliance[:] = np.nan
        return frame, compliance, (lu, pivots)

    def leg_results(self, outcome: ReducedOutcome) -> LegResults:
        """
        Return the legs' SolveResults at the outcome's state, each built when first read.

        The builders read the outcome's own arrays (made for it, not changed afterwards).
        """
        state = outcome.state
        return LegResults((partial(self._leg_result, state.leg_x[0], state.wrenches[0]),
                           partial(self._leg_result, state.leg_x[1], state.wrenches[1]),
                           partial(self._leg_result, state.leg_x[2], state.wrenches[2])))

    def _leg_result(self, x: np.ndarray, wrench: np.ndarray) -> SolveResult:
        """Return the SolveResult of one leg of the chain at its unknowns ``x`` and ``wrench``."""
        model = self.model
        frames = model.frames(x, wrench)
        return SolveResult(
            converged=True, message='converged (a leg of the chain)', iterations=0,
            residual_norm=0.0, residual_by_type=model.residual_by_kind(np.zeros(model.size)),
            force=wrench[:3].copy(), moment=wrench[3:].copy(),
            frames={name: frames[k].copy() for k, name in enumerate(FRAME_NAMES)},
            backbones=model.points(x, wrench), solve_time_s=0.0, method='fast',
            unknowns=x * model.unknown_scale, fidelity=self.level)

    def linearize(self, result: DeltaResult, outcome: ReducedOutcome, inputs: np.ndarray,
                  critical_load_n: Optional[float]) -> None:
        """
        Add the platform compliance, input sensitivity and verdicts (linearization.linearize's).

        From the platform Jacobian at the solution (exact in the reduced legs); each leg's
        held verdict (held.held_verdict) from its reduced H and compliance, compared with
        the unloaded reduced leg and the full leg's held buckling load ``critical_load_n``.
        """
        state = outcome.state.chain_state()
        right = np.zeros((SIZE, 18))
        right[:, :12] = self.chain.input_sensitivity(state, inputs)
        right[18:, 12:] = np.eye(6)
        try:
            solved = -np.linalg.solve(outcome.jacobian, right)[:6]
        except np.linalg.LinAlgError:
            solved = np.full((6, 18), np.nan)
        if not np.all(np.isfinite(solved)):
            result.stable = False
            result.message += '; no platform compliance: the Newton Jacobian is singular'
            return
        result.input_sensitivity = solved[:, :12]
        result.platform_compliance = solved[:, 12:]
        height = self.params.stack_height
        scale = np.concatenate([np.ones(3), np.full(3, 1.0 / height)])
        stiffness = np.linalg.inv(result.platform_compliance)
        scaled = scale[:, None] * stiffness * scale[None, :]
        result.stiffness_margin = float(np.linalg.eigvalsh(0.5 * (scaled + scaled.T))[0])
        reference = self.unloaded_reference(critical_load_n)
        verdicts = []
        for k in range(3):
            _, compliance, lu = self.leg_linearization(outcome.state.leg_x[k],
                                                       outcome.state.wrenches[k])
            verdicts.append(held_verdict(lu, compliance, outcome.state.wrenches[k], reference))
        result.leg_stability = tuple(verdicts)
        result.stable = chain_verdict(bool(result.stiffness_margin > 0.0), result.leg_stability)
        for k, verdict in enumerate(verdicts, start=1):
            if verdict.stable is not True:
                result.message += f'; leg {k}: {verdict.message}'

    def unloaded_reference(self, critical_load_n: Optional[float]) -> HeldReference:
        """Return the held verdicts' reference: the unloaded reduced leg, ``critical_load_n``."""
        if self._held is None or self._held.critical_load_n != critical_load_n:
            _, compliance, lu = self.leg_linearization(np.zeros(self.model.size), np.zeros(6))
            self._held = held_reference(lu, compliance, self.params.stack_height,
                                        critical_load_n)
        return self._held
