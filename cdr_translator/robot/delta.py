"""
Forward statics of the Continuum Delta Robot: three translator legs and a rigid platform.

Given the slider positions q and a payload wrench on the platform, find the platform
pose and the wrench each leg carries. Unknowns (24): the platform position p and
orientation R (6, R updated multiplicatively, R <- exp([dphi]) R, dphi in {w}) and the
wrench w_i = [f_i; m_i] the platform applies to each leg's end disk, in the leg base
frame {pe_i} about the end-disk centre (18; exactly the wrench TranslatorSolver takes).
Residuals (24):

* pose compatibility (18): the end-disk pose of leg i solved under w_i, minus the pose
  of the platform's attachment i seen from the leg base, in {pe_i} (position, m; rotation
  vector of R_de R_target^T, rad);
* platform equilibrium (6): payload + sum of the leg reactions -w_i, as a force and a
  moment about the platform origin in {w} (N, N m): the platform is a free body, each
  reaction acting at its attachment point (where the compatibility residual puts the
  leg's end-disk centre, to 1e-10 m).

Newton's method solves them; the Jacobian couples the legs only through the platform
pose, each leg entering through its 6x6 compliance (d twist / d wrench at the end disk,
{pe_i}), from the leg's exact linearization (one tangent-linear shot: its shooting
Jacobian and end-disk pose derivative; implicit differentiation). Two iterations:

* coupled (warm solves): the legs' own shooting unknowns join the platform's; an iterate
  costs one residual shot per leg, the Newton system is reduced to the platform's 24 by
  eliminating each leg with its LU (see ``_correction``), and chord steps reuse that
  factorization across iterations and solves until they contract too slowly (Broyden
  updates within a solve; a quadratic predictor along a steadily followed path). The legs'
  SolveResults (shape, stability, error estimate) are built from the solved leg unknowns
  when first asked for (DeltaResult.leg_results, TranslatorSolver.result_at).
* nested (cold solves from home, where the legs' shooting is far from linear, and the
  fallback of a stalled coupled solve): every iterate solves each leg in full under its
  wrench, warm-started.

Steps are damped by Deuflhard's natural monotonicity test. The robot walks from its
previous solution (or home: straight legs, no load) to the requested input by
predictor-corrector continuation, as the leg solver does for one translator.
"""

from dataclasses import dataclass, field, fields
import functools
import math
from pathlib import Path
import time
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from .inverse import InverseResult, InverseSolver
from .kernels import chord_verdict, coupled_iterations, coupled_step, FAR, NO_STEP
from .kernels import platform_residual, REBUILD, secant_update, shoot_legs, turn_and_move
from .kernels import within
from .params import cdr_values, check_sliders, DeltaParams, Leg
from .result import DeltaResult, LegResults, rotation_vector
from .._blas import one_blas_thread
from .._linalg import factorize, solve_lu
from ..params import Accuracy, DEFAULT_PARAMS_PATH, TranslatorParams
from ..result import SolveResult
from ..solver import check_wrench, TranslatorSolver
from ..stability import pose_twist

#: Size of the unknown and residual vectors: platform pose (6) + three leg wrenches (18).
SIZE = 24

#: Smallest fraction of the remaining input change a continuation step may take.
MIN_CONTINUATION_STEP = 1e-3

#: Chord steps whose contractions of the Newton correction have a geometric mean above
#: this, or one step contracting by less than SLOW_CHORD, rebuild the factorization (three
#: exact leg Jacobians and the platform LU).
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

#: A factorization made within this distance of the solution (largest change of the scaled
#: unknowns, platform and legs) serves the compliance and stability verdict there: it
#: moves the compliance by about as much, relatively, below the 1e-8 to which implicit and
#: finite-difference compliances agree.
REUSE_DISTANCE = 1e-9

#: Largest change of the scaled unknowns (platform and legs) a continuation step of the
#: coupled Newton may predict; a step predicting more is shortened.
PREDICTOR_REACH = 3.0


COUPLE_WITHIN = 0.1

#: The polynomial predictor (_extrapolate) is used when the input change it does not
#: extrapolate makes at most this fraction of the residual change of the whole.
EXTRAPOLATE_WITHIN = 0.5

#: Highest degree of the polynomial predictor: the last PREDICTOR_DEGREE solves' steps.
#: Along bench.delta_statics' slider circle (interleaved in one process) degree 3 took
#: 3.96 iterations per warm solve against 4.91 for the quadratic; degree 4 took 5.62: the
#: solves converge to about 1e-8, and its weights (sum 15, against 7) amplify that.
PREDICTOR_DEGREE = 3

#: Broyden updates gathered on one factorization at most (then H stays until a rebuild).
MAX_SECANTS = 24

#: The work counters of a solve (DeltaResult fields of the same names).
COUNTS = ('leg_solves', 'leg_shots', 'leg_jacobians')


def _skew(vector: np.ndarray) -> np.ndarray:
    """Return the cross-product matrix [a]x of a 3-vector a: [a]x b = a x b."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _inverse_left_jacobian(vector: np.ndarray) -> np.ndarray:
    """
    Inverse left Jacobian of SO(3) at rotation vector ``vector``.

    d log(exp([a]) R) / da at a = 0, for R = exp([vector]); its transpose (the inverse
    right Jacobian) is d log(R exp([a])) / da.
    """
    angle = float(np.linalg.norm(vector))
    cross = _skew(vector)
    if angle < 1e-6:
        coefficient = 1.0 / 12.0  # the series limit
    else:
        coefficient = (1.0 / angle ** 2
                       - (1.0 + math.cos(angle)) / (2.0 * angle * math.sin(angle)))
    return np.eye(3) - 0.5 * cross + coefficient * cross @ cross


@dataclass
class _State:
    """
    Platform pose and leg wrenches (the platform unknowns), and the legs' own unknowns.

    ``unknowns`` (3, n): each leg's nondimensional shooting unknowns (its Problem's);
    ``frames`` (3, 4, 4): each leg's end-disk frame in {pe_i} there; ``leg_error``: the
    largest nondimensional leg residual; ``legs``: the legs' (unjudged) SolveResults when
    they were solved in full at this state (nested iteration), else None.
    """

    position: np.ndarray
    rotation: np.ndarray
    wrenches: np.ndarray
    unknowns: np.ndarray
    frames: Optional[np.ndarray] = None
    leg_residuals: Optional[np.ndarray] = None
    leg_error: float = math.inf
    legs: Optional[List[SolveResult]] = None

    def moved(self, step: np.ndarray, x_scale: np.ndarray) -> '_State':
        """
        Apply a flat scaled step [dp; dphi; dw_1; dw_2; dw_3 (/ x_scale); leg steps (3 x n)].

        The platform turns by exp([dphi]) (kernels.turn_and_move, as the compiled
        iterations move their trials); the result is not yet shot.
        """
        moved = _State(np.empty(3), np.empty((3, 3)), np.empty((3, 6)),
                       np.empty_like(self.unknowns))
        turn_and_move(self.position, self.rotation, self.wrenches, self.unknowns,
                      np.ascontiguousarray(step, dtype=float), 1.0, x_scale, moved.position,
                      moved.rotation, moved.wrenches, moved.unknowns)
        return moved


@dataclass
class _LegLinearization:
    """One leg's exact linearization at a state: what the platform Newton needs of it."""

    lu: tuple  # LU factorization of the leg's shooting Jacobian (nondimensional)
    pose: np.ndarray  # d(end-disk frame)/d(unknowns), (12, n): Problem.pose_jacobian
    twist: np.ndarray  # d(end-disk twist)/d(unknowns), (6, n): stability.pose_twist of it
    rotation: np.ndarray  # end-disk rotation in {pe_i} there
    gain: np.ndarray  # J^-1 dr/dw (n, 6): unknowns per SI wrench
    compliance: np.ndarray  # (6, 6) SI, cdr_translator/compliance.py's convention
    wrench: np.ndarray  # the wrench it was made at


@dataclass
class _PathStep:
    """One converged coupled solve: from ``start`` to ``end`` for an input change."""

    start: _State
    end: _State
    inputs_change: np.ndarray  # du (12)
    step: np.ndarray  # end - start, flat and scaled (_difference)


class _Secants:
    """
    Good-Broyden updates of the coupled Newton's inverse Jacobian, on one factorization.

    The unknowns' steps are flat and scaled (platform / x_scale, then the legs' (3, n)
    nondimensional unknowns), as ``_norm`` measures them. Update i maps H_i to
    H_{i+1} = H_i + (s - H_i y) s^T H_i / (s^T H_i y), s the step taken and y the change
    of the residuals (Kelley, "Solving Nonlinear Equations with Newton's Method", SIAM
    2003, Sec. 1.11, as chord.py holds them for one leg): kept as u = (s - H_i y) /
    (s^T H_i y) and s, H_{i+1} r = H_i r + u (s . H_i r) (chord.apply_updates).
    """

    def __init__(self, size: int) -> None:
        """Room for MAX_SECANTS updates of flat steps of ``size``; none yet."""
        self.updates = np.empty((MAX_SECANTS, size))
        self.steps = np.empty((MAX_SECANTS, size))
        self.count = 0

    def add(self, step: np.ndarray, change: np.ndarray, correction: np.ndarray) -> np.ndarray:
        """
        Add the update of step s (flat, scaled) whose residual change y has H y = ``change``.

        Return ``correction`` (H r for some r, before the update) after it: H_{i+1} r. Once
        MAX_SECANTS are gathered H stays as it is (a rebuild starts afresh).
        """
        updated = np.array(correction, dtype=float)
        self.count = int(secant_update(self.updates, self.steps, self.count,
                                       np.ascontiguousarray(step, dtype=float),
                                       np.ascontiguousarray(change, dtype=float), updated))
        return updated


@dataclass
class _Factorization:
    """The platform Jacobian's LU (scaled) and the leg linearizations it was built from."""

    platform: tuple
    legs: Tuple[_LegLinearization, ...]
    state: _State  # where it was made
    #: Broyden updates gathered on it, by this and later solves until it is rebuilt
    secants: _Secants = field(init=False)
    # for the chord steps (kernels.coupled_step), stacked over the legs: the LU factors
    # (3, n, n) and pivots (3, n), T_k (3, 6, n) and J_k^-1 dr/dw (3, n, 6); and the scaled
    # platform Jacobian's inverse (24, 24)
    factors: np.ndarray = field(init=False)
    pivots: np.ndarray = field(init=False)
    twists: np.ndarray = field(init=False)
    gains: np.ndarray = field(init=False)
    platform_inverse: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        """Stack the legs' matrices, invert the platform Jacobian, start the secants."""
        # C order: the substitutions run along rows (LAPACK's factors are column-major)
        self.factors = np.ascontiguousarray(np.stack([leg.lu[0] for leg in self.legs]))
        self.pivots = np.stack([leg.lu[1] for leg in self.legs])
        self.twists = np.ascontiguousarray(np.stack([leg.twist for leg in self.legs]))
        self.gains = np.ascontiguousarray(np.stack([leg.gain for leg in self.legs]))
        self.platform_inverse = np.ascontiguousarray(solve_lu(self.platform, np.eye(SIZE)))
        self.secants = _Secants(SIZE + self.gains.shape[0] * self.gains.shape[1])


@dataclass
class _Outcome:
    """Where a Newton correction ended."""

    state: _State
    residual: np.ndarray
    iterations: int
    converged: bool
    message: str
    factorization: Optional[_Factorization] = None


@dataclass
class _CoupledRun:
    """Where ``kernels.coupled_iterations`` stopped, and what _newton carries on with."""

    status: int  # kernels' CONVERGED_AT_TOP, OUT_OF_BUDGET, REBUILD, NO_STEP or FAR
    iterations: int  # iterations it did (a failed line search counts)
    state: _State
    residual: np.ndarray
    step: Optional[np.ndarray]  # the pending correction, if any
    fresh: bool
    chord_steps: int
    chord_log: float


class _Deadline(Exception):
    """The time limit passed during a leg solve."""


class DeltaRobot:
    """
    Forward statics of the CDR; successive solves warm-start.

    >>> robot = DeltaRobot()                        # config/translator.yaml
    >>> result = robot.solve([0.0, 0.0, 0.0], [0.0, 0.0, -9.81])   # m; N in {w}
    """

    def __init__(self, params: Optional[TranslatorParams] = None,
                 geometry: Optional[DeltaParams] = None, *,
                 equilibrium_tolerance: float = 1e-10, position_tolerance: float = 1e-10,
                 rotation_tolerance: float = 1e-9, max_iterations: int = 12,
                 time_limit_s: float = 30.0) -> None:
        """
        Set up three leg solvers for ``params`` and the CDR ``geometry`` (default: YAML).

        Converged means every equilibrium component is within ``equilibrium_tolerance``
        (N, N m), every leg's end disk within ``position_tolerance`` (m) and
        ``rotation_tolerance`` (rad) of its platform attachment, and every leg's own
        shooting residual within its solver's tolerance. ``max_iterations`` caps the
        Newton iterations of one continuation step (a step that needs more is halved),
        ``time_limit_s`` a whole solve. The linearization at home (three exact leg
        Jacobians, a few ms) is made here, once: cold solves start from it.
        """
        if max_iterations < 1:
            raise ValueError(f'max_iterations must be at least 1, got {max_iterations}')
        self.params = params if params is not None else TranslatorParams.from_yaml()
        self.geometry = geometry if geometry is not None else DeltaParams.from_yaml()
        height = self.params.stack_height
        self.legs: Tuple[Leg, Leg, Leg] = self.geometry.legs(height)
        self.home_position = np.array([0.0, 0.0, -self.geometry.home_height(height)])
        self.equilibrium_tolerance = equilibrium_tolerance
        self.position_tolerance = position_tolerance
        self.rotation_tolerance = rotation_tolerance
        self.max_iterations = max_iterations
        self.time_limit_s = time_limit_s
        # a leg is one link of the closed chain: its discretization stays fixed across the
        # robot's Newton iterations (no automatic refinement) and its equilibrium is not
        # judged alone (a leg's stability under a dead tip load is not the chain's)
        # the leg solves of the nested iteration converge, nothing more (judge=False): only
        # the legs of the result are judged, when read (_leg_results)
        self.leg_solvers = tuple(TranslatorSolver(self.params, time_limit_s=time_limit_s,
                                                  accuracy=Accuracy(0.0, 0.0),
                                                  follow_stable_branch=False, judge=False)
                                 for _ in range(3))
        self._leg_tolerance = min(solver.tolerance for solver in self.leg_solvers)
        # scales for a balanced Newton system: the stack height, and the force that bends
        # the five backbones of a leg noticeably over it
        length = height
        force = 5.0 * self.params.bending_stiffness / height ** 2
        self._x_scale = np.concatenate(
            [np.full(3, length), np.ones(3), np.tile(np.repeat([force, force * length], 3), 3)])
        self._r_scale = np.concatenate(
            [np.tile(np.repeat([length, 1.0], 3), 3), np.repeat([force, force * length], 3)])
        rotations = np.stack([leg.rotation for leg in self.legs])
        self._leg_rotations = rotations
        self._attachments = np.stack([leg.attachment for leg in self.legs])
        self._home_bases = np.stack([leg.home_base for leg in self.legs])
        self._slider_axes = np.stack([leg.slider_axis for leg in self.legs])
        self._platform = (self._leg_rotations, self._attachments, self._home_bases,
                          self._slider_axes, self._r_scale, self._x_scale)
        # the input sensitivity's blocks that depend on neither state nor inputs
        self._constant_sensitivity = np.zeros((SIZE, 12))
        for k, leg in enumerate(self.legs):
            self._constant_sensitivity[6 * k:6 * k + 3, k] = leg.rotation.T @ leg.slider_axis
        self._constant_sensitivity[18:21, 3:6] = np.eye(3)
        self._constant_sensitivity[21:24, 6:9] = np.eye(3)
        self._counts = dict.fromkeys(COUNTS, 0)
        self._no_legs = np.zeros((3, self.leg_solvers[0].problem.size))
        problem = self.leg_solvers[0].problem
        self._leg_scales = (problem.x_scale, problem.residual_scale, problem.model_args)
        self._deadline = math.inf
        self._previous: Optional[Tuple[_State, np.ndarray]] = None  # (state, inputs)
        #: the last (up to two) coupled solves' steps, latest last (_extrapolate); emptied
        #: by a solve that is not one
        self._path: List[_PathStep] = []
        #: start_at arguments of each leg solver, applied before the next full leg solve
        self._legs_at: Optional[Tuple[tuple, ...]] = None
        self._factorization: Optional[_Factorization] = None
        self._inverse = InverseSolver(self)
        home = self._home_state()
        self._home = (home, self._factorize(home, np.zeros(12)))

    @classmethod
    def from_yaml(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH,
                  **options: Any) -> 'DeltaRobot':
        """Build from a params file over the shipped one (``cdr_values``: model and geometry)."""
        values = cdr_values([path])
        params = TranslatorParams.from_mapping({field.name: values[field.name]
                                                for field in fields(TranslatorParams)})
        geometry = DeltaParams.from_mapping({field.name: values[field.name]
                                             for field in fields(DeltaParams)})
        return cls(params, geometry, **options)

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts from home."""
        self._previous = None
        self._factorization = None
        self._path = []
        self._legs_at = None
        self._inverse.reset()
        for solver in self.leg_solvers:
            solver.reset()

    # public ----------------------------------------------------------------------------------
    @one_blas_thread
    def solve(self, sliders: ArrayLike, payload_force: ArrayLike,
              payload_moment: ArrayLike = (0.0, 0.0, 0.0),
              payload_offset: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True, compliance: bool = False) -> DeltaResult:
        """
        Solve the platform pose for slider positions (m) and a payload on the platform.

        ``payload_force`` (N) and ``payload_moment`` (N m) are in {w}; the force acts at
        ``payload_offset`` (m), a point fixed in the platform frame {p} (default: the
        platform origin). ``compliance`` adds the platform compliance, the input
        sensitivity and the stability verdict (see DeltaResult). They need the legs'
        exact linearization at the solution: reused when the last factorization was made
        there (within REUSE_DISTANCE), else three exact leg Jacobians (one tangent-linear
        shot each; the dominant cost of a warm solve with ``compliance``), which the next
        solve then iterates on. Bad input raises ValueError; non-convergence is a result.
        """
        offset = np.asarray(payload_offset, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f'payload offset must be 3 finite coordinates (m), got {offset}')
        inputs = np.concatenate([check_sliders(sliders, self.geometry.slider_stroke),
                                 check_wrench(payload_force, payload_moment), offset])
        started = time.perf_counter()
        self._deadline = started + self.time_limit_s
        self._counts = dict.fromkeys(COUNTS, 0)
        if not (warm_start and self._previous is not None):
            self.reset()
            self._previous = (self._home[0], np.zeros(12))
            self._factorization = self._home[1]
        previous, factorization = self._previous, self._factorization
        # from home the legs' shooting is far from linear (a coupled Newton needed 5-10
        # times the iterations): there each iterate's legs are solved in full
        coupled = previous[0] is not self._home[0]
        with np.errstate(over='ignore', invalid='ignore'):
            outcome = self._continuation(inputs, coupled)
            if coupled and not outcome.converged and time.perf_counter() < self._deadline:
                # the coupled iteration stalled: solve the legs in full at every iterate
                self._previous, self._factorization = previous, factorization
                nested = self._continuation(inputs, coupled=False)
                nested.iterations += outcome.iterations
                if nested.converged:
                    nested.message += ' (legs solved in full after the coupled Newton ' \
                        f'stalled: {outcome.message})'
                if nested.converged or (np.linalg.norm(nested.residual)
                                        < np.linalg.norm(outcome.residual)):
                    outcome = nested
            legs = self._leg_results(outcome.state, outcome.factorization)
        if outcome.converged:
            self._previous = (outcome.state, inputs)
        result = self._result(outcome, legs, inputs, time.perf_counter() - started)
        if compliance and outcome.converged:
            with np.errstate(over='ignore', invalid='ignore'):
                self._linearize(result, outcome, inputs)
            result.solve_time_s = time.perf_counter() - started
            self._count_into(result)
        return result

    def _linearize(self, result: DeltaResult, outcome: _Outcome, inputs: np.ndarray) -> None:
        """Add the compliance, input sensitivity and stability verdict to ``result``."""
        state, factorization = outcome.state, outcome.factorization
        try:
            if factorization is None or _distance(factorization.state, state,
                                                  self._x_scale) > REUSE_DISTANCE:
                factorization = self._factorize(state, inputs)
                self._factorization = factorization  # exact at the solution: the next
                # solve's chord steps start from it
            right = np.zeros((SIZE, 18))
            right[:, :12] = self._input_sensitivity(state, inputs)
            right[18:, 12:] = np.eye(6)
            solved = -self._x_scale[:6, None] * solve_lu(factorization.platform,
                                                         right / self._r_scale[:, None])[:6]
        except (_Deadline, ArithmeticError, np.linalg.LinAlgError, ValueError) as error:
            result.stable = False
            result.message += f'; no platform compliance: {error}'
            return
        if not np.all(np.isfinite(solved)):
            result.stable = False
            result.message += '; no platform compliance: the Newton Jacobian is singular'
            return
        result.input_sensitivity = solved[:, :12]
        result.platform_compliance = solved[:, 12:]
        scale = np.concatenate([np.ones(3), np.full(3, 1.0 / self.params.stack_height)])
        try:
            stiffness = np.linalg.inv(result.platform_compliance)
        except np.linalg.LinAlgError:
            result.stable = False
            result.message += '; the platform compliance is singular'
            return
        scaled = scale[:, None] * stiffness * scale[None, :]
        result.stiffness_margin = float(np.linalg.eigvalsh(0.5 * (scaled + scaled.T))[0])
        result.stable = bool(result.stiffness_margin > 0.0)

    def inverse(self, platform_position: ArrayLike,
                payload_force: ArrayLike = (0.0, 0.0, 0.0),
                payload_moment: ArrayLike = (0.0, 0.0, 0.0),
                payload_offset: ArrayLike = (0.0, 0.0, 0.0),
                warm_start: bool = True) -> InverseResult:
        """
        Inverse statics: slider positions putting the platform origin at ``platform_position``.

        Target in m in {w}, payload as in ``solve``. Successive calls warm-start along a
        path; the sliders stay within the stroke. An unreachable target is a result
        (``reachable`` False) at the nearest reachable point, naming the binding stroke
        limits; bad input raises ValueError. See cdr_translator.robot.inverse.
        """
        return self._inverse.solve(platform_position, payload_force, payload_moment,
                                   payload_offset, warm_start)

    # continuation ----------------------------------------------------------------------------
    def _home_state(self) -> _State:
        """Straight legs, no load, platform at home: an exact solution for q = 0, no payload."""
        state = _State(self.home_position.copy(), np.eye(3), np.zeros((3, 6)),
                       np.zeros((3, self.leg_solvers[0].problem.size)))
        self._store_legs(state, [solver.solve(np.zeros(3)) for solver in self.leg_solvers])
        self._counts['leg_solves'] += 3
        return state

    def _continuation(self, inputs: np.ndarray, coupled: bool) -> _Outcome:
        """
        Walk from the previous solution to ``inputs`` (sliders, payload).

        Each step predicts the solution to first order with the stored factorization,
        dx = -J^-1 (dr/du) du (coupled, a whole step along a steadily followed path: to
        second order, ``_extrapolate``), and Newton corrects it (``coupled``: leg unknowns
        and platform together; else every iterate's legs solved in full); a failed step is
        halved, a good one doubled.
        """
        if self._previous is None:
            raise RuntimeError('continuation needs a previous solution')
        state, start = self._previous
        factorization = self._factorization
        if factorization is not None:
            factorization.secants.count = 0  # a solve's Broyden updates are its own
        done, step, iterations = 0.0, 1.0, 0
        current = start
        outcome: Optional[_Outcome] = None
        first = self._input_sensitivity(state, start)
        while done < 1.0:
            target = min(1.0, done + step)
            goal = start + target * (inputs - start)
            guess = state
            if factorization is not None:
                sensitivity = first if done == 0.0 else self._input_sensitivity(state, current)
                change = sensitivity @ (goal - current)
                predicted = None
                if coupled and target == 1.0 and done == 0.0:
                    predicted = self._extrapolate(state, inputs - start, first, factorization)
                if predicted is None:
                    predicted = self._correction(change, None, factorization, coupled)
                reach = float(np.abs(predicted).max())
                if coupled and reach > PREDICTOR_REACH:
                    # beyond the linear regime of the legs' shooting: a shorter step
                    fraction = max(PREDICTOR_REACH / reach,
                                   MIN_CONTINUATION_STEP / (target - done))
                    target = done + fraction * (target - done)
                    goal = start + target * (inputs - start)
                    predicted = fraction * self._correction(change, None, factorization,
                                                            coupled)
                guess = state.moved(predicted, self._x_scale)
            outcome = self._newton(guess, goal, factorization, coupled)
            iterations += outcome.iterations
            if outcome.converged:
                done, state, current = target, outcome.state, goal
                factorization = outcome.factorization
                step *= 2.0
                continue
            step = 0.5 * (target - done)
            if step < MIN_CONTINUATION_STEP or time.perf_counter() > self._deadline:
                if not outcome.state.leg_error <= self._leg_tolerance:
                    outcome.state = state  # the last solution every leg converged at
                    outcome.factorization = factorization
                outcome.residual = self._residual(outcome.state, inputs)
                outcome.iterations = iterations
                outcome.message = (f'continuation stalled at {done:.1%} of the way to the '
                                   f'sliders and payload: {outcome.message}')
                return outcome
        self._factorization = factorization
        if outcome is None:  # cannot happen: the loop runs at least once
            raise RuntimeError('continuation made no step')
        if coupled and outcome.converged:  # this solve's step, for the next ones' predictor
            record = _PathStep(self._previous[0], outcome.state, inputs - start,
                               _difference(outcome.state, self._previous[0], self._x_scale))
            self._path = [*self._path[1 - PREDICTOR_DEGREE:], record]
        else:
            self._path = []
        outcome.iterations = iterations
        return outcome

    def _extrapolate(self, state: _State, inputs_change: np.ndarray, sensitivity: np.ndarray,
                     factorization: _Factorization) -> Optional[np.ndarray]:
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
        path = self._path
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
            size = float(np.linalg.norm(rest / self._r_scale))
            if size <= smallest * (1.0 + 1e-9):  # equal within rounding: the higher degree
                chosen = (size, weights, rest)
            smallest = min(smallest, size)
        size, weights, rest = chosen
        whole = sensitivity @ inputs_change
        if size > EXTRAPOLATE_WITHIN * np.linalg.norm(whole / self._r_scale):
            return None
        return (sum(weight * path[-1 - j].step for j, weight in enumerate(weights))
                + self._correction(rest, None, factorization, True))

    # Newton ----------------------------------------------------------------------------------
    def _newton(self, state: _State, inputs: np.ndarray,
                factorization: Optional[_Factorization], coupled: bool) -> _Outcome:
        """
        Damped Newton with the natural monotonicity test; given a factorization, chord steps.

        ``coupled``: the unknowns are the platform's and the legs' own shooting unknowns
        together, each iterate one residual shot per leg; the Newton system is reduced to
        the platform's 24 by eliminating each leg's unknowns with its LU (the legs enter
        through their compliances, as in the nested form, plus the twist each leg's own
        Newton correction makes), and every accepted step updates the inverse Jacobian by
        Broyden's good formula (``_Secants``, kept with the factorization). Else every
        iterate solves the legs in full.
        A step is judged in the unknowns, not in the residual: the trial point must shrink
        the simplified Newton correction J^-1 r (same factorization) relative to the step
        (Deuflhard's restricted monotonicity test). That needs no weighting of metres
        against newtons, and it accepts the full step of the force-stiff leg axes that a
        residual-norm test rejects far from the solution. The simplified correction of an
        accepted trial is the next step (after its Broyden update). A chord step
        contracting by less than CHORD_RATE, or failing, rebuilds the factorization.
        """
        try:
            evaluated = self._evaluate(state, coupled)
        except _Deadline as error:
            return _Outcome(state, np.full(SIZE, np.inf), 0, False, str(error), factorization)
        if not evaluated:
            return _Outcome(state, np.full(SIZE, np.inf), 0, False,
                            'a leg did not converge at the predicted wrenches', factorization)
        residual = self._residual(state, inputs)
        fresh, chord_steps, chord_log = False, 0, 0.0
        step: Optional[np.ndarray] = None  # the next correction, once an iteration made it
        far = False  # the compiled iterations left the current one to this loop
        iteration = 1
        while iteration <= self.max_iterations:
            if self._converged(residual, state):
                return _Outcome(state, residual, iteration - 1, True, 'converged',
                                factorization)
            if time.perf_counter() > self._deadline:
                return _Outcome(state, residual, iteration - 1, False,
                                f'time limit of {self.time_limit_s} s reached', factorization)
            try:
                if factorization is None:
                    factorization = self._factorize(state, inputs)
                    fresh, step = True, None
                if coupled and not far:
                    run = self._coupled_iterations(state, residual, step, inputs,
                                                   factorization, fresh, chord_steps,
                                                   chord_log, self.max_iterations - iteration + 1)
                    state, residual, step = run.state, run.residual, run.step
                    fresh, chord_steps, chord_log = run.fresh, run.chord_steps, run.chord_log
                    iteration += run.iterations
                    if run.status == NO_STEP:
                        return _Outcome(state, residual, iteration - 1, False,
                                        'damping found no contracting Newton step',
                                        factorization)
                    if run.status == REBUILD:
                        factorization, step = None, None
                    far = run.status == FAR
                    continue
                far = False
                if step is None:
                    step = self._correction(residual, state.leg_residuals if coupled else None,
                                            factorization, coupled)
                step_size = self._norm(step, coupled)
                trial = self._line_search(state, step, inputs, factorization, coupled)
            except (_Deadline, ArithmeticError) as error:
                return _Outcome(state, residual, iteration, False, str(error), factorization)
            if trial is None:
                if fresh:
                    return _Outcome(state, residual, iteration, False,
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
                    and not self._converged(residual, state):
                # near the solution the legs' shooting is nearly linear: finish coupled,
                # three shots per iterate instead of three leg solves
                finish = self._newton(state, inputs, factorization, True)
                finish.iterations += iteration
                if finish.converged:
                    return finish
            iteration += 1
        converged = self._converged(residual, state)
        return _Outcome(state, residual, self.max_iterations, converged,
                        'converged' if converged
                        else f'no convergence in {self.max_iterations} iterations',
                        factorization)

    def _coupled_iterations(self, state: _State, residual: np.ndarray,
                            step: Optional[np.ndarray], inputs: np.ndarray,
                            factorization: _Factorization, fresh: bool, chord_steps: int,
                            chord_log: float, allowed: int) -> _CoupledRun:
        """
        Run up to ``allowed`` coupled chord iterations in one compiled call.

        kernels.coupled_iterations does what the loop of ``_newton`` does for them (one
        compiled call instead of about 0.1 ms of Python per iteration); the state it
        reaches is a new _State (``state`` itself when no trial was accepted).
        """
        if state.frames is None or state.leg_residuals is None:
            raise RuntimeError('the legs have not been shot at this state')
        reached = (state.position.copy(), state.rotation.copy(), state.wrenches.copy(),
                   state.unknowns.copy(), state.frames.copy(), state.leg_residuals.copy(),
                   residual.copy())
        scratch = tuple(np.empty_like(array) for array in reached)
        flat = step.copy() if step is not None else np.empty(SIZE + state.unknowns.size)
        secants = factorization.secants
        (status, iterations, shots, leg_error, secants.count, chord_steps, chord_log,
         has_step, fresh, moved) = coupled_iterations(
            reached, scratch, flat, step is not None, inputs, self._leg_scales, self._platform,
            (factorization.factors, factorization.pivots, factorization.twists,
             factorization.gains, factorization.platform_inverse),
            secants.updates, secants.steps, int(secants.count),
            (float(self.equilibrium_tolerance), float(self.position_tolerance),
             float(self.rotation_tolerance), float(self._leg_tolerance)),
            (SLOW_CHORD, CHORD_RATE, CHORD_FLOOR, CHORD_LIMIT, int(allowed)), bool(fresh),
            int(chord_steps), float(chord_log), float(state.leg_error))
        self._counts['leg_shots'] += shots
        if moved:
            state = _State(*reached[:4], frames=reached[4], leg_residuals=reached[5],
                           leg_error=leg_error)
            residual = reached[6]
        return _CoupledRun(status, iterations, state, residual, flat if has_step else None,
                           fresh, chord_steps, chord_log)

    def _correction(self, residual: np.ndarray, leg_residuals: Optional[np.ndarray],
                    factorization: _Factorization, coupled: bool) -> np.ndarray:
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
        ``coupled``: with the factorization's Broyden updates (``_Secants``).
        """
        legs = factorization.gains
        out = np.empty(SIZE + legs.shape[0] * legs.shape[1])
        secants = factorization.secants
        coupled_step(residual, leg_residuals if leg_residuals is not None else self._no_legs,
                     leg_residuals is not None, self._r_scale, self._x_scale,
                     factorization.factors, factorization.pivots, factorization.twists, legs,
                     factorization.platform_inverse, secants.updates, secants.steps,
                     secants.count if coupled else 0, out)
        return out

    @staticmethod
    def _norm(step: np.ndarray, coupled: bool) -> float:
        """Norm of a flat scaled step (the legs' part counts only when ``coupled``)."""
        counted = step if coupled else step[:SIZE]
        return math.sqrt(float(counted @ counted))

    def _line_search(self, state: _State, step: np.ndarray, inputs: np.ndarray,
                     factorization: _Factorization, coupled: bool
                     ) -> Optional[Tuple[_State, np.ndarray, float, Optional[np.ndarray]]]:
        """
        Halve the Newton ``step`` (flat, scaled) until a trial passes the monotonicity test.

        Return (state, residual, contraction ||J^-1 r_trial|| / ||step||, the next step), or
        None. A converged trial is taken at once (contraction 0, no next step); ``coupled``,
        an accepted one updates the inverse Jacobian (``_Secants``), which makes the next
        step from its simplified correction.
        """
        norm = self._norm(step, coupled)
        scale = 1.0
        for _ in range(10):
            trial = state.moved(scale * step, self._x_scale)
            if self._evaluate(trial, coupled):
                residual = self._residual(trial, inputs)
                if self._converged(residual, trial):
                    return trial, residual, 0.0, None
                simplified = self._correction(residual, trial.leg_residuals if coupled else None,
                                              factorization, coupled)
                contraction = self._norm(simplified, coupled) / norm
                if contraction < 1.0 - 0.25 * scale:
                    if coupled:  # H y = H r_trial - H r = step - simplified
                        simplified = factorization.secants.add(scale * step, step - simplified,
                                                               simplified)
                    return trial, residual, contraction, simplified
            scale *= 0.5
        return None

    def _converged(self, residual: np.ndarray, state: _State) -> bool:
        return bool(state.leg_error <= self._leg_tolerance
                    and within(residual, self.equilibrium_tolerance, self.position_tolerance,
                               self.rotation_tolerance))

    # legs ------------------------------------------------------------------------------------
    def _evaluate(self, state: _State, coupled: bool) -> bool:
        """
        Give ``state`` its legs' end-disk frames; False if a leg cannot be evaluated there.

        ``coupled``: one residual shot per leg at the state's leg unknowns. Else each leg
        is solved under its wrench (warm-started), its unknowns replaced by the solution.
        """
        if not coupled:
            legs = [self._solve_leg(k, state.wrenches[k]) for k in range(3)]
            self._store_legs(state, legs)
            return all(leg.converged for leg in legs)
        residuals = np.empty_like(state.unknowns)
        frames = np.empty((3, 4, 4))
        state.leg_error = shoot_legs(state.unknowns, state.wrenches, *self._leg_scales,
                                     residuals, frames)
        self._counts['leg_shots'] += 3
        state.leg_residuals, state.frames = residuals, frames
        return math.isfinite(state.leg_error)

    def _store_legs(self, state: _State, legs: List[SolveResult]) -> None:
        """Set ``state``'s leg unknowns, frames and residual size from solved legs."""
        state.legs = legs
        state.frames = np.stack([leg.frames['de'] for leg in legs])
        state.unknowns = np.stack([leg.unknowns / solver.problem.x_scale
                                   for leg, solver in zip(legs, self.leg_solvers)])
        state.leg_residuals = None
        # a converged leg met its solver's tolerance on the largest residual component
        state.leg_error = 0.0 if all(leg.converged for leg in legs) else math.inf

    def _solve_leg(self, k: int, wrench: np.ndarray) -> SolveResult:
        remaining = self._deadline - time.perf_counter()
        if remaining <= 0.0:
            raise _Deadline(f'time limit of {self.time_limit_s} s reached')
        if self._legs_at is not None:  # the last coupled solution: each leg starts there
            for solver, start in zip(self.leg_solvers, self._legs_at):
                solver.start_at(*start)
            self._legs_at = None
        solver = self.leg_solvers[k]
        solver.time_limit_s = remaining
        self._counts['leg_solves'] += 1
        return solver.solve(wrench[:3], wrench[3:])

    def _leg_results(self, state: _State,
                     factorization: Optional[_Factorization]) -> Sequence[SolveResult]:
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
            self._legs_at = tuple(starts)
        return LegResults(functools.partial(solver.result_at, *start)
                          for solver, start in zip(self.leg_solvers, starts))

    def _factorize(self, state: _State, inputs: np.ndarray) -> _Factorization:
        """
        Exact linearization at ``state``: each leg's tangent-linear shot, and the platform LU.

        ArithmeticError when a leg Jacobian or the platform Jacobian is singular.
        """
        if state.frames is None:
            raise RuntimeError('the legs have not been evaluated at this state')
        legs = []
        for k, solver in enumerate(self.leg_solvers):
            problem = solver.problem
            _, jacobian, pose = problem.exact_jacobian(state.unknowns[k], state.wrenches[k])
            lu = factorize(jacobian)
            gain = solve_lu(lu, problem.wrench_sensitivity)
            rotation = state.frames[k, :3, :3].copy()
            twist = pose_twist(pose, rotation)
            compliance = -twist @ gain
            if not np.all(np.isfinite(compliance)):
                raise ArithmeticError(f'the Jacobian of leg {k + 1} is singular')
            legs.append(_LegLinearization(lu, pose.copy(), twist, rotation, gain, compliance,
                                          state.wrenches[k].copy()))
        self._counts['leg_jacobians'] += 3
        jacobian = self._jacobian(state, inputs, [leg.compliance for leg in legs])
        platform = factorize(jacobian / self._r_scale[:, None] * self._x_scale[None, :])
        if not np.all(np.isfinite(platform[0])) or np.any(np.diag(platform[0]) == 0.0):
            raise ArithmeticError('the platform Jacobian is singular')
        return _Factorization(platform, tuple(legs), state)

    # residual and derivatives ----------------------------------------------------------------
    def _reactions(self, state: _State) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the leg forces on the platform in {w} (3, 3) and their lever arms (3, 3).

        The platform is a free body loaded at its attachment points, the lever arms
        R a_i; the compatibility residual keeps each end disk there.
        """
        forces = np.array([-leg.rotation @ wrench[:3]
                           for leg, wrench in zip(self.legs, state.wrenches)])
        arms = np.array([state.rotation @ leg.attachment for leg in self.legs])
        return forces, arms

    def _residual(self, state: _State, inputs: np.ndarray) -> np.ndarray:
        """Compatibility (18: m, rad, in {pe_i}) and equilibrium (6: N, N m, in {w})."""
        if state.frames is None:
            raise RuntimeError('the legs have not been evaluated at this state')
        residual = np.empty(SIZE)
        rotations = self._leg_rotations
        if not platform_residual(state.position, state.rotation, state.wrenches, state.frames,
                                 inputs, rotations, self._attachments, self._home_bases,
                                 self._slider_axes, residual):
            # a rotation error of 90 degrees or more (far from the solution)
            for k in range(3):
                target = rotations[k].T @ state.rotation @ rotations[k]
                residual[6 * k + 3:6 * k + 6] = rotation_vector(
                    state.frames[k, :3, :3] @ target.T)
        return residual

    def _jacobian(self, state: _State, inputs: np.ndarray,
                  compliances: List[np.ndarray]) -> np.ndarray:
        """d(residual)/d(platform unknowns), each leg entering through its ``compliances``."""
        force, offset = inputs[3:6], inputs[9:]
        jacobian = np.zeros((SIZE, SIZE))
        forces, arms = self._reactions(state)
        residual = self._residual(state, inputs)
        jacobian[21:24, 3:6] = _skew(force) @ _skew(state.rotation @ offset)
        for k, leg in enumerate(self.legs):
            columns = slice(6 + 6 * k, 12 + 6 * k)
            compliance = compliances[k]
            # the rotation error log(R_de R_target^T): the end disk turns it from the left,
            # the platform from the right
            inverse = _inverse_left_jacobian(residual[6 * k + 3:6 * k + 6])
            jacobian[6 * k:6 * k + 3, columns] = compliance[:3]
            jacobian[6 * k + 3:6 * k + 6, columns] = inverse @ compliance[3:]
            jacobian[6 * k:6 * k + 3, 0:3] = -leg.rotation.T
            jacobian[6 * k:6 * k + 3, 3:6] = leg.rotation.T @ _skew(arms[k])
            jacobian[6 * k + 3:6 * k + 6, 3:6] = -inverse.T @ leg.rotation.T
            jacobian[18:21, 6 + 6 * k:9 + 6 * k] = -leg.rotation
            jacobian[21:24, 6 + 6 * k:9 + 6 * k] = -_skew(arms[k]) @ leg.rotation
            jacobian[21:24, 9 + 6 * k:12 + 6 * k] = -leg.rotation
            jacobian[21:24, 3:6] += _skew(forces[k]) @ _skew(arms[k])
        return jacobian

    def _input_sensitivity(self, state: _State, inputs: np.ndarray) -> np.ndarray:
        """d(residual)/d(inputs) for inputs [q (3); force (3); moment (3); offset (3)]."""
        sensitivity = self._constant_sensitivity.copy()
        sensitivity[21:24, 3:6] = _skew(state.rotation @ inputs[9:])
        sensitivity[21:24, 9:12] = -_skew(inputs[3:6]) @ state.rotation
        return sensitivity

    # result ----------------------------------------------------------------------------------
    def _count_into(self, result: DeltaResult) -> None:
        result.leg_solves = self._counts['leg_solves']
        result.leg_shots = self._counts['leg_shots']
        result.leg_jacobians = self._counts['leg_jacobians']

    def _result(self, outcome: _Outcome, legs: Sequence[SolveResult], inputs: np.ndarray,
                elapsed: float) -> DeltaResult:
        state = outcome.state
        residual = outcome.residual
        if not np.all(np.isfinite(residual)):
            residual = np.full(SIZE, np.nan)
        result = DeltaResult(
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, sliders=inputs[:3].copy(),
            payload_force=inputs[3:6].copy(), payload_moment=inputs[6:9].copy(),
            payload_offset=inputs[9:].copy(), platform_position=state.position.copy(),
            platform_rotation=state.rotation.copy(), home_position=self.home_position.copy(),
            leg_results=legs, leg_tip_wrenches=state.wrenches.copy(),
            equilibrium_residual=residual[18:].copy(),
            compatibility_residual=residual[:18].reshape(3, 6).copy(),
            solve_time_s=elapsed, leg_solves=0)
        self._count_into(result)
        return result


def _difference(first: _State, second: _State, x_scale: np.ndarray) -> np.ndarray:
    """
    ``first`` minus ``second`` in the flat scaled unknowns (platform / x_scale, then legs).

    The rotation's part is the rotation vector of R_first R_second^T (``_State.moved``'s).
    """
    platform = np.concatenate([first.position - second.position,
                               rotation_vector(first.rotation @ second.rotation.T),
                               (first.wrenches - second.wrenches).ravel()]) / x_scale
    return np.concatenate([platform, (first.unknowns - second.unknowns).ravel()])


def _distance(first: _State, second: _State, x_scale: np.ndarray) -> float:
    """Largest difference of two states in the scaled unknowns (platform and legs)."""
    return float(np.abs(_difference(first, second, x_scale)).max())


def solve_delta(sliders: ArrayLike, payload_force: ArrayLike,
                payload_moment: ArrayLike = (0.0, 0.0, 0.0),
                payload_offset: ArrayLike = (0.0, 0.0, 0.0),
                params_path=DEFAULT_PARAMS_PATH) -> DeltaResult:
    """One cold forward-statics solve with the parameters of ``params_path``."""
    return DeltaRobot.from_yaml(params_path).solve(sliders, payload_force, payload_moment,
                                                   payload_offset)
