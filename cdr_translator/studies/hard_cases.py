"""
The hard-case suite: loads at the edges of the translator's range, solved, verified, judged.

Every case is a sequence of end-disk wrenches solved in order with one solver, the first
from the unloaded state, the rest warm-started (load reversals, jumps), optionally on
changed parameters (short/long tube, soft/stiff material, more spacer disks). Each
converged solve is re-checked by :mod:`cdr_translator.solve.verify`; the last one is also
judged for stability (:func:`stability`). When a converged state fails verification only
through discretization error, :func:`run_case` can re-solve it on a finer grid
(warm-started from the coarse solution) until it verifies.

Axial buckling lives in :mod:`cdr_translator.studies.buckling` and the Markdown report in
:mod:`cdr_translator.studies.hard_case_report`. ``bench/hard_cases.py`` runs it all and
writes bench/results/hard_cases.md;
``tests/studies/test_hard_cases.py`` runs the quick cases.
"""

from dataclasses import dataclass
import math
from typing import Any, List, Optional, Tuple

import numpy as np

from .finite_difference import finite_difference_compliance
from ..analysis.compliance import analyse
from ..params.translator_params import Accuracy, TranslatorParams
from ..solve.result import SolveResult
from ..solve.solver import TranslatorSolver
from ..solve.verify import Verification, verify

#: Time cap of one solve in the suite (s); also the documented worst case of a case step.
CASE_TIME_LIMIT_S = 20.0

#: The finest discretization (RK4 steps per disk interval) a re-solve may use.
MAX_STEPS_PER_SEGMENT = 1024

#: What a solve's message says when the solver's fallback continuation found it.
TRACKED = 'fallback continuation'

#: Checks whose failure no refinement of the discretization can cure.
DISCRETIZATION_FREE_CHECKS = ('global_force_n', 'global_moment_nm')

Wrench = Tuple[Tuple[float, float, float], Tuple[float, float, float]]


def load(fx: float = 0.0, fy: float = 0.0, fz: float = 0.0, mx: float = 0.0,
         my: float = 0.0, mz: float = 0.0) -> Wrench:
    """Return a wrench (force N, moment N m) in {pe} at the end-disk centre."""
    return ((float(fx), float(fy), float(fz)), (float(mx), float(my), float(mz)))


@dataclass(frozen=True)
class HardCase:
    """
    One case: ``loads`` solved in order (first cold, then warm) with changed parameters.

    ``quick`` cases run in ``make test``; the rest only in ``make hard-cases``.
    """

    name: str
    group: str
    loads: Tuple[Wrench, ...]
    params: Tuple[Tuple[str, Any], ...] = ()
    quick: bool = True


def _directions() -> List[np.ndarray]:
    """Return 14 unit vectors: the 6 axis directions and the 8 cube diagonals."""
    axes = [sign * np.eye(3)[k] for k in range(3) for sign in (1.0, -1.0)]
    diagonals = [np.array([sx, sy, sz]) / math.sqrt(3.0)
                 for sx in (1.0, -1.0) for sy in (1.0, -1.0) for sz in (1.0, -1.0)]
    return axes + diagonals


def _combined_cases() -> List[HardCase]:
    """Force 30 N along each direction with 0.3 N m about the next direction in the list."""
    directions = _directions()
    cases = []
    for k, direction in enumerate(directions):
        moment = directions[(k + 5) % len(directions)]
        cases.append(HardCase(
            f'30 N along ({", ".join(f"{c + 0.0:+.2f}" for c in direction)}) + 0.3 N m',
            'combined', (load(*(30.0 * direction), *(0.3 * moment)),), quick=k % 3 == 0))
    return cases


def cases() -> List[HardCase]:
    """Return the whole suite, in report order."""
    ramp = tuple(load(1e-3, 0.0, -force) for force in np.arange(5.0, 50.0, 5.0))
    return [
        HardCase('lateral 12 N (Table II)', 'lateral', (load(12.0),)),
        HardCase('lateral 60 N', 'lateral', (load(60.0),)),
        HardCase('lateral 230 N', 'lateral', (load(230.0),), quick=False),
        HardCase('lateral 500 N', 'lateral', (load(500.0),), quick=False),
        HardCase('diagonal 80 N at 45 deg', 'lateral', (load(56.57, 56.57),), quick=False),
        HardCase('PJ past 90 deg: 100 N out, 100 N down', 'lateral',
                 (load(100.0, 0.0, -100.0),)),
        HardCase('PJ past 100 deg: 200 N out, 400 N down', 'lateral',
                 (load(200.0, 0.0, -400.0),), quick=False),
        HardCase('compression 15 N (half the buckling load)', 'compression',
                 (load(fz=-15.0),)),
        HardCase('compression 44 N, perfect (straight past buckling)', 'compression',
                 (load(fz=-44.0),)),
        HardCase('compression ramp 5..45 N, 1 mN lateral imperfection', 'compression',
                 ramp, quick=False),
        HardCase('post-buckled 44 N toward a secondary (2 N along x, compress, release)',
                 'compression', (load(2.0), load(2.0, 0.0, -44.0), load(fz=-44.0))),
        HardCase('post-buckled 44 N from a 17 deg imperfection (ends on the diagonal)',
                 'compression', (load(1.91, 0.59), load(1.91, 0.59, -44.0), load(fz=-44.0))),
        HardCase('tension 2000 N', 'compression', (load(fz=2000.0),)),
        HardCase('torsion 1 N m', 'torsion', (load(mz=1.0),)),
        HardCase('torsion 10 N m', 'torsion', (load(mz=10.0),)),
        HardCase('torsion 20 N m', 'torsion', (load(mz=20.0),), quick=False),
        HardCase('torsion 40 N m', 'torsion', (load(mz=40.0),), quick=False),
        *_combined_cases(),
        HardCase('reversal +40 N -> -40 N lateral', 'reversal', (load(40.0), load(-40.0))),
        HardCase('reversal +100 N -> -100 N lateral', 'reversal',
                 (load(100.0), load(-100.0)), quick=False),
        HardCase('reversal of a combined wrench', 'reversal',
                 (load(15.0, -8.0, 5.0, 0.2, 0.1, -0.1),
                  load(-15.0, 8.0, -5.0, -0.2, -0.1, 0.1))),
        HardCase('reversal +10 N m -> -10 N m torsion', 'reversal',
                 (load(mz=10.0), load(mz=-10.0))),
        HardCase('zero load', 'tiny', (load(),)),
        HardCase('1e-9 N lateral', 'tiny', (load(1e-9),)),
        HardCase('1e-9 N / 1e-12 N m mixed', 'tiny',
                 (load(1e-9, -1e-9, 1e-9, 1e-12, -1e-12, 1e-12),)),
        HardCase('zero after 100 N (warm)', 'tiny', (load(100.0), load())),
        HardCase('jumps: 0, 100 N, small, 60 N down-out, 0, torsion', 'jumps',
                 (load(), load(100.0), load(-5.0, 3.0, -2.0), load(60.0, 0.0, -60.0),
                  load(), load(-3.0, 2.0, 0.0, 0.0, 0.0, 5.0))),
        HardCase('jumps between opposite corners, 20 N + 0.2 N m', 'jumps',
                 (load(20.0, 20.0, -20.0, 0.2, 0.2, 0.2),
                  load(-20.0, -20.0, 20.0, -0.2, -0.2, -0.2),
                  load(20.0, -20.0, 20.0, 0.2, -0.2, 0.2))),
        HardCase('short tube (20 mm), 12 N and 60 N', 'parameters',
                 (load(12.0), load(60.0)), (('tube_length', 0.02),)),
        HardCase('long tube (500 mm), 12 N', 'parameters', (load(12.0),),
                 (('tube_length', 0.5),)),
        HardCase('soft material (E 10 GPa), 12 N', 'parameters', (load(12.0),),
                 (('youngs_modulus', 1e10),)),
        HardCase('stiff material (E 210 GPa), 20 N', 'parameters', (load(20.0),),
                 (('youngs_modulus', 2.1e11),)),
        HardCase('thin backbones (0.6 mm), 3 N', 'parameters', (load(3.0),),
                 (('backbone_diameter', 0.0006),)),
        HardCase('3 spacer disks per joint, 20 N', 'parameters', (load(20.0),),
                 (('spacers_per_joint', 3),)),
        HardCase('5 spacer disks per joint, 20 N', 'parameters', (load(20.0),),
                 (('spacers_per_joint', 5),), quick=False),
        HardCase('9 spacer disks per joint, 2 N', 'parameters', (load(2.0),),
                 (('spacers_per_joint', 9),), quick=False),
        HardCase('9 spacer disks per joint, 20 N', 'parameters', (load(20.0),),
                 (('spacers_per_joint', 9),), quick=False),
    ]


@dataclass
class LoadOutcome:
    """
    One solve of a case: the wrench, the solve's numbers, and its verification.

    ``verified_steps`` is the discretization (RK4 steps per disk interval) at which the
    state verified, larger than the case's after a refinement; None if it did not.
    """

    wrench: Wrench
    converged: bool
    iterations: int
    time_s: float
    residual: float
    message: str
    verification: Verification
    verified_steps: Optional[int]
    verification_message: str


@dataclass
class CaseReport:
    """
    Outcome of one case: totals over its solves, the final state, its stability.

    ``steps`` is the case's discretization (RK4 steps per disk interval). ``stable`` is
    None when it is unknown (``stability`` says why).
    """

    case: HardCase
    loads: List[LoadOutcome]
    final: SolveResult
    steps: int
    stable: Optional[bool]
    stability: str

    @property
    def converged(self) -> bool:
        """Whether every solve of the case converged."""
        return all(outcome.converged for outcome in self.loads)

    @property
    def verified_steps(self) -> Optional[int]:
        """Finest discretization any solve needed to verify; None if one did not."""
        steps = [outcome.verified_steps for outcome in self.loads]
        known = [step for step in steps if step is not None]
        return max(known) if known and len(known) == len(steps) else None

    @property
    def verified(self) -> bool:
        """Whether every solve converged and passed verification, maybe on a finer grid."""
        return self.converged and self.verified_steps is not None

    @property
    def iterations(self) -> int:
        """Newton iterations of all solves, failed continuation steps included."""
        return sum(outcome.iterations for outcome in self.loads)

    @property
    def time_s(self) -> float:
        """Wall time of all solves (not of verification, refinement or stability)."""
        return sum(outcome.time_s for outcome in self.loads)

    @property
    def residual(self) -> float:
        """Largest final residual norm (nondimensional) over the solves."""
        return max(outcome.residual for outcome in self.loads)

    @property
    def outcome(self) -> str:
        """One-line verdict for the report."""
        for outcome in self.loads:
            if not outcome.converged:
                return f'not converged: {outcome.message}'
        for outcome in self.loads:
            if outcome.verified_steps is None:
                return f'converged, not verified: {outcome.verification_message}'
        if self.verified_steps != self.steps:
            return f'verified at {self.verified_steps} steps per interval'
        return 'verified'


def study_solver(params: TranslatorParams, path: str = 'default') -> TranslatorSolver:
    """
    Return a solver reporting what it converged to at the case's own discretization.

    No automatic refinement (the suite refines and verifies itself, see ``_refine``) and no
    stable-branch following: the suite studies unstable equilibria too (their ``stable``
    is False in the result and judged here). ``path`` is the solver's (see
    TranslatorSolver).
    """
    return TranslatorSolver(params, time_limit_s=CASE_TIME_LIMIT_S,
                            accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False,
                            path=path)


def stability(solver: TranslatorSolver, result: SolveResult) -> Tuple[Optional[bool], str]:
    """
    Judge whether a converged equilibrium is stable; return (stable or None, reason).

    Two tests, both needed: the end-disk stiffness K = C^-1 (``result.compliance``, or
    central differences of solves where that failed) must have a positive-definite
    symmetric part, and the determinant of the shooting Jacobian
    must keep the sign it has in the unloaded (stable) state. An eigenvalue of the
    structure's stiffness crossing zero anywhere makes the Jacobian singular; an odd number
    of such crossings flips the determinant's sign, which catches internal modes the end
    disk does not feel. A symmetric pair of internal crossings would escape the second test
    (the four-fold symmetry allows one); that limit is stated in
    docs/explanation/solution_quality.md.
    """
    if not result.converged:
        return None, 'not converged'
    analysis = result.compliance
    source = 'end-disk stiffness'
    if analysis is None:  # the implicit computation failed: differences of solves instead
        try:
            analysis = analyse(finite_difference_compliance(solver.params, result.force,
                                                            result.moment),
                               solver.params.stack_height, method='finite differences')
            source = 'end-disk stiffness (from finite differences of solves)'
        except ArithmeticError as error:
            reason = result.message.partition('no compliance: ')[2] or 'not computed'
            return None, f'unknown: implicit compliance: {reason}; finite differences: {error}'
    problem = solver.problem
    wrench = np.concatenate([result.force, result.moment])
    xs = result.unknowns / problem.x_scale
    sign = np.linalg.slogdet(problem.jacobian(xs, wrench, problem.residual(xs, wrench)))[0]
    zero = np.zeros(6)
    straight = problem.straight_guess(zero)
    unloaded = np.linalg.slogdet(
        problem.jacobian(straight, zero, problem.residual(straight, zero)))[0]
    if not analysis.stable:
        return False, (f'{source} not positive definite (smallest eigenvalue '
                       f'{analysis.smallest_stiffness_eigenvalue:.3g})')
    if sign != unloaded:
        return False, 'the Jacobian determinant changed sign: an internal mode is unstable'
    return True, f'{source} positive definite, Jacobian sign as unloaded'


def _refine(params: TranslatorParams, result: SolveResult,
            verification: Verification) -> Tuple[Optional[int], str]:
    """
    Re-solve a converged state on finer grids until it verifies; return (steps, message).

    RK4's error falls as steps^-4, so the next grid is predicted from how far the worst
    check is beyond its limit (with a 1.5 margin), warm-started from the last solution;
    a state the solver's fallback continuation found (its message says so) is re-solved
    by that continuation alone (``path='tracking'``), the first time cold.
    """
    if any(verification.checks[name] > verification.limits[name]
           for name in DISCRETIZATION_FREE_CHECKS):
        return None, _short(verification)
    steps = params.steps_per_segment
    tracked, refined = TRACKED in result.message, False
    while True:
        worst = verification.worst()
        ratio = verification.checks[worst] / verification.limits[worst]
        steps = max(2 * steps, int(math.ceil(steps * (1.5 * ratio) ** 0.25)))
        if steps > MAX_STEPS_PER_SEGMENT:
            return None, (f'{_short(verification)} at {params.steps_per_segment} steps per '
                          f'interval (discretization error)')
        params = params.with_changes(steps_per_segment=steps)
        if tracked:
            # the case's coarse solution is too far from a fine grid's for the shot's
            # sensitivity: the first re-solve follows the load path from the unloaded
            # state, later ones the Newton homotopy from the last fine solution
            solver = study_solver(params, 'tracking')
            solver.start_from(result)
            result = solver.solve(result.force, result.moment, warm_start=refined)
        else:
            solver = study_solver(params)
            solver.start_from(result)
            result = solver.solve(result.force, result.moment)
        if not result.converged:
            return None, f'the re-solve at {steps} steps failed: {result.message}'
        refined = True
        verification = verify(result, params)
        if verification.passed:
            return steps, 'verified'


def run_case(case: HardCase, params: TranslatorParams, refine: bool = False) -> CaseReport:
    """
    Solve, verify and judge one case on ``params`` changed by ``case.params``.

    Every converged solve is verified at the case's discretization; with ``refine`` one
    that fails only through discretization error is re-solved on finer grids.
    """
    params = params.with_changes(**dict(case.params))
    solver = study_solver(params)
    outcomes = []
    for index, (force, moment) in enumerate(case.loads):
        last = index == len(case.loads) - 1
        result = solver.solve(force, moment, warm_start=index > 0, compliance=last)
        verification = verify(result, params)
        steps: Optional[int] = params.steps_per_segment if verification.passed else None
        message = _short(verification)
        if refine and result.converged and not verification.passed:
            steps, message = _refine(params, result, verification)
        outcomes.append(LoadOutcome((force, moment), result.converged, result.iterations,
                                    result.solve_time_s, result.residual_norm,
                                    result.message, verification, steps, message))
    judged, reason = stability(solver, result)
    return CaseReport(case, outcomes, result, params.steps_per_segment, judged, reason)


def _short(verification: Verification) -> str:
    """Say 'verified' or name the worst check against its limit."""
    if verification.passed or not verification.checks:
        return verification.message
    worst = verification.worst()
    return (f'{worst} {verification.checks[worst]:.2g} > {verification.limits[worst]:.2g}'
            if verification.checks[worst] > verification.limits[worst]
            else verification.message)


def run_suite(params: TranslatorParams, quick_only: bool = False,
              refine: bool = False) -> List[CaseReport]:
    """Run every case (or the quick ones) of :func:`cases`."""
    return [run_case(case, params, refine) for case in cases()
            if case.quick or not quick_only]
