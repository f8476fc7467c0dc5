"""
The 'auto' fidelity: per wrench, the cheapest level that meets the error budget, checked.

The candidates, tried in this order:

* 'linear': the first-order expansion about the last full solution that made one
  (fidelity.linear). Its first-order term is exact, so its error grows as the square of the
  offset s = box_scale(w - w0) from that solution; it is estimated as kappa s^2, with a
  curvature kappa (position and angle) learned from checks and started, before any, from
  the validated errors of the level (config/fidelity_validation.yaml). An answer inside the
  trust region -- offsets up to CHECK_GROWTH times the farthest one checked on this
  expansion -- whose estimate uses at most LINEAR_TARGET of the budget is taken as it is.
  Farther out, the answer is checked before it is taken: one shot of the full model at the
  predicted unknowns gives their residual, the equations' own measure of how far the
  prediction is from a solution, and its norm times a gain is the linear answer's error
  (``check_prediction``). The gain (error per unit residual, position and angle) is
  measured on each expansion at its first check, which is a full solve instead: the
  prediction against the solution, the residual at the prediction. It varies along an
  expansion by tens of per cent (more between expansions), so GAIN_MARGIN times it is used.
  A check passes if its error, grown as the square of the offset to the edge of the trust
  region it opens (CHECK_GROWTH times the offset), stays inside LINEAR_TARGET of the
  budget; else the wrench escalates.
* 'cc', 'rod': where their validated errors meet the budget, cheapest first by the cost
  measured as the solver runs. With an expansion at hand the reduced answer is compared with
  its prediction: a distance beyond the budget plus the prediction's estimated error proves
  the reduced answer outside the budget (triangle inequality), and the next level is tried.
* 'full', otherwise. A new expansion is made about its solution when the reuse it promises
  pays for it: the answers it may serve (the offsets the last expansions served, over the
  last wrench step) times what each saves (the measured cost of the level that would
  answer instead, less a linear answer's) against the cost of two full solves after a
  long step (at the expansion and at its first check) and the expansion. The first
  expansion, with no served offsets to go by, is made where it may serve
  MIN_EXPANSION_REUSE answers inside the validated offset box and, in place of full
  answers, the largest trust region it may open (MAX_RADIUS_GROWTH times that box) would
  pay: it is how the reach is learned; in place of a reduced level, the validated box must
  pay. At a budget so tight, or wrench steps so large, that no expansion pays, the
  answers are plain full solves. A full solve one wrench step after the last full answer
  starts from that; after other answers, from the expansion's prediction.

Batches: ``auto_batch``.

Costs are measured once per process and parameter set, when the first 'auto' solver with a
budget is made (``measure_costs``: the fastest of CALIBRATION_REPEATS timings, robust to a
busy machine), and kept: the choices then depend on the wrenches alone, so that a batch
takes the levels its single solves take.

Reduced levels and the expansion are used only inside the largest validated wrench box.
"""

import math
from typing import Dict, List, Optional, Tuple, TYPE_CHECKING

import numpy as np

from . import auto_batch
from .auto_batch import NO_BUDGET, NO_CHEAPER, NO_DATA, NO_VERDICT, OUTSIDE, TRUSTED
from .validation import box_half_widths as validation_half_widths
from .validation import box_scale, frame_errors
from .._linalg import norm
from ..batch import BatchResult
from ..result import FRAME_NAMES, SolveResult

if TYPE_CHECKING:
    from .solver import FidelitySolver

#: Reduced levels, cheapest first (the order the validated choice tries them).
LEVEL_COST_ORDER = ('linear', 'cc', 'rod')

#: Share of the budget a linear answer's estimated (or checked) error may use.
LINEAR_TARGET = 0.7

#: Unchecked linear answers may lie this many times farther out than the farthest check.
CHECK_GROWTH = 1.15

#: A new expansion trusts, unchecked, this fraction of the radius its curvature predicts.
FIRST_CHECK = 0.5

#: The trust radius may exceed the one the validated worst case gives by this factor at most.
MAX_RADIUS_GROWTH = 4.0

#: The check's error estimate is its measured gain times this.
GAIN_MARGIN = 1.25

#: Timings per level whose fastest is its cost; the wrench step an expansion is timed at,
#: and the small step a warm full solve is timed at (box scales).
CALIBRATION_REPEATS = 5
CALIBRATION_STEP = 0.1
CALIBRATION_SMALL_STEP = 0.005

#: Offsets served by this many past expansions make the reach a new one is expected to have.
REACH_MEMORY = 3

#: Where the costs are timed: a load of this box scale along CALIBRATION_DIRECTION.
CALIBRATION_SCALE = 0.2
CALIBRATION_DIRECTION = np.array([1.0, 0.5, -0.5, 0.3, 0.2, 0.4])

#: Costs measured so far, per parameter set (``measure_costs``).
_MEASURED_COSTS: Dict[str, Dict[str, float]] = {}

#: An expansion must promise this many times its own cost in savings (counted at the
#: fastest warm full step: along a sequence the full level's periodic checks cost more) ...
EXPANSION_MARGIN = 1.0

#: ... and at least this many answers at the wrench's current pace.
MIN_EXPANSION_REUSE = 4.0


def validated_curvature(validation) -> np.ndarray:
    """Largest validated error of 'linear' per squared offset scale: (m, deg); inf: none."""
    bound = None if validation is None else validation.levels.get('linear')
    if bound is None:
        return np.full(2, math.inf)
    return np.array([max(error / scale ** 2 for error, scale in
                         zip(errors, bound.scales))
                     for errors in (bound.max_position_error_m, bound.max_angle_error_deg)])


class AutoFidelity:
    """The choices, checks, trust region and measured costs of one FidelitySolver's 'auto'."""

    def __init__(self, solver: 'FidelitySolver') -> None:
        """Bind ``solver`` (its budget, validation, levels and expansion)."""
        self.solver = solver
        #: each level's measured cost (s), and the expansion's ('expansion'); none until
        #: ``measure_costs``
        self.costs: Dict[str, float] = {}
        #: how often each event happened: checks made and failed, reduced answers refuted,
        #: expansions made
        self.counts = dict.fromkeys(('checks', 'failed_checks', 'refuted', 'expansions'), 0)
        self._reaches_for: Optional[tuple] = None
        self._reach_by_level: Dict[str, float] = {}
        self._reaches_served: List[float] = []  # farthest offset each past expansion served
        self._origin: Optional[np.ndarray] = None  # the expansion's wrench last looked at
        self._origin_inside = False  # and whether it lies inside the validated box
        self._target = LINEAR_TARGET * self.budget  # (m, deg) a linear answer may use ...
        self._target_for = (solver.max_position_error, solver.max_angle_error_deg)  # ... here
        self._validated_radius: Tuple[tuple, float] = ((), math.nan)  # (budget, radius)
        self.reset()

    def measure_costs(self) -> None:
        """Measure the levels' costs (``measure_costs``) if the choices need them."""
        solver = self.solver
        if (solver.fidelity == 'auto' and solver.validation is not None
                and solver.max_position_error > 0.0 and solver.max_angle_error_deg > 0.0):
            self.costs = measure_costs(solver)

    def reset(self) -> None:
        """Forget the trust region (the solver forgot its expansion)."""
        self.curvature = validated_curvature(self.solver.validation)
        self.trusted = 0.0
        self._measured: Optional[np.ndarray] = None  # largest kappa checked on the expansion
        self._served = 0.0  # farthest offset a linear answer took on the expansion
        self._gain: Optional[np.ndarray] = None  # the check's gain on this expansion

    @property
    def budget(self) -> np.ndarray:
        """Return the largest position (m) and angle (deg) errors allowed."""
        return np.array([self.solver.max_position_error, self.solver.max_angle_error_deg])

    # the validated choice ---------------------------------------------------------------------
    def validated_choice(self, wrench: np.ndarray) -> Tuple[str, str]:
        """
        Return (level, reason): the cheapest level whose validated error meets the budget.

        For 'linear' the offset from the expansion's wrench must lie in a validated offset
        box; ``solve`` widens that by checks.
        """
        solver = self.solver
        if solver.max_position_error <= 0.0 or solver.max_angle_error_deg <= 0.0:
            return 'full', NO_BUDGET
        if solver.validation is None:
            return 'full', NO_DATA
        reaches = self.reaches()
        scale = box_scale(wrench)
        for level in LEVEL_COST_ORDER:
            if level == 'linear' and not solver.tangent.ready:
                continue
            reach = reaches.get(level, -math.inf)
            origin = solver.tangent.origin
            if math.isnan(reach):  # bounds that do not grow: the box-by-box rule
                admitted = solver.validation.admissible(
                    level, wrench, solver.max_position_error, solver.max_angle_error_deg,
                    origin=origin)
            elif level == 'linear':
                admitted = (origin is not None and box_scale(origin) <= 1.0
                            and box_scale(wrench - origin) <= reach)
            else:
                admitted = scale <= reach
            if admitted:
                return level, 'the cheapest level whose validated error meets the budget'
        if scale > 1.0:
            return 'full', OUTSIDE
        return 'full', 'no reduced level meets the budget here'

    def reaches(self) -> Dict[str, float]:
        """Each level's validated reach under the budget (LevelBound.reach), made once."""
        solver = self.solver
        assert solver.validation is not None
        key = (solver.max_position_error, solver.max_angle_error_deg, id(solver.validation))
        if self._reaches_for != key:
            self._reach_by_level = {
                level: bound.reach(solver.max_position_error, solver.max_angle_error_deg)
                for level, bound in solver.validation.levels.items()}
            self._reaches_for = key
        return self._reach_by_level

    # the trust region of 'linear' -------------------------------------------------------------
    def radius(self, curvature: np.ndarray) -> float:
        """Offset scale at which ``curvature`` puts the linear error at LINEAR_TARGET."""
        with np.errstate(divide='ignore'):
            return float(np.sqrt(LINEAR_TARGET * self.budget / curvature).min())

    def linear_verdict(self, wrench: np.ndarray) -> Optional[str]:
        """'take' (inside the trust region), 'check', or None: 'linear' is not a candidate."""
        return self._verdict(wrench)[0]

    def _verdict(self, wrench: np.ndarray) -> Tuple[Optional[str], float]:
        """(``linear_verdict``, the offset scale from the expansion's wrench; NaN: none)."""
        origin = self.solver.tangent.origin
        if origin is None:
            return None, math.nan
        if origin is not self._origin:  # a new expansion (TangentModel.build copies w0)
            self._origin, self._origin_inside = origin, box_scale(origin) <= 1.0
        if not self._origin_inside or box_scale(wrench) > 1.0:
            return None, math.nan
        scale = box_scale(wrench - origin)
        solver = self.solver
        if self._target_for != (solver.max_position_error, solver.max_angle_error_deg):
            self._target_for = (solver.max_position_error, solver.max_angle_error_deg)
            self._target = LINEAR_TARGET * self.budget
        # as within_linear_target computes it, in floats
        square, curvature, target = scale * scale, self.curvature, self._target
        if curvature[0] * square > target[0] or curvature[1] * square > target[1]:
            return None, scale
        return ('take' if scale <= self.trusted else 'check'), scale

    def within_linear_target(self, scales: np.ndarray) -> np.ndarray:
        """Per offset scale: whether the curvature puts its linear error inside the target."""
        estimates = self.curvature * np.asarray(scales)[..., None] ** 2
        return (estimates <= LINEAR_TARGET * self.budget).all(axis=-1)

    def served(self, scale: float) -> None:
        """Note a linear answer at offset ``scale`` from the expansion."""
        self._served = max(self._served, scale)

    @property
    def gain(self) -> np.ndarray:
        """Linear error (m, deg) per unit residual norm at the prediction; inf: not measured."""
        if self._gain is None:
            return np.full(2, math.inf)
        return GAIN_MARGIN * self._gain

    def prediction_residual(self, wrench: np.ndarray, unknowns: np.ndarray) -> float:
        """Norm of the full model's nondimensional residual at predicted SI ``unknowns``."""
        problem = self.solver.full.problem
        return norm(problem.residual(unknowns / problem.x_scale, wrench))

    def check_prediction(self, wrench: np.ndarray, unknowns: np.ndarray) -> np.ndarray:
        """Estimated errors (m, deg) of the linear answer with SI ``unknowns`` at ``wrench``."""
        with np.errstate(invalid='ignore'):
            errors = self.gain * self.prediction_residual(wrench, unknowns)
        return np.where(np.isnan(errors), math.inf, errors)

    def _learn(self, scale: float, errors: np.ndarray) -> None:
        """Fold errors measured at offset ``scale`` into the expansion's curvature."""
        if scale <= 0.0 or not np.isfinite(errors).all():
            return
        measured = errors / scale ** 2
        self._measured = (measured if self._measured is None
                          else np.maximum(self._measured, measured))
        self.curvature = self._measured

    def _new_expansion(self) -> None:
        """Start the trust region of a new expansion from the last one's curvature."""
        floor = validated_curvature(self.solver.validation) / MAX_RADIUS_GROWTH ** 2
        if self._measured is not None:
            self.curvature = np.maximum(self._measured, floor)
        self._measured = None
        if self._served > 0.0:
            self._reaches_served = (self._reaches_served + [self._served])[-REACH_MEMORY:]
        self._served = 0.0
        self._gain = None
        self.trusted = FIRST_CHECK * self.radius(self.curvature)
        self.counts['expansions'] += 1

    # solving ----------------------------------------------------------------------------------
    def solve(self, wrench: np.ndarray, compliance: bool, options: dict) -> SolveResult:
        """Answer ``wrench`` at the cheapest level that meets the budget (module docstring)."""
        solver = self.solver
        if (solver.max_position_error <= 0.0 or solver.max_angle_error_deg <= 0.0
                or solver.validation is None):
            level, reason = self.validated_choice(wrench)
            return solver._solve_at(level, reason, wrench, compliance, options)
        # an answer below 'full' carries the verdict of a full solution near it (verdicts.py):
        # where none is near, the answer is a full solve, which judges itself
        covered = solver.carried_verdict(wrench) is not None
        verdict, scale = self._verdict(wrench) if covered else (None, math.nan)
        if verdict == 'take':
            self.served(scale)
            return solver._solve_at('linear', TRUSTED, wrench, compliance, options,
                                    self.curvature * scale ** 2)
        if verdict == 'check' and self._gain is None:
            return self._first_check(wrench, compliance, options)
        if verdict == 'check':
            errors = self.check_prediction(wrench, solver.tangent.unknowns(wrench))
            self.counts['checks'] += 1
            self._learn(scale, errors)
            if (errors * CHECK_GROWTH ** 2 <= LINEAR_TARGET * self.budget).all():
                self.trusted = max(self.trusted, CHECK_GROWTH * scale)
                self.served(scale)
                return solver._solve_at(
                    'linear', "checked by the full model's residual: error about "
                    f'{1e3 * errors[0]:.3g} mm, {errors[1]:.3g} deg', wrench, compliance,
                    options, errors)
            self.counts['failed_checks'] += 1
        levels = self._reduced_candidates(wrench)
        uncovered = not covered and (bool(levels) or self._verdict(wrench)[0] is not None)
        if not covered:
            levels = []
        if self._expansion_pays(wrench, self.costs[levels[0]] if levels else None):
            return self._full(wrench, True, compliance, options, 'an expansion about it pays')
        if not levels:  # the same question as just answered
            if uncovered and box_scale(wrench) <= 1.0:
                return self._verdict_solve(wrench, compliance, options)
            return solver._solve_at('full', OUTSIDE if box_scale(wrench) > 1.0 else NO_CHEAPER,
                                    wrench, compliance, options)
        validation = solver.validation
        assert validation is not None  # a budget without data answers 'full'
        for level in levels:
            result = solver._solve_at(level, 'validated error inside the budget here', wrench,
                                      compliance, options,
                                      validation.levels[level].errors_at(box_scale(wrench)))
            if result.converged and not self._refuted(wrench, result):
                return result
        reason = OUTSIDE if box_scale(wrench) > 1.0 else NO_CHEAPER
        return self._full(wrench, self._expansion_pays(wrench, None), compliance, options,
                          reason)

    def _verdict_solve(self, wrench: np.ndarray, compliance: bool,
                       options: dict) -> SolveResult:
        """Answer in full for want of a verdict; the reduced answers near it carry its verdict."""
        result = self.solver._solve_at('full', NO_VERDICT, wrench, compliance, options)
        self.solver.note_full_answer(wrench, result.stable, result.stability_margin)
        return result

    def _first_check(self, wrench: np.ndarray, compliance: bool,
                     options: dict) -> SolveResult:
        """Check an expansion the first time: a full solve, which measures the check's gain."""
        solver = self.solver
        origin = solver.tangent.origin
        assert origin is not None
        scale = box_scale(wrench - origin)
        unknowns, frames = solver.tangent.unknowns(wrench), solver.tangent.frames(wrench)
        residual = self._start_full_at(wrench, unknowns)
        result = solver._solve_at('full', 'the first check of the expansion', wrench,
                                  compliance, options)
        solver.note_full_answer(wrench, result.stable, result.stability_margin)
        self.counts['checks'] += 1
        if not result.converged or residual <= 0.0:
            self.counts['failed_checks'] += 1
            return result
        position, angle = frame_errors(frames, np.stack([result.frames[name]
                                                         for name in FRAME_NAMES]))
        errors = np.array([position, math.degrees(angle)])
        self._gain = errors / residual
        self._learn(scale, errors)
        if (errors * CHECK_GROWTH ** 2 <= LINEAR_TARGET * self.budget).all():
            self.trusted = max(self.trusted, CHECK_GROWTH * scale)
        else:
            self.counts['failed_checks'] += 1
        return result

    def _start_full_at(self, wrench: np.ndarray, unknowns: np.ndarray) -> float:
        """
        Start the full model's next solve at the predicted SI ``unknowns``; their residual.

        The prediction is a nearer start than the last full solution, and the expansion's
        factorization serves its first chord steps.
        """
        solver, tangent = self.solver, self.solver.tangent
        assert tangent.origin is not None
        solver.full.start_at(unknowns / solver.full.problem.x_scale, wrench,
                             (tangent.factorization, tangent.pose_jacobian, tangent.origin))
        return self.prediction_residual(wrench, unknowns)

    def solve_many(self, wrenches: np.ndarray, batch: BatchResult, compliance: bool) -> None:
        """Solve the rows of ``wrenches`` into ``batch`` as consecutive ``solve`` calls would."""
        auto_batch.solve_many(self, wrenches, batch, compliance)

    def _reduced_candidates(self, wrench: np.ndarray) -> List[str]:
        """'cc' and 'rod' where their validated errors meet the budget, cheapest first."""
        if box_scale(wrench) > 1.0:
            return []
        reaches = self.reaches()
        scale = box_scale(wrench)
        solver = self.solver
        assert solver.validation is not None  # a budget without data answers 'full'
        admitted = []
        for level in ('cc', 'rod'):
            reach = reaches.get(level, -math.inf)
            if (scale <= reach if not math.isnan(reach) else solver.validation.admissible(
                    level, wrench, solver.max_position_error, solver.max_angle_error_deg)):
                admitted.append(level)
        return sorted(admitted, key=self.costs.__getitem__)

    def _refuted(self, wrench: np.ndarray, result: SolveResult) -> bool:
        """Whether the expansion's prediction proves ``result`` outside the budget."""
        tangent = self.solver.tangent
        if not tangent.ready:
            return False
        scale = box_scale(wrench - tangent.origin)
        frames = tangent.frames(wrench)
        position, angle = frame_errors(np.stack([result.frames[name] for name in FRAME_NAMES]),
                                       frames)
        distance = np.array([position, math.degrees(angle)])
        refuted = bool((distance > self.budget + self.curvature * scale ** 2).any())
        self.counts['refuted'] += refuted
        return refuted

    def _expansion_pays(self, wrench: np.ndarray, alternative: Optional[float]) -> bool:
        """
        Whether to expand about a full solution at ``wrench`` (module docstring).

        ``alternative``: the cost of the level that would answer instead (None: a warm full
        solve's). Each answer the expansion serves saves that cost less a linear answer's.
        """
        last = self.solver._last_wrench
        if last is None or box_scale(wrench) > 1.0:
            return False
        reach, growth, saving, pays = self._expansion_terms(alternative)
        if saving <= 0.0:
            return False
        reuse = reach / max(box_scale(wrench - last), 1e-12)
        return reuse >= MIN_EXPANSION_REUSE and growth * reuse * saving > pays

    def expansion_pays_at(self, steps: np.ndarray, alternative: Optional[float]) -> np.ndarray:
        """``_expansion_pays`` for wrenches inside the box that come after ``steps`` (scales)."""
        reach, growth, saving, pays = self._expansion_terms(alternative)
        if saving <= 0.0:
            return np.zeros(len(steps), bool)
        reuse = reach / np.maximum(steps, 1e-12)
        return (reuse >= MIN_EXPANSION_REUSE) & (growth * reuse * saving > pays)

    def _expansion_terms(self, alternative: Optional[float]
                         ) -> Tuple[float, float, float, float]:
        """(Offset an expansion may serve, its growth, saving per answer, cost to beat)."""
        cost = self.costs['full step'] if alternative is None else alternative
        saving = cost - self.costs['linear']
        # two full solves after a long step (at the expansion and at its first check)
        pays = EXPANSION_MARGIN * (2.0 * self.costs['full'] + self.costs['expansion'])
        if self._reaches_served:
            return sum(self._reaches_served) / len(self._reaches_served), 1.0, saving, pays
        # the first expansion, to learn what one serves: in place of full solves if the
        # largest trust region it may open pays, of a reduced level if the validated one does
        key = (self.solver.max_position_error, self.solver.max_angle_error_deg,
               id(self.solver.validation))
        if self._validated_radius[0] != key:
            self._validated_radius = (key, self.radius(
                validated_curvature(self.solver.validation)))
        growth = MAX_RADIUS_GROWTH if alternative is None else 1.0
        return self._validated_radius[1], growth, saving, pays

    def _full(self, wrench: np.ndarray, expand: bool, compliance: bool, options: dict,
              reason: str) -> SolveResult:
        """Solve the full model at ``wrench``; expand about its solution when ``expand``."""
        solver = self.solver
        if not expand:
            return solver._solve_at('full', reason, wrench, compliance, options)
        tangent = solver.tangent
        previous = None
        if tangent.origin is not None:  # the old expansion's error here, measured
            unknowns, frames = tangent.unknowns(wrench), tangent.frames(wrench)
            if solver._last_level != 'full':  # else the last full solution is one step away
                self._start_full_at(wrench, unknowns)
            previous = (box_scale(wrench - tangent.origin), frames)
        result = solver.cache_full_solution(wrench, compliance, **options)
        result.message += f' [full: {reason}]'
        solver._last_wrench, solver._last_level = wrench, 'full'
        if previous is not None and result.converged:
            frames = np.stack([result.frames[name] for name in FRAME_NAMES])
            position, angle = frame_errors(previous[1], frames)
            self._learn(previous[0], np.array([position, math.degrees(angle)]))
        self._new_expansion()
        return result


def measure_costs(solver: 'FidelitySolver') -> Dict[str, float]:
    """
    Time each level of ``solver`` (s per answer; 'expansion': one expansion), once per process.

    'full', 'cc' and 'rod' answer a step of CALIBRATION_STEP box scales from a solution at
    CALIBRATION_SCALE; 'full step' a further step of CALIBRATION_SMALL_STEP (a warm solve
    along a slow sequence); 'expansion' expands about the full solution, and 'linear'
    answers one more such step from it. The fastest of
    CALIBRATION_REPEATS; the solver is reset afterwards.
    """
    key = f'{solver.params!r} {solver.rod_steps} {solver.full.tolerance!r}'
    if key not in _MEASURED_COSTS:
        direction = CALIBRATION_DIRECTION * validation_half_widths()
        start = CALIBRATION_SCALE * direction
        end = start + CALIBRATION_STEP * direction
        times: Dict[str, List[float]] = {level: [] for level in (
            'full', 'full step', 'expansion', 'linear', 'cc', 'rod')}
        for _ in range(CALIBRATION_REPEATS):
            solver.reset()
            for level in ('full', 'cc', 'rod'):
                solver._solve_at(level, '', start, False, {})
                times[level].append(solver._solve_at(level, '', end, False, {}).solve_time_s)
            further = end + CALIBRATION_SMALL_STEP * direction
            result = solver._solve_at('full', '', further, False, {})
            times['full step'].append(result.solve_time_s)
            solver.tangent.build(result.unknowns / solver.full.problem.x_scale, further)
            times['expansion'].append(solver.tangent.build_time_s)
            nearby = further + CALIBRATION_SMALL_STEP * direction
            times['linear'].append(solver._solve_at('linear', '', nearby, False, {}).solve_time_s)
        _MEASURED_COSTS[key] = {level: min(values) for level, values in times.items()}
        solver.reset()
    return dict(_MEASURED_COSTS[key])
