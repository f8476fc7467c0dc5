"""
Inverse statics of the Continuum Delta Robot: sliders for a platform target under a payload.

Three sliders, three translational degrees of freedom: the unknowns are q (3) and the
equations p(q, payload) = target, p the platform origin of the forward statics
(``DeltaRobot.solve``). The platform's orientation is not controlled: the parasitic
rotation that results is reported (``platform_rotation_deg``), not hidden.

Method: projected Gauss-Newton inside the slider box |q_i| <= slider_stroke. Each iterate
is a warm-started forward solve with ``compliance=True``, whose ``input_sensitivity``
gives the exact dp/dq of the assembled closed chain at that solution (legs' compliances
through the constrained Newton Jacobian). The step is the bounded linear least-squares
min ||dp/dq dq + p - target|| with q + dq in the box, halved until the distance to the
target falls. Inside the box this is Newton's method (quadratic convergence, 2-4 forward
solves from a path neighbour); a target outside the reachable set ends at a local
nearest reachable point with at least one slider on its stroke limit (the limit that
binds), reported as a result with a message, never an exception.

Along a path, a solve starts from the previous solution's sliders plus the first-order
prediction (dp/dq)^-1 (target - previous target).
"""

from dataclasses import dataclass
import math
import time
from typing import Optional, Protocol, Tuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import lsq_linear

from .params import DeltaParams
from .result import DeltaResult
from .. import geometry
from ..solver import check_wrench


class ForwardStatics(Protocol):
    """What the inverse statics needs of a robot: its geometry and its forward statics."""

    geometry: DeltaParams

    def solve(self, sliders: ArrayLike, payload_force: ArrayLike,
              payload_moment: ArrayLike = ..., payload_offset: ArrayLike = ...,
              warm_start: bool = ..., compliance: bool = ...) -> DeltaResult:
        """Solve the forward statics (``DeltaRobot.solve``)."""


#: Default largest distance of the platform origin from the target that counts as reached (m).
POSITION_TOLERANCE = 1e-9

#: Default cap on Gauss-Newton iterations (each is one warm forward solve).
MAX_ITERATIONS = 40

#: A slider within this of its stroke limit is on it (m).
LIMIT_TOLERANCE = 1e-12

#: The iteration has found the nearest reachable point once a step improves the distance
#: to the target by less than this (m).
STALL_TOLERANCE = 1e-12

#: How the message of a converged but unreachable result starts: what happened, first.
UNREACHABLE = 'nearest reachable point found, target unreachable'


@dataclass
class InverseResult:
    """
    Outcome of one inverse-statics solve (SI, rad; positions in the world frame {w}).

    ``converged``: the iteration converged, to the target when ``reachable``, otherwise to
    the nearest reachable point (a local minimum of the distance inside the slider box).
    ``reachable``: the platform origin is within ``tolerance`` of ``target``.
    ``binding``: the stroke limits the sliders sit on, e.g. ``('slider 2 upper',)``.
    ``forward``: the forward solve at ``sliders`` (platform pose, legs, compliance, stability),
    None when no forward solve converged. Failures are results with a ``message``, which
    says what happened first: target reached, ``UNREACHABLE`` (the nearest reachable point),
    or why the target was not reached.
    """

    converged: bool
    reachable: bool
    message: str
    target: np.ndarray
    sliders: np.ndarray
    platform_position: np.ndarray
    position_error: float
    binding: Tuple[str, ...]
    iterations: int
    forward_solves: int
    solve_time_s: float
    tolerance: float
    forward: Optional[DeltaResult] = None

    @property
    def platform_rotation(self) -> np.ndarray:
        """Platform orientation in {w} (3x3; NaN without a forward solve)."""
        if self.forward is None:
            return np.full((3, 3), np.nan)
        return self.forward.platform_rotation

    @property
    def platform_rotation_angle(self) -> float:
        """Parasitic rotation of the platform from its home orientation (rad)."""
        if self.forward is None:
            return math.nan
        return geometry.rotation_angle(self.forward.platform_rotation)

    def to_dict(self) -> dict:
        """JSON-ready summary; degrees only here, at the edge."""
        forward = self.forward
        data = {
            'converged': bool(self.converged),
            'reachable': bool(self.reachable),
            'message': self.message,
            'target_m': self.target.tolist(),
            'sliders_m': self.sliders.tolist(),
            'platform_position_m': self.platform_position.tolist(),
            'position_error_m': float(self.position_error),
            'platform_rotation_deg': math.degrees(self.platform_rotation_angle),
            'binding_limits': list(self.binding),
            'iterations': int(self.iterations),
            'forward_solves': int(self.forward_solves),
            'solve_time_s': float(self.solve_time_s),
            'tolerance_m': float(self.tolerance),
        }
        if forward is not None:
            details = forward.to_dict()
            for key in ('platform_rotation_vector_deg', 'platform_quaternion_xyzw',
                        'leg_bending_deg', 'leg_tip_wrench', 'stable',
                        'platform_compliance', 'platform_compliance_eigenvalues',
                        'stiffness_margin_n_per_m', 'payload_force_n', 'payload_moment_nm',
                        'payload_offset_m', 'leg_stability'):
                data[key] = details[key]
        return data


def check_target(target: ArrayLike) -> np.ndarray:
    """Return the target position (3,), m; ValueError naming a bad value."""
    array = np.asarray(target, dtype=float)
    if array.shape != (3,):
        raise ValueError(f'target must have 3 coordinates (m), got shape {array.shape}')
    for axis, value in zip('xyz', array):
        if not math.isfinite(value):
            raise ValueError(f'target {axis} coordinate is {value}: it must be finite')
    return array


def _binding(sliders: np.ndarray, stroke: float) -> Tuple[str, ...]:
    """Names of the stroke limits the sliders sit on."""
    names = []
    for leg, value in enumerate(sliders, start=1):
        if value >= stroke - LIMIT_TOLERANCE:
            names.append(f'slider {leg} upper')
        elif value <= -stroke + LIMIT_TOLERANCE:
            names.append(f'slider {leg} lower')
    return tuple(names)


def _mm(vector: np.ndarray) -> str:
    return '[' + ', '.join(f'{1e3 * v:.3f}' for v in vector) + '] mm'


class InverseSolver:
    """
    Inverse statics on a DeltaRobot; successive solves warm-start along a path.

    Use through ``DeltaRobot.inverse``, which keeps one per robot.
    """

    def __init__(self, robot: ForwardStatics, tolerance: float = POSITION_TOLERANCE,
                 max_iterations: int = MAX_ITERATIONS) -> None:
        """Solve on ``robot``; ``tolerance`` (m) is the reached distance, > 0."""
        if not (math.isfinite(tolerance) and tolerance > 0.0):
            raise ValueError(f'tolerance must be a positive distance (m), got {tolerance}')
        if max_iterations < 1:
            raise ValueError(f'max_iterations must be at least 1, got {max_iterations}')
        self.robot = robot
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self._previous: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None

    def reset(self) -> None:
        """Forget the path: the next solve starts from the sliders at home."""
        self._previous = None

    def solve(self, target: ArrayLike, payload_force: ArrayLike = (0.0, 0.0, 0.0),
              payload_moment: ArrayLike = (0.0, 0.0, 0.0),
              payload_offset: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True) -> InverseResult:
        """Slider positions putting the platform origin at ``target`` (m, {w}) under a payload."""
        goal = check_target(target)
        wrench = check_wrench(np.asarray(payload_force, dtype=float).tolist(),
                              np.asarray(payload_moment, dtype=float).tolist())
        force, moment = wrench[:3].tolist(), wrench[3:].tolist()
        offset = np.asarray(payload_offset, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f'payload offset must be 3 finite coordinates (m), got {offset}')
        robot = self.robot
        stroke = robot.geometry.slider_stroke
        started = time.perf_counter()
        if not warm_start:
            self._previous = None
        sliders = np.zeros(3)
        if self._previous is not None:
            previous_target, previous_sliders, slope = self._previous
            try:
                step = np.linalg.solve(slope, goal - previous_target)
            except np.linalg.LinAlgError:
                step = np.zeros(3)
            sliders = np.clip(previous_sliders + step, -stroke, stroke)

        last = [np.full(3, np.nan)]  # the sliders of the robot's latest forward solve

        def forward(at: np.ndarray) -> DeltaResult:
            last[0] = at
            return robot.solve(at.tolist(), force, moment, offset.tolist(),
                               warm_start=warm_start or solves > 0, compliance=True)

        solves = 0
        result = forward(sliders)
        solves += 1
        if not (result.converged and result.input_sensitivity is not None):
            return self._failure(goal, sliders, result, solves, started,
                                 f'forward statics failed at sliders {_mm(sliders)}: '
                                 f'{result.message}')
        error = result.platform_position - goal
        distance = float(np.linalg.norm(error))
        iterations = 0
        message = ''
        converged = False
        while True:
            if distance <= self.tolerance:
                converged, message = True, 'target reached: the platform is at the target'
                break
            if iterations >= self.max_iterations:
                message = f'no convergence in {self.max_iterations} iterations'
                break
            iterations += 1
            slope = result.input_sensitivity[:3, :3]
            step = lsq_linear(slope, -error, bounds=(-stroke - sliders, stroke - sliders),
                              method='bvls', tol=1e-14).x
            scale, accepted = 1.0, None
            predicted = float(np.linalg.norm(slope @ step + error))
            for _ in range(12 if distance - predicted >= STALL_TOLERANCE else 0):
                trial_sliders = np.clip(sliders + scale * step, -stroke, stroke)
                trial = forward(trial_sliders)
                solves += 1
                if trial.converged and trial.input_sensitivity is not None:
                    trial_distance = float(np.linalg.norm(trial.platform_position - goal))
                    if trial_distance < distance:
                        accepted = (trial_sliders, trial, trial_distance)
                        break
                scale *= 0.5
            if accepted is None or distance - accepted[2] < STALL_TOLERANCE:
                if accepted is not None:
                    sliders, result, distance = accepted
                    error = result.platform_position - goal
                if _binding(sliders, stroke):
                    converged = True  # a local nearest reachable point on the box boundary
                    message = 'nearest reachable point'
                else:
                    message = 'the distance to the target stopped falling inside the stroke'
                break
            sliders, result, distance = accepted
            error = result.platform_position - goal
        if not np.array_equal(last[0], sliders):
            # a rejected trial was solved last: put the robot's warm start back here
            result = forward(sliders)
            solves += 1
        binding = _binding(sliders, stroke)
        reachable = distance <= self.tolerance
        if reachable and result.input_sensitivity is not None:
            self._previous = (goal, sliders.copy(), result.input_sensitivity[:3, :3].copy())
        elif converged:
            limits = ', '.join(f'{name} stroke limit ({"+" if "upper" in name else "-"}'
                               f'{1e3 * stroke:g} mm)' for name in binding)
            message = (f'{UNREACHABLE}: {_mm(goal)} is {1e3 * distance:.3f} mm from the '
                       f'nearest reachable platform position {_mm(result.platform_position)}; '
                       f'binding: {limits}')
        else:
            message = (f'target {_mm(goal)} not reached ({1e3 * distance:.3g} mm away at '
                       f'sliders {_mm(sliders)}): {message}')
        return InverseResult(
            converged=converged, reachable=reachable, message=message, target=goal,
            sliders=sliders.copy(), platform_position=result.platform_position.copy(),
            position_error=distance, binding=binding, iterations=iterations,
            forward_solves=solves, solve_time_s=time.perf_counter() - started,
            tolerance=self.tolerance, forward=result)

    def _failure(self, goal: np.ndarray, sliders: np.ndarray, result: DeltaResult,
                 solves: int, started: float, message: str) -> InverseResult:
        """Return the result for a forward solve that failed before any iteration."""
        self._previous = None
        return InverseResult(
            converged=False, reachable=False, message=message, target=goal,
            sliders=sliders.copy(), platform_position=result.platform_position.copy(),
            position_error=float(np.linalg.norm(result.platform_position - goal)),
            binding=_binding(sliders, self.robot.geometry.slider_stroke), iterations=0,
            forward_solves=solves, solve_time_s=time.perf_counter() - started,
            tolerance=self.tolerance, forward=None)
