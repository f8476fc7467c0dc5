"""
FidelitySolver: one solve interface over every fidelity level, and the error budget.

Levels: 'full' (TranslatorSolver, the paper's model), 'rod' (equivalent rod, 7 unknowns),
'cc' (constant-curvature virtual work, 8), 'linear' (first-order expansion about a cached
full solution). 'auto' picks, for each wrench, the cheapest level that meets the budget
(``max_position_error`` m, ``max_angle_error_deg`` deg) by its validated error
(``fidelity.validation``), the errors it checks as it goes and the costs it measures
(``fidelity.auto``), and falls back to 'full' outside every validated range. Every result
says which level produced it (``result.fidelity``) and why (``result.message``).
"""

import math
from pathlib import Path
import time
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from . import batch_rows
from .auto import AutoFidelity
from .linear import TangentModel
from .reduced import ReducedModel, ReducedOutcome, ROD_STEPS
from .validation import box_scale, DEFAULT_VALIDATION_PATH, Validation
from .verdicts import carried, FullVerdict, load_scale_at, note, unloaded_verdict
from .._blas import one_blas_thread
from ..batch import BatchResult, check_wrenches
from ..checks import check_number
from ..compliance import analyse, ComplianceAnalysis, frame_twist
from ..params import Accuracy, DEFAULT_PARAMS_PATH, translator_values, TranslatorParams
from ..problem import RESIDUAL_KINDS
from ..result import FRAME_NAMES, SolveResult
from ..solver import check_wrench, NO_MOMENT, TranslatorSolver

#: The levels a solve can use.
LEVELS = ('full', 'rod', 'cc', 'linear')

#: Values of the ``fidelity`` parameter: a level, or 'auto' (the error budget decides).
FIDELITIES = LEVELS + ('auto',)

#: Wrench steps of the finite-difference compliance of a reduced level (N, N m).
COMPLIANCE_STEPS = (1e-3, 1e-4)

_DEFAULT = object()

#: stability.load_scale of each parameter set the reduced levels' verdicts used (verdicts.py)
_LOAD_SCALES: Dict[str, float] = {}


class FidelitySolver:
    """
    Solve the translator at a chosen fidelity or within an error budget.

    Same ``solve``/``reset`` interface and SolveResult as TranslatorSolver:

    >>> solver = FidelitySolver(params, max_position_error=1e-3, max_angle_error_deg=0.5)
    >>> result = solver.solve([12.0, 0.0, 0.0])
    >>> result.fidelity                   # the level used, e.g. 'rod'
    """

    def __init__(self, params: Optional[TranslatorParams] = None, fidelity: str = 'auto',
                 max_position_error: float = 0.0, max_angle_error_deg: float = 0.0,
                 rod_steps: int = ROD_STEPS,
                 validation: Any = _DEFAULT,
                 tolerance: float = 1e-10, time_limit_s: float = 10.0,
                 accuracy: Optional[Accuracy] = None) -> None:
        """
        Set up every level for ``params`` (default: config/translator.yaml).

        A zero budget (the default) lets 'auto' use 'full' only. ``validation`` defaults to
        config/fidelity_validation.yaml; data for other parameters count as none.
        ``tolerance``, ``time_limit_s`` and ``accuracy`` (its error target, default the
        shipped YAML's) go to the full model's TranslatorSolver.
        """
        if fidelity not in FIDELITIES:
            raise ValueError(f'fidelity must be one of {FIDELITIES}, got {fidelity!r}')
        for name, value in (('max_position_error', max_position_error),
                            ('max_angle_error_deg', max_angle_error_deg)):
            check_number(name, value, low=0.0)
        if fidelity != 'auto' and (max_position_error > 0.0 or max_angle_error_deg > 0.0):
            raise ValueError(f"an error budget needs fidelity 'auto', got {fidelity!r}")
        self.full = TranslatorSolver(params, tolerance=tolerance, time_limit_s=time_limit_s,
                                     accuracy=accuracy)
        self.params = self.full.params
        self.fidelity = fidelity
        self.max_position_error = float(max_position_error)
        self.max_angle_error_deg = float(max_angle_error_deg)
        self.rod_steps = rod_steps
        self.reduced = {'cc': ReducedModel.constant_curvature(self.params),
                        'rod': ReducedModel.equivalent_rod(self.params, rod_steps)}
        self.tangent = TangentModel(self.full.problem)
        if validation is _DEFAULT:
            validation = Validation.load(DEFAULT_VALIDATION_PATH)
        if validation is not None and not validation.matches(self.params, rod_steps):
            validation = None
        self.validation: Optional[Validation] = validation
        self._previous = dict.fromkeys(self.reduced)
        self._last_wrench: Optional[np.ndarray] = None
        self._last_level: Optional[str] = None
        #: the full solutions whose verdicts the reduced levels' answers carry (verdicts.py)
        self.load_scale = self._measure_load_scale() if fidelity != 'full' else math.nan
        self._unloaded_verdict = unloaded_verdict()
        self._full_verdict: Optional[FullVerdict] = None  # of the last full answer
        self._expansion_verdict: Optional[FullVerdict] = None  # of the expansion's solution
        #: the choices, checks and measured costs of 'auto'
        self.auto = AutoFidelity(self)
        self.auto.measure_costs()

    @property
    def time_limit_s(self) -> float:
        """Cap of one solve (s), any level; settable, like TranslatorSolver's."""
        return self.full.time_limit_s

    @time_limit_s.setter
    def time_limit_s(self, value: float) -> None:
        self.full.time_limit_s = value

    @classmethod
    def from_params_file(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH,
                         **options) -> 'FidelitySolver':
        """
        Build from a params file: the model, ``fidelity`` and the budget.

        The budget keys are ``max_position_error`` (m) and ``max_angle_error`` (deg), the
        accuracy target ``accuracy_position_m`` and ``accuracy_angle_deg``; the file
        overrides the shipped config/translator.yaml key by key (``translator_values``).
        """
        values = translator_values(path)
        settings = {'fidelity': values['fidelity'],
                    'max_position_error': values['max_position_error'],
                    'max_angle_error_deg': values['max_angle_error'],
                    'accuracy': Accuracy.from_mapping(values)}
        settings.update(options)
        return cls(TranslatorParams.from_yaml(path), **settings)

    def reset(self) -> None:
        """Forget every previous solution and the cached tangent: the next solve is cold."""
        self.full.reset()
        self.tangent.clear()
        self._previous = dict.fromkeys(self.reduced)
        self._last_wrench = None
        self._last_level = None
        self._full_verdict = self._expansion_verdict = None
        self.auto.reset()

    def _measure_load_scale(self) -> float:
        """stability.load_scale of the full model (once per parameter set), the solver reset."""
        key = f'{self.params!r} {self.full.tolerance!r}'
        if key not in _LOAD_SCALES:
            unloaded = self.full.solve(np.zeros(3))
            self.full.reset()
            if not unloaded.converged:
                raise ArithmeticError(f'the unloaded translator does not solve: '
                                      f'{unloaded.message}')
            _LOAD_SCALES[key] = load_scale_at(self.full.problem,
                                              unloaded.unknowns / self.full.problem.x_scale)
        return _LOAD_SCALES[key]

    # stability verdicts of the reduced levels (verdicts.py) -------------------------------------
    def verdict_references(self) -> List[FullVerdict]:
        """Return the full solutions whose verdicts a reduced answer may carry (verdicts.py)."""
        references = [self._unloaded_verdict]
        for reference in (self._expansion_verdict, self._full_verdict):
            if reference is not None:
                references.append(reference)
        return references

    def carried_verdict(self, wrench: np.ndarray) -> Optional[FullVerdict]:
        """Return the full solution whose verdict an answer at ``wrench`` carries (None: none)."""
        return carried(wrench, self.verdict_references(), self.load_scale,
                       self.params.stack_height)

    def note_full_answer(self, wrench: np.ndarray, stable: Optional[bool],
                         margin: float) -> None:
        """
        Keep the verdict of a full answer at ``wrench`` (none kept when it has none).

        Kept: the expansions' solutions and the full answers 'auto' gives for a verdict
        (``AutoFidelity.solve``): answers a batch gives alike, row by row.
        """
        if stable is not None:
            self._full_verdict = FullVerdict(
                wrench.copy(), bool(stable), float(margin),
                f'the last full answer, at {np.round(wrench, 4).tolist()}')

    # level choice -----------------------------------------------------------------------------
    def choose(self, wrench: np.ndarray) -> Tuple[str, str]:
        """
        Return (level, reason) for ``wrench``: the fixed level, or the validated choice.

        The validated choice is the cheapest level whose validated error meets the budget
        (``AutoFidelity.validated_choice``); 'auto' solves start there and widen the
        'linear' level's range by checks (``fidelity.auto``).
        """
        if self.fidelity != 'auto':
            return self.fidelity, f'fidelity fixed to {self.fidelity}'
        return self.auto.validated_choice(wrench)

    # solving --------------------------------------------------------------------------------
    def solve(self, force: ArrayLike, moment: ArrayLike = NO_MOMENT,
              warm_start: bool = True, compliance: bool = False,
              **compliance_options: float) -> SolveResult:
        """
        Solve for an end-disk wrench (N, N m, in {pe} at the end-disk centre).

        ``compliance``: 'full' gives the implicit compliance, 'linear' the cached
        solution's, 'cc' and 'rod' central differences of their own solves.
        """
        wrench = check_wrench(force, moment)
        if not warm_start:
            self.reset()
        if self.fidelity == 'auto':
            return self.auto.solve(wrench, compliance, compliance_options)
        return self._solve_at(self.fidelity, f'fidelity fixed to {self.fidelity}', wrench,
                              compliance, compliance_options)

    @one_blas_thread
    def solve_many(self, forces: ArrayLike, moments: Optional[ArrayLike] = None, *,
                   compliance: bool = False) -> BatchResult:
        """
        Solve the rows (N, 3) of ``forces`` and ``moments`` (default none) in order.

        The rows equal N consecutive ``solve`` calls, and the solver is left as they would
        leave it; a run of rows at one reduced level goes to that level's compiled sequence
        (``batch_rows.solve_run``), which writes the pose columns without a SolveResult. A
        failing row is flagged, not raised (TranslatorSolver.solve_many).
        """
        wrenches = check_wrenches(forces, moments)
        batch = BatchResult.empty(wrenches, compliance)
        if self.fidelity == 'auto':
            self.auto.solve_many(wrenches, batch, compliance)
            return batch
        reason = f'fidelity fixed to {self.fidelity}'
        if not len(wrenches):
            return batch
        first = 0
        if self.fidelity == 'linear' and not self.tangent.ready:
            # the first row makes the expansion the others use
            batch_rows.solve_run(self, 'linear', reason, wrenches, range(1), batch, compliance)
            first = 1
        batch_rows.solve_run(self, self.fidelity, reason, wrenches, range(first, len(wrenches)),
                             batch, compliance)
        return batch

    def _solve_at(self, level: str, reason: str, wrench: np.ndarray, compliance: bool,
                  compliance_options: dict,
                  estimate: Optional[np.ndarray] = None) -> SolveResult:
        """
        Solve at the chosen ``level`` (for ``reason``, which ends the message).

        ``estimate``: the reduced answer's error (m, deg) as 'auto' validated or checked it,
        which the result then carries with the verdict on the budget; None: not estimated.
        """
        if level == 'linear' and not self.tangent.ready:
            result = self.cache_full_solution(wrench, compliance, **compliance_options)
            result.message += '; linear level: no cached solution yet, solved in full'
        elif level == 'full':
            result = self._solve_full(wrench, compliance, compliance_options)
        elif level == 'linear':
            result = self._solve_linear(wrench, compliance, compliance_options)
        else:
            result = self._solve_reduced(level, wrench, compliance, compliance_options)
        if result.fidelity != 'full' and result.converged:
            self._judge_reduced(result, wrench, estimate)
        result.message += f' [{result.fidelity}: {reason}]'
        self._last_wrench = wrench
        self._last_level = result.fidelity
        return result

    def _judge_reduced(self, result: SolveResult, wrench: np.ndarray,
                       estimate: Optional[np.ndarray]) -> None:
        """Give a converged reduced answer its carried verdict and its estimate (if any)."""
        reference = self.carried_verdict(wrench)
        if reference is not None:
            result.stable, result.stability_margin = reference.stable, reference.margin
        result.message += note(result.fidelity, reference)
        if estimate is not None:
            result.error_estimate_m, result.error_estimate_deg = float(estimate[0]), float(
                estimate[1])
            result.accuracy_met = bool(estimate[0] <= self.max_position_error
                                       and estimate[1] <= self.max_angle_error_deg)

    def cache_full_solution(self, wrench: np.ndarray, compliance: bool = False,
                            **compliance_options: float) -> SolveResult:
        """Solve the full model at ``wrench`` and expand the linear level about it."""
        started = time.perf_counter()
        # warm start, compliance and verify given by position: the options are only floats
        result = self.full.solve(wrench[:3], wrench[3:], True, compliance, False,
                                 **compliance_options)
        self.note_full_answer(wrench, result.stable, result.stability_margin)
        if result.converged:
            try:
                self.tangent.build(result.unknowns / self.full.problem.x_scale, wrench)
            except ArithmeticError as error:
                self.tangent.clear()
                self._expansion_verdict = None
                result.message += f'; no linear expansion here: {error}'
            else:
                self._expansion_verdict = None if result.stable is None else FullVerdict(
                    wrench.copy(), bool(result.stable), float(result.stability_margin),
                    f"the linear level's expansion point {self.tangent.origin_text}")
        result.solve_time_s = time.perf_counter() - started
        return result

    def _solve_full(self, wrench: np.ndarray, compliance: bool,
                    compliance_options: dict) -> SolveResult:
        """Solve the full model (an expansion about it, if 'auto' wants one: fidelity.auto)."""
        return self.full.solve(wrench[:3], wrench[3:], compliance=compliance,
                               **compliance_options)

    def _solve_linear(self, wrench: np.ndarray, compliance: bool,
                      compliance_options: dict) -> SolveResult:
        """Return the expansion's frames; its unknowns, points and dictionaries when read."""
        started = time.perf_counter()
        frames = self.tangent.frames(wrench)
        elapsed = time.perf_counter() - started
        unknowns, points = self.tangent.unknowns_and_points(wrench)
        offset = max(map(abs, (wrench - self.tangent.origin).tolist()))
        # the level solves no equations: its residual is zero by construction
        result = SolveResult.deferred(
            {'frames': lambda: dict(zip(FRAME_NAMES, frames)), 'backbones': points,
             'unknowns': unknowns,
             'residual_by_type': lambda: dict.fromkeys(RESIDUAL_KINDS, 0.0)},
            converged=True, message=f'first-order expansion about the full solution at '
            f'{self.tangent.origin_text} (largest offset {offset:.3g})', iterations=0,
            residual_norm=0.0, force=wrench[:3].copy(), moment=wrench[3:].copy(),
            solve_time_s=elapsed, method='fast', fidelity='linear')
        if compliance:
            result.compliance = self.tangent.compliance(**compliance_options)
        return result

    def _solve_reduced(self, level: str, wrench: np.ndarray, compliance: bool,
                       compliance_options: dict) -> SolveResult:
        outcome, elapsed = self._reduced_outcome(level, wrench)
        result = self._reduced_result(level, outcome, wrench, elapsed)
        if compliance and outcome.converged:
            result.compliance, failure = self._reduced_compliance(level, outcome, wrench,
                                                                  compliance_options)
            result.message += failure
        return result

    def _reduced_outcome(self, level: str, wrench: np.ndarray) -> Tuple[ReducedOutcome, float]:
        """Solve a reduced level from its last solution (or unloaded); (outcome, time)."""
        model = self.reduced[level]
        started = time.perf_counter()
        start = self._previous[level]
        if start is not None and box_scale(wrench - start[1]) > box_scale(wrench):
            start = None  # the unloaded state is nearer than the last solution
        outcome = model.solve(wrench, start, started + self.time_limit_s)
        if not outcome.converged and start is not None:
            # the warm start may sit too far away: restart from the unloaded state
            restart = model.solve(wrench, None, started + self.time_limit_s)
            restart.iterations += outcome.iterations
            if restart.converged:
                outcome = restart
        elapsed = time.perf_counter() - started
        if outcome.converged:
            self._previous[level] = (outcome.x, wrench)
        return outcome, elapsed

    def _reduced_result(self, level: str, outcome: ReducedOutcome, wrench: np.ndarray,
                        elapsed: float) -> SolveResult:
        """Return a reduced solve's result; its shape and residual dictionary made when read."""
        model, x, rs = self.reduced[level], outcome.x, outcome.rs
        return SolveResult.deferred(
            {'frames': lambda: dict(zip(FRAME_NAMES, model.frames(x, wrench))),
             'backbones': lambda: model.points(x, wrench),
             'residual_by_type': lambda: model.residual_by_kind(rs)},
            converged=outcome.converged, message=outcome.message,
            iterations=outcome.iterations, residual_norm=float(np.sqrt(rs @ rs)),
            force=wrench[:3].copy(), moment=wrench[3:].copy(), solve_time_s=elapsed,
            method='fast', unknowns=x * model.unknown_scale, fidelity=level)

    def _reduced_compliance(self, level: str, outcome: ReducedOutcome, wrench: np.ndarray,
                            options: dict) -> Tuple[Optional[ComplianceAnalysis], str]:
        """(compliance of a converged reduced solve, or None and the message tail saying why)."""
        model = self.reduced[level]
        try:
            analysis: Optional[ComplianceAnalysis] = _reduced_compliance(
                model, outcome.x, wrench, self.params.stack_height, options)
            failure = ''
        except ArithmeticError as error:
            analysis, failure = None, f'; no compliance: {error}'
        self._previous[level] = (outcome.x, wrench)  # the differences moved the model
        return analysis, failure


def _reduced_compliance(model: ReducedModel, x: np.ndarray, wrench: np.ndarray,
                        characteristic_length: float,
                        options: dict) -> ComplianceAnalysis:
    """Compliance of a reduced level by central differences of its own solves."""
    started = time.perf_counter()
    matrix = np.empty((6, 6))
    deadline = started + 10.0
    for column in range(6):
        offset = np.zeros(6)
        offset[column] = COMPLIANCE_STEPS[column // 3]
        ends = []
        for sign in (1.0, -1.0):
            outcome = model.solve(wrench + sign * offset, (x, wrench), deadline)
            if not outcome.converged:
                raise ArithmeticError(f'{model.name} compliance solve failed: {outcome.message}')
            ends.append(model.frames(outcome.x, wrench + sign * offset)[3])
        matrix[:, column] = frame_twist(ends[1], ends[0]) / (2.0 * offset[column])
    return analyse(matrix, characteristic_length, method=f'{model.name} finite differences',
                   time_s=time.perf_counter() - started, **options)
