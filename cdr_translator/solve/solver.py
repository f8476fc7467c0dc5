"""
TranslatorSolver: Newton on the shooting residual, warm starts, continuation, baseline.

``method='fast'`` (default): compiled kernel; Newton with the exact Jacobian (or 'fd'),
backtracking line search, and for warm starts a first-order predictor plus chord steps
that reuse the previous LU factorization, refreshed only when convergence slows. Cold
solves of translators with spacer disks correct by multiple shooting instead
(multiple_shooting.py).
``method='paper'``: the paper's numerics as published (Section III.D) — the same model
source run interpreted, Levenberg-Marquardt (Eq. 13) with a finite-difference Jacobian
of one residual per column, stopping at the paper's tolerances. It is the baseline that
benchmarks divide by.

The solver is the front of its parts: continuation.py (the load path, with the state
carried between solves), correctors.py, branch.py (stability verdict, stable branch),
refinement.py (error estimate, accuracy target), given_unknowns.py (``result_at``) and
wrench_estimation.py (the wrench from a measured pose, by cdr_translator.estimation).
"""

from contextlib import nullcontext
from functools import partial
import math
import time
from typing import Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

from . import (branch, continuation, correctors, given_unknowns, lean_rows, refinement,
               wrench_estimation)
from .batch import BatchResult, check_wrenches
from .continuation import LIFT_FROM_SPACERS, PathState
from .correctors import Limits, Outcome, Pose
from .result import SolveResult
from .verify import verify as verify_result
from .. import estimation
from .._blas import one_blas_thread
from .._jit import interpreted_kernels
from .._linalg import residual_norm
from ..analysis.accuracy import ErrorEstimate
from ..analysis.stability import Reference, Stability
from ..bvp.problem import JACOBIANS, Problem
from ..checks import check_integer, check_number, check_vector
from ..params.translator_params import Accuracy, TranslatorParams

METHODS = ('fast', 'paper')

#: How a solve follows the load path: the chord/Newton continuation ('default', with the
#: tracking one as its fallback) or path_following.track alone ('tracking').
PATHS = ('default', 'tracking')


#: The default moment of a solve: none.
NO_MOMENT = (0.0, 0.0, 0.0)

_FLOAT = np.dtype(float)


def check_wrench(force: ArrayLike, moment: ArrayLike = NO_MOMENT) -> np.ndarray:
    """
    Return the 6-vector [force; moment]; InputError (a ValueError) naming a bad component.

    Float arrays of three (and the default moment) are copied in without numpy's conversion
    chain: the check then costs about a microsecond of a warm solve, not several.
    """
    if type(force) is np.ndarray and force.dtype is _FLOAT and force.shape == (3,):
        if moment is NO_MOMENT:
            wrench = np.zeros(6)
            wrench[:3] = force
        elif type(moment) is np.ndarray and moment.dtype is _FLOAT and moment.shape == (3,):
            wrench = np.concatenate((force, moment))
        else:
            wrench = None
        if wrench is not None and math.isfinite(wrench.dot(wrench)):  # else: name the bad one
            return wrench
    return np.concatenate([check_vector('force', force), check_vector('moment', moment)])


class TranslatorSolver:
    """
    Solve the loaded shape of one translator; successive solves warm-start.

    >>> solver = TranslatorSolver(TranslatorParams.from_yaml())
    >>> result = solver.solve([12.0, 0.0, 0.0])      # N, in {pe}, at the end-disk centre
    """

    def __init__(self, params: Optional[TranslatorParams] = None, method: str = 'fast',
                 tolerance: float = 1e-10, max_iterations: Optional[int] = None,
                 time_limit_s: float = 10.0, jacobian: str = 'exact',
                 accuracy: Optional[Accuracy] = None,
                 follow_stable_branch: bool = True, fallback: bool = True,
                 path: str = 'default', judge: bool = True) -> None:
        """
        Set up for ``params`` (default: config/translator.yaml).

        ``tolerance`` bounds the largest nondimensional residual (lengths in units of the
        disk spacing, forces in EI/D^2, moments in EI/D). ``max_iterations`` caps the
        Newton iterations of one continuation step (default 12: a step that needs more is
        halved instead) or, for ``method='paper'``, the Levenberg-Marquardt iterations
        (default 30); ``time_limit_s`` caps a whole solve. ``jacobian`` is 'exact' (the
        tangent-linear shot of tangent.translator_jacobian, default) or 'fd' (forward
        differences, one shot per unknown: the former default, kept for tests and the
        benchmark); ``method='paper'`` always differentiates the paper's way, 'fd'.
        ``accuracy`` is the discretization-error target of every solve (default: the
        accuracy keys of config/translator.yaml): a converged solve whose estimate
        (accuracy.py) exceeds it is re-solved with more steps per segment, whichever
        continuation found it, within the time limit (refinement.py). Every converged
        solve is judged stable or not (stability.py); an unstable one is, with
        ``follow_stable_branch``, perturbed along its critical mode and re-converged on the
        stable branch when one is found (without it, or if none is found, it is returned
        with ``stable`` False and a message saying so; studies of unstable equilibria such
        as studies/hard_cases.py switch it off). With ``fallback`` (default) a solve whose
        continuation stalled (also after a restart from the unloaded state) is continued
        from the last state it reached by path_following.track: a Hermite predictor on
        exact tangents and an exact-Newton corrector that accepts a residual at the
        shot's rounding floor (said in the message); solves that converge without it are
        unchanged. ``method='paper'`` has no fallback.
        ``path='tracking'`` skips the default continuation and follows the load path with
        the fallback's alone (from the previous solution, else from the unloaded state):
        fewer, exact-Jacobian iterations, which pays on fine grids of the hard cases.
        With spacer disks (``lift_from_spacers`` or more per joint, LIFT_FROM_SPACERS) and
        the exact Jacobian, a cold continuation corrects by the lifted Newton method
        (multiple_shooting.py); warm solves stay single shooting (chord steps).
        ``judge=False`` skips the stability verdict, the error estimate and so refinement:
        ``stable`` stays None, the estimates NaN and ``accuracy_met`` False, as the message
        says (for a caller that iterates on leg solutions and judges only the one it keeps,
        with ``result_at``: robot/delta.py's nested iteration).
        """
        if path not in PATHS:
            raise ValueError(f'path must be one of {PATHS}, got {path!r}')
        if jacobian not in JACOBIANS:
            raise ValueError(f'jacobian must be one of {JACOBIANS}, got {jacobian!r}')
        if method not in METHODS:
            raise ValueError(f'method must be one of {METHODS}, got {method!r}')
        if params is not None and not isinstance(params, TranslatorParams):
            raise ValueError(f'params must be a TranslatorParams (TranslatorParams.from_yaml '
                             f'reads a params file), got {type(params).__name__} {params!r}')
        if accuracy is not None and not isinstance(accuracy, Accuracy):
            raise ValueError(f'accuracy must be an Accuracy(position_m, angle_deg), got '
                             f'{type(accuracy).__name__} {accuracy!r}')
        self.params = params if params is not None else TranslatorParams.from_yaml()
        self.method = method
        if max_iterations is None:
            max_iterations = 30 if method == 'paper' else 12
        self.max_iterations = check_integer('max_iterations', max_iterations, low=1)
        self.time_limit_s = check_number('time_limit_s', time_limit_s, low=0.0)
        self.tolerance = check_number('tolerance', tolerance, low=0.0, low_open=True)
        if method == 'paper':
            jacobian = 'fd'
        self.jacobian = jacobian
        kernel = interpreted_kernels() if method == 'paper' else None
        self.problem = (Problem(self.params, jacobian=jacobian) if kernel is None
                        else Problem(self.params, kernel, jacobian))
        self._state = PathState(self.problem.size)
        self._verdicts = branch.Verdicts()
        self._refinements = refinement.Refinements()
        self.accuracy = accuracy if accuracy is not None else Accuracy.from_yaml()
        self.follow_stable_branch = follow_stable_branch
        self.judge = judge
        self.fallback = fallback
        self.path = path
        #: cold continuations correct by lifted Newton from this many spacer disks per joint
        #: on (None: never); LIFT_FROM_SPACERS unless changed (benchmarks compare both)
        self.lift_from_spacers = LIFT_FROM_SPACERS
        if method == 'fast':
            continuation.unloaded(self.problem, self._state)  # compiles the kernels now

    @property
    def _previous(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """(unknowns, wrench) of the last converged solve, the next warm start."""
        return self._state.previous

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        state = self._state
        state.previous, state.lu, state.pose = None, None, None
        self._refinements.kept = None

    def start_from(self, result: SolveResult, keep_factorization: bool = False) -> None:
        """
        Warm-start the next solve from ``result``, e.g. one of a coarser discretization.

        The unknowns mean the same at any ``steps_per_segment``; only the number of spacer
        disks (and so their count) must match. With ``keep_factorization`` the solver's own
        factorization from its previous solve stays for the chord steps (refinement does
        this: its solver, reused solve after solve, then rarely rebuilds a Jacobian).
        """
        unknowns = np.asarray(result.unknowns, dtype=float)
        if unknowns.shape != (self.problem.size,) or not np.all(np.isfinite(unknowns)):
            raise ValueError(f'cannot start from a result with {unknowns.shape} unknowns '
                             f'(finite ones, {self.problem.size} expected)')
        state = self._state
        state.previous = (unknowns / self.problem.x_scale,
                          np.concatenate([result.force, result.moment]))
        self._refinements.kept = None
        if not keep_factorization:
            state.lu, state.pose = None, None

    def start_at(self, xs: np.ndarray, wrench: np.ndarray,
                 factorization: Optional[Tuple[tuple, np.ndarray, np.ndarray]] = None) -> None:
        """
        Warm-start the next solve from nondimensional unknowns ``xs`` at ``wrench`` (SI).

        For a caller that iterates on the shooting residual itself (robot/delta.py's coupled
        Newton): a solve at ``wrench`` then only confirms the residual and judges stability
        and the discretization error. ``factorization`` = (LU of the Jacobian, its end-frame
        derivative ``problem.pose_jacobian``, the wrench it was made at) is used for both and
        for chord steps; without one, the stability verdict factors an exact Jacobian.
        """
        state = self._state
        state.previous = (np.array(xs, dtype=float), check_wrench(wrench[:3], wrench[3:]))
        self._refinements.kept = None
        if factorization is None:
            state.lu, state.pose = None, None
        else:
            lu, pose, made_at = factorization
            state.lu, state.pose = lu, (pose, np.array(made_at, dtype=float))

    @one_blas_thread
    def result_at(self, xs: np.ndarray, wrench: np.ndarray,
                  factorization: Optional[Tuple[tuple, np.ndarray, np.ndarray]] = None
                  ) -> SolveResult:
        """
        Return the SolveResult at nondimensional unknowns ``xs`` under ``wrench`` (SI).

        For a caller that converged the shooting residual itself (robot/delta.py's coupled
        Newton): what ``start_at(xs, wrench, factorization)`` and a solve give when the
        residual at ``xs`` is within the tolerance (zero iterations, the same shape,
        stability verdict and error estimate from the same arithmetic), without the
        continuation around it: one shot with the shape recorded, the verdict (from
        ``factorization``, as ``start_at`` takes it; an exact Jacobian at ``xs`` when
        there is none or it is too far, as in a solve) and the error estimate, whatever
        ``judge`` says. Unlike a solve it iterates never: a residual above the tolerance
        gives ``converged`` False and a message. The solver's warm start and stored
        factorization are unchanged.
        """
        return given_unknowns.result_at(self, xs, check_wrench(wrench[:3], wrench[3:]),
                                        factorization)

    def solve(self, force: ArrayLike, moment: ArrayLike = NO_MOMENT,
              warm_start: bool = True, compliance: bool = False, verify: bool = False,
              **compliance_options: float) -> SolveResult:
        """
        Solve for an end-disk wrench (N, N m) in {pe} applied at the end-disk centre.

        With ``compliance`` the result also carries the end-disk compliance matrix and its
        primary-mobility analysis (``cdr_translator.analysis.compliance``; options
        ``sparsity_threshold`` and ``mobility_ratio`` go to ``compliance.analyse``), computed
        by implicit differentiation at the converged solution, timed apart from the solve.
        With ``verify`` the result is re-checked independently (``cdr_translator.solve.verify``:
        ``result.verification``, ``result.verified``), also timed apart (10-100 ms).
        A warm solve after a refined one solves at the refined steps per segment directly
        (``refinement.solve_kept``, docs/explanation/solution_quality.md).
        """
        wrench = check_wrench(force, moment)
        started = time.perf_counter()
        if warm_start and not (compliance or verify) and self._refinements.kept is None:
            return lean_rows.solve_warm(self, wrench, started, compliance_options)
        return self._solve(wrench, started, warm_start, compliance, verify,
                           compliance_options)

    @one_blas_thread
    def _solve(self, wrench: np.ndarray, started: float, warm_start: bool, compliance: bool,
               verify: bool, compliance_options: dict) -> SolveResult:
        """Solve at ``wrench`` by the general path (``solve``), BLAS on one thread."""
        refinements = self._refinements
        if refinements.kept is not None and not warm_start:
            refinements.kept = None  # a cold solve starts over at this solver's steps
        elif refinements.kept is not None:
            kept = refinement.solve_kept(self, wrench, started, compliance, verify,
                                         compliance_options)
            if kept is not None:
                return kept
        outcome = self._correct(wrench, warm_start, started)
        return self._judged(outcome, self._verdict(outcome, wrench), wrench, started,
                            compliance, verify, compliance_options)

    @one_blas_thread
    def estimate_wrench(self, position: ArrayLike, quaternion_xyzw: Optional[ArrayLike] = None,
                        *, pose_covariance: Optional[ArrayLike] = None,
                        moment: Optional[ArrayLike] = None,
                        force: Optional[ArrayLike] = None,
                        estimate: Optional[estimation.Components] = None,
                        prior_mean: Optional[ArrayLike] = None,
                        prior_covariance: Optional[ArrayLike] = None,
                        target_force_sd: float = estimation.DEFAULT_TARGET_FORCE_SD,
                        target_moment_sd: float = estimation.DEFAULT_TARGET_MOMENT_SD
                        ) -> estimation.WrenchEstimate:
        """
        Estimate the end-disk wrench (N, N m, in {pe}) from a measured end-disk pose.

        ``position`` (m) and ``quaternion_xyzw`` in {pe}. ``estimate`` names the components
        solved for: 'wrench', 'force' (a point contact at the tip: the moment held),
        'moment', 'lateral' (the axial force and the moment held), or names from 'fx', 'fy',
        'fz', 'mx', 'my', 'mz'; the others are held at ``force`` and ``moment`` (default
        zero). Without ``estimate``: all six with an orientation, else the force (or the
        moment when only ``force`` is given). ``pose_covariance``: 6x6 (position, rotation
        about the base axes; 3x3 for a position); without one the pose is exact and the
        accuracy not assessed. ``prior_mean`` (6) and ``prior_covariance`` (6x6, default
        zero mean, 25 N and 2.5 N m standard deviations): the Gaussian prior on the wrench;
        ``target_force_sd`` and ``target_moment_sd``: the posterior standard deviations that
        meet the accuracy target. A maximum-a-posteriori estimate with the exact compliance,
        warm-started from the previous estimate (cdr_translator/estimation); an
        unmatched pose is a flagged result, bad input an InputError (a ValueError).
        """
        return wrench_estimation.estimate_wrench(
            self, position, quaternion_xyzw, pose_covariance=pose_covariance, moment=moment,
            force=force, estimate=estimate, prior_mean=prior_mean,
            prior_covariance=prior_covariance, target_force_sd=target_force_sd,
            target_moment_sd=target_moment_sd)

    @one_blas_thread
    def solve_many(self, forces: ArrayLike, moments: Optional[ArrayLike] = None, *,
                   compliance: bool = False) -> BatchResult:
        """
        Solve the wrenches of rows (N, 3) of ``forces`` and ``moments`` (default none) in order.

        The rows equal N consecutive ``solve`` calls (runs of usual warm rows: one compiled
        loop, lean_rows.solve_rows). A failing row is flagged (``converged`` False,
        ``message``), never raised; InputError (a ValueError) names a bad input row.
        """
        wrenches = check_wrenches(forces, moments)
        batch = BatchResult.empty(wrenches, compliance)
        lean_rows.solve_rows(self, batch, wrenches, range(len(wrenches)), compliance)
        return batch

    def _correct(self, wrench: np.ndarray, warm_start: bool, started: float) -> Outcome:
        """Converge at ``wrench``: the warm step, else continuation, restart, fallback."""
        state = self._state
        state.exact_at = None  # the unknowns state.lu is exact at, once known
        deadline = started + self.time_limit_s
        corrector = self._levenberg_marquardt if self.method == 'paper' else self._newton
        warm = warm_start and state.previous is not None and bool(state.previous[1].any())
        begin = state.previous[0] if warm and state.previous is not None else None
        usual, spent = (self._warm_step(wrench, deadline)  # compiled: nothing to silence
                        if warm and self.method == 'fast' and self.path != 'tracking'
                        else (None, 0))
        # numpy's errstate costs 5 us: only the general path has rejected steps that overflow
        with nullcontext() if usual is not None else np.errstate(over='ignore', invalid='ignore'):
            if usual is not None:
                outcome = usual
            elif self.path == 'tracking' and self.method == 'fast':
                outcome = continuation.track_only(self.problem, state, self._limits(),
                                                  wrench, warm, deadline)
            else:
                outcome = self._continuation(wrench, warm_start, deadline, corrector)
            outcome.iterations += spent
            # a warm sequence the default continuation followed (the paper's baseline and
            # the tracking path keep their first-order predictor): the path extrapolated
            continued = outcome.converged and self.path != 'tracking' and self.method == 'fast'
            if warm and not outcome.converged and time.perf_counter() < deadline:
                # the warm start may sit on another branch or too far away: restart cold
                restart = self._continuation(wrench, False, deadline, corrector)
                restart.iterations += outcome.iterations
                restart.message += ' (after a restart from the unloaded state)'
                if restart.converged or residual_norm(restart.rs) < residual_norm(outcome.rs):
                    outcome = restart
            if (not outcome.converged and self.fallback and self.method == 'fast'
                    and outcome.reached is not None and time.perf_counter() < deadline):
                outcome = continuation.track(self.problem, state, self._limits(), outcome,
                                             wrench, deadline)
        if outcome.converged:
            state.previous = (outcome.xs, wrench)
            continuation.extend_path(state, outcome.xs, wrench,
                                     continued and state.path_last is begin)
        return outcome

    def _verdict(self, outcome: Outcome, wrench: np.ndarray) -> Optional[Stability]:
        """Stability verdict of a converged fast solve that is judged, else None."""
        if not (outcome.converged and self.method == 'fast' and self.judge):
            return None
        if outcome.shape is None or outcome.shape[0] is not outcome.xs:
            outcome.shape = (outcome.xs, *self.problem.shape(outcome.xs, wrench))
        return self._stability(outcome, wrench, outcome.shape[2][3][:3, :3])

    def _judged(self, outcome: Outcome, verdict: Optional[Stability], wrench: np.ndarray,
                started: float, compliance: bool, verify: bool,
                compliance_options: dict) -> SolveResult:
        """Return the result of ``outcome`` given its verdict: branch, estimate, refinement."""
        state, refinements = self._state, self._refinements
        deadline = started + self.time_limit_s
        result = outcome.result(self.problem, wrench, self.method)
        if verdict is not None:
            if (not verdict.stable and self.follow_stable_branch
                    and time.perf_counter() < deadline):
                stable, verdict = branch.follow_stable_branch(  # Newton as the corrector
                    state, self.params.stack_height,
                    partial(self._continuation, corrector=self._newton), self._stability,
                    outcome, verdict, wrench, deadline)
                if stable is not outcome:
                    outcome, result = stable, stable.result(self.problem, wrench, self.method)
        if verdict is not None:
            branch.apply_verdict(result, verdict)
        if outcome.converged and not self.judge:
            # converged is all this result claims: it must not read as verified accurate
            result.accuracy_met = False
            result.message += '; not judged (judge=False): no stability verdict or error estimate'
        if outcome.converged and self.judge:
            self._estimate_error(result, outcome, wrench)
            if not result.accuracy_met and self.method == 'fast':
                assert refinements.last_estimate is not None  # set by _estimate_error
                refined = refinement.refine(self, result, refinements.last_estimate, self,
                                            wrench, deadline, compliance, verify,
                                            compliance_options, outcome.tracked)
                if refined is not None:
                    refined.solve_time_s = time.perf_counter() - started
                    return refined
            if not result.accuracy_met:
                result.message += refinement.accuracy_shortfall(result)
        result.solve_time_s = time.perf_counter() - started
        if compliance and outcome.converged:
            try:
                result.compliance = lean_rows.compliance_at(
                    self, outcome, wrench, result.frames['de'][:3, :3], **compliance_options)
            except ArithmeticError as error:
                result.message += f'; no compliance: {error}'
        if verify:
            result.verification = verify_result(result, self.params)
        return result

    # the parts, bound to this solver's problem, limits and state ------------------------------
    def _limits(self) -> Limits:
        """Return what ends a corrector now (the time limit may have been changed)."""
        return Limits(self.tolerance, self.time_limit_s)

    def _lifting(self) -> bool:
        """Say whether cold continuations correct by lifted Newton (multiple shooting)."""
        return (self.lift_from_spacers is not None and self.method == 'fast'
                and self.jacobian == 'exact'
                and self.params.spacers_per_joint >= self.lift_from_spacers)

    def _newton(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                lu: Optional[tuple], max_iterations: int, pose_in: Optional[Pose] = None,
                known: Optional[Tuple[np.ndarray, int]] = None) -> Outcome:
        """Correct by correctors.newton."""
        return correctors.newton(self.problem, self._limits(), xs, wrench, deadline, lu,
                                 max_iterations, pose_in, known)

    def _levenberg_marquardt(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                             lu: Optional[tuple], max_iterations: int,
                             pose_in: Optional[Pose] = None) -> Outcome:
        """Correct by correctors.levenberg_marquardt (``lu``, ``pose_in``: not used)."""
        return correctors.levenberg_marquardt(self.problem, self._limits(), xs, wrench,
                                              deadline, max_iterations)

    def _lifted_newton(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                       lu: Optional[tuple], max_iterations: int,
                       pose_in: Optional[Pose] = None) -> Outcome:
        """Correct by correctors.lifted_newton with this solver's lifted nodes."""
        return correctors.lifted_newton(self.problem, self._limits(), self._state.lifted, xs,
                                        wrench, deadline, lu, max_iterations, pose_in)

    def _continuation(self, wrench: np.ndarray, warm_start: bool, deadline: float,
                      corrector: continuation.Corrector) -> Outcome:
        """Continue to ``wrench`` (continuation.continue_to); cold ones lift (_lifting)."""
        lifting = corrector == self._newton and self._lifting()
        return continuation.continue_to(
            self.problem, self._state, self._limits(), self.max_iterations, wrench,
            warm_start, deadline, corrector, self._lifted_newton if lifting else None)

    def _usual_solve(self, wrench: np.ndarray, started: float) -> tuple:
        """Solve a usual warm row in one compiled call (lean_rows.usual_solve)."""
        return lean_rows.usual_solve(self, wrench, started)

    def _warm_step(self, wrench: np.ndarray, deadline: float) -> Tuple[Optional[Outcome], int]:
        """Solve the usual warm case in one compiled call (continuation.warm_step)."""
        settings = continuation.warm_settings(self._state, self.tolerance, self.max_iterations,
                                              self.judge)
        return continuation.warm_step(self.problem, self._state, self.max_iterations,
                                      settings, wrench, deadline, self._newton)

    def _stability(self, outcome: Outcome, wrench: np.ndarray,
                   rotation: Optional[np.ndarray] = None) -> Stability:
        """Verdict at a converged outcome (branch.judge)."""
        return branch.judge(self.problem, self._state, self._verdicts, outcome, wrench,
                            rotation)

    def _origin(self) -> Reference:
        """Return the unloaded state's stiffness and det J sign (branch.origin)."""
        return branch.origin(self.problem, self._state, self._verdicts)

    def _estimate_error(self, result: SolveResult, outcome: Outcome,
                        wrench: np.ndarray) -> None:
        """Set the result's discretization-error estimate (accuracy.py) and its verdict."""
        estimate = (outcome.estimate if outcome.estimate is not None
                    else self._estimate_at(outcome, result, wrench))
        refinement.set_estimate(result, estimate, self.accuracy)
        self._refinements.last_estimate = estimate

    def _estimate_at(self, outcome: Outcome, result: SolveResult,
                     wrench: np.ndarray) -> ErrorEstimate:
        """Estimate the error of a converged outcome (refinement.estimate_at)."""
        return refinement.estimate_at(self.problem, outcome, result, wrench)
