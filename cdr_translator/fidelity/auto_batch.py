"""
Batches of the 'auto' fidelity: runs of rows that one compiled call answers, as solves would.

``AutoFidelity.solve`` decides row by row, but two kinds of run can be told in advance from
the wrenches alone, since neither changes the state the decisions read (the expansion, its
trust region, the measured costs):

* rows inside the trust region of the expansion: the expansion's compiled poses
  (``batch_rows.solve_run`` at 'linear');
* rows that ``solve`` answers by a full solve without a new expansion -- no linear answer
  or check is possible, no reduced level is admitted, and an expansion would not pay for
  itself (``AutoFidelity.expansion_pays``) -- and every row of a solver without a budget or
  validation data: the full model's batch rows (``batch_rows.solve_run`` at 'full', whose
  rows equal its single solves).

Every other row is one ``solve``.
"""

import math
from typing import Optional, Tuple, TYPE_CHECKING

import numpy as np

from . import batch_rows
from .validation import box_scale, box_scales
from .verdicts import carried_rows
from ..batch import BatchResult

if TYPE_CHECKING:
    from .auto import AutoFidelity

#: Rows a batch looks ahead at first for a run it can tell in advance.
WINDOW = 16

#: Reasons of 'auto' answers: a linear answer taken unchecked; full answers without an
#: expansion (outside every validated range, nothing cheaper admitted, no budget, no data).
TRUSTED = 'inside the trust region of the expansion about the last full solution'
OUTSIDE = 'wrench outside the validated range'
NO_CHEAPER = 'no cheaper level meets the budget'
NO_BUDGET = 'no error budget'
NO_DATA = 'no validation data for these parameters'
NO_VERDICT = ('no full solution near enough to carry its stability verdict to a cheaper '
              'level here')


def solve_many(auto: 'AutoFidelity', wrenches: np.ndarray, batch: BatchResult,
               compliance: bool) -> None:
    """Solve the rows of ``wrenches`` into ``batch`` as consecutive ``auto.solve`` would."""
    solver = auto.solver

    def _row(batch: BatchResult, row: int, wrench: np.ndarray, compliance: bool) -> float:
        """One row by ``solve``."""
        result = auto.solve(wrench, compliance, {})
        batch.record(row, result)
        return result.solve_time_s

    row = 0
    while row < len(wrenches):
        end = row + trusted_rows(auto, wrenches[row:])
        if end > row:
            origin = solver.tangent.origin
            scales = box_scales(wrenches[row:end] - origin)
            auto.served(float(scales.max()))
            batch_rows.solve_run(solver, 'linear', TRUSTED, wrenches, range(row, end),
                                 batch, compliance, auto.curvature * scales[:, None] ** 2)
            row = end
            continue
        count, level = reduced_rows(auto, wrenches[row:], compliance)
        if count:
            assert solver.validation is not None  # reduced_rows needs the data
            estimates = solver.validation.levels[level].errors_at(
                box_scales(wrenches[row:row + count]))
            row += batch_rows.reduced_run_to_failure(solver, level, wrenches,
                                                     range(row, row + count), batch, estimates)
            if row < len(wrenches):  # the row that failed there (or the next): by solve
                batch.run(row, _row, wrenches[row], compliance)
                row += 1
            continue
        count, reason = full_rows(auto, wrenches[row:])
        if count:
            batch_rows.solve_run(solver, 'full', reason, wrenches, range(row, row + count),
                                 batch, compliance)
            row += count
            continue
        batch.run(row, _row, wrenches[row], compliance)
        row += 1


def _runs(wrenches: np.ndarray, taken) -> int:
    """
    How many leading rows of ``wrenches`` ``taken(part, first)`` takes.

    Looked at in windows that double from WINDOW rows, so that a batch whose runs are short
    does not measure every later row at every run; ``first`` is the part's first row.
    """
    count, window = 0, WINDOW
    while count < len(wrenches):
        part = wrenches[count:count + window]
        accepted = taken(part, count)
        if not accepted.all():
            return count + int(np.argmin(accepted))
        count, window = count + len(part), 2 * window
    return count


def covered(auto: 'AutoFidelity', wrenches: np.ndarray) -> np.ndarray:
    """Per row: whether a full solution's verdict reaches it (FidelitySolver.carried_verdict)."""
    solver = auto.solver
    return carried_rows(wrenches, solver.verdict_references(), solver.load_scale,
                        solver.params.stack_height) >= 0


def trusted_rows(auto: 'AutoFidelity', wrenches: np.ndarray) -> int:
    """How many leading rows of ``wrenches`` ``auto.solve`` answers by the expansion, unchecked."""
    origin = auto.solver.tangent.origin
    if origin is None or box_scale(origin) > 1.0:
        return 0

    def taken(part: np.ndarray, first: int) -> np.ndarray:
        scales = box_scales(part - origin)
        return ((box_scales(part) <= 1.0) & (scales <= auto.trusted)
                & auto.within_linear_target(scales) & covered(auto, part))

    return _runs(wrenches, taken)


def _stepped(auto: 'AutoFidelity', wrenches: np.ndarray, first: int, part: np.ndarray,
             alternative: Optional[float]) -> np.ndarray:
    """
    Per row of ``part`` (rows ``first`` on of ``wrenches``): whether an expansion pays there.

    As ``AutoFidelity._expansion_pays`` decides after the row before it (the solver's last
    wrench for the first row) with the state unchanged; rows outside the box count too.
    """
    before = wrenches[first - 1] if first else auto.solver._last_wrench
    if before is None:  # the first solve of a solver: no step, no expansion
        expands = np.zeros(len(part), bool)
        expands[1:] = auto.expansion_pays_at(box_scales(np.diff(part, axis=0)), alternative)
        return expands
    return auto.expansion_pays_at(box_scales(part - np.vstack([before, part[:-1]])),
                                  alternative)


def reduced_rows(auto: 'AutoFidelity', wrenches: np.ndarray, compliance: bool
                 ) -> Tuple[int, str]:
    """
    (count, level): the leading rows ``auto.solve`` first tries at one reduced level.

    Told in advance only without an expansion (nothing can refute a reduced answer then)
    and for compiled runs; each row is taken while that level answers it (the run stops
    at a row it fails, which ``solve`` then answers by the next level).
    """
    solver = auto.solver
    if (solver.tangent.ready or compliance or not batch_rows.compiled_runs(solver)
            or not auto.costs):
        return 0, ''
    reaches = auto.reaches()
    levels = [level for level in sorted(('cc', 'rod'), key=auto.costs.__getitem__)
              if not math.isnan(reaches.get(level, -math.inf))]
    scale = box_scale(wrenches[0])
    chosen = next((level for level in levels if scale <= reaches.get(level, -math.inf)), None)
    if len(levels) < 2 or chosen is None or scale > 1.0:
        return 0, ''
    cheaper = levels[:levels.index(chosen)]

    def taken(part: np.ndarray, first: int) -> np.ndarray:
        scales = box_scales(part)
        admitted = (scales <= 1.0) & (scales <= reaches[chosen])
        for level in cheaper:
            admitted &= scales > reaches[level]
        return (admitted & ~_stepped(auto, wrenches, first, part, auto.costs[chosen])
                & covered(auto, part))

    return _runs(wrenches, taken), chosen


def full_rows(auto: 'AutoFidelity', wrenches: np.ndarray) -> Tuple[int, str]:
    """
    (count, reason): the leading rows ``auto.solve`` answers by a full solve, as it is.

    The rows share the reason their full answers give; 0 when the first row may be
    answered otherwise, or its decision is not one this tells in advance (bounds that do
    not grow with the box scale).
    """
    solver = auto.solver
    level, reason = auto.validated_choice(wrenches[0])
    if reason in (NO_BUDGET, NO_DATA):
        return len(wrenches), reason
    reaches = auto.reaches()
    if any(math.isnan(reaches.get(level, -math.inf)) for level in ('cc', 'rod')):
        return 0, ''
    origin = solver.tangent.origin
    outside = box_scale(wrenches[0]) > 1.0

    def taken(part: np.ndarray, first: int) -> np.ndarray:
        scales = box_scales(part)
        inside = scales <= 1.0
        answered = inside & (scales <= max(reaches.get('cc', -math.inf),
                                           reaches.get('rod', -math.inf)))
        if origin is not None and box_scale(origin) <= 1.0:
            answered |= inside & auto.within_linear_target(box_scales(part - origin))
        expands = _stepped(auto, wrenches, first, part, None)
        return ~answered & ~(expands & inside) & (~inside if outside else inside)

    return _runs(wrenches, taken), OUTSIDE if outside else NO_CHEAPER
