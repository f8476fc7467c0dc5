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
  eliminating each leg with its LU (see ``CoupledNewton.correction``), and chord steps reuse that
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

This module is the front (``DeltaRobot``): it checks the input, runs the continuation
(robot/continuation.py) with the coupled Newton (robot/coupled_newton.py) over the chain's
residual (robot/chain.py) and legs (robot/legs.py), and assembles the result, with the
linearization at the solution on request (robot/linearization.py).
"""

from dataclasses import fields
import math
from pathlib import Path
import time
from typing import Any, Callable, cast, Dict, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from .chain import Chain, ChainState, SIZE
from .continuation import ChainContinuation
from .coupled_newton import CoupledNewton, Limits, Outcome
from .held_leg import held_critical_load, held_reference, HeldReference
from .inverse import InverseResult, InverseSolver
from .legs import ChainLegs
from .levels import check_fidelity
from .linearization import Factorization, factorize, linearize
from .params import cdr_values, check_sliders, DeltaParams, Leg
from .payload_estimate import estimate_payload, PayloadEstimate
from .reduced_batch import solve_rows
from .reduced_legs import ReducedLegs
from .result import DeltaResult
from .._blas import one_blas_thread
from ..checks import check_number
from ..params.translator_params import DEFAULT_PARAMS_PATH, TranslatorParams
from ..solve.result import SolveResult
from ..solve.solver import check_wrench, TranslatorSolver


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
                 time_limit_s: float = 30.0, fidelity: str = 'full',
                 max_position_error: float = 0.0, max_angle_error: float = 0.0) -> None:
        """
        Set up three leg solvers for ``params`` and the CDR ``geometry`` (default: YAML).

        Converged means every equilibrium component is within ``equilibrium_tolerance``
        (N, N m), every leg's end disk within ``position_tolerance`` (m) and
        ``rotation_tolerance`` (rad) of its platform attachment, and every leg's own
        shooting residual within its solver's tolerance. ``max_iterations`` caps the
        Newton iterations of one continuation step (a step that needs more is halved),
        ``time_limit_s`` a whole solve. The linearization at home (three exact leg
        Jacobians, a few ms) is made here, once: cold solves start from it.

        ``fidelity`` is the legs' level (robot/levels.py): 'full', 'rod', 'cc', or 'auto':
        the cheapest reduced level whose validated error at every leg's tip wrench is
        within ``max_position_error`` (m) and ``max_angle_error`` (deg), else full legs
        (a zero budget, the default: full legs only).
        """
        if max_iterations < 1:
            raise ValueError(f'max_iterations must be at least 1, got {max_iterations}')
        check_fidelity(fidelity, max_position_error, max_angle_error)
        self.fidelity = fidelity
        self.max_position_error = float(max_position_error)
        self.max_angle_error = float(max_angle_error)
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
        self._chain = Chain(self.legs, self.params)
        self._chain_legs = ChainLegs(self.params, time_limit_s)
        self._newton = CoupledNewton(self._chain, self._chain_legs, self._limits())
        self._continuation = ChainContinuation(self._newton)
        self._inverse = InverseSolver(self)
        home = self._chain_legs.home_state(self.home_position)
        self._home = (home, factorize(self._chain, self._chain_legs, home, np.zeros(12)))
        self._held: Optional[HeldReference] = None  # made by the first compliance solve
        self._reduced = ReducedLegs(self._chain, self.params, fidelity, self.max_position_error,
                                    self.max_angle_error, max_iterations, self.home_position)

    @property
    def leg_solvers(self) -> Tuple[TranslatorSolver, ...]:
        """Return the three legs' solvers (kept by robot/legs.py's ChainLegs)."""
        return self._chain_legs.solvers

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
        self._continuation.reset()
        self._inverse.reset()
        self._chain_legs.reset()
        self._reduced.reset()

    # public ----------------------------------------------------------------------------------
    def solve(self, sliders: ArrayLike, payload_force: ArrayLike,
              payload_moment: ArrayLike = (0.0, 0.0, 0.0),
              payload_offset: ArrayLike = (0.0, 0.0, 0.0),
              warm_start: bool = True, compliance: bool = False,
              time_limit_s: Optional[float] = None) -> DeltaResult:
        """
        Solve the platform pose for slider positions (m) and a payload on the platform.

        ``payload_force`` (N) and ``payload_moment`` (N m) are in {w}; the force acts at
        ``payload_offset`` (m), a point fixed in the platform frame {p} (default: the
        platform origin). ``compliance`` adds the platform compliance, the input
        sensitivity and the stability verdict (see DeltaResult). They need the legs'
        exact linearization at the solution: reused when the last factorization was made
        there (within linearization.REUSE_DISTANCE), else three exact leg Jacobians (one
        tangent-linear shot each; the dominant cost of a warm solve with ``compliance``),
        which the next solve then iterates on; the first one also finds the legs' held
        buckling load (held.held_critical_load, not in ``solve_time_s``). ``time_limit_s``
        caps this solve (default: the attribute ``time_limit_s``). Bad input raises
        ValueError; non-convergence is a result.
        """
        inputs = self._inputs(sliders, payload_force, payload_moment, payload_offset)
        limit = (self.time_limit_s if time_limit_s is None
                 else check_number('time_limit_s', time_limit_s, low=0.0))
        # made once, apart from the solve's time (the legs' held buckling load)
        held = self._held_reference() if compliance else None
        started = time.perf_counter()
        if self._reduced:
            tolerances = np.array((self.equilibrium_tolerance, self.position_tolerance,
                                   self.rotation_tolerance))
            reduced = self._reduced.solve(inputs, warm_start, tolerances, held, started,
                                          limit)
            if reduced is not None:
                return reduced
        return self._solve_full(inputs, warm_start, held, started, limit)

    @one_blas_thread
    def _solve_full(self, inputs: np.ndarray, warm_start: bool, held: Optional[HeldReference],
                    started: float, time_limit_s: float) -> DeltaResult:
        """Solve with full legs (``solve``'s inputs checked, ``held`` made) within a limit."""
        self._chain_legs.begin(started, time_limit_s)
        self._newton.limits = self._limits()
        path = self._continuation
        if not (warm_start and path.previous is not None):
            self.reset()
            path.previous = (self._home[0], np.zeros(12))
            path.factorization = self._home[1]
        previous, factorization = path.previous, path.factorization
        # from home the legs' shooting is far from linear (a coupled Newton needed 5-10
        # times the iterations): there each iterate's legs are solved in full
        coupled = previous[0] is not self._home[0]
        with np.errstate(over='ignore', invalid='ignore'):
            outcome = path.walk(inputs, coupled)
            if coupled and not outcome.converged and not self._chain_legs.out_of_time():
                # the coupled iteration stalled: solve the legs in full at every iterate
                path.previous, path.factorization = previous, factorization
                nested = path.walk(inputs, coupled=False)
                nested.iterations += outcome.iterations
                if nested.converged:
                    nested.message += ' (legs solved in full after the coupled Newton ' \
                        f'stalled: {outcome.message})'
                if nested.converged or (np.linalg.norm(nested.residual)
                                        < np.linalg.norm(outcome.residual)):
                    outcome = nested
            legs = self._chain_legs.results(outcome.state, outcome.factorization)
        if outcome.converged:
            path.previous = (outcome.state, inputs)
        result = self._result(outcome, legs, inputs, time.perf_counter() - started)
        if held is not None and outcome.converged:
            made = self._linearize(result, outcome.state, outcome.factorization, inputs, held)
            if made is not None:  # exact at the solution: the next solve iterates on it
                path.factorization = made
            result.solve_time_s = time.perf_counter() - started
            self._chain_legs.count_into(result)
        return result

    def solve_columns(self, sliders: np.ndarray, payload_forces: np.ndarray,
                      out: Dict[str, np.ndarray],
                      store: Callable[[Dict[str, np.ndarray], int, DeltaResult], None]) -> bool:
        """
        Solve samples in order, each warm from the last, with compliance, into columns.

        ``sliders`` and ``payload_forces`` (N, 3; at the platform origin); ``out``: the
        atlas's result columns (robot/samples.py), ``store`` its copy of one DeltaResult
        into a row. Only for 'cc' legs (one compiled loop, robot/reduced_batch.py); row i
        equals ``solve(sliders[i], payload_forces[i], compliance=True)`` made after row
        i - 1. False, ``out`` untouched, for other levels.
        """
        chain = self._reduced.chains.get(self.fidelity)
        if chain is None or not chain.couples:
            return False
        rows = np.zeros((len(sliders), SIZE // 2))
        rows[:, :3] = sliders
        rows[:, 3:6] = payload_forces
        tolerances = np.array([self.equilibrium_tolerance, self.position_tolerance,
                               self.rotation_tolerance])
        solve_rows(chain, rows, tolerances, self._held_reference().critical_load_n,
                   self._reduced.bound_tables[self.fidelity],
                   lambda row: self.solve(sliders[row], payload_forces[row], compliance=True),
                   out, store)
        return True

    def deferred_linearization(self, result: DeltaResult) -> Callable[[], None]:
        """
        Return a call adding ``compliance=True``'s parts to ``result``, this robot's last solve.

        ``result`` must be the latest solve, converged, made without ``compliance``; the
        call (made at most once, any time later) linearizes at that solution as ``solve``
        would have (three leg Jacobians, unless the solve's last factorization was made
        there), adds their count to ``result.leg_jacobians`` and their time to its
        ``solve_time_s``. The robot's own warm start is left as it is by then.
        """
        if result.leg_fidelity[0] != 'full':
            return self._reduced.deferred_linearization(result, self._held_reference)
        path = self._continuation
        if not result.converged or path.previous is None:
            raise RuntimeError('only a converged solve can be linearized later')
        state, inputs = path.previous
        factorization = path.factorization

        def add() -> None:
            held = self._held_reference()  # made once, apart from the solve's time
            started = time.perf_counter()
            made = self._linearize(result, state, factorization, inputs, held)
            result.leg_jacobians += 0 if made is None else len(made.legs)
            result.solve_time_s += time.perf_counter() - started
        return add

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

    @one_blas_thread
    def estimate_payload(self, platform_position: ArrayLike, sliders: ArrayLike,
                         platform_quaternion_xyzw: Optional[ArrayLike] = None, *,
                         covariance: Optional[ArrayLike] = None, max_force: float = math.inf,
                         max_moment: float = math.inf) -> PayloadEstimate:
        """
        Estimate the payload (N, N m, in {w}) from a measured platform pose at ``sliders``.

        Position (m, {w}) only: the force under no moment; with the orientation all six
        components. ``covariance`` (6x6 or, for a position, 3x3) is propagated to the
        estimate's. ``max_force`` and ``max_moment`` (N, N m; cdr_node passes its own) bound
        the payloads the search tries. Flagged, not raised, when no payload matches; see
        robot/payload_estimate.py.
        """
        return estimate_payload(self, self._solve_with_compliance,
                                self.leg_solvers[0].unloaded_reference(), len(self.leg_solvers),
                                self.params.stack_height, self.geometry.slider_stroke,
                                self.time_limit_s, self.has_warm_start, self.reset,
                                platform_position, sliders, platform_quaternion_xyzw,
                                covariance=covariance, max_force=max_force,
                                max_moment=max_moment)

    @property
    def has_warm_start(self) -> bool:
        """Whether the next solve with ``warm_start`` starts from a previous solution."""
        return self._continuation.previous is not None

    # private ---------------------------------------------------------------------------------
    def _solve_with_compliance(self, sliders: np.ndarray, payload: np.ndarray,
                               time_limit_s: float) -> DeltaResult:
        """Solve under ``payload`` (6) at ``sliders`` with the compliance, within a limit."""
        return self.solve(sliders, payload[:3], payload[3:], compliance=True,
                          time_limit_s=time_limit_s)

    def _inputs(self, sliders: ArrayLike, payload_force: ArrayLike, payload_moment: ArrayLike,
                payload_offset: ArrayLike) -> np.ndarray:
        """
        Return ``solve``'s 12 inputs checked; ValueError naming a bad one.

        Three numbers each, finite, the sliders within the stroke, pass in one array
        conversion (about a microsecond); anything else goes through the checks that name
        what is wrong.
        """
        stroke = self.geometry.slider_stroke
        try:
            parts = cast(Tuple[Sequence[float], ...],
                         (sliders, payload_force, payload_moment, payload_offset))
            if len(parts[0]) == len(parts[1]) == len(parts[2]) == len(parts[3]) == 3:
                inputs = np.array((*parts[0], *parts[1], *parts[2], *parts[3]), dtype=float)
                first, second, third = inputs[:3].tolist()
                if inputs.shape == (12,) and math.isfinite(inputs.dot(inputs)) \
                        and max(abs(first), abs(second), abs(third)) <= stroke:
                    return inputs
        except (TypeError, ValueError):
            pass
        offset = np.asarray(payload_offset, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f'payload offset must be 3 finite coordinates (m), got {offset}')
        return np.concatenate([check_sliders(sliders, stroke),
                               check_wrench(payload_force, payload_moment), offset])

    def _held_reference(self) -> HeldReference:
        """
        Return the unloaded leg and its held buckling load, which the held verdicts compare with.

        Made once, at the first compliance solve: the buckling load takes a march along
        straight compression (held.held_critical_load, a few hundred ms, cached per
        parameter set); none found leaves the legs' verdicts unknown.
        """
        if self._held is None:
            try:
                critical: Optional[float] = held_critical_load(self.params).load_n
            except ArithmeticError:
                critical = None
            home = self._home[1].legs[0]
            self._held = held_reference(home.lu, home.compliance, self.params.stack_height,
                                        critical)
        return self._held

    @one_blas_thread
    def _linearize(self, result: DeltaResult, state: ChainState,
                   factorization: Optional[Factorization],
                   inputs: np.ndarray, held: HeldReference) -> Optional[Factorization]:
        """Add the linearization at solution ``state`` to ``result`` (linearization.linearize)."""
        with np.errstate(over='ignore', invalid='ignore'):
            return linearize(result, self._chain, self._chain_legs, state, factorization,
                             inputs, self.params.stack_height, held)

    def _limits(self) -> Limits:
        """Return the Newton's tolerances and iteration cap as this robot's attributes set them."""
        return Limits(self.equilibrium_tolerance, self.position_tolerance,
                      self.rotation_tolerance, self._chain_legs.tolerance, self.max_iterations)

    def _result(self, outcome: Outcome, legs: Sequence[SolveResult], inputs: np.ndarray,
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
        self._chain_legs.count_into(result)
        return result


def solve_delta(sliders: ArrayLike, payload_force: ArrayLike,
                payload_moment: ArrayLike = (0.0, 0.0, 0.0),
                payload_offset: ArrayLike = (0.0, 0.0, 0.0),
                params_path=DEFAULT_PARAMS_PATH) -> DeltaResult:
    """One cold forward-statics solve with the parameters of ``params_path``."""
    return DeltaRobot.from_yaml(params_path).solve(sliders, payload_force, payload_moment,
                                                   payload_offset)
