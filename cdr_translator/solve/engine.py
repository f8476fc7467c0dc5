"""
The engine of one translator: the solve state and every step that reads or changes it.

An ``Engine`` owns what a solve carries to the next (``continuation.PathState``: the last
solution, the stored factorization, the path of warm solves), the last stability verdict
(``branch.Verdicts``) and the refinement memory (``Refinements``: the engines at other
steps per segment and the steps a warm sequence keeps). Its public methods are the steps
of a solve (``correct``, ``verdict``, ``judged``, ``estimate_error``, ``compliance``),
whole solves (``solve``, ``solve_rows``), ``result_at`` given unknowns, and the warm
start (``start_at``, ``start_from``, ``take_over``, ``reset``, ``has_warm_start``).
``TranslatorSolver`` (solver.py) is its face: it checks the input and owns the time
limit, which reaches the engine as an argument of each solve.

The helpers the engine calls take arrays, its state objects and callables, never the
engine: continuation.py, correctors.py, branch.py, refinement.py (the refinement policy
over a callable re-solve), warm_fast_path.py (the compiled warm step and batch rows).
"""

from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
import time
from typing import Callable, Dict, Optional, Tuple

import numpy as np

from . import branch, continuation, correctors, refinement
from .batch import BatchResult, SolveDetails
from .branch import LOAD_FLOOR, STALE_WRENCH
from .continuation import LIFT_FROM_SPACERS, PathState, warm_settings
from .correctors import Limits, Outcome, Pose
from .result import SolveResult
from .verify import verify as verify_result
from .warm_fast_path import Checks, DJ, ERROR_DEG, ERROR_M, ERROR_RAD, PJ, POSITION
from .warm_fast_path import QUATERNION, residual_by_kind, Run, warm_rows
from .._blas import one_blas_thread
from .._jit import interpreted_kernels
from .._linalg import residual_norm
from ..analysis.accuracy import ErrorEstimate, kept_steps, meets
from ..analysis.compliance import analysis_from_stored, check_tolerance, compliance_analysis
from ..analysis.compliance import ComplianceAnalysis, EXACT
from ..analysis.stability import (assess_compliance, CLOSE_BRANCH_MARGIN, load_scale, Reference,
                                  Stability)
from ..bvp.problem import Problem
from ..params.translator_params import Accuracy, TranslatorParams

__all__ = ['Engine', 'Factorization', 'Options', 'Refinements']

#: A factorization as ``start_at`` and ``result_at`` take it: (LU of the Jacobian, its
#: end-frame derivative ``problem.pose_jacobian``, the wrench it was made at).
Factorization = Tuple[tuple, np.ndarray, np.ndarray]


@dataclass
class Options:
    """
    How the engine solves (TranslatorSolver's arguments of the same names).

    Read at each solve, so that a change between solves takes effect at the next.
    """

    tolerance: float
    max_iterations: int
    accuracy: Accuracy
    follow_stable_branch: bool = True
    judge: bool = True
    fallback: bool = True
    path: str = 'default'
    #: cold continuations correct by lifted Newton from this many spacer disks per joint on
    #: (None: never)
    lift_from_spacers: Optional[int] = LIFT_FROM_SPACERS


@dataclass
class Refinements:
    """
    The engines at other steps per segment and what the next warm solve starts at.

    ``engines`` are the owner's engines at other steps per segment; ``kept`` is the steps
    per segment the next warm solve starts at (a key of ``engines``), kept from the
    refinement of an earlier one, None: the owner's own; ``last_estimate`` the estimate of
    the owner's last judged solve.
    """

    engines: Dict[int, 'Engine'] = field(default_factory=dict)
    kept: Optional[int] = None
    last_estimate: Optional[ErrorEstimate] = None

    def engine(self, owner: 'Engine', steps: int) -> 'Engine':
        """Return ``owner``'s engine at ``steps`` steps per segment, without a target."""
        made = self.engines.get(steps)
        if made is None:
            options = owner.options
            made = self.engines[steps] = Engine(
                owner.params.with_changes(steps_per_segment=steps), 'fast', owner.jacobian,
                Options(options.tolerance, options.max_iterations, Accuracy(0.0, 0.0),
                        options.follow_stable_branch))
        return made


class Engine:
    """The solve state of one translator and the steps of a solve over it."""

    def __init__(self, params: TranslatorParams, method: str, jacobian: str,
                 options: Options) -> None:
        """Set up the problem of ``params`` (``method``, ``jacobian`` as TranslatorSolver's)."""
        self.params = params
        self.method = method
        self.jacobian = jacobian
        self.options = options
        kernel = interpreted_kernels() if method == 'paper' else None
        self.problem = (Problem(params, jacobian=jacobian) if kernel is None
                        else Problem(params, kernel, jacobian))
        self._state = PathState(self.problem.size)
        self._verdicts = branch.Verdicts()
        self._refinements = Refinements()
        if method == 'fast':
            continuation.unloaded(self.problem, self._state)  # compiles the kernels now

    # the warm start ---------------------------------------------------------------------------
    @property
    def has_warm_start(self) -> bool:
        """
        Whether the next warm solve continues from a state (not from nothing, after ``reset``).

        A converged solve, ``start_at``/``start_from``, or a continuation that stalled
        (the state it reached; the unloaded one when it made no progress) leaves one.
        """
        return self._state.previous is not None

    @property
    def previous_solution(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """(nondimensional unknowns, wrench) of the last converged solve: the warm start."""
        return self._state.previous

    @property
    def last_estimate(self) -> Optional[ErrorEstimate]:
        """Return the error estimate of the last judged solve (None: none yet)."""
        return self._refinements.last_estimate

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        state = self._state
        state.previous, state.lu, state.pose = None, None, None
        self._refinements.kept = None

    def start_from(self, xs: np.ndarray, wrench: np.ndarray,
                   keep_factorization: bool = False) -> None:
        """Warm-start from nondimensional ``xs`` at ``wrench``; the stored LU kept or not."""
        state = self._state
        state.previous = (xs, wrench)
        self._refinements.kept = None
        if not keep_factorization:
            state.lu, state.pose = None, None

    def start_at(self, xs: np.ndarray, wrench: np.ndarray,
                 factorization: Optional[Factorization] = None) -> None:
        """Warm-start from nondimensional ``xs`` at ``wrench`` with ``factorization`` (or none)."""
        state = self._state
        state.previous = (xs, wrench)
        self._refinements.kept = None
        if factorization is None:
            state.lu, state.pose = None, None
        else:
            lu, pose, made_at = factorization
            state.lu, state.pose = lu, (pose, np.array(made_at, dtype=float))

    def take_over(self, source: 'Engine') -> None:
        """
        Warm-start the next solve from ``source``'s last solution and factorization.

        ``source`` solves the same structure at other steps per segment: the unknowns mean
        the same, and its factorization (the Jacobian differs by the discretization error)
        serves the chord steps and the stability verdict as a stale one would.
        """
        state, other = self._state, source._state
        state.previous, state.lu, state.pose = other.previous, other.lu, other.pose
        self._refinements.kept = None

    def unloaded_reference(self) -> Reference:
        """Return the unloaded state's stiffness and det J sign (branch.origin), made once."""
        return branch.origin(self.problem, self._state, self._verdicts)

    # whole solves ------------------------------------------------------------------------------
    def solve(self, wrench: np.ndarray, started: float, time_limit_s: float,
              warm_start: bool = True, compliance: bool = False, verify: bool = False,
              compliance_options: Optional[dict] = None,
              path: Optional[str] = None) -> SolveResult:
        """
        Solve at the checked ``wrench``, begun at ``started`` and limited to ``time_limit_s``.

        A usual warm row without compliance is one compiled call (``usual_solve``, the
        batch's row; no BLAS in it, so no thread limit to set); when that call stops, the
        general solve goes on from the warm step it took (``PathState.handed_over``). A
        solve with compliance takes the general path, as ``solve_rows`` does: the compiled
        row is no faster there, and a process that solves with compliance only (an
        estimate's forward solves) then never loads the row's kernel (60 ms from the
        cache). ``path`` overrides ``options.path`` for this solve.
        """
        options = {} if compliance_options is None else compliance_options
        path = self.options.path if path is None else path
        if (warm_start and not verify and not compliance and self._refinements.kept is None
                and path == 'default'):
            usual, undo = self.usual_solve(wrench, started)
            if usual is not None:
                return usual
            try:
                return self._solve(wrench, started, time_limit_s, True, compliance, False,
                                   options, path)
            finally:
                if undo is not None and self._state.handed_over is not None:
                    undo()  # the solve did not go on from the step: as if never taken
                self._state.handed_over = None
        return self._solve(wrench, started, time_limit_s, warm_start, compliance, verify,
                           options, path)

    @one_blas_thread
    def _solve(self, wrench: np.ndarray, started: float, time_limit_s: float,
               warm_start: bool, compliance: bool, verify: bool, compliance_options: dict,
               path: str) -> SolveResult:
        """Solve at ``wrench`` by the general path (``solve``), BLAS on one thread."""
        refinements = self._refinements
        if refinements.kept is not None and not warm_start:
            refinements.kept = None  # a cold solve starts over at this engine's steps
        elif refinements.kept is not None:
            kept = self._solve_kept(wrench, started, time_limit_s, compliance, verify,
                                    compliance_options)
            if kept is not None:
                return kept
        outcome = self.correct(wrench, warm_start, started, time_limit_s, path)
        return self.judged(outcome, self.verdict(outcome, wrench), wrench, started,
                           time_limit_s, compliance, verify, compliance_options)

    def solve_rows(self, batch: BatchResult, wrenches: np.ndarray, rows: range,
                   compliance: bool, time_limit_s: float) -> None:
        """
        Solve ``rows`` of ``wrenches`` into ``batch`` as consecutive ``solve`` calls would.

        Runs of usual warm rows (without compliance) go to one compiled call, the other rows
        one by one (``solve_row``), each going on from the warm step that stopped the run.
        """
        row = rows.start
        solve_one = partial(self.solve_row, time_limit_s=time_limit_s)
        state = self._state
        while row < rows.stop:
            undo = None
            if not compliance:
                done, undo = self._usual_rows(batch, wrenches, range(row, rows.stop))
                row += done
            if row < rows.stop:
                try:
                    batch.run(row, solve_one, wrenches[row], compliance)
                finally:
                    if state.handed_over is not None and undo is not None:
                        undo()  # the row's solve did not go on from the step: as if never taken
                    state.handed_over = None  # only ever for this row's solve
                row += 1

    def solve_row(self, batch: BatchResult, row: int, wrench: np.ndarray, compliance: bool,
                  time_limit_s: float) -> float:
        """Solve row ``row`` of ``batch`` as ``solve`` would; return its solve time (s)."""
        started = time.perf_counter()
        if self._refinements.kept is not None:
            result = self.solve(wrench, started, time_limit_s, compliance=compliance)
            batch.record(row, result)
            return result.solve_time_s
        outcome = self.correct(wrench, True, started, time_limit_s)
        verdict = self.verdict(outcome, wrench)
        estimate = outcome.estimate
        target = self.options.accuracy
        if (verdict is None or not verdict.stable or estimate is None or outcome.shape is None
                or not meets(estimate, target.position_m, target.angle_deg)):
            result = self.judged(outcome, verdict, wrench, started, time_limit_s, compliance)
            batch.record(row, result)
            return result.solve_time_s
        # judged stable and accurate: what ``judged`` finds, without the result
        self._refinements.last_estimate = estimate
        elapsed = time.perf_counter() - started
        frames = outcome.shape[2]
        analysis: Optional[ComplianceAnalysis] = None
        message = ''
        if compliance:
            try:
                analysis = self.compliance(outcome, wrench, frames[3])
            except ArithmeticError as error:
                message = f'{outcome.message}; no compliance: {error}'
        details = SolveDetails(outcome.iterations, residual_norm(outcome.rs), verdict.stable,
                               verdict.margin, self.params.steps_per_segment, self.method,
                               message or outcome.message, analysis)
        batch.record_pose(row, frames, verdict.stable, estimate,
                          None if analysis is None else analysis.matrix, message,
                          details=details)
        return elapsed

    # the usual warm row: one compiled call -------------------------------------------------------
    def usual_solve(self, wrench: np.ndarray, started: float
                    ) -> Tuple[Optional[SolveResult], Optional[Callable[[], None]]]:
        """
        Return ``solve``'s result at ``wrench`` when it is a usual warm row.

        The row is one compiled call (``_usual_run``); its result is the one the whole solve
        gives (the same step, kept verdict and estimate). Else (None, undo): the general
        solve goes on from the warm step taken (``PathState.handed_over``), and ``undo``
        (when a step was taken) puts the Broyden updates back if that solve does not.
        """
        run = self._usual_run(wrench.reshape(1, 6))
        if run is None or run.rows == 0:
            return None, None if run is None else run.undo
        problem = self.problem
        iterations, slot, residual, report = run.last_step
        points, frames = problem.recorded_shape(slot)
        verdict, estimate = self._verdicts.verdict, self._refinements.last_estimate
        assert verdict is not None and estimate is not None  # _usual_run's conditions
        return SolveResult(
            True, 'converged', iterations, residual_norm(residual), residual_by_kind(report),
            wrench[:3].copy(), wrench[3:].copy(),
            {'pe': frames[0], 'pm': frames[1], 'dm': frames[2], 'de': frames[3]}, points,
            time.perf_counter() - started, self.method, run.previous[0] * problem.x_scale,
            stable=verdict.stable, stability_margin=verdict.margin,
            error_estimate_m=estimate.position_m, error_estimate_deg=estimate.angle_deg,
            accuracy_met=True, steps_per_segment=self.params.steps_per_segment), None

    def _usual_rows(self, batch: BatchResult, wrenches: np.ndarray,
                    rows: range) -> Tuple[int, Optional[Callable[[], None]]]:
        """
        Solve the usual warm rows at the head of ``rows`` in one compiled call (``_usual_run``).

        Returns how many, and the ``warm_fast_path.Run.undo`` of the warm step handed to the
        next row's solve (``PathState.handed_over``); (0, None) when the state is not that
        of a usual warm row.
        """
        started = time.perf_counter()
        run = self._usual_run(wrenches[rows.start:rows.stop])
        if run is None or run.rows == 0:
            return 0, None if run is None else run.undo
        answers = run.answers
        batch.record_poses(slice(rows.start, rows.start + run.rows),
                           answers[:, POSITION:QUATERNION + 4],
                           answers[:, [PJ, PJ + 1, DJ, DJ + 1]], 'full',
                           (time.perf_counter() - started) / run.rows, stable=True,
                           estimate=answers[:, [ERROR_M, ERROR_DEG]])
        return run.rows, run.undo

    def _usual_run(self, wrenches: np.ndarray) -> Optional[Run]:
        """
        Solve the usual warm rows at the head of ``wrenches`` (n, 6) in one compiled call.

        The state is left as that many ``solve`` calls leave it; the warm step taken at the
        row that stopped the run is handed to that row's solve (``PathState.handed_over``).
        None (nothing done) when the state is not that of a usual warm row: a fast, judged
        engine on the default path, not at kept refined steps, with a stored factorization
        whose stable verdict (margin at least stability.CLOSE_BRANCH_MARGIN) the next solve
        would keep.
        """
        state, verdicts, problem, options = self._state, self._verdicts, self.problem, \
            self.options
        verdict, previous, pose = verdicts.verdict, state.previous, state.pose
        if (verdict is None or not verdict.stable or verdict.margin < CLOSE_BRANCH_MARGIN
                or verdicts.verdict_lu is not state.lu or state.lu is None or pose is None
                or pose[0] is None or previous is None or verdicts.origin is None
                or not options.judge or self.method != 'fast' or options.path != 'default'
                or self._refinements.kept is not None):
            return None
        count = state.path_count if state.path_last is previous[0] else 0
        target = options.accuracy
        checks = Checks(pose[1], verdicts.origin.length,
                        LOAD_FLOOR * load_scale(verdicts.origin),
                        min(STALE_WRENCH, 0.5 * verdict.margin), target.position_m,
                        target.angle_deg)
        run = warm_rows(problem, previous, (state.path_xs, state.path_wrenches, count),
                        wrenches, state.lu, pose[0],
                        warm_settings(state, options.tolerance, options.max_iterations, True),
                        checks)
        if run.stopped_at is not None:  # the solve of the row that stopped it goes on from there
            state.handed_over = (wrenches[run.rows], *run.stopped_at)
        if run.rows == 0:
            return run
        state.previous = run.previous
        state.path_count, state.path_last = run.path_count, run.previous[0]
        state.exact_at = None
        last = run.answers[-1]
        self._refinements.last_estimate = ErrorEstimate(
            float(last[ERROR_M]), float(last[ERROR_RAD]), self.params.steps_per_segment,
            run.coarse_steps)
        return run

    # the steps of a solve ------------------------------------------------------------------------
    def correct(self, wrench: np.ndarray, warm_start: bool, started: float,
                time_limit_s: float, path: Optional[str] = None) -> Outcome:
        """Converge at ``wrench``: the warm step, else continuation, restart, fallback."""
        options = self.options
        path = options.path if path is None else path
        state = self._state
        state.exact_at = None  # the unknowns state.lu is exact at, once known
        deadline = started + time_limit_s
        limits = Limits(options.tolerance, time_limit_s)
        fast = self.method == 'fast'
        newton = partial(self._newton, limits)
        corrector = newton if fast else partial(self._levenberg_marquardt, limits)
        warm = warm_start and state.previous is not None and bool(state.previous[1].any())
        begin = state.previous[0] if warm and state.previous is not None else None
        usual, spent = (self.warm_step(wrench, deadline, newton)  # compiled: nothing to silence
                        if warm and fast and path != 'tracking' else (None, 0))
        # numpy's errstate costs 5 us: only the general path has rejected steps that overflow
        with nullcontext() if usual is not None else np.errstate(over='ignore', invalid='ignore'):
            if usual is not None:
                outcome = usual
            elif path == 'tracking' and fast:
                outcome = continuation.track_only(self.problem, state, limits, wrench, warm,
                                                  deadline)
            else:
                outcome = self._continue(wrench, warm_start, deadline, limits, corrector, fast)
            outcome.iterations += spent
            # a warm sequence the default continuation followed (the paper's baseline and
            # the tracking path keep their first-order predictor): the path extrapolated
            continued = outcome.converged and path != 'tracking' and fast
            if warm and not outcome.converged and time.perf_counter() < deadline:
                # the warm start may sit on another branch or too far away: restart cold
                restart = self._continue(wrench, False, deadline, limits, corrector, fast)
                restart.iterations += outcome.iterations
                restart.message += ' (after a restart from the unloaded state)'
                if restart.converged or residual_norm(restart.rs) < residual_norm(outcome.rs):
                    outcome = restart
            if (not outcome.converged and options.fallback and fast
                    and outcome.reached is not None and time.perf_counter() < deadline):
                outcome = continuation.track(self.problem, state, limits, outcome, wrench,
                                             deadline)
        if outcome.converged:
            state.previous = (outcome.xs, wrench)
            continuation.extend_path(state, outcome.xs, wrench,
                                     continued and state.path_last is begin)
        return outcome

    def warm_step(self, wrench: np.ndarray, deadline: float,
                  newton: continuation.Corrector) -> Tuple[Optional[Outcome], int]:
        """Solve the usual warm case in one compiled call (continuation.warm_step)."""
        options = self.options
        settings = warm_settings(self._state, options.tolerance, options.max_iterations,
                                 options.judge)
        return continuation.warm_step(self.problem, self._state, options.max_iterations,
                                      settings, wrench, deadline, newton)

    def verdict(self, outcome: Outcome, wrench: np.ndarray) -> Optional[Stability]:
        """Stability verdict of a converged fast solve that is judged, else None."""
        if not (outcome.converged and self.method == 'fast' and self.options.judge):
            return None
        if outcome.shape is None or outcome.shape[0] is not outcome.xs:
            outcome.shape = (outcome.xs, *self.problem.shape(outcome.xs, wrench))
        return self.stability(outcome, wrench, outcome.shape[2][3][:3, :3])

    def stability(self, outcome: Outcome, wrench: np.ndarray,
                  rotation: Optional[np.ndarray] = None) -> Stability:
        """Verdict at a converged outcome (branch.judge)."""
        return branch.judge(self.problem, self._state, self._verdicts, outcome, wrench,
                            rotation)

    def judged(self, outcome: Outcome, verdict: Optional[Stability], wrench: np.ndarray,
               started: float, time_limit_s: float, compliance: bool = False,
               verify: bool = False, compliance_options: Optional[dict] = None) -> SolveResult:
        """Return the result of ``outcome`` given its verdict: branch, estimate, refinement."""
        options = self.options
        extra = {} if compliance_options is None else compliance_options
        deadline = started + time_limit_s
        result = outcome.result(self.problem, wrench, self.method)
        if verdict is not None:
            if (not verdict.stable and options.follow_stable_branch
                    and time.perf_counter() < deadline):
                limits = Limits(options.tolerance, time_limit_s)
                stable, verdict = branch.follow_stable_branch(  # Newton as the corrector
                    self._state, self.params.stack_height,
                    partial(self._continue, limits=limits,
                            corrector=partial(self._newton, limits), newton=True),
                    self.stability, outcome, verdict, wrench, deadline)
                if stable is not outcome:
                    outcome, result = stable, stable.result(self.problem, wrench, self.method)
        if verdict is not None:
            branch.apply_verdict(result, verdict)
        if outcome.converged and not options.judge:
            # converged is all this result claims: it must not read as verified accurate
            result.accuracy_met = False
            result.message += '; not judged (judge=False): no stability verdict or error estimate'
        if outcome.converged and options.judge:
            estimate = self.estimate_error(result, outcome, wrench)
            if not result.accuracy_met and self.method == 'fast':
                refined = self._refine(result, estimate, self, wrench, deadline, time_limit_s,
                                       compliance, verify, extra, outcome.tracked)
                if refined is not None:
                    refined.solve_time_s = time.perf_counter() - started
                    return refined
            if not result.accuracy_met:
                result.message += refinement.accuracy_shortfall(result)
        result.solve_time_s = time.perf_counter() - started
        if compliance and outcome.converged:
            try:
                result.compliance = self.compliance(outcome, wrench, result.frames['de'],
                                                    **extra)
            except ArithmeticError as error:
                result.message += f'; no compliance: {error}'
        if verify:
            result.verification = verify_result(result, self.params)
        return result

    def estimate_error(self, result: SolveResult, outcome: Outcome,
                       wrench: np.ndarray) -> ErrorEstimate:
        """Set the result's discretization-error estimate (accuracy.py) and its verdict."""
        estimate = (outcome.estimate if outcome.estimate is not None
                    else self.estimate_at(outcome, result, wrench))
        refinement.set_estimate(result, estimate, self.options.accuracy)
        self._refinements.last_estimate = estimate
        return estimate

    def estimate_at(self, outcome: Outcome, result: SolveResult,
                    wrench: np.ndarray) -> ErrorEstimate:
        """Estimate the error of a converged outcome (refinement.estimate_at)."""
        return refinement.estimate_at(self.problem, outcome, result, wrench)

    def compliance(self, outcome: Outcome, wrench: np.ndarray, end_frame: np.ndarray,
                   **options: float) -> ComplianceAnalysis:
        """
        Compliance at a converged outcome (end-disk frame ``end_frame``, 4x4).

        With ``compliance_tolerance`` (relative; default 0) a stored factorization made
        elsewhere serves when the error it states is within it (compliance.stored_compliance:
        one probe shot, no new Jacobian); else the exact compliance, whose factorization
        becomes the stored one.
        """
        started = time.perf_counter()
        state = self._state
        stored = state.pose[0] if state.pose is not None else None
        tolerance = check_tolerance(options.pop('compliance_tolerance', EXACT))
        factorization = None
        if state.lu is not None and stored is not None:
            if state.exact_at is outcome.xs:
                factorization = (state.lu, stored)
            elif tolerance > 0.0:
                analysis = analysis_from_stored(self.problem, outcome.xs, wrench, outcome.rs,
                                                end_frame, state.lu, stored, tolerance,
                                                started, **options)
                if analysis is not None:
                    return analysis
        analysis, state.lu, pose = compliance_analysis(self.problem, outcome.xs, wrench,
                                                       factorization, end_frame[:3, :3],
                                                       started, **options)
        state.pose = (pose, wrench.copy())
        state.exact_at = outcome.xs
        verdicts = self._verdicts
        if factorization is None and verdicts.origin is not None:
            # the verdict at the exact factorization that is now the stored one, from the
            # compliance just made with it: the next warm solve keeps a verdict made on
            # the factorization it steps on (without compliance it may then be a usual
            # compiled row) instead of assessing that factorization again
            verdicts.verdict_lu = state.lu
            verdicts.verdict = assess_compliance(analysis.matrix.copy(), state.lu,
                                                 verdicts.origin)
        return analysis

    def result_at(self, xs: np.ndarray, wrench: np.ndarray,
                  factorization: Optional[Factorization] = None) -> SolveResult:
        """
        Return the SolveResult at nondimensional unknowns ``xs`` under the checked ``wrench``.

        One shot with the shape recorded, the verdict (from ``factorization``, as
        ``start_at`` takes it, else from an exact Jacobian at ``xs``) and the error
        estimate, from the same arithmetic as a solve, without the continuation around it;
        a residual above the tolerance gives ``converged`` False and a message, never an
        iteration. The warm start and stored factorization are left as they were.
        """
        started = time.perf_counter()
        xs = np.array(xs, dtype=float)
        state = self._state
        saved = (state.lu, state.pose, state.exact_at)
        tolerance = self.options.tolerance
        rs = self.problem.residual_and_shape(xs, wrench)
        largest = float(np.abs(rs).max())
        converged = largest <= tolerance
        lu, pose = (None, None) if factorization is None else (
            factorization[0], (factorization[1], np.array(factorization[2], dtype=float)))
        outcome = Outcome(xs, rs, 0, converged, 'converged' if converged else
                          f'residual {largest:.2g} above the tolerance {tolerance:.2g} '
                          'at the given unknowns', lu, pose)
        outcome.shape = (xs, *self.problem.recorded_shape(0))
        result = outcome.result(self.problem, wrench, self.method)
        if converged:
            try:
                if self.method == 'fast':
                    branch.apply_verdict(result, self.stability(outcome, wrench,
                                                                result.frames['de'][:3, :3]))
                self.estimate_error(result, outcome, wrench)
            finally:
                state.lu, state.pose, state.exact_at = saved
        result.solve_time_s = time.perf_counter() - started
        return result

    # refinement ------------------------------------------------------------------------------
    def _refine(self, result: SolveResult, estimate: ErrorEstimate, source: 'Engine',
                wrench: np.ndarray, deadline: float, time_limit_s: float, compliance: bool,
                verify: bool, compliance_options: dict,
                tracked: bool = False) -> Optional[SolveResult]:
        """
        Refine ``result`` of ``source`` (this engine or a refined one) by refinement.refine.

        Each re-solve is an engine of ``Refinements`` taking over from the last converged
        one; the next warm solve starts at the refined steps (``Refinements.kept``).
        """
        sources = [source]

        def attempt(steps: int, cold: bool,
                    limit_s: float) -> Tuple[SolveResult, Optional[ErrorEstimate]]:
            """Re-solve at ``steps`` from the last converged source (or unloaded: ``cold``)."""
            engine = self._refinements.engine(self, steps)
            engine.take_over(sources[-1])
            tried = engine.solve(wrench.copy(), time.perf_counter(), limit_s,
                                 warm_start=not cold, compliance=compliance, verify=verify,
                                 compliance_options=compliance_options,
                                 path='tracking' if tracked else 'default')
            if tried.converged:
                sources.append(engine)
            return tried, engine.last_estimate

        refined = refinement.refine(result, estimate, self.options.accuracy, deadline,
                                    time_limit_s, attempt, tracked)
        if refined is not None:
            self._refinements.kept = refined.steps_per_segment
        return refined

    def _solve_kept(self, wrench: np.ndarray, started: float, time_limit_s: float,
                    compliance: bool, verify: bool,
                    compliance_options: dict) -> Optional[SolveResult]:
        """
        Warm solve at the steps per segment kept from an earlier refinement.

        A warm sequence that needed refinement usually needs it again: solving at the kept
        steps directly skips this engine's own solve and the refined one after it. The solve
        is judged at those steps: refined further when its estimate misses the target
        (``_refine``), and the next solve steps down (accuracy.kept_steps) when it has room.
        Returns None, forgetting the kept steps, when that solve did not converge or the
        wrench moved by more than STALE_WRENCH (relative) since the last one (a long
        continuation, cheaper at this engine's steps): the engine then solves as usual, from
        the last solution.
        """
        refinements = self._refinements
        steps = refinements.kept
        assert steps is not None
        engine = refinements.engines[steps]
        refinements.kept = None
        previous = engine.previous_solution
        if previous is None or float(np.linalg.norm(wrench - previous[1])) > \
                STALE_WRENCH * float(np.linalg.norm(wrench)):
            return None  # not a warm sequence: a long continuation is cheaper at fewer steps
        attempt = engine.solve(wrench.copy(), time.perf_counter(), time_limit_s,
                               compliance=compliance, verify=verify,
                               compliance_options=compliance_options)
        if not attempt.converged:
            return None
        estimate = engine.last_estimate
        assert engine.previous_solution is not None and estimate is not None
        self._state.previous = engine.previous_solution
        refinements.last_estimate = estimate
        target = self.options.accuracy
        attempt.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
        extra = '' if attempt.message == 'converged' else f' ({attempt.message})'
        attempt.message = (f'converged{extra} at {steps} steps per segment, kept from the '
                           'refinement of an earlier solve')
        result = attempt
        if not attempt.accuracy_met:
            refined = self._refine(attempt, estimate, engine, wrench, started + time_limit_s,
                                   time_limit_s, compliance, verify, compliance_options)
            if refined is not None:
                result = refined
            else:
                refinements.kept = steps
                result.message += refinement.accuracy_shortfall(result)
        else:
            fewer = kept_steps(estimate, target.position_m, target.angle_deg,
                               self.params.steps_per_segment)
            if fewer == steps:
                refinements.kept = steps
            elif fewer > self.params.steps_per_segment:
                refinements.kept = fewer
                refinements.engine(self, fewer).take_over(engine)
            else:
                self.take_over(engine)
        result.solve_time_s = time.perf_counter() - started
        return result

    # the correctors, bound to this engine's problem, state and the solve's limits -------------
    @property
    def lifting(self) -> bool:
        """Whether cold continuations correct by lifted Newton (multiple shooting) now."""
        lift_from = self.options.lift_from_spacers
        return (lift_from is not None and self.method == 'fast' and self.jacobian == 'exact'
                and self.params.spacers_per_joint >= lift_from)

    def _newton(self, limits: Limits, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                lu: Optional[tuple], max_iterations: int, pose_in: Optional[Pose] = None,
                known: Optional[Tuple[np.ndarray, int]] = None) -> Outcome:
        """Correct by correctors.newton."""
        return correctors.newton(self.problem, limits, xs, wrench, deadline, lu,
                                 max_iterations, pose_in, known)

    def _levenberg_marquardt(self, limits: Limits, xs: np.ndarray, wrench: np.ndarray,
                             deadline: float, lu: Optional[tuple], max_iterations: int,
                             pose_in: Optional[Pose] = None) -> Outcome:
        """Correct by correctors.levenberg_marquardt (``lu``, ``pose_in``: not used)."""
        return correctors.levenberg_marquardt(self.problem, limits, xs, wrench, deadline,
                                              max_iterations)

    def _lifted_newton(self, limits: Limits, xs: np.ndarray, wrench: np.ndarray,
                       deadline: float, lu: Optional[tuple], max_iterations: int,
                       pose_in: Optional[Pose] = None) -> Outcome:
        """Correct by correctors.lifted_newton with this engine's lifted nodes."""
        return correctors.lifted_newton(self.problem, limits, self._state.lifted, xs, wrench,
                                        deadline, lu, max_iterations, pose_in)

    def _continue(self, wrench: np.ndarray, warm_start: bool, deadline: float, limits: Limits,
                  corrector: continuation.Corrector, newton: bool) -> Outcome:
        """Continue to ``wrench`` (continuation.continue_to); cold Newton ones may lift."""
        lifting = newton and self.lifting
        return continuation.continue_to(
            self.problem, self._state, limits, self.options.max_iterations, wrench,
            warm_start, deadline, corrector,
            partial(self._lifted_newton, limits) if lifting else None)
