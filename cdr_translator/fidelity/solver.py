"""
FidelitySolver: one solve interface over every fidelity level, and the error budget.

Levels: 'full' (TranslatorSolver, the paper's model), 'rod' (equivalent rod, 7 unknowns),
'cc' (constant-curvature virtual work, 8), 'linear' (first-order expansion about a cached
full solution), each behind the level protocol (``fidelity.level``). 'auto' picks, for each
wrench, the cheapest level that meets the budget (``max_position_error`` m,
``max_angle_error_deg`` deg) by its validated error (``fidelity.validation``), the errors
it checks as it goes and the costs it measures (``fidelity.auto``), and falls back to
'full' outside every validated range. Every result says which level produced it
(``result.fidelity``) and why (``result.message``), how stable and how accurate it is, or
that it was not assessed (``fidelity.verdicts``).
"""

from pathlib import Path
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from . import auto_runs
from .auto import AutoFidelity
from .full_level import FullLevel
from .level import Asked, Level
from .linear import TangentModel
from .linear_level import LinearLevel
from .reduced import ReducedModel, ROD_STEPS
from .reduced_level import ReducedLevel
from .validation import DEFAULT_VALIDATION_PATH, Validation
from .verdicts import Judge, load_scale_at, unloaded_verdict
from .._blas import one_blas_thread
from ..analysis.compliance import ComplianceAnalysis
from ..checks import check_number
from ..params.translator_params import (Accuracy, DEFAULT_PARAMS_PATH, translator_values,
                                        TranslatorParams)
from ..solve.batch import BatchResult, check_wrenches
from ..solve.result import SolveResult
from ..solve.solver import check_wrench, NO_MOMENT, TranslatorSolver

#: The levels a solve can use.
LEVELS = ('full', 'rod', 'cc', 'linear')

#: Values of the ``fidelity`` parameter: a level, or 'auto' (the error budget decides).
FIDELITIES = LEVELS + ('auto',)

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
        self.rod_steps = rod_steps
        #: the reduced models of 'cc' and 'rod'
        self.reduced = {'cc': ReducedModel.constant_curvature(self.params),
                        'rod': ReducedModel.equivalent_rod(self.params, rod_steps)}
        self._linear = LinearLevel(self.full)
        #: the levels by name (fidelity.level's protocol)
        self.levels: Dict[str, Level] = {
            'full': FullLevel(self.full), 'linear': self._linear,
            **{name: ReducedLevel(model, self.params.stack_height)
               for name, model in self.reduced.items()}}
        if validation is _DEFAULT:
            validation = Validation.load(DEFAULT_VALIDATION_PATH)
        if validation is not None and not validation.matches(self.params, rod_steps):
            validation = None
        self.validation: Optional[Validation] = validation
        #: w* (stability.load_scale): how far a full solution's verdict reaches (verdicts.py)
        self.load_scale = self._measure_load_scale() if fidelity != 'full' else float('nan')
        self._unloaded = unloaded_verdict()
        self._judge_of: Tuple[object, ...] = ()
        self._judge = Judge.of((self._unloaded,), self.load_scale, self.params.stack_height)
        #: the choices, checks and measured costs of 'auto', with its memory
        self.auto = AutoFidelity(self.levels, self._linear, self.full, validation,
                                 float(max_position_error), float(max_angle_error_deg),
                                 self.load_scale)
        if fidelity == 'auto':
            self.auto.measure_costs(self.reset,
                                    f'{self.params!r} {rod_steps} {self.full.tolerance!r}')

    @property
    def tangent(self) -> TangentModel:
        """Return the 'linear' level's expansion (its cached full solution, sensitivities)."""
        return self._linear.tangent

    @property
    def max_position_error(self) -> float:
        """Position budget (m) of 'auto' (0: none)."""
        return self.auto.max_position_error

    @property
    def max_angle_error_deg(self) -> float:
        """Angle budget (deg) of 'auto' (0: none)."""
        return self.auto.max_angle_error_deg

    @property
    def time_limit_s(self) -> float:
        """Cap of one solve (s), any level; settable, like TranslatorSolver's."""
        return self.full.time_limit_s

    @time_limit_s.setter
    def time_limit_s(self, value: float) -> None:
        self.full.time_limit_s = value

    @classmethod
    def from_params_file(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH,
                         **options: Any) -> 'FidelitySolver':
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
        """Forget every previous solution and the expansion: the next solve is cold."""
        for level in self.levels.values():
            level.reset()
        self.auto.reset()

    def _measure_load_scale(self) -> float:
        """Return stability.load_scale of the full model (once per parameter set), reset."""
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

    # level choice -----------------------------------------------------------------------------
    def choose(self, wrench: np.ndarray) -> Tuple[str, str]:
        """
        Return (level, reason) for ``wrench``: the fixed level, or the validated choice.

        The validated choice is the cheapest level whose validated error meets the budget
        (``AutoFidelity.validated_choice``); 'auto' solves start there, answer in full
        where no full solution's stability verdict reaches a cheaper answer, and widen the
        'linear' level's range by checks (``fidelity.auto``).
        """
        if self.fidelity != 'auto':
            return self.fidelity, f'fidelity fixed to {self.fidelity}'
        return self.auto.validated_choice(wrench)

    # solving --------------------------------------------------------------------------------
    def _asked(self) -> Asked:
        """Return what a fixed level is asked: its reason, the verdicts at hand, the limit."""
        at_hand = (self._linear.verdict,)
        if at_hand != self._judge_of:
            self._judge_of = at_hand
            self._judge = Judge.of((self._unloaded,) + at_hand, self.load_scale,
                                   self.params.stack_height)
        return Asked(f'fidelity fixed to {self.fidelity}', self._judge, self.full.time_limit_s)

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
        return self.levels[self.fidelity].solve(wrench, compliance, compliance_options,
                                                self._asked())

    @one_blas_thread
    def solve_many(self, forces: ArrayLike, moments: Optional[ArrayLike] = None, *,
                   compliance: bool = False) -> BatchResult:
        """
        Solve the rows (N, 3) of ``forces`` and ``moments`` (default none) in order.

        The rows equal N consecutive ``solve`` calls, and the solver is left as they would
        leave it; a run of rows at one level goes to that level's ``solve_many`` (compiled
        where the level has a compiled sequence), which writes the pose columns without a
        SolveResult. A failing row is flagged, not raised (TranslatorSolver.solve_many).
        """
        wrenches = check_wrenches(forces, moments)
        batch = BatchResult.empty(wrenches, compliance)
        if self.fidelity == 'auto':
            auto_runs.solve_many(self.auto, wrenches, batch, compliance)
            return batch
        if not len(wrenches):
            return batch
        level = self.levels[self.fidelity]
        first = 0
        if self.fidelity == 'linear' and not self._linear.ready:
            # the first row makes the expansion the others use
            first = level.solve_many(wrenches, range(1), batch, compliance, self._asked())
        level.solve_many(wrenches, range(first, len(wrenches)), batch, compliance,
                         self._asked())
        return batch

    def cache_full_solution(self, wrench: np.ndarray, compliance: bool = False,
                            **compliance_options: float) -> SolveResult:
        """Solve the full model at ``wrench`` and expand the linear level about it."""
        return self._linear.expand(wrench, compliance, compliance_options)

    def compliance(self, answer: SolveResult, **options: float) -> ComplianceAnalysis:
        """Return the end-disk compliance of a converged ``answer`` by the level that gave it."""
        return self.levels[answer.fidelity].compliance(answer, options)
