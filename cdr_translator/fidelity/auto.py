"""
The 'auto' fidelity: per wrench, the cheapest level that meets the error budget, checked.

The candidates, tried in this order:

* 'linear': the first-order expansion about the last full solution that made one
  (fidelity.linear). Its first-order term is exact, so its error grows as the square of the
  offset s = box_scale(w - w0) from that solution; it is estimated as kappa s^2, with a
  curvature kappa (position and angle) learned from checks and started, before any, from
  the validated errors of the level (config/fidelity_validation.yaml). An answer inside the
  trust region whose estimate uses at most LINEAR_TARGET of the budget is taken as it is.
  The trust region: offsets up to FIRST_CHECK times the radius the curvature gives, in any
  direction, and the neighbourhood of each check that passed -- wrenches no farther from it
  than CHECK_GROWTH - 1 times its offset, out to CHECK_GROWTH times the farthest offset
  checked. The curvature is measured along the offsets checked; a noisy stream wanders to
  others, where it may be larger, so a check's trust reaches only the offsets near it.
  Farther out, the answer is checked before it is taken: one shot of the full model at the
  predicted unknowns gives their residual, the equations' own measure of how far the
  prediction is from a solution, and its norm times a gain is the linear answer's error
  (``check_prediction``). The gain (error per unit residual, position and angle) is
  measured on each expansion at its first check, which is a full solve instead: the
  prediction against the solution, the residual at the prediction. It varies along an
  expansion by tens of per cent (more between expansions), so GAIN_MARGIN times it is used.
  A check passes if its error, grown as the square of the offset to the edge of the trust
  region it opens (CHECK_GROWTH times the offset), stays inside LINEAR_TARGET of the
  budget; else the wrench escalates. Where 'cc' or 'rod' is admitted and costs less than a
  check (its shot), it answers instead of a check (a noisy stream near the unloaded state:
  most offsets need one).
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

Every answer below 'full' carries the stability verdict of a full solution near it
(fidelity.verdicts): where none is near enough, the answer is a full solve (NO_VERDICT),
and the reduced answers near it carry its verdict.

Which levels the validation data admit: ``admission``. Batches: ``auto_runs``. Costs are
measured once per process and parameter set, when the first 'auto' solver with a budget is
made (``auto_costs``), and kept: the choices then depend on the wrenches alone, so that a
batch takes the levels its single solves take.

Reduced levels and the expansion are used only inside the largest validated wrench box.
"""

import math
from typing import Callable, Dict, List, Mapping, Optional, Tuple

import numpy as np

from .admission import Admission, OUTSIDE
from .auto_costs import measure_costs
from .level import Asked, Level
from .linear_level import LinearLevel
from .validation import box_scale, box_scales, frame_errors, Validation
from .verdicts import FullVerdict, Judge, unloaded_verdict
from .._linalg import norm
from ..solve.batch import BatchResult
from ..solve.result import FRAME_NAMES, SolveResult
from ..solve.solver import TranslatorSolver

#: Share of the budget a linear answer's estimated (or checked) error may use.
LINEAR_TARGET = 0.7

#: Unchecked linear answers may lie this many times farther out than the farthest check,
#: and no farther from a check that passed than CHECK_GROWTH - 1 times its offset.
CHECK_GROWTH = 1.15

#: Checks that passed on an expansion whose neighbourhoods are trusted (the latest ones).
REMEMBERED_CHECKS = 16

#: A new expansion trusts, unchecked, this fraction of the radius its curvature predicts.
FIRST_CHECK = 0.5

#: The trust radius may exceed the one the validated worst case gives by this factor at most.
MAX_RADIUS_GROWTH = 4.0

#: The check's error estimate is its measured gain times this.
GAIN_MARGIN = 1.25

#: Offsets served by this many past expansions make the reach a new one is expected to have.
REACH_MEMORY = 3

#: An expansion must promise this many times its own cost in savings (counted at the
#: fastest warm full step: along a sequence the full level's periodic checks cost more) ...
EXPANSION_MARGIN = 1.0

#: ... and at least this many answers at the wrench's current pace.
MIN_EXPANSION_REUSE = 4.0

#: Reasons of 'auto' answers: a linear answer taken unchecked; full answers without an
#: expansion (besides admission's: nothing cheaper admitted, no full solution near enough
#: to carry a verdict to a cheaper level).
TRUSTED = 'inside the trust region of the expansion about the last full solution'
NO_CHEAPER = 'no cheaper level meets the budget'
NO_VERDICT = ('no full solution near enough to carry its stability verdict to a cheaper '
              'level here')

#: Why a reduced level answers inside its validated range.
VALIDATED = 'validated error inside the budget here'


def validated_curvature(validation: Optional[Validation]) -> np.ndarray:
    """Largest validated error of 'linear' per squared offset scale: (m, deg); inf: none."""
    bound = None if validation is None else validation.levels.get('linear')
    if bound is None:
        return np.full(2, math.inf)
    return np.array([max(error / scale ** 2 for error, scale in
                         zip(errors, bound.scales))
                     for errors in (bound.max_position_error_m, bound.max_angle_error_deg)])


class AutoFidelity:
    """
    The policy of 'auto' over the levels, with its memory.

    It remembers the trust region of the expansion, the measured costs, how often each
    event happened, the last answer (its wrench and level) and the verdict of the last full
    answer it gave for a verdict (which the reduced answers near it carry: verdicts.py).
    It reads the levels through the level protocol and the 'linear' level's expansion.
    """

    def __init__(self, levels: Mapping[str, Level], linear: LinearLevel,
                 full: TranslatorSolver, validation: Optional[Validation],
                 max_position_error: float, max_angle_error_deg: float,
                 load_scale: float) -> None:
        """
        Decide over ``levels`` (by name; ``linear`` the 'linear' one, ``full`` the full model).

        ``validation`` (None: no data), the budget (m, deg) and w* (stability.load_scale:
        the reduced answers' verdicts) are the policy's.
        """
        self.levels = levels
        self.linear = linear
        self.full = full
        self.validation = validation
        self.max_position_error = max_position_error
        self.max_angle_error_deg = max_angle_error_deg
        self.load_scale = load_scale
        #: each level's measured cost (s), and the expansion's ('expansion'); none until
        #: ``measure_costs``
        self.costs: Dict[str, float] = {}
        #: how often each event happened: checks made and failed, reduced answers refuted,
        #: expansions made
        self.counts = dict.fromkeys(('checks', 'failed_checks', 'refuted', 'expansions'), 0)
        self._unloaded = unloaded_verdict()
        self._judge_of: Tuple[Optional[FullVerdict], Optional[FullVerdict]] = (None, None)
        self._judge = Judge.of((self._unloaded,), load_scale, full.params.stack_height,
                               (max_position_error, max_angle_error_deg))
        #: which levels the validation data admit under the budget
        self.admission = Admission(validation, max_position_error, max_angle_error_deg)
        self._reaches_served: List[float] = []  # farthest offset each past expansion served
        self._origin: Optional[np.ndarray] = None  # the expansion's wrench last looked at
        self._origin_inside = False  # and whether it lies inside the validated box
        self._target = LINEAR_TARGET * self.budget  # (m, deg) a linear answer may use ...
        self._target_for = (max_position_error, max_angle_error_deg)  # ... at this budget
        self._validated_radius: Tuple[tuple, float] = ((), math.nan)  # (budget, radius)
        self.reset()

    def measure_costs(self, reset: Callable[[], None], key: str) -> None:
        """
        Measure the levels' costs (auto_costs.measure_costs) if the choices need them.

        ``reset`` forgets every level's memory and this policy's; ``key`` names the
        parameter set the costs hold for.
        """
        if (self.validation is not None and self.max_position_error > 0.0
                and self.max_angle_error_deg > 0.0):
            self.costs = measure_costs(self.levels, self.linear, lambda: self.asked(''),
                                       reset, key)

    def reset(self) -> None:
        """Forget the trust region, the last answer and the last full verdict."""
        self.curvature = validated_curvature(self.validation)
        #: the trust region: its largest offset scale (0: none), the offset trusted in every
        #: direction, and the checks that passed with the distance each is trusted to
        self.trusted = 0.0
        self.trusted_everywhere = 0.0
        self.passed_checks: List[Tuple[np.ndarray, float]] = []
        self._measured: Optional[np.ndarray] = None  # largest kappa checked on the expansion
        self._served = 0.0  # farthest offset a linear answer took on the expansion
        self._gain: Optional[np.ndarray] = None  # the check's gain on this expansion
        #: the wrench (6,) and level of the last answer (None: none since the reset)
        self.last_wrench: Optional[np.ndarray] = None
        self.last_level: Optional[str] = None
        #: the verdict of the last full answer given for a verdict, a check or an expansion
        self.full_verdict: Optional[FullVerdict] = None

    # answers through the levels -----------------------------------------------------------------
    def judge(self) -> Judge:
        """Return how answers below 'full' are judged now (verdicts.Judge, the budget)."""
        at_hand = (self.linear.verdict, self.full_verdict)
        if at_hand != self._judge_of:
            self._judge_of = at_hand
            self._judge = Judge.of((self._unloaded,) + at_hand, self.load_scale,
                                   self.full.params.stack_height,
                                   (self.max_position_error, self.max_angle_error_deg))
        return self._judge

    def asked(self, reason: str, estimates: Optional[np.ndarray] = None,
              stop_at_failure: bool = False) -> Asked:
        """Return what an answer for ``reason`` asks of a level now (level.Asked)."""
        return Asked(reason, self.judge(), self.full.time_limit_s, estimates, stop_at_failure)

    def answer(self, level: str, reason: str, wrench: np.ndarray, compliance: bool,
               options: Mapping[str, float],
               estimate: Optional[np.ndarray] = None) -> SolveResult:
        """Answer ``wrench`` at ``level`` for ``reason`` (with its validated ``estimate``)."""
        result = self.levels[level].solve(wrench, compliance, options,
                                          self.asked(reason, estimate))
        self.last_wrench, self.last_level = wrench, result.fidelity
        return result

    def run(self, level: str, reason: str, wrenches: np.ndarray, rows: range,
            batch: BatchResult, compliance: bool, estimates: Optional[np.ndarray] = None,
            stop_at_failure: bool = False) -> int:
        """Answer ``rows`` at ``level`` by one call of its solve_many; return how many."""
        count = self.levels[level].solve_many(wrenches, rows, batch, compliance,
                                              self.asked(reason, estimates, stop_at_failure))
        if count:
            last = rows.start + count - 1
            self.last_wrench, self.last_level = wrenches[last], str(batch.fidelity[last])
        return count

    def note_full_answer(self, wrench: np.ndarray, stable: Optional[bool],
                         margin: float) -> None:
        """Keep the verdict of a full answer at ``wrench`` (none kept when it has none)."""
        if stable is not None:
            self.full_verdict = FullVerdict(
                wrench.copy(), bool(stable), float(margin),
                f'the last full answer, at {np.round(wrench, 4).tolist()}')

    @property
    def budget(self) -> np.ndarray:
        """Return the largest position (m) and angle (deg) errors allowed."""
        return np.array([self.max_position_error, self.max_angle_error_deg])

    def validated_choice(self, wrench: np.ndarray) -> Tuple[str, str]:
        """Return (level, reason): the cheapest level admitted at ``wrench`` (admission.py)."""
        return self.admission.choice(wrench, self.linear.tangent.origin)

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
        origin = self.linear.tangent.origin
        if origin is None:
            return None, math.nan
        if origin is not self._origin:  # a new expansion (TangentModel.build copies w0)
            self._origin, self._origin_inside = origin, box_scale(origin) <= 1.0
        if not self._origin_inside or box_scale(wrench) > 1.0:
            return None, math.nan
        scale = box_scale(wrench - origin)
        if self._target_for != (self.max_position_error, self.max_angle_error_deg):
            self._target_for = (self.max_position_error, self.max_angle_error_deg)
            self._target = LINEAR_TARGET * self.budget
        # as within_linear_target computes it, in floats
        square, curvature, target = scale * scale, self.curvature, self._target
        if curvature[0] * square > target[0] or curvature[1] * square > target[1]:
            return None, scale
        return ('take' if self._trusted_at(wrench, scale) else 'check'), scale

    def _trusted_at(self, wrench: np.ndarray, scale: float) -> bool:
        """Whether ``wrench``, offset ``scale`` from the expansion, lies in the trust region."""
        if scale > self.trusted:
            return False
        return scale <= self.trusted_everywhere or any(
            box_scale(wrench - checked) <= reach for checked, reach in self.passed_checks)

    def within_trust(self, wrenches: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """``_trusted_at`` of each row of ``wrenches`` at offset ``scales``, in the same floats."""
        trusted = scales <= self.trusted_everywhere
        for checked, reach in self.passed_checks:
            trusted |= box_scales(wrenches - checked) <= reach
        return trusted & (scales <= self.trusted)

    def _passed(self, wrench: np.ndarray, scale: float) -> None:
        """Trust the neighbourhood of a check that passed at ``wrench``, offset ``scale``."""
        self.trusted = max(self.trusted, CHECK_GROWTH * scale)
        self.passed_checks = (self.passed_checks + [(wrench.copy(), (CHECK_GROWTH - 1.0) * scale)]
                              )[-REMEMBERED_CHECKS:]

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
        problem = self.full.problem
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
        floor = validated_curvature(self.validation) / MAX_RADIUS_GROWTH ** 2
        if self._measured is not None:
            self.curvature = np.maximum(self._measured, floor)
        self._measured = None
        if self._served > 0.0:
            self._reaches_served = (self._reaches_served + [self._served])[-REACH_MEMORY:]
        self._served = 0.0
        self._gain = None
        self.trusted = self.trusted_everywhere = FIRST_CHECK * self.radius(self.curvature)
        self.passed_checks = []
        self.counts['expansions'] += 1

    # solving ----------------------------------------------------------------------------------
    def solve(self, wrench: np.ndarray, compliance: bool,
              options: Mapping[str, float]) -> SolveResult:
        """Answer ``wrench`` at the cheapest level that meets the budget (module docstring)."""
        if (self.max_position_error <= 0.0 or self.max_angle_error_deg <= 0.0
                or self.validation is None):
            level, reason = self.validated_choice(wrench)
            return self.answer(level, reason, wrench, compliance, options)
        # an answer below 'full' carries the verdict of a full solution near it (verdicts.py):
        # where none is near, the answer is a full solve, which judges itself
        covered = self.judge().carried(wrench) is not None
        verdict, scale = self._verdict(wrench) if covered else (None, math.nan)
        if verdict == 'check' and self._cheaper_than_a_check(wrench):
            verdict = None
        if verdict == 'take':
            self.served(scale)
            return self.answer('linear', TRUSTED, wrench, compliance, options,
                               self.curvature * scale ** 2)
        if verdict == 'check' and self._gain is None:
            return self._first_check(wrench, compliance, options)
        if verdict == 'check':
            errors = self.check_prediction(wrench, self.linear.tangent.unknowns(wrench))
            self.counts['checks'] += 1
            self._learn(scale, errors)
            if (errors * CHECK_GROWTH ** 2 <= LINEAR_TARGET * self.budget).all():
                self._passed(wrench, scale)
                self.served(scale)
                return self.answer(
                    'linear', "checked by the full model's residual: error about "
                    f'{1e3 * errors[0]:.3g} mm, {errors[1]:.3g} deg', wrench, compliance,
                    options, errors)
            self.counts['failed_checks'] += 1
        levels = sorted(self.admission.reduced(wrench), key=self.costs.__getitem__)
        uncovered = not covered and (bool(levels) or self._verdict(wrench)[0] is not None)
        if not covered:
            levels = []
        if self._expansion_pays(wrench, self.costs[levels[0]] if levels else None):
            return self.answer_in_full(wrench, True, compliance, options,
                                       'an expansion about it pays')
        if not levels:  # the same question as just answered
            if uncovered and box_scale(wrench) <= 1.0:
                return self._verdict_solve(wrench, compliance, options)
            return self.answer('full', OUTSIDE if box_scale(wrench) > 1.0 else NO_CHEAPER,
                               wrench, compliance, options)
        validation = self.validation
        assert validation is not None  # a budget without data answers 'full'
        for level in levels:
            result = self.answer(level, VALIDATED, wrench, compliance, options,
                                 validation.levels[level].errors_at(box_scale(wrench)))
            if result.converged and not self._refuted(wrench, result):
                return result
        reason = OUTSIDE if box_scale(wrench) > 1.0 else NO_CHEAPER
        return self.answer_in_full(wrench, self._expansion_pays(wrench, None), compliance,
                                   options, reason)

    def _cheaper_than_a_check(self, wrench: np.ndarray) -> bool:
        """Whether a reduced level admitted at ``wrench`` costs less than checking 'linear'."""
        check = self.costs.get('check', math.inf)
        return any(self.costs[level] < check for level in self.admission.reduced(wrench))

    def _verdict_solve(self, wrench: np.ndarray, compliance: bool,
                       options: Mapping[str, float]) -> SolveResult:
        """Answer in full for want of a verdict; the reduced answers near it carry its verdict."""
        result = self.answer('full', NO_VERDICT, wrench, compliance, options)
        self.note_full_answer(wrench, result.stable, result.stability_margin)
        return result

    def _first_check(self, wrench: np.ndarray, compliance: bool,
                     options: Mapping[str, float]) -> SolveResult:
        """Check an expansion the first time: a full solve, which measures the check's gain."""
        tangent = self.linear.tangent
        origin = tangent.origin
        assert origin is not None
        scale = box_scale(wrench - origin)
        unknowns, frames = tangent.unknowns(wrench), tangent.frames(wrench)
        residual = self._start_full_at(wrench, unknowns)
        result = self.answer('full', 'the first check of the expansion', wrench, compliance,
                             options)
        self.note_full_answer(wrench, result.stable, result.stability_margin)
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
            self._passed(wrench, scale)
        else:
            self.counts['failed_checks'] += 1
        return result

    def _start_full_at(self, wrench: np.ndarray, unknowns: np.ndarray) -> float:
        """
        Start the full model's next solve at the predicted SI ``unknowns``; their residual.

        The prediction is a nearer start than the last full solution, and the expansion's
        factorization serves its first chord steps.
        """
        tangent = self.linear.tangent
        assert tangent.origin is not None
        self.full.start_at(unknowns / self.full.problem.x_scale, wrench,
                           (tangent.factorization, tangent.pose_jacobian, tangent.origin))
        return self.prediction_residual(wrench, unknowns)

    def _refuted(self, wrench: np.ndarray, result: SolveResult) -> bool:
        """Whether the expansion's prediction proves ``result`` outside the budget."""
        tangent = self.linear.tangent
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
        last = self.last_wrench
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
        key = (self.max_position_error, self.max_angle_error_deg, id(self.validation))
        if self._validated_radius[0] != key:
            self._validated_radius = (key, self.radius(validated_curvature(self.validation)))
        growth = MAX_RADIUS_GROWTH if alternative is None else 1.0
        return self._validated_radius[1], growth, saving, pays

    def answer_in_full(self, wrench: np.ndarray, expand: bool, compliance: bool,
                       options: Mapping[str, float], reason: str) -> SolveResult:
        """Solve the full model at ``wrench``; expand about its solution when ``expand``."""
        if not expand:
            return self.answer('full', reason, wrench, compliance, options)
        tangent = self.linear.tangent
        previous = None
        if tangent.origin is not None:  # the old expansion's error here, measured
            unknowns, frames = tangent.unknowns(wrench), tangent.frames(wrench)
            if self.last_level != 'full':  # else the last full solution is one step away
                self._start_full_at(wrench, unknowns)
            previous = (box_scale(wrench - tangent.origin), frames)
        result = self.linear.expand(wrench, compliance, options)
        result.message += f' [full: {reason}]'
        self.last_wrench, self.last_level = wrench, 'full'
        self.note_full_answer(wrench, result.stable, result.stability_margin)
        if previous is not None and result.converged:
            frames = np.stack([result.frames[name] for name in FRAME_NAMES])
            position, angle = frame_errors(previous[1], frames)
            self._learn(previous[0], np.array([position, math.degrees(angle)]))
        self._new_expansion()
        return result
