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
{pe_i}: ``TranslatorSolver.solve(..., compliance=True)``, implicit differentiation). Steps
are damped by Deuflhard's natural monotonicity test and reuse a factorization while it
contracts. Every leg solve is warm-started from that leg's previous solution, and the robot
walks from its previous solution (or home: straight legs, no load) to the requested input
by predictor-corrector continuation, as the leg solver does for one translator.
"""

from dataclasses import dataclass, fields
import math
from pathlib import Path
import time
from typing import Any, List, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import lu_factor, lu_solve
from scipy.spatial.transform import Rotation

from .inverse import InverseResult, InverseSolver
from .params import cdr_values, check_sliders, DeltaParams, Leg
from .result import DeltaResult, rotation_vector
from ..params import Accuracy, DEFAULT_PARAMS_PATH, TranslatorParams
from ..result import SolveResult
from ..solver import check_wrench, TranslatorSolver

#: Size of the unknown and residual vectors: platform pose (6) + three leg wrenches (18).
SIZE = 24

#: Smallest fraction of the remaining input change a continuation step may take.
MIN_CONTINUATION_STEP = 1e-3


def _skew(vector: np.ndarray) -> np.ndarray:
    """Return the cross-product matrix [a]x of a 3-vector a: [a]x b = a x b."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _rotation_matrix(vector: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad)."""
    return Rotation.from_rotvec(vector).as_matrix()


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
    """Platform pose and leg wrenches: the unknowns, plus the legs solved under them."""

    position: np.ndarray
    rotation: np.ndarray
    wrenches: np.ndarray
    legs: Optional[List[SolveResult]] = None

    def moved(self, step: np.ndarray) -> '_State':
        """Apply a step [dp; dphi; dw_1; dw_2; dw_3] (legs not yet solved)."""
        return _State(self.position + step[:3], _rotation_matrix(step[3:6]) @ self.rotation,
                      self.wrenches + step[6:].reshape(3, 6))


def _solved(state: _State) -> List[SolveResult]:
    """Return the legs solved under ``state`` (a residual is only taken after solving them)."""
    if state.legs is None:
        raise RuntimeError('the legs have not been solved under this state')
    return state.legs


@dataclass
class _Outcome:
    """Where a Newton correction ended."""

    state: _State
    residual: np.ndarray
    iterations: int
    converged: bool
    message: str
    lu: Optional[tuple] = None


class _Deadline(Exception):
    """The time limit passed during a leg solve."""


class _LegFailure(Exception):
    """A leg solve needed for the Jacobian failed."""


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
        (N, N m) and every leg's end disk within ``position_tolerance`` (m) and
        ``rotation_tolerance`` (rad) of its platform attachment. ``max_iterations`` caps
        the Newton iterations of one continuation step (a step that needs more is
        halved), ``time_limit_s`` a whole solve.
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
        self.leg_solvers = tuple(TranslatorSolver(self.params, time_limit_s=time_limit_s,
                                                  accuracy=Accuracy(0.0, 0.0),
                                                  follow_stable_branch=False)
                                 for _ in range(3))
        # scales for a balanced Newton system: the stack height, and the force that bends
        # the five backbones of a leg noticeably over it
        length = height
        force = 5.0 * self.params.bending_stiffness / height ** 2
        self._x_scale = np.concatenate(
            [np.full(3, length), np.ones(3), np.tile(np.repeat([force, force * length], 3), 3)])
        self._r_scale = np.concatenate(
            [np.tile(np.repeat([length, 1.0], 3), 3), np.repeat([force, force * length], 3)])
        self._leg_solves = 0
        self._deadline = math.inf
        self._previous: Optional[Tuple[_State, np.ndarray]] = None  # (state, inputs)
        self._lu: Optional[tuple] = None
        self._inverse = InverseSolver(self)

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
        self._lu = None
        self._inverse.reset()
        for solver in self.leg_solvers:
            solver.reset()

    # public ----------------------------------------------------------------------------------
    def solve(self, sliders: ArrayLike, payload_force: ArrayLike,
              payload_moment: ArrayLike = (0.0, 0.0, 0.0),
              payload_offset: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True, compliance: bool = False) -> DeltaResult:
        """
        Solve the platform pose for slider positions (m) and a payload on the platform.

        ``payload_force`` (N) and ``payload_moment`` (N m) are in {w}; the force acts at
        ``payload_offset`` (m), a point fixed in the platform frame {p} (default: the
        platform origin). ``compliance`` adds the platform compliance, the input
        sensitivity and the stability verdict (see DeltaResult; three more leg solves).
        Bad input raises ValueError; non-convergence is a result.
        """
        offset = np.asarray(payload_offset, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f'payload offset must be 3 finite coordinates (m), got {offset}')
        inputs = np.concatenate([check_sliders(sliders, self.geometry.slider_stroke),
                                 check_wrench(payload_force, payload_moment), offset])
        started = time.perf_counter()
        self._deadline = started + self.time_limit_s
        self._leg_solves = 0
        if not (warm_start and self._previous is not None):
            self.reset()
            self._previous = (self._home_state(), np.zeros(12))
        with np.errstate(over='ignore', invalid='ignore'):
            outcome = self._continuation(inputs)
        if outcome.converged:
            self._previous = (outcome.state, inputs)
        result = self._result(outcome, inputs, time.perf_counter() - started)
        if compliance and outcome.converged:
            with np.errstate(over='ignore', invalid='ignore'):
                self._linearize(result, outcome.state, inputs)
            result.solve_time_s = time.perf_counter() - started
            result.leg_solves = self._leg_solves
        return result

    def _linearize(self, result: DeltaResult, state: _State, inputs: np.ndarray) -> None:
        """Add the compliance, input sensitivity and stability verdict to ``result``."""
        try:
            jacobian = self._jacobian(state, inputs)
            lu = lu_factor(jacobian / self._r_scale[:, None] * self._x_scale[None, :],
                           check_finite=False)
            right = np.zeros((SIZE, 18))
            right[:, :12] = self._input_sensitivity(state, inputs)
            right[18:, 12:] = np.eye(6)
            solved = -self._x_scale[:6, None] * lu_solve(
                lu, right / self._r_scale[:, None], check_finite=False)[:6]
        except (_Deadline, _LegFailure, np.linalg.LinAlgError, ValueError) as error:
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
        state = _State(self.home_position.copy(), np.eye(3), np.zeros((3, 6)))
        state.legs = [solver.solve(np.zeros(3)) for solver in self.leg_solvers]
        self._leg_solves += 3
        return state

    def _continuation(self, inputs: np.ndarray) -> _Outcome:
        """
        Walk from the previous solution to ``inputs`` (sliders, payload).

        Each step predicts the solution to first order with the stored LU of the Jacobian,
        dx = -J^-1 (dr/du) du, and Newton corrects it; a failed step is halved, a good one
        doubled.
        """
        if self._previous is None:
            raise RuntimeError('continuation needs a previous solution')
        state, start = self._previous
        lu = self._lu
        done, step, iterations = 0.0, 1.0, 0
        current = start
        outcome: Optional[_Outcome] = None
        while done < 1.0:
            target = min(1.0, done + step)
            goal = start + target * (inputs - start)
            guess = state
            if lu is not None:
                guess = state.moved(-self._x_scale * lu_solve(
                    lu, self._input_sensitivity(state, current) @ (goal - current)
                    / self._r_scale, check_finite=False))
            outcome = self._newton(guess, goal, lu)
            iterations += outcome.iterations
            if outcome.converged:
                done, state, current, lu = target, outcome.state, goal, outcome.lu
                step *= 2.0
                continue
            step = 0.5 * (target - done)
            if step < MIN_CONTINUATION_STEP or time.perf_counter() > self._deadline:
                if outcome.state.legs is None \
                        or not all(leg.converged for leg in outcome.state.legs):
                    outcome.state = state  # the last solution every leg converged at
                outcome.residual = self._residual(outcome.state, inputs)
                outcome.iterations = iterations
                outcome.message = (f'continuation stalled at {done:.1%} of the way to the '
                                   f'sliders and payload: {outcome.message}')
                return outcome
        self._lu = lu
        if outcome is None:  # cannot happen: the loop runs at least once
            raise RuntimeError('continuation made no step')
        outcome.iterations = iterations
        return outcome

    # Newton ----------------------------------------------------------------------------------
    def _newton(self, state: _State, inputs: np.ndarray, lu: Optional[tuple]) -> _Outcome:
        """
        Damped Newton with the natural monotonicity test; given ``lu``, chord steps first.

        A step is judged in the unknowns, not in the residual: the trial point must shrink
        the simplified Newton correction J^-1 r (same factorization) relative to the step
        (Deuflhard's restricted monotonicity test). That needs no weighting of metres
        against newtons, and it accepts the full step of the force-stiff leg axes that a
        residual-norm test rejects far from the solution.
        """
        try:
            legs = self._solve_legs(state)
        except _Deadline as error:
            return _Outcome(state, np.full(SIZE, np.inf), 0, False, str(error), lu)
        if not all(leg.converged for leg in legs):
            return _Outcome(state, np.full(SIZE, np.inf), 0, False,
                            'a leg did not converge at the predicted wrenches', lu)
        residual = self._residual(state, inputs)
        fresh = False
        for iteration in range(1, self.max_iterations + 1):
            if self._converged(residual):
                return _Outcome(state, residual, iteration - 1, True, 'converged', lu)
            if time.perf_counter() > self._deadline:
                return _Outcome(state, residual, iteration - 1, False,
                                f'time limit of {self.time_limit_s} s reached', lu)
            try:
                if lu is None:
                    jacobian = self._jacobian(state, inputs)
                    lu = lu_factor(jacobian / self._r_scale[:, None] * self._x_scale[None, :],
                                   check_finite=False)
                    fresh = True
                step = -lu_solve(lu, residual / self._r_scale, check_finite=False)
                trial = self._line_search(state, step, inputs, lu)
            except (_Deadline, _LegFailure) as error:
                return _Outcome(state, residual, iteration, False, str(error), lu)
            if trial is None:
                if fresh:
                    return _Outcome(state, residual, iteration, False,
                                    'damping found no contracting Newton step', lu)
                lu = None  # a stale Jacobian pointed the wrong way; rebuild it
                continue
            state, residual, contraction = trial
            if not fresh and contraction > 0.25:
                lu = None  # chord steps converge too slowly; rebuild the Jacobian
            fresh = False
        converged = self._converged(residual)
        return _Outcome(state, residual, self.max_iterations, converged,
                        'converged' if converged
                        else f'no convergence in {self.max_iterations} iterations', lu)

    def _line_search(self, state: _State, step: np.ndarray, inputs: np.ndarray,
                     lu: tuple) -> Optional[Tuple[_State, np.ndarray, float]]:
        """
        Halve the scaled Newton ``step`` until a trial passes the monotonicity test.

        Return (state, residual, contraction ||J^-1 r_trial|| / ||step||), or None.
        """
        norm = float(np.linalg.norm(step))
        scale = 1.0
        for _ in range(10):
            trial = state.moved(scale * self._x_scale * step)
            if all(leg.converged for leg in self._solve_legs(trial)):
                residual = self._residual(trial, inputs)
                simplified = lu_solve(lu, residual / self._r_scale, check_finite=False)
                contraction = float(np.linalg.norm(simplified)) / norm
                if contraction < 1.0 - 0.25 * scale:
                    return trial, residual, contraction
            scale *= 0.5
        return None

    def _converged(self, residual: np.ndarray) -> bool:
        compatibility = residual[:18].reshape(3, 2, 3)
        return bool(np.abs(residual[18:]).max() <= self.equilibrium_tolerance
                    and np.abs(compatibility[:, 0]).max() <= self.position_tolerance
                    and np.abs(compatibility[:, 1]).max() <= self.rotation_tolerance)

    # legs ------------------------------------------------------------------------------------
    def _solve_legs(self, state: _State) -> List[SolveResult]:
        """Solve each leg under its wrench (warm-started); store the results in ``state`` too."""
        legs = [self._solve_leg(k, state.wrenches[k]) for k in range(3)]
        state.legs = legs
        return legs

    def _solve_leg(self, k: int, wrench: np.ndarray, compliance: bool = False) -> SolveResult:
        remaining = self._deadline - time.perf_counter()
        if remaining <= 0.0:
            raise _Deadline(f'time limit of {self.time_limit_s} s reached')
        solver = self.leg_solvers[k]
        solver.time_limit_s = remaining
        self._leg_solves += 1
        return solver.solve(wrench[:3], wrench[3:], compliance=compliance)

    def _compliance(self, k: int, wrench: np.ndarray) -> np.ndarray:
        """Compliance of leg k at ``wrench``: d[v; w]/d[f; m] at the end disk in {pe_k}."""
        result = self._solve_leg(k, wrench, compliance=True)
        if result.compliance is None:
            raise _LegFailure(f'no compliance of leg {k + 1}: {result.message}')
        return result.compliance.matrix

    # residual and derivatives ----------------------------------------------------------------
    def _targets(self, state: _State, sliders: np.ndarray) -> List[Tuple[np.ndarray,
                                                                         np.ndarray]]:
        """Pose (rotation, position) of each platform attachment in its leg base frame."""
        targets = []
        for leg, slider in zip(self.legs, sliders):
            position = leg.rotation.T @ (state.position + state.rotation @ leg.attachment
                                         - leg.base(slider))
            rotation = leg.rotation.T @ state.rotation @ leg.rotation
            targets.append((rotation, position))
        return targets

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
        sliders, force, moment, offset = inputs[:3], inputs[3:6], inputs[6:9], inputs[9:]
        residual = np.empty(SIZE)
        for k, (rotation, position) in enumerate(self._targets(state, sliders)):
            frame = _solved(state)[k].frames['de']
            residual[6 * k:6 * k + 3] = frame[:3, 3] - position
            residual[6 * k + 3:6 * k + 6] = rotation_vector(frame[:3, :3] @ rotation.T)
        forces, arms = self._reactions(state)
        residual[18:21] = force + forces.sum(axis=0)
        residual[21:24] = (moment + np.cross(state.rotation @ offset, force)
                           + np.cross(arms, forces).sum(axis=0))
        for k, leg in enumerate(self.legs):
            residual[21:24] -= leg.rotation @ state.wrenches[k, 3:]
        return residual

    def _jacobian(self, state: _State, inputs: np.ndarray) -> np.ndarray:
        """d(residual)/d(unknowns), the leg blocks from each leg's compliance."""
        force, offset = inputs[3:6], inputs[9:]
        jacobian = np.zeros((SIZE, SIZE))
        forces, arms = self._reactions(state)
        residual = self._residual(state, inputs)
        jacobian[21:24, 3:6] = _skew(force) @ _skew(state.rotation @ offset)
        for k, leg in enumerate(self.legs):
            columns = slice(6 + 6 * k, 12 + 6 * k)
            compliance = self._compliance(k, state.wrenches[k])
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
        sensitivity = np.zeros((SIZE, 12))
        for k, leg in enumerate(self.legs):
            sensitivity[6 * k:6 * k + 3, k] = leg.rotation.T @ leg.slider_axis
        sensitivity[18:21, 3:6] = np.eye(3)
        sensitivity[21:24, 3:6] = _skew(state.rotation @ inputs[9:])
        sensitivity[21:24, 6:9] = np.eye(3)
        sensitivity[21:24, 9:12] = -_skew(inputs[3:6]) @ state.rotation
        return sensitivity

    # result ----------------------------------------------------------------------------------
    def _result(self, outcome: _Outcome, inputs: np.ndarray, elapsed: float) -> DeltaResult:
        state = outcome.state
        residual = outcome.residual
        if state.legs is None or not np.all(np.isfinite(residual)):
            residual = np.full(SIZE, np.nan)
        return DeltaResult(
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, sliders=inputs[:3].copy(),
            payload_force=inputs[3:6].copy(), payload_moment=inputs[6:9].copy(),
            payload_offset=inputs[9:].copy(), platform_position=state.position.copy(),
            platform_rotation=state.rotation.copy(), home_position=self.home_position.copy(),
            leg_results=tuple(state.legs) if state.legs is not None else (),
            leg_tip_wrenches=state.wrenches.copy(),
            equilibrium_residual=residual[18:].copy(),
            compatibility_residual=residual[:18].reshape(3, 6).copy(),
            solve_time_s=elapsed, leg_solves=self._leg_solves)


def solve_delta(sliders: ArrayLike, payload_force: ArrayLike,
                payload_moment: ArrayLike = (0.0, 0.0, 0.0),
                payload_offset: ArrayLike = (0.0, 0.0, 0.0),
                params_path=DEFAULT_PARAMS_PATH) -> DeltaResult:
    """One cold forward-statics solve with the parameters of ``params_path``."""
    return DeltaRobot.from_yaml(params_path).solve(sliders, payload_force, payload_moment,
                                                   payload_offset)
