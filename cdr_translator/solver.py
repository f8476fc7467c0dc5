"""
TranslatorSolver: Newton on the shooting residual, warm starts, continuation, baseline.

``method='fast'`` (default): compiled kernel; Newton with the exact Jacobian (or 'fd'),
backtracking line search, and for warm starts a first-order predictor plus chord steps
that reuse the previous LU factorization, refreshed only when convergence slows. Cold
solves of translators with spacer disks correct by multiple shooting instead (multiple_shooting).
``method='paper'``: the paper's numerics as published (Section III.D) — the same model
source run interpreted, Levenberg-Marquardt (Eq. 13) with a finite-difference Jacobian
of one residual per column, stopping at the paper's tolerances. It is the baseline that
benchmarks divide by.
"""

from dataclasses import dataclass
import functools
import math
import time
from typing import Any, Callable, Dict, Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

from . import chord, multiple_shooting, path_following, stability
from ._jit import interpreted_kernels
from .accuracy import ErrorEstimate, estimate as estimate_error, kept_steps, meets, refined_steps
from .checks import check_integer, check_number, check_vector
from .compliance import compliance_analysis
from .params import Accuracy, MAX_REFINED_STEPS, TranslatorParams
from .problem import JACOBIANS, Problem, RESIDUAL_KINDS
from .result import FRAME_NAMES, PAPER_TOLERANCES, SolveResult
from .verify import verify as verify_result
from .warm_step import settings_array as warm_step_settings, warm_step

METHODS = ('fast', 'paper')

#: How a solve follows the load path: the chord/Newton continuation ('default', with the
#: tracking one as its fallback) or path_following.track alone ('tracking').
PATHS = ('default', 'tracking')

#: A chord step that shrinks the residual by less than this rebuilds the Jacobian. A rebuild
#: (Jacobian, LU, stability verdict) costs about as much as a dozen Newton-Broyden steps: on
#: the node bench's 100 Hz sweep (0.19 N steps) 0.25 rebuilt 0.54 times per solve (p50
#: 1.3 ms), 0.5 0.15 times (p50 0.7 ms); at 1 kHz steps and along bench.speed_vs_error's
#: sequence the two are within noise of each other (fewer rebuilds, one more step).
CHORD_RATE = 0.5

#: Largest nondimensional change of the unknowns a first continuation step may predict.
PREDICTOR_REACH = 0.3

#: Smallest fraction of the remaining wrench change a continuation step may take.
MIN_CONTINUATION_STEP = 1e-3

#: A stability margin below this is recomputed on an exact Jacobian at the solution.
RECHECK_MARGIN = 0.05

#: A factorization made at a wrench further than this (relative to |w|, SI components)
#: from the solved one is not trusted for the stability verdict.
STALE_WRENCH = 0.2

#: Smallest load (a fraction of stability.load_scale, w*) that a wrench's drift since its
#: factorization is measured against for the stability verdict: at w* / 2 a drift within half
#: the margin (the rule) moves the margin by at most about a quarter of it near no load.
#: Measuring against |w| alone, a translator at rest under 0.05 N of sensor noise rebuilt the
#: exact Jacobian on every solve (1.73 ms median; 0.56 ms at a 5 N offset).
LOAD_FLOOR = 0.5

#: Refined re-solves at most (each aims at the target from the error's N^-4 law).
MAX_REFINEMENTS = 5

#: Perturb-and-reconverge attempts past a bifurcation (a symmetric structure may first
#: land on a saddle branch, e.g. buckled along x when the stable one is diagonal).
BRANCH_ATTEMPTS = 3

#: Size of the critical-mode imperfection that steers past a bifurcation, relative to the
#: wrench (stability margin < 0): large enough to leave the unstable branch's basin.
IMPERFECTION = 0.02

#: Cold continuations of translators with at least this many spacer disks per joint correct
#: by the lifted Newton method (multiple_shooting.newton) instead of single shooting;
#: None: never.
LIFT_FROM_SPACERS: Optional[int] = 2

#: Largest nondimensional residual at which a corrector out of iterations gets another
#: round on the same step instead of a halved step (it is converging, only slowly).
NEARLY_CONVERGED = 1e-6

#: A warm solve's whole-step predictor extrapolates the last solutions of a sequence (three
#: to chord.PATH_LENGTH) when their wrenches' polynomial reaches the new wrench within this
#: fraction of the step (else: the first-order predictor alone). Along
#: bench.speed_vs_error's sequence the quadratic cut the corrector iterations from 5.06 to
#: 3.31 per solve.
EXTRAPOLATION_MISS = 0.5


@dataclass
class _Outcome:
    """Where an iteration ended: nondimensional unknowns and residual, and why."""

    xs: np.ndarray
    rs: np.ndarray
    iterations: int
    converged: bool
    message: str
    lu: Optional[tuple] = None
    #: (derivative of the end-disk frame, or None with jacobian='fd'; wrench) at the point
    #: ``lu`` factorizes
    pose: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None
    #: (unknowns, wrench) of the last converged state of a stalled continuation
    reached: Optional[Tuple[np.ndarray, np.ndarray]] = None
    #: (the unknowns it belongs to, centre lines, frames) recorded by the last shot, if any
    shape: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None
    #: the error estimate and largest residuals by kind, when the iteration made them
    #: (warm_step.py); None: computed from the rest
    estimate: Optional[ErrorEstimate] = None
    residual_by_kind: Optional[dict] = None


#: A lifted Newton state: unknowns, their nodes (SI), a factorization made on the way (or
#: None) and the node tangents of the same lifted shot (or None).
_LiftedState = Tuple[np.ndarray, np.ndarray, Optional[tuple], Optional[np.ndarray]]


def check_wrench(force: ArrayLike, moment: ArrayLike) -> np.ndarray:
    """Return the 6-vector [force; moment]; InputError (a ValueError) naming a bad component."""
    return np.concatenate([check_vector('force', force), check_vector('moment', moment)])


def _blas_controller() -> Optional[Any]:
    """
    Return a threadpoolctl controller of the loaded BLAS libraries; None without threadpoolctl.

    threadpoolctl is optional: rosdep has no key for it (so package.xml cannot declare it),
    pip installs get it (setup.py). Without it BLAS keeps its own thread count, which
    ``OPENBLAS_NUM_THREADS=1`` in the environment sets to one.
    """
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


#: The BLAS libraries loaded in this process (numpy's and scipy's OpenBLAS), or None
_BLAS = _blas_controller()


#: The BLAS libraries' controllers (threadpoolctl.LibController: get_num_threads,
#: set_num_threads), none without threadpoolctl
_BLAS_LIBRARIES = ([] if _BLAS is None else
                   [library for library in _BLAS.lib_controllers if library.user_api == 'blas'])


def one_blas_thread(method: Callable) -> Callable:
    """
    Run ``method`` with BLAS limited to one thread, the previous limits restored after.

    The factorizations here are 90x90: extra BLAS threads cannot speed them up, and on a busy
    machine their spin-waiting made a compliance computation 10x slower (1.8 -> 10 ms median).
    The limits are read and set on the libraries directly (a few us; threadpoolctl's
    ``limit()`` context, which first gathers every library's info, took 30-40 us, a tenth of
    a warm solve); libraries already at one thread (``OPENBLAS_NUM_THREADS=1``, or a call
    nested in another limited one) are left alone. Without threadpoolctl ``method`` is
    returned unchanged.
    """
    if not _BLAS_LIBRARIES:
        return method

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        changed = [(library, threads) for library in _BLAS_LIBRARIES
                   for threads in (library.get_num_threads(),)
                   if threads is not None and threads != 1]
        for library, _ in changed:
            library.set_num_threads(1)
        try:
            return method(*args, **kwargs)
        finally:
            for library, threads in changed:
                library.set_num_threads(threads)
    return wrapper


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
        (accuracy.py) exceeds it is re-solved with more steps per segment. Every converged
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
        self._previous: Optional[Tuple[np.ndarray, np.ndarray]] = None  # (xs, wrench)
        #: the last solutions of consecutive warm solves, oldest first (unknowns, wrenches),
        #: how many (at most chord.PATH_LENGTH) and the unknowns of the last
        #: (``_previous``'s while the chain holds): the whole-step predictor extrapolates them
        self._path_xs = np.empty((chord.PATH_LENGTH, self.problem.size))
        self._path_wrenches = np.empty((chord.PATH_LENGTH, 6))
        self._path_count = 0
        self._path_last: Optional[np.ndarray] = None
        self._lu: Optional[tuple] = None
        self._pose: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None
        #: lifted states (unknowns, their nodes, a factorization, its node tangents or None):
        #: of the last converged lifted correction, of the last one at all, of the unloaded
        #: solution (a few MB each at 9 spacer disks: the node tangents)
        self._nodes: Optional[_LiftedState] = None
        self._lifted_last: Optional[_LiftedState] = None
        self._unloaded_nodes: Optional[_LiftedState] = None
        self._unloaded_lu: Optional[tuple] = None
        self._unloaded_pose: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None
        self._stability_origin: Optional[stability.Reference] = None
        self._exact_at: Optional[np.ndarray] = None
        self._verdict: Optional[stability.Stability] = None
        self._verdict_lu: Optional[tuple] = None
        self.accuracy = accuracy if accuracy is not None else Accuracy.from_yaml()
        self.follow_stable_branch = follow_stable_branch
        self.judge = judge
        self.fallback = fallback
        self.path = path
        #: cold continuations correct by lifted Newton from this many spacer disks per joint
        #: on (None: never); LIFT_FROM_SPACERS unless changed (benchmarks compare both)
        self.lift_from_spacers = LIFT_FROM_SPACERS
        self._refined: Dict[int, 'TranslatorSolver'] = {}
        #: steps per segment the next warm solve starts at (a key of ``_refined``), kept from
        #: the refinement of an earlier one; None: this solver's own (``_solve_kept``)
        self._kept: Optional[int] = None
        self._last_estimate: Optional[ErrorEstimate] = None
        #: warm_step's settings array and the (tolerance, max_iterations, judge) it was made for
        self._warm_settings_array = np.empty(0)
        self._warm_settings_for: Optional[Tuple[float, int, bool]] = None
        if method == 'fast':
            self._unloaded()  # loads the compiled kernels now, not inside the first solve

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        self._previous = None
        self._lu = None
        self._pose = None
        self._kept = None

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
        self._previous = (unknowns / self.problem.x_scale,
                          np.concatenate([result.force, result.moment]))
        self._kept = None
        if not keep_factorization:
            self._lu = None
            self._pose = None

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
        self._previous = (np.array(xs, dtype=float), check_wrench(wrench[:3], wrench[3:]))
        self._kept = None
        if factorization is None:
            self._lu, self._pose = None, None
        else:
            lu, pose, made_at = factorization
            self._lu, self._pose = lu, (pose, np.array(made_at, dtype=float))

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
        started = time.perf_counter()
        wrench = check_wrench(wrench[:3], wrench[3:])
        xs = np.array(xs, dtype=float)
        saved = (self._lu, self._pose, self._exact_at)
        rs = self.problem.residual_and_shape(xs, wrench)
        largest = float(np.abs(rs).max())
        converged = largest <= self.tolerance
        lu, pose = (None, None) if factorization is None else (
            factorization[0], (factorization[1], np.array(factorization[2], dtype=float)))
        outcome = _Outcome(xs, rs, 0, converged, 'converged' if converged else
                           f'residual {largest:.2g} above the tolerance {self.tolerance:.2g} '
                           'at the given unknowns', lu, pose)
        outcome.shape = (xs, *self.problem.recorded_shape(0))
        result = self._result(outcome, wrench, 0.0)
        if converged:
            try:
                if self.method == 'fast':
                    _apply_verdict(result, self._stability(outcome, wrench,
                                                           result.frames['de'][:3, :3]))
                self._estimate_error(result, outcome, wrench)
            finally:
                self._lu, self._pose, self._exact_at = saved
        result.solve_time_s = time.perf_counter() - started
        return result

    @one_blas_thread
    def solve(self, force: ArrayLike, moment: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True, compliance: bool = False, verify: bool = False,
              **compliance_options: float) -> SolveResult:
        """
        Solve for an end-disk wrench (N, N m) in {pe} applied at the end-disk centre.

        With ``compliance`` the result also carries the end-disk compliance matrix and its
        primary-mobility analysis (``cdr_translator.compliance``; options
        ``sparsity_threshold`` and ``mobility_ratio`` go to ``compliance.analyse``), computed
        by implicit differentiation at the converged solution, timed apart from the solve.
        With ``verify`` the result is re-checked independently (``cdr_translator.verify``:
        ``result.verification``, ``result.verified``), also timed apart (10-100 ms).
        A warm solve after a refined one solves at the refined steps per segment directly
        (``_solve_kept``, docs/accuracy.md).
        """
        wrench = check_wrench(force, moment)
        started = time.perf_counter()
        if self._kept is not None and not warm_start:
            self._kept = None  # a cold solve starts over at this solver's steps
        elif self._kept is not None:
            kept = self._solve_kept(wrench, started, compliance, verify, compliance_options)
            if kept is not None:
                return kept
        self._exact_at = None  # the unknowns self._lu is exact at, once known
        deadline = started + self.time_limit_s
        corrector = self._levenberg_marquardt if self.method == 'paper' else self._newton
        warm = warm_start and self._previous is not None and bool(self._previous[1].any())
        begin = self._previous[0] if warm and self._previous is not None else None
        with np.errstate(over='ignore', invalid='ignore'):  # rejected trial steps overflow
            usual, spent = (self._warm_step(wrench, deadline)
                            if warm and self.method == 'fast' and self.path != 'tracking'
                            else (None, 0))
            if usual is not None:
                outcome = usual
            elif self.path == 'tracking' and self.method == 'fast':
                outcome = self._track_only(wrench, warm, deadline)
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
                if restart.converged or _norm(restart.rs) < _norm(outcome.rs):
                    outcome = restart
            if (not outcome.converged and self.fallback and self.method == 'fast'
                    and outcome.reached is not None and time.perf_counter() < deadline):
                outcome = self._track(outcome, wrench, deadline)
        if outcome.converged:
            self._previous = (outcome.xs, wrench)
            self._extend_path(outcome.xs, wrench, continued and self._path_last is begin)
        verdict = None
        result = self._result(outcome, wrench, 0.0)
        if outcome.converged and self.method == 'fast' and self.judge:
            verdict = self._stability(outcome, wrench, result.frames['de'][:3, :3])
            if (not verdict.stable and self.follow_stable_branch
                    and time.perf_counter() < deadline):
                branch, verdict = self._follow_stable_branch(outcome, verdict, wrench, deadline)
                if branch is not outcome:
                    outcome, result = branch, self._result(branch, wrench, 0.0)
        if verdict is not None:
            _apply_verdict(result, verdict)
        if outcome.converged and not self.judge:
            # converged is all this result claims: it must not read as verified accurate
            result.accuracy_met = False
            result.message += '; not judged (judge=False): no stability verdict or error estimate'
        if outcome.converged and self.judge:
            self._estimate_error(result, outcome, wrench)
            if not result.accuracy_met and self.method == 'fast':
                assert self._last_estimate is not None  # set by _estimate_error
                refined = self._refine(result, self._last_estimate, self, wrench, deadline,
                                       compliance, verify, compliance_options)
                if refined is not None:
                    refined.solve_time_s = time.perf_counter() - started
                    return refined
            if not result.accuracy_met:
                result.message += _accuracy_shortfall(result)
        result.solve_time_s = time.perf_counter() - started
        if compliance and outcome.converged:
            stored = self._pose[0] if self._pose is not None else None
            factorization = ((self._lu, stored) if self._exact_at is outcome.xs
                             and self._lu is not None and stored is not None else None)
            try:
                result.compliance, self._lu, pose = compliance_analysis(
                    self.problem, outcome.xs, wrench, factorization,
                    result.frames['de'][:3, :3], **compliance_options)
                self._pose = (pose, wrench.copy())
                self._exact_at = outcome.xs
            except ArithmeticError as error:
                result.message += f'; no compliance: {error}'
        if verify:
            result.verification = verify_result(result, self.params)
        return result

    # accuracy --------------------------------------------------------------------------------
    def _estimate_error(self, result: SolveResult, outcome: _Outcome,
                        wrench: np.ndarray) -> None:
        """Set the result's discretization-error estimate (accuracy.py) and its verdict."""
        if outcome.estimate is not None:
            estimate = outcome.estimate
        else:
            estimate = self._estimate_at(outcome, result, wrench)
        result.error_estimate_m = estimate.position_m
        result.error_estimate_deg = estimate.angle_deg
        target = self.accuracy
        result.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
        self._last_estimate = estimate

    def _estimate_at(self, outcome: _Outcome, result: SolveResult,
                     wrench: np.ndarray) -> ErrorEstimate:
        """Estimate the error of a converged outcome (accuracy.estimate)."""
        pose = outcome.pose[0] if outcome.pose is not None else None
        frames = (outcome.shape[2] if outcome.shape is not None and outcome.shape[0] is outcome.xs
                  else np.stack([result.frames[name] for name in FRAME_NAMES]))
        return estimate_error(self.problem, outcome.xs, wrench, outcome.rs, frames,
                              outcome.lu, pose)

    def _refine(self, result: SolveResult, estimate: ErrorEstimate,
                source: 'TranslatorSolver', wrench: np.ndarray, deadline: float,
                compliance: bool, verify: bool,
                compliance_options: dict) -> Optional[SolveResult]:
        """
        Re-solve with more steps per segment until the accuracy target is met.

        ``result`` (with its ``estimate``) is the solve of ``source`` (this solver, or a
        refined one of a kept solve). Each refined solve starts from the previous one's
        solution and factorization (the unknowns mean the same at any discretization, and
        the Jacobians differ by the discretization error: its chord steps converge).
        Returns the last converged refined result (its message says whether the target was
        met), or None when no refinement converged; the next warm solve starts at its steps.
        """
        refined = None
        target = self.accuracy
        for _ in range(MAX_REFINEMENTS):
            steps = refined_steps(estimate, target.position_m, target.angle_deg,
                                  MAX_REFINED_STEPS)
            remaining = deadline - time.perf_counter()
            if steps <= estimate.steps or remaining <= 0.0:
                break
            solver = self._refined_solver(steps)
            solver.time_limit_s = remaining
            solver._take_over(source)
            attempt = solver.solve(wrench[:3], wrench[3:], compliance=compliance,
                                   verify=verify, **compliance_options)
            if not attempt.converged:
                break
            refined = attempt
            source = solver
            assert solver._last_estimate is not None
            estimate = solver._last_estimate
            refined.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
            if refined.accuracy_met:
                break
        if refined is None:
            return None
        self._kept = refined.steps_per_segment
        refined.iterations += result.iterations
        extra = '' if refined.message == 'converged' else f' ({refined.message})'
        refined.message = result.message + extra
        refined.message += (f'; refined to {refined.steps_per_segment} steps per segment '
                            f'(estimated error at {result.steps_per_segment}: '
                            f'{result.error_estimate_m:.2g} m, '
                            f'{result.error_estimate_deg:.2g} deg)')
        if not refined.accuracy_met:
            refined.message += _accuracy_shortfall(refined)
        return refined

    def _refined_solver(self, steps: int) -> 'TranslatorSolver':
        """Return the solver at ``steps`` steps per segment (made once; no target of its own)."""
        solver = self._refined.get(steps)
        if solver is None:
            solver = TranslatorSolver(self.params.with_changes(steps_per_segment=steps),
                                      tolerance=self.tolerance,
                                      max_iterations=self.max_iterations,
                                      jacobian=self.jacobian, accuracy=Accuracy(0.0, 0.0),
                                      follow_stable_branch=self.follow_stable_branch)
            self._refined[steps] = solver
        return solver

    def _take_over(self, source: 'TranslatorSolver') -> None:
        """
        Warm-start the next solve from ``source``'s last solution and factorization.

        ``source`` solves the same structure at other steps per segment: the unknowns mean
        the same, and its factorization (the Jacobian differs by the discretization error)
        serves the chord steps and the stability verdict as a stale one would.
        """
        self._previous = source._previous
        self._lu, self._pose = source._lu, source._pose
        self._kept = None

    def _solve_kept(self, wrench: np.ndarray, started: float, compliance: bool, verify: bool,
                    compliance_options: dict) -> Optional[SolveResult]:
        """
        Warm solve at the steps per segment kept from an earlier refinement (``_kept``).

        A warm sequence that needed refinement usually needs it again: solving at the kept
        steps directly skips this solver's own solve and the refined one after it. The
        solve is judged at those steps: refined further when its estimate misses the target
        (``_refine``), and the next solve steps down (accuracy.kept_steps) when it has room.
        Returns None, forgetting the kept steps, when that solve did not converge or the
        wrench moved by more than STALE_WRENCH (relative) since the last one (a long
        continuation, cheaper at this solver's steps): this solver then solves as usual,
        from the last solution.
        """
        steps = self._kept
        assert steps is not None
        solver = self._refined[steps]
        self._kept = None
        if solver._previous is None or float(np.linalg.norm(wrench - solver._previous[1])) > \
                STALE_WRENCH * float(np.linalg.norm(wrench)):
            return None  # not a warm sequence: a long continuation is cheaper at fewer steps
        solver.time_limit_s = self.time_limit_s
        attempt = solver.solve(wrench[:3], wrench[3:], compliance=compliance, verify=verify,
                               **compliance_options)
        if not attempt.converged:
            return None
        assert solver._previous is not None and solver._last_estimate is not None
        self._previous = solver._previous
        estimate = self._last_estimate = solver._last_estimate
        target = self.accuracy
        attempt.accuracy_met = meets(estimate, target.position_m, target.angle_deg)
        extra = '' if attempt.message == 'converged' else f' ({attempt.message})'
        attempt.message = (f'converged{extra} at {steps} steps per segment, kept from the '
                           'refinement of an earlier solve')
        result = attempt
        if not attempt.accuracy_met:
            refined = self._refine(attempt, estimate, solver, wrench,
                                   started + self.time_limit_s, compliance, verify,
                                   compliance_options)
            if refined is not None:
                result = refined
            else:
                self._kept = steps
                result.message += _accuracy_shortfall(result)
        else:
            fewer = kept_steps(estimate, target.position_m, target.angle_deg,
                               self.params.steps_per_segment)
            if fewer == steps:
                self._kept = steps
            elif fewer > self.params.steps_per_segment:
                self._kept = fewer
                self._refined_solver(fewer)._take_over(solver)
            else:
                self._take_over(solver)
        result.solve_time_s = time.perf_counter() - started
        return result

    # stability -------------------------------------------------------------------------------
    def _origin(self) -> stability.Reference:
        """Return the unloaded state's stiffness and det J sign (stability.py), made once."""
        if self._stability_origin is None:
            (xs, zero), lu = self._unloaded()
            pose = self._unloaded_pose[0] if self._unloaded_pose is not None else None
            if pose is None:  # jacobian='fd': the tangent shot gives the pose derivative
                pose = self.problem.exact_jacobian(xs, zero)[2]
            _, frames = self.problem.shape(xs, zero)
            self._stability_origin = stability.reference(
                lu, pose, frames[3][:3, :3], self.problem.wrench_sensitivity,
                self.params.stack_height)
        return self._stability_origin

    def _stability(self, outcome: _Outcome, wrench: np.ndarray,
                   rotation: Optional[np.ndarray] = None) -> stability.Stability:
        """
        Verdict at a converged outcome from the factorization its iteration ended with.

        That factorization may be from an earlier iterate or solve (chord steps); when it was
        made at a wrench further (relative to |w|, or to LOAD_FLOOR of the load scale when
        |w| is smaller; sizes by stability.wrench_size) than STALE_WRENCH or half the margin
        it gives, or the verdict is unstable or its margin below RECHECK_MARGIN, the verdict is
        redone on an exact Jacobian at the solution itself, which then also becomes the
        stored factorization.
        """
        problem = self.problem
        lu = outcome.lu
        pose, lu_wrench = outcome.pose if outcome.pose is not None else (None, None)
        if rotation is None:
            rotation = problem.residual_and_end_frame(outcome.xs, wrench)[1][:3, :3]
        if lu is not None and pose is not None and lu_wrench is not None:
            if self._verdict_lu is lu and self._verdict is not None:
                verdict = self._verdict  # chord steps keep a factorization over many solves
            else:
                verdict = stability.assess(lu, pose, rotation, problem.wrench_sensitivity,
                                           self._origin())
                self._verdict_lu, self._verdict = lu, verdict
            # the margin moves about as fast as the load, relative to the load: a verdict
            # from a factorization made at a wrench more than half the margin away (or
            # STALE_WRENCH) could already be on the other side of zero. Near no load it
            # moves by about |dw| / w* (stability.load_scale): measured against a load of
            # at least LOAD_FLOOR w*, sensor noise around zero keeps the verdict
            origin = self._origin()
            length = origin.length
            drift = stability.wrench_size(wrench - lu_wrench, length) / max(
                stability.wrench_size(wrench, length),
                LOAD_FLOOR * stability.load_scale(origin))
            if verdict.stable and verdict.margin >= RECHECK_MARGIN and \
                    drift <= min(STALE_WRENCH, 0.5 * verdict.margin):
                return verdict
        _, jac, pose = problem.exact_jacobian(outcome.xs, wrench)
        lu = stability.factorize(jac)
        outcome.lu, outcome.pose = lu, (pose.copy(), wrench.copy())
        outcome.estimate = None  # made on the stale factorization: redone on this one
        self._lu, self._pose = outcome.lu, outcome.pose
        self._exact_at = outcome.xs
        return stability.assess(lu, pose, rotation, problem.wrench_sensitivity, self._origin())

    def _follow_stable_branch(self, outcome: _Outcome, verdict: stability.Stability,
                              wrench: np.ndarray,
                              deadline: float) -> Tuple[_Outcome, stability.Stability]:
        """
        Past a bifurcation: perturb along the critical mode and re-converge (Riks' way).

        The wrench is given an imperfection along the critical mode (IMPERFECTION of the
        wrench's size, stability.critical_wrench), solved from the unloaded state, which
        follows the imperfect, stable path; the imperfection is then removed by a warm
        continuation that stays on the branch it reached. Returns the new outcome when it
        converged stably, else the original one with its verdict.
        """
        saved = (self._previous, self._lu, self._pose)
        length = self.params.stack_height
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
            first = self._continuation(perturbed, False, deadline, self._newton)
            iterations += first.iterations
            if not first.converged:
                break
            self._stability(first, perturbed)  # the exact factorization there: a stale
            # one's predictor led the way back to the unstable branch
            self._previous = (first.xs, perturbed)
            second = self._continuation(wrench, True, deadline, self._newton)
            iterations += second.iterations
            if not second.converged:
                break
            new_verdict = self._stability(second, wrench)
            if new_verdict.stable:
                self._previous = (second.xs, wrench)
                second.iterations = iterations
                second.message = ('converged on the stable branch: the first solution was '
                                  f'unstable (margin {verdict.margin:.3g}); perturbed along '
                                  f'the critical mode and re-converged ({attempt + 1} '
                                  'perturbation(s))')
                return second, new_verdict
            current_verdict = new_verdict
        self._previous, self._lu, self._pose = saved
        return outcome, verdict

    # continuation ----------------------------------------------------------------------------
    def _continuation(self, wrench: np.ndarray, warm_start: bool, deadline: float,
                      corrector: Callable[..., _Outcome]) -> _Outcome:
        """
        Predictor-corrector continuation from the previous solution (or the unloaded one).

        Each step predicts the solution at a larger wrench to first order with the stored LU
        factorization, dx = -J^-1 (dr/dw) dw (without one, the last solution is the guess),
        and the corrector (Newton, or the paper's Levenberg-Marquardt) refines it. A failed
        step is halved; a step is doubled after one that converged in at most half the
        allowed iterations, but never right after a failure (halving then doubling again
        would retry the step that just failed); a corrector that ran out of iterations within
        NEARLY_CONVERGED of the solution continues instead. A warm start is the same walk,
        usually one step. If it stalls, the outcome is the best state found, its residual
        taken at the requested wrench.
        """
        if not (warm_start and self._previous is not None):
            self._previous, self._lu = self._unloaded()
            self._pose = self._unloaded_pose
            if corrector == self._newton and self._lifting():
                corrector = self._lifted_newton
                self._nodes = self._unloaded_lifted(self._previous[0])
        assert self._previous is not None
        xs, start = self._previous
        lu, pose = self._lu, self._pose
        # the whole step's prediction: sizes the first step, is its guess if whole
        predicted = None if lu is None else self._extrapolated(xs, wrench, lu)
        if predicted is not None:
            whole: Optional[np.ndarray] = xs - predicted
        elif lu is not None:
            whole = self.problem.wrench_response(lu, wrench - start)
            predicted = xs - whole
        else:
            whole = None
        done, step, iterations = 0.0, _first_step(whole), 0
        current = start
        outcome: Optional[_Outcome] = None
        grow = 2.0
        while done < 1.0:
            target = min(1.0, done + step)
            goal = start + target * (wrench - start)
            if lu is None:
                guess = xs
            elif predicted is not None and target == 1.0 and done == 0.0:
                guess = predicted
            else:
                guess = xs - self.problem.wrench_response(lu, goal - current)
            outcome = corrector(guess, goal, deadline, lu, self.max_iterations, pose)
            iterations += outcome.iterations
            if (not outcome.converged and np.abs(outcome.rs).max() < NEARLY_CONVERGED
                    and time.perf_counter() < deadline):
                # out of iterations but inside the basin: keep correcting, don't halve
                outcome = corrector(outcome.xs, goal, deadline, outcome.lu, self.max_iterations,
                                    outcome.pose)
                iterations += outcome.iterations
            if outcome.converged:
                done, xs, current, lu, pose = target, outcome.xs, goal, outcome.lu, outcome.pose
                if outcome.iterations <= self.max_iterations // 2:
                    step *= grow
                grow = 2.0
                continue
            grow = 1.0
            step = 0.5 * (target - done)
            if step < MIN_CONTINUATION_STEP or time.perf_counter() > deadline:
                stalled = self._stalled(xs, outcome, wrench, done, iterations, deadline)
                stalled.reached = (xs, current)
                return stalled
        self._lu, self._pose = lu, pose
        if outcome is None:  # cannot happen: the loop runs at least once
            raise RuntimeError('continuation made no step')
        outcome.iterations = iterations
        return outcome

    def _warm_step(self, wrench: np.ndarray, deadline: float) -> Tuple[Optional[_Outcome], int]:
        """
        Solve the usual warm case in one compiled call (warm_step.py); None if not usual.

        Applies when the previous solution has a stored exact factorization: then the
        prediction (the path's extrapolation, else first order), the chord steps on that
        factorization and the error estimate are one call. When the chord steps stall it
        goes on as ``_newton`` would (a fresh Jacobian at the iterate); when that fails too,
        or the prediction reaches too far for one step, it returns None with the iterations
        spent, and ``_continuation`` solves from the previous solution, as it would have
        without this call.
        """
        previous, lu, pose = self._previous, self._lu, self._pose
        if previous is None or lu is None or pose is None or pose[0] is None:
            return None, 0
        count = self._path_count if self._path_last is previous[0] else 0
        step, xs, rs = warm_step(self.problem, previous,
                                 (self._path_xs, self._path_wrenches, count),
                                 wrench, lu, pose[0], self._warm_settings())
        if step.status == chord.CONVERGED:
            outcome = _Outcome(xs, rs, step.iterations, True, 'converged', lu, pose,
                               estimate=step.estimate, residual_by_kind=step.residual_by_kind)
            outcome.shape = (xs, *self.problem.recorded_shape(step.slot))
            return outcome, 0
        if step.status == chord.REFACTOR and time.perf_counter() <= deadline:
            outcome = self._newton(xs, wrench, deadline, None,
                                   self.max_iterations - step.iterations, pose,
                                   known=(rs, step.slot))
            if outcome.converged:
                self._lu, self._pose = outcome.lu, outcome.pose
                outcome.iterations += step.iterations
                return outcome, 0
            return None, step.iterations + outcome.iterations
        return None, step.iterations

    def _warm_settings(self) -> np.ndarray:
        """Return the settings warm_step takes (made again when one it depends on changes)."""
        key = (self.tolerance, self.max_iterations, self.judge)
        if self._warm_settings_for != key:
            self._warm_settings_array = warm_step_settings(
                self.tolerance, self.max_iterations, CHORD_RATE, EXTRAPOLATION_MISS,
                PREDICTOR_REACH, estimate=self.judge)
            self._warm_settings_for = key
        return self._warm_settings_array

    def _extend_path(self, xs: np.ndarray, wrench: np.ndarray, chained: bool) -> None:
        """Append a solution to the path of warm solves; without ``chained`` start a new one."""
        count = self._path_count if chained else 0
        if count == chord.PATH_LENGTH:
            self._path_xs[:-1] = self._path_xs[1:]
            self._path_wrenches[:-1] = self._path_wrenches[1:]
            count -= 1
        self._path_xs[count] = xs
        self._path_wrenches[count] = wrench
        self._path_count, self._path_last = count + 1, xs

    def _extrapolated(self, xs: np.ndarray, wrench: np.ndarray,
                      lu: tuple) -> Optional[np.ndarray]:
        """
        Predict the solution at ``wrench`` from the last solutions of a warm sequence, or None.

        Problem.extrapolate (chord.extrapolate) from the path of warm solves when it holds
        three solutions or more and ends at ``xs``; None else or when ``wrench`` does not
        continue the path (its polynomial misses ``wrench`` by more than EXTRAPOLATION_MISS
        of the step).
        """
        if self._path_count < 3 or self._path_last is not xs:
            return None
        return self.problem.extrapolate(lu, self._path_xs, self._path_wrenches,
                                        self._path_count, wrench, EXTRAPOLATION_MISS)

    def _track(self, stalled: _Outcome, wrench: np.ndarray, deadline: float) -> _Outcome:
        """
        Continue a stalled continuation by path_following.track from where it stopped.

        Returns the tracked outcome, converged with an exact factorization (also stored for
        the next solve), or the stalled one with the fallback's failure added to its message.
        """
        assert stalled.reached is not None
        xs, start = stalled.reached
        tracked = path_following.track(self.problem, xs, start, wrench, self.tolerance,
                                       deadline)
        iterations = stalled.iterations + tracked.iterations
        if not tracked.converged:
            stalled.iterations = iterations
            stalled.message += (f'; the fallback continuation failed: {tracked.message}'
                                if stalled.message else
                                f'the tracking continuation failed: {tracked.message}')
            if _norm(tracked.rs) < _norm(stalled.rs):
                stalled.xs, stalled.rs = tracked.xs, tracked.rs
            return stalled
        message = (f'converged by the fallback continuation ({tracked.steps} steps with a '
                   'Hermite predictor on exact tangents)')
        if stalled.message:
            message += f' after: {stalled.message}'
        elif tracked.floor <= 0.0:
            message = 'converged'  # path='tracking' at the tolerance
        if tracked.floor > 0.0:
            message += (f'; residual {np.abs(tracked.rs).max():.2g} at the rounding floor '
                        f'{tracked.floor:.2g} of the shot, above the tolerance '
                        f'{self.tolerance:.2g}')
        pose = (tracked.pose, wrench.copy())
        self._lu, self._pose = tracked.lu, pose
        self._exact_at = tracked.xs
        return _Outcome(tracked.xs, tracked.rs, iterations, True, message, tracked.lu, pose)

    def _track_only(self, wrench: np.ndarray, warm: bool, deadline: float) -> _Outcome:
        """Solve by path_following.track alone: from the previous solution, else unloaded."""
        starts = [self._previous] if warm and self._previous is not None else []
        starts.append(self._unloaded()[0])
        outcome: Optional[_Outcome] = None
        iterations = 0
        for xs, start in starts:
            begin = _Outcome(xs, self.problem.residual(xs, wrench), iterations, False, '',
                             reached=(xs, start))
            outcome = self._track(begin, wrench, deadline)
            iterations = outcome.iterations
            if outcome.converged or time.perf_counter() > deadline:
                break
        assert outcome is not None
        return outcome

    def _stalled(self, xs: np.ndarray, failed: _Outcome, wrench: np.ndarray, done: float,
                 iterations: int, deadline: float) -> _Outcome:
        """Best of the last converged state and the failed iterate, judged at ``wrench``."""
        candidates = [(candidate, self.problem.residual(candidate, wrench))
                      for candidate in (xs, failed.xs)]
        best, rs = min(candidates, key=lambda pair: _norm(pair[1])
                       if math.isfinite(_norm(pair[1])) else math.inf)
        reason = failed.message
        if 'time limit' not in reason and time.perf_counter() > deadline:
            reason = f'time limit of {self.time_limit_s} s reached after: {reason}'
        return _Outcome(best, rs, iterations, False,
                        f'continuation stalled at {done:.1%} of the way to the wrench: '
                        f'{reason}')

    def _unloaded(self) -> Tuple[Tuple[np.ndarray, np.ndarray], tuple]:
        """Return the straight unloaded solution and its LU factorization (computed once)."""
        if self._unloaded_lu is None:
            zero = np.zeros(6)
            xs = self.problem.straight_guess(zero)
            self._unloaded_lu = stability.factorize(
                self.problem.jacobian(xs, zero, self.problem.residual(xs, zero)))
            self._unloaded_pose = (self.problem.pose_jacobian, zero)
        return (self.problem.straight_guess(np.zeros(6)), np.zeros(6)), self._unloaded_lu

    # correctors ------------------------------------------------------------------------------
    def _lifting(self) -> bool:
        """Say whether cold continuations correct by lifted Newton (multiple shooting)."""
        return (self.lift_from_spacers is not None and self.method == 'fast'
                and self.jacobian == 'exact'
                and self.params.spacers_per_joint >= self.lift_from_spacers)

    def _unloaded_lifted(self, xs: np.ndarray) -> '_LiftedState':
        """
        Return the lifted state of the unloaded solution ``xs`` (its nodes made once).

        Its factorization is the unloaded one (at zero defects the lifted Jacobian is the
        single-shooting one), with the node tangents of a lifted shot there.
        """
        if self._unloaded_nodes is None:
            zero = np.zeros(6)
            nodes = self.problem.node_states(xs, zero)
            self.problem.lifted_jacobian(xs, nodes, zero)
            self._unloaded_nodes = (xs, nodes, self._unloaded()[1], self.problem.node_tangents)
        _, nodes, lu, tangents = self._unloaded_nodes
        return xs, nodes, lu, tangents

    def _lifted_newton(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                       lu: Optional[tuple], max_iterations: int,
                       pose_in: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None
                       ) -> _Outcome:
        """
        Multiple shooting by lifted Newton (multiple_shooting) from ``xs`` and nodes to go with it.

        The nodes are those of a lifted correction that ended at ``xs``; else, if ``xs`` is
        a prediction made with the factorization ``lu`` of the last converged correction,
        that correction's nodes moved by the same first-order prediction (its node
        tangents); else the states single shooting carries at ``xs``. ``lu`` and
        ``pose_in`` are returned when no iteration was needed.
        """
        tangents = None  # those of ``lu``, when known
        for state in (self._lifted_last, self._nodes):
            if state is not None and state[0] is xs:
                nodes = state[1]
                break
        else:
            state = self._nodes
            if state is not None and lu is not None and state[2] is lu and state[3] is not None:
                nodes = self.problem.advance_nodes(state[1], xs - state[0], 0.0, state[3])
            else:
                nodes = self.problem.node_states(xs, wrench)
        if state is not None and lu is not None and state[2] is lu:
            tangents = state[3]
        done = multiple_shooting.newton(self.problem, xs, nodes, wrench, self.tolerance,
                                        max_iterations, deadline)
        self._lifted_last = ((done.xs, done.nodes, done.lu, done.tangents) if done.lu is not None
                             else (done.xs, done.nodes, lu, tangents))
        if done.converged:
            self._nodes = self._lifted_last
        if done.lu is None:
            return _Outcome(done.xs, done.rs, done.iterations, done.converged, done.message,
                            lu, pose_in)
        return _Outcome(done.xs, done.rs, done.iterations, done.converged, done.message,
                        done.lu, (done.pose, wrench.copy()))

    def _newton(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                lu: Optional[tuple], max_iterations: int,
                pose_in: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None,
                known: Optional[Tuple[np.ndarray, int]] = None) -> _Outcome:
        """
        Damped Newton; given ``lu`` it starts with chord steps on that factorization.

        The iterations run compiled (chord.chord_iterations: backtracking line search, a
        chord step that shrinks the residual by less than CHORD_RATE discards the
        factorization); Python only refactors, between those calls, and checks the deadline.
        Given ``lu`` (a warm solve's usual case) the residual at ``xs`` is the first shot of
        the first compiled call. ``known`` = (residual at ``xs``, the slot of the problem's
        shape buffers that holds its shape), when a call before this one shot there.
        """
        problem = self.problem
        xs = np.array(xs, dtype=float)
        shoot = lu is not None and known is None and time.perf_counter() <= deadline
        slot = 0
        if shoot:
            rs, norm = np.empty(problem.size), math.nan  # chord_newton's first shot sets both
        elif known is not None:
            rs, slot = known[0].copy(), known[1]
            norm = _norm(rs)
        else:
            rs = problem.residual_and_shape(xs, wrench)
            norm = _norm(rs)
        done, fresh, pose = 0, False, pose_in

        def ended(converged: bool, message: str) -> _Outcome:
            outcome = _Outcome(xs, rs, done, converged, message, lu, pose)
            outcome.shape = (xs, *problem.recorded_shape(slot))
            return outcome

        while True:
            if not shoot:
                if not math.isfinite(norm):
                    return ended(False, 'residual became non-finite during the iteration')
                if np.abs(rs).max() <= self.tolerance:
                    return ended(True, 'converged')
                if done >= max_iterations:
                    return ended(False, f'no convergence in {max_iterations} iterations')
                if time.perf_counter() > deadline:
                    return ended(False, f'time limit of {self.time_limit_s} s reached')
            if lu is None:
                # a singular J shows as a non-finite step
                lu = stability.factorize(problem.jacobian(xs, wrench, rs))
                pose = (problem.pose_jacobian, wrench.copy())
                fresh = True
            status, used, norm, slot = problem.chord_newton(
                xs, rs, wrench, lu, fresh, self.tolerance, max_iterations - done, CHORD_RATE,
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

    def _levenberg_marquardt(self, xs: np.ndarray, wrench: np.ndarray, deadline: float,
                             lu: Optional[tuple], max_iterations: int,
                             pose_in: Optional[Tuple[Optional[np.ndarray], np.ndarray]] = None
                             ) -> _Outcome:
        """
        Eq. (13) with a one-residual-per-column Jacobian, to the paper's tolerances.

        ``lu`` and ``pose_in`` are ignored: the paper's method keeps no factorization between
        solves.
        """
        problem = self.problem
        tolerances = np.array([PAPER_TOLERANCES[kind] for kind in RESIDUAL_KINDS])
        rs = problem.residual(xs, wrench)
        damping = 1e-3
        for iteration in range(1, max_iterations + 1):
            if np.all(np.array(list(problem.residual_by_kind(rs).values())) <= tolerances):
                return _Outcome(xs, rs, iteration - 1, True,
                                "converged to the paper's tolerances")
            if time.perf_counter() > deadline:
                return _Outcome(xs, rs, iteration - 1, False,
                                f'time limit of {self.time_limit_s} s reached')
            jac = problem.jacobian(xs, wrench, rs)
            normal = jac.T @ jac
            gradient = jac.T @ rs
            while True:
                step = -np.linalg.solve(normal + damping * np.eye(problem.size), gradient)
                trial_rs = problem.residual(xs + step, wrench)
                if _norm(trial_rs) < _norm(rs):
                    xs, rs = xs + step, trial_rs
                    damping = max(damping / 10.0, 1e-12)
                    break
                damping *= 10.0
                if damping > 1e12:
                    return _Outcome(xs, rs, iteration, False,
                                    'Levenberg-Marquardt damping diverged')
        return _Outcome(xs, rs, max_iterations, False,
                        f'no convergence in {max_iterations} iterations')

    # result ----------------------------------------------------------------------------------
    def _result(self, outcome: _Outcome, wrench: np.ndarray, elapsed: float) -> SolveResult:
        problem = self.problem
        if outcome.shape is not None and outcome.shape[0] is outcome.xs:
            points, frames = outcome.shape[1:]
        else:
            points, frames = problem.shape(outcome.xs, wrench)
        return SolveResult(
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, residual_norm=_norm(outcome.rs),
            residual_by_type=(outcome.residual_by_kind if outcome.residual_by_kind is not None
                              else problem.residual_by_kind(outcome.rs)),
            force=wrench[:3].copy(), moment=wrench[3:].copy(),
            frames=dict(zip(FRAME_NAMES, frames)),  # views of a copy no one else keeps
            backbones=points, solve_time_s=elapsed, method=self.method,
            unknowns=outcome.xs * problem.x_scale,
            steps_per_segment=self.params.steps_per_segment)


def _apply_verdict(result: SolveResult, verdict: stability.Stability) -> None:
    """Set the result's stability verdict and margin; an unstable one joins the message."""
    result.stable = verdict.stable
    result.stability_margin = verdict.margin
    if not verdict.stable:
        result.message += f'; {verdict.message}'


def _accuracy_shortfall(result: SolveResult) -> str:
    """Return the message tail of a result whose error estimate misses the accuracy target."""
    return (f'; accuracy target not met: estimated error {result.error_estimate_m:.2g} m, '
            f'{result.error_estimate_deg:.2g} deg at {result.steps_per_segment} steps per '
            'segment')


def _first_step(predicted: Optional[np.ndarray]) -> float:
    """
    Fraction of the wrench change to try first: whole if its linear prediction is small.

    ``predicted`` is the predicted change of the unknowns for the whole step (None without
    a factorization). A first step whose predicted change exceeds PREDICTOR_REACH
    (nondimensional) left the linear regime; trying it anyway cost a failed corrector and a
    halving (cold 12 N: 30 ms with the whole step, 9 ms sized this way).
    """
    if predicted is None:
        return 1.0
    largest = np.abs(predicted).max()
    if largest <= PREDICTOR_REACH:
        return 1.0
    return max(PREDICTOR_REACH / largest, MIN_CONTINUATION_STEP)


def _norm(values: np.ndarray) -> float:
    """Return the Euclidean norm of a residual vector (chord.norm: compiled, no warnings)."""
    return float(chord.norm(values))
