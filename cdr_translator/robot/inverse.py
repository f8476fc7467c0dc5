"""
Inverse statics of the Continuum Delta Robot: sliders for a platform target under a payload.

Three sliders, three translational degrees of freedom: the unknowns are q (3) and the
equations p(q, payload) = target, p the platform origin of the forward statics
(``DeltaRobot.solve``). The platform's orientation is not controlled: the parasitic
rotation that results is reported (``platform_rotation_deg``), not hidden.

Method: projected quasi-Newton inside the slider box |q_i| <= slider_stroke. Each iterate
is one warm-started forward solve; the slope dp/dq is kept by Broyden updates from the
observed pairs (q, p) of all forward solves, along a path across solves too
(robot/slider_path.py). The step is the bounded linear least-squares min ||B dq + p -
target|| with q + dq in the box, halved until the distance to the target falls. The
exact slope (a forward solve with ``compliance``: its ``input_sensitivity``, the legs'
compliances through the constrained Newton Jacobian) is taken only where the secants do
not serve: a cold start, an iteration that stalls or contracts slowly, and a step that
reaches a stroke limit. There the iteration is the projected Gauss-Newton with the exact
slope at every iterate, which ends at a local nearest reachable point with at least one
slider on its stroke limit when the target is out of reach (a result with a message,
never an exception).

Start: along a path, the sliders extrapolated from the last solves (slider_path); cold,
the straight-leg inverse (robot/straight_legs.py), the legs as rigid links of their stack
height. The forward solve at the answer has its compliance and stability verdict made on
first read of ``InverseResult.forward`` (three leg Jacobians, not in ``solve_time_s``).
"""

from dataclasses import dataclass, field
import math
import time
from typing import Callable, Optional, Protocol, Tuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import lsq_linear

from .params import DeltaParams, Leg
from .result import DeltaResult
from .slider_path import SliderPath
from .straight_legs import straight_leg_sliders
from .. import geometry
from ..params.translator_params import TranslatorParams
from ..solve.solver import check_wrench


class ForwardStatics(Protocol):
    """What the inverse statics needs of a robot: its geometry and its forward statics."""

    geometry: DeltaParams
    legs: Tuple[Leg, Leg, Leg]
    params: TranslatorParams

    def solve(self, sliders: ArrayLike, payload_force: ArrayLike,
              payload_moment: ArrayLike = ..., payload_offset: ArrayLike = ...,
              warm_start: bool = ..., compliance: bool = ...) -> DeltaResult:
        """Solve the forward statics (``DeltaRobot.solve``)."""

    def deferred_linearization(self, result: DeltaResult) -> Callable[[], None]:
        """Return a call adding the linearization to the last solve (``DeltaRobot``'s)."""


#: Default largest distance of the platform origin from the target that counts as reached (m).
POSITION_TOLERANCE = 1e-9

#: Default cap on the iterations (each one or a few warm forward solves).
MAX_ITERATIONS = 40

#: A slider within this of its stroke limit is on it (m).
LIMIT_TOLERANCE = 1e-12

#: The iteration has found the nearest reachable point once a step improves the distance
#: to the target by less than this (m).
STALL_TOLERANCE = 1e-12

#: How the message of a converged but unreachable result starts: what happened, first.
UNREACHABLE = 'nearest reachable point found, target unreachable'

#: A secant iterate that leaves more than this fraction of the distance to the target
#: makes the next iterates take the exact slope. The secant steps along a path contract
#: by 1e-2 or better (the slope's relative error over a millimetre).
SLOW_CONTRACTION = 0.25


@dataclass
class InverseResult:
    """
    Outcome of one inverse-statics solve (SI, rad; positions in the world frame {w}).

    ``converged``: the iteration converged, to the target when ``reachable``, otherwise to
    the nearest reachable point (a local minimum of the distance inside the slider box).
    ``reachable``: the platform origin is within ``tolerance`` of ``target``.
    ``binding``: the stroke limits the sliders sit on, e.g. ``('slider 2 upper',)``.
    ``forward``: the forward solve at ``sliders`` (platform pose, legs, compliance, stability),
    None when no forward solve converged; when it was solved without its compliance, that
    is made on first read (``solution``: the same solve, as it is so far). Failures are
    results with a ``message``, which says what happened first: target reached,
    ``UNREACHABLE`` (the nearest reachable point), or why the target was not reached. The
    work: ``forward_solves`` (each warm but a cold start's first), ``exact_slopes`` (those
    with the compliance for the exact dp/dq), ``leg_solves`` and ``leg_jacobians`` (summed
    over the forward solves, DeltaResult's).
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
    solution: Optional[DeltaResult] = None
    exact_slopes: int = 0
    leg_solves: int = 0
    leg_jacobians: int = 0
    #: the call adding ``solution``'s linearization, until ``forward`` is first read
    linearization: Optional[Callable[[], None]] = field(default=None, repr=False,
                                                        compare=False)

    @property
    def forward(self) -> Optional[DeltaResult]:
        """Return the forward solve at ``sliders``, its linearization made now if not yet."""
        if self.linearization is not None:
            add, self.linearization = self.linearization, None
            add()
        return self.solution

    @property
    def platform_rotation(self) -> np.ndarray:
        """Platform orientation in {w} (3x3; NaN without a forward solve)."""
        if self.solution is None:
            return np.full((3, 3), np.nan)
        return self.solution.platform_rotation

    @property
    def platform_rotation_angle(self) -> float:
        """Parasitic rotation of the platform from its home orientation (rad)."""
        if self.solution is None:
            return math.nan
        return geometry.rotation_angle(self.solution.platform_rotation)

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


def _bounded_step(slope: np.ndarray, error: np.ndarray, sliders: np.ndarray,
                  stroke: float) -> np.ndarray:
    """
    Return dq minimizing ||slope dq + error|| with |sliders + dq| <= stroke.

    The Newton step when it stays inside (scipy's BVLS costs about 0.5 ms, a forward solve's
    worth), else BVLS.
    """
    try:
        step = np.linalg.solve(slope, -error)
    except np.linalg.LinAlgError:
        step = np.full(3, np.inf)
    if np.all(np.abs(sliders + step) <= stroke):
        return np.asarray(step)
    return np.asarray(lsq_linear(slope, -error, bounds=(-stroke - sliders, stroke - sliders),
                                 method='bvls', tol=1e-14).x)


class ForwardSolves:
    """The forward solves of one inverse solve: counted, each observed by the slider path."""

    def __init__(self, robot: ForwardStatics, path: SliderPath, load: np.ndarray,
                 fresh: bool) -> None:
        """Solve on ``robot`` under ``load`` (force, moment, offset); ``fresh``: first cold."""
        self.robot = robot
        self.path = path
        self.load = (load[:3].tolist(), load[3:6].tolist(), load[6:].tolist())
        self.fresh = fresh
        self.solves = self.exact_slopes = self.leg_solves = self.leg_jacobians = 0
        #: the sliders of the robot's latest forward solve
        self.last = np.full(3, np.nan)

    def __call__(self, sliders: np.ndarray, exact: bool) -> DeltaResult:
        """Solve the forward statics at ``sliders``; ``exact``: with the exact dp/dq."""
        force, moment, offset = self.load
        result = self.robot.solve(sliders.tolist(), force, moment, offset,
                                  warm_start=not (self.fresh and self.solves == 0),
                                  compliance=exact)
        self.solves += 1
        self.exact_slopes += int(exact)
        self.leg_solves += result.leg_solves
        self.leg_jacobians += result.leg_jacobians
        self.last = sliders.copy()
        if result.converged:
            if result.input_sensitivity is not None:
                self.path.restart(result.input_sensitivity[:3, :3], sliders,
                                  result.platform_position)
            else:
                self.path.observe(sliders, result.platform_position)
        return result


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
        self._path = SliderPath()

    def reset(self) -> None:
        """Forget the path: the next solve starts from the straight-leg inverse."""
        self._path = SliderPath()

    def solve(self, target: ArrayLike, payload_force: ArrayLike = (0.0, 0.0, 0.0),
              payload_moment: ArrayLike = (0.0, 0.0, 0.0),
              payload_offset: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True) -> InverseResult:
        """Slider positions putting the platform origin at ``target`` (m, {w}) under a payload."""
        goal = check_target(target)
        wrench = check_wrench(np.asarray(payload_force, dtype=float).tolist(),
                              np.asarray(payload_moment, dtype=float).tolist())
        offset = np.asarray(payload_offset, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f'payload offset must be 3 finite coordinates (m), got {offset}')
        load = np.concatenate([wrench, offset])
        robot = self.robot
        stroke = robot.geometry.slider_stroke
        started = time.perf_counter()
        path = self._path if warm_start else SliderPath()
        guess = path.predict(goal, load)
        cold = guess is None  # no slope yet: the first forward solve gives the exact one
        if guess is None:
            path = SliderPath()
            guess = straight_leg_sliders(robot.legs, robot.params.stack_height, goal)
        if not np.all(np.isfinite(guess)):  # (a straight-leg inverse out of reach)
            guess = np.nan_to_num(guess)
        sliders = np.clip(guess, -stroke, stroke)
        forward = ForwardSolves(robot, path, load, fresh=not warm_start)
        result = forward(sliders, cold)
        exact = False  # whether the iterates take the exact slope, not the secants'
        if not (result.converged and (result.input_sensitivity is not None or not cold)):
            return self._failure(goal, sliders, result, forward, started,
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
            slope = path.slope
            if not exact and slope is not None:
                step = _bounded_step(slope, error, sliders, stroke)
                # the nearest reachable point on a stroke limit needs the exact slope
                exact = bool(np.any(np.abs(sliders + step) >= stroke - LIMIT_TOLERANCE))
            if exact or slope is None:
                exact = True
                if result.input_sensitivity is None:
                    result = forward(sliders, True)
                    if not (result.converged and result.input_sensitivity is not None):
                        message = f'no exact slope: {result.message}'
                        break
                    error = result.platform_position - goal
                    distance = float(np.linalg.norm(error))
                slope = result.input_sensitivity[:3, :3]
                step = _bounded_step(slope, error, sliders, stroke)
            scale, accepted = 1.0, None
            predicted = float(np.linalg.norm(slope @ step + error))
            for _ in range(12 if distance - predicted >= STALL_TOLERANCE else 0):
                trial_sliders = np.clip(sliders + scale * step, -stroke, stroke)
                trial = forward(trial_sliders, exact)
                if trial.converged and (trial.input_sensitivity is not None or not exact):
                    trial_distance = float(np.linalg.norm(trial.platform_position - goal))
                    if trial_distance < distance:
                        accepted = (trial_sliders, trial, trial_distance)
                        break
                scale *= 0.5
            stalled = accepted is None or distance - accepted[2] < STALL_TOLERANCE
            if accepted is not None:
                slow = accepted[2] > SLOW_CONTRACTION * distance
                sliders, result, distance = accepted
                error = result.platform_position - goal
                exact = exact or slow  # the secants contract too slowly here
            if stalled and not exact:
                exact = True  # the secants stalled: the exact slope from here on
                continue
            if stalled:
                if _binding(sliders, stroke):
                    converged = True  # a local nearest reachable point on the box boundary
                    message = 'nearest reachable point'
                else:
                    message = 'the distance to the target stopped falling inside the stroke'
                break
        if not np.array_equal(forward.last, sliders):
            # a rejected trial was solved last: put the robot's warm start back here
            result = forward(sliders, False)
        self._path = path
        binding = _binding(sliders, stroke)
        reachable = distance <= self.tolerance
        if reachable:
            path.record(goal, sliders, error, load)
        elif converged:
            limits = ', '.join(f'{name} stroke limit ({"+" if "upper" in name else "-"}'
                               f'{1e3 * stroke:g} mm)' for name in binding)
            message = (f'{UNREACHABLE}: {_mm(goal)} is {1e3 * distance:.3f} mm from the '
                       f'nearest reachable platform position {_mm(result.platform_position)}; '
                       f'binding: {limits}')
        else:
            message = (f'target {_mm(goal)} not reached ({1e3 * distance:.3g} mm away at '
                       f'sliders {_mm(sliders)}): {message}')
        linearization = None
        if result.converged and result.input_sensitivity is None:
            linearization = robot.deferred_linearization(result)
        return InverseResult(
            converged=converged, reachable=reachable, message=message, target=goal,
            sliders=sliders.copy(), platform_position=result.platform_position.copy(),
            position_error=distance, binding=binding, iterations=iterations,
            forward_solves=forward.solves, solve_time_s=time.perf_counter() - started,
            tolerance=self.tolerance, solution=result, exact_slopes=forward.exact_slopes,
            leg_solves=forward.leg_solves, leg_jacobians=forward.leg_jacobians,
            linearization=linearization)

    def _failure(self, goal: np.ndarray, sliders: np.ndarray, result: DeltaResult,
                 forward: ForwardSolves, started: float, message: str) -> InverseResult:
        """Return the result for a forward solve that failed before any iteration."""
        self._path = SliderPath()
        return InverseResult(
            converged=False, reachable=False, message=message, target=goal,
            sliders=sliders.copy(), platform_position=result.platform_position.copy(),
            position_error=float(np.linalg.norm(result.platform_position - goal)),
            binding=_binding(sliders, self.robot.geometry.slider_stroke), iterations=0,
            forward_solves=forward.solves, solve_time_s=time.perf_counter() - started,
            tolerance=self.tolerance, solution=None, exact_slopes=forward.exact_slopes,
            leg_solves=forward.leg_solves, leg_jacobians=forward.leg_jacobians)
