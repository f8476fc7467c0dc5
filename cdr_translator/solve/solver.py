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

The solver is the face of its engine (engine.py), which owns the solve state (the last
solution, the factorization, the verdicts, the refinement memory) and carries a solve
through continuation.py, correctors.py, branch.py and refinement.py. The face checks the
input, owns the time limit (a solve's ``time_limit_s`` argument, else the attribute) and
hands the translator to wrench_estimation.py as callables (the wrench from a measured pose,
by cdr_translator.estimation).
"""

import math
import time
from typing import Any, Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

from . import wrench_estimation
from .batch import BatchResult, check_wrenches
from .continuation import LIFT_FROM_SPACERS
from .engine import Engine, Factorization, Options
from .result import SolveResult
from .. import estimation
from .._blas import one_blas_thread
from ..analysis.compliance import check_tolerance
from ..analysis.stability import Reference
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


def _option(name: str, doc: str) -> Any:
    """Return a property reading and writing the engine's option ``name``."""
    def read(solver: 'TranslatorSolver') -> Any:
        """Return the option."""
        return getattr(solver.engine.options, name)

    def write(solver: 'TranslatorSolver', value: Any) -> None:
        """Set the option for the next solves."""
        setattr(solver.engine.options, name, value)
    return property(read, write, doc=doc)


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
        params = params if params is not None else TranslatorParams.from_yaml()
        if max_iterations is None:
            max_iterations = 30 if method == 'paper' else 12
        max_iterations = check_integer('max_iterations', max_iterations, low=1)
        self.time_limit_s = check_number('time_limit_s', time_limit_s, low=0.0)
        options = Options(check_number('tolerance', tolerance, low=0.0, low_open=True),
                          max_iterations,
                          accuracy if accuracy is not None else Accuracy.from_yaml(),
                          follow_stable_branch, judge, fallback, path, LIFT_FROM_SPACERS)
        #: the engine: the solve state and the steps of a solve (engine.py)
        self.engine = Engine(params, method, 'fd' if method == 'paper' else jacobian, options)

    tolerance = _option('tolerance', 'The largest nondimensional residual of a converged solve.')
    max_iterations = _option('max_iterations', 'Newton (or Levenberg-Marquardt) iterations of '
                             'one continuation step at most.')
    accuracy = _option('accuracy', 'The discretization-error target of every solve.')
    follow_stable_branch = _option('follow_stable_branch', 'Whether an unstable solution is '
                                   'perturbed onto the stable branch.')
    judge = _option('judge', 'Whether solves get a stability verdict and an error estimate.')
    fallback = _option('fallback', 'Whether a stalled continuation goes on by path following.')
    path = _option('path', 'How a solve follows the load path: one of PATHS.')
    lift_from_spacers = _option('lift_from_spacers', 'Cold continuations correct by lifted '
                                'Newton from this many spacer disks per joint on (None: never; '
                                'LIFT_FROM_SPACERS unless changed: benchmarks compare both).')

    @property
    def params(self) -> TranslatorParams:
        """Return the translator's parameters."""
        return self.engine.params

    @property
    def method(self) -> str:
        """'fast' or 'paper' (METHODS)."""
        return self.engine.method

    @property
    def jacobian(self) -> str:
        """'exact' or 'fd' (always 'fd' for ``method='paper'``)."""
        return self.engine.jacobian

    @property
    def problem(self) -> Problem:
        """Return the boundary-value problem solved (cdr_translator.bvp.problem)."""
        return self.engine.problem

    @property
    def has_warm_start(self) -> bool:
        """Whether the next warm solve continues from a state (Engine.has_warm_start)."""
        return self.engine.has_warm_start

    @property
    def previous_solution(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """(nondimensional unknowns, wrench) the next warm solve starts from (None: cold)."""
        return self.engine.previous_solution

    def unloaded_reference(self) -> Reference:
        """Return the unloaded state's stiffness and det J sign (analysis.stability)."""
        return self.engine.unloaded_reference()

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        self.engine.reset()

    def start_from(self, result: SolveResult, keep_factorization: bool = False) -> None:
        """
        Warm-start the next solve from ``result``, e.g. one of a coarser discretization.

        The unknowns mean the same at any ``steps_per_segment``; only the number of spacer
        disks (and so their count) must match. With ``keep_factorization`` the solver's own
        factorization from its previous solve stays for the chord steps.
        """
        unknowns = np.asarray(result.unknowns, dtype=float)
        if unknowns.shape != (self.problem.size,) or not np.all(np.isfinite(unknowns)):
            raise ValueError(f'cannot start from a result with {unknowns.shape} unknowns '
                             f'(finite ones, {self.problem.size} expected)')
        self.engine.start_from(unknowns / self.problem.x_scale,
                               np.concatenate([result.force, result.moment]),
                               keep_factorization)

    def start_at(self, xs: np.ndarray, wrench: np.ndarray,
                 factorization: Optional[Factorization] = None) -> None:
        """
        Warm-start the next solve from nondimensional unknowns ``xs`` at ``wrench`` (SI).

        For a caller that iterates on the shooting residual itself (robot/delta.py's coupled
        Newton): a solve at ``wrench`` then only confirms the residual and judges stability
        and the discretization error. ``factorization`` = (LU of the Jacobian, its end-frame
        derivative ``problem.pose_jacobian``, the wrench it was made at) is used for both and
        for chord steps; without one, the stability verdict factors an exact Jacobian.
        """
        self.engine.start_at(np.array(xs, dtype=float), check_wrench(wrench[:3], wrench[3:]),
                             factorization)

    @one_blas_thread
    def result_at(self, xs: np.ndarray, wrench: np.ndarray,
                  factorization: Optional[Factorization] = None) -> SolveResult:
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
        return self.engine.result_at(xs, check_wrench(wrench[:3], wrench[3:]), factorization)

    def solve(self, force: ArrayLike, moment: ArrayLike = NO_MOMENT,
              warm_start: bool = True, compliance: bool = False, verify: bool = False,
              time_limit_s: Optional[float] = None,
              **compliance_options: float) -> SolveResult:
        """
        Solve for an end-disk wrench (N, N m) in {pe} applied at the end-disk centre.

        With ``compliance`` the result also carries the end-disk compliance matrix and its
        primary-mobility analysis (``cdr_translator.analysis.compliance``; options
        ``sparsity_threshold`` and ``mobility_ratio`` go to ``compliance.analyse``), computed
        by implicit differentiation at the converged solution, timed apart from the solve.
        Option ``compliance_tolerance`` (relative, default 0): a warm solve's stored
        factorization serves instead of a new Jacobian when the error it states
        (``compliance_estimated_error``, measured by one probe shot) is within it.
        With ``verify`` the result is re-checked independently (``cdr_translator.solve.verify``:
        ``result.verification``, ``result.verified``), also timed apart (10-100 ms).
        ``time_limit_s`` caps this solve (default: the attribute ``time_limit_s``).
        A warm solve after a refined one solves at the refined steps per segment directly
        (docs/explanation/solution_quality.md).
        """
        wrench = check_wrench(force, moment)
        started = time.perf_counter()
        limit = (self.time_limit_s if time_limit_s is None
                 else check_number('time_limit_s', time_limit_s, low=0.0))
        if 'compliance_tolerance' in compliance_options:
            check_tolerance(compliance_options['compliance_tolerance'])
        return self.engine.solve(wrench, started, limit, warm_start, compliance, verify,
                                 compliance_options)

    @one_blas_thread
    def estimate_wrench(self, position: ArrayLike, quaternion_xyzw: Optional[ArrayLike] = None,
                        *, pose_covariance: Optional[ArrayLike] = None,
                        moment: Optional[ArrayLike] = None,
                        force: Optional[ArrayLike] = None,
                        estimate: Optional[estimation.Components] = None,
                        prior_mean: Optional[ArrayLike] = None,
                        prior_covariance: Optional[ArrayLike] = None,
                        target_force_sd: float = estimation.DEFAULT_TARGET_FORCE_SD,
                        target_moment_sd: float = estimation.DEFAULT_TARGET_MOMENT_SD,
                        max_force: float = math.inf, max_moment: float = math.inf
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
        meet the accuracy target; ``max_force`` and ``max_moment`` (N, N m; translator_node
        passes its own): the largest force and moment magnitudes the search tries, so that
        a pose only a larger load matches is an unmatched result at once instead of a
        search among loads the node would reject. A maximum-a-posteriori estimate with the exact
        compliance, warm-started from the previous estimate (cdr_translator/estimation);
        an unmatched pose is a flagged result, bad input an InputError (a ValueError).
        """
        return wrench_estimation.estimate_wrench(
            self, self._solve_with_compliance, self.unloaded_reference(),
            self.params.stack_height, self.time_limit_s, self.has_warm_start, self.reset,
            position, quaternion_xyzw, pose_covariance=pose_covariance, moment=moment,
            force=force, estimate=estimate, prior_mean=prior_mean,
            prior_covariance=prior_covariance, target_force_sd=target_force_sd,
            target_moment_sd=target_moment_sd, max_force=max_force, max_moment=max_moment)

    @one_blas_thread
    def solve_many(self, forces: ArrayLike, moments: Optional[ArrayLike] = None, *,
                   compliance: bool = False) -> BatchResult:
        """
        Solve the wrenches of rows (N, 3) of ``forces`` and ``moments`` (default none) in order.

        The rows equal N consecutive ``solve`` calls (runs of usual warm rows: one compiled
        loop, ``Engine.solve_rows``). A failing row is flagged (``converged`` False,
        ``message``), never raised; InputError (a ValueError) names a bad input row.
        """
        wrenches = check_wrenches(forces, moments)
        batch = BatchResult.empty(wrenches, compliance)
        self.engine.solve_rows(batch, wrenches, range(len(wrenches)), compliance,
                               self.time_limit_s)
        return batch

    def solve_batch_rows(self, batch: BatchResult, wrenches: np.ndarray, rows: range,
                         compliance: bool) -> None:
        """Solve ``rows`` of checked ``wrenches`` (N, 6) into ``batch`` as ``solve_many`` does."""
        self.engine.solve_rows(batch, wrenches, rows, compliance, self.time_limit_s)

    def solve_batch_row(self, batch: BatchResult, row: int, wrench: np.ndarray,
                        compliance: bool) -> float:
        """Solve row ``row`` of ``batch`` at checked ``wrench`` as ``solve``; its time (s)."""
        return self.engine.solve_row(batch, row, wrench, compliance, self.time_limit_s)

    def _solve_with_compliance(self, wrench: np.ndarray, time_limit_s: float) -> SolveResult:
        """Solve at ``wrench`` (6) with its compliance within ``time_limit_s``."""
        return self.solve(wrench[:3], wrench[3:], compliance=True, time_limit_s=time_limit_s)
