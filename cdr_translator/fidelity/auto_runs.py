"""
Batches of the 'auto' fidelity: runs of rows that one level answers in one call, as solves would.

``AutoFidelity.solve`` decides row by row, but three kinds of run can be told in advance
from the wrenches alone, since none changes the state the decisions read (the expansion,
its trust region, the verdicts at hand, the measured costs):

* rows inside the trust region of the expansion: the 'linear' level's compiled poses;
* without an expansion, rows that one reduced level is the first choice for: its compiled
  sequence, up to the first row it fails;
* rows that ``solve`` answers by a full solve without a new expansion -- no linear answer
  or check is possible, no reduced level is admitted, and an expansion would not pay for
  itself (``AutoFidelity.expansion_pays_at``) -- and every row of a solver without a budget
  or validation data: the full level's rows, which equal its single solves.

Every other row is one ``solve``. The runs go through ``AutoFidelity.run`` (the level's
``solve_many``), which keeps the policy's memory as the single answers would.
"""

import math
from typing import Callable, Optional, Tuple

import numpy as np

from .admission import NO_BUDGET, NO_DATA, OUTSIDE
from .auto import AutoFidelity, NO_CHEAPER, TRUSTED
from .reduced_level import compiled_runs
from .validation import box_scale, box_scales
from .verdicts import Judge
from ..solve.batch import BatchResult

#: Rows a batch looks ahead at first for a run it can tell in advance.
WINDOW = 16


def solve_many(auto: AutoFidelity, wrenches: np.ndarray, batch: BatchResult,
               compliance: bool) -> None:
    """Solve the rows of ``wrenches`` into ``batch`` as consecutive ``auto.solve`` would."""
    def _row(batch: BatchResult, row: int, wrench: np.ndarray, compliance: bool) -> float:
        """One row by ``solve``."""
        result = auto.solve(wrench, compliance, {})
        batch.record(row, result)
        return result.solve_time_s

    row = 0
    while row < len(wrenches):
        end = row + trusted_rows(auto, wrenches[row:])
        if end > row:
            scales = box_scales(wrenches[row:end] - auto.linear.tangent.origin)
            auto.served(float(scales.max()))
            auto.run('linear', TRUSTED, wrenches, range(row, end), batch, compliance,
                     auto.curvature * scales[:, None] ** 2)
            row = end
            continue
        count, level = reduced_rows(auto, wrenches[row:], compliance)
        if count:
            assert auto.validation is not None  # reduced_rows needs the data
            estimates = auto.validation.levels[level].errors_at(
                box_scales(wrenches[row:row + count]))
            row += auto.run(level, '', wrenches, range(row, row + count), batch, False,
                            estimates, stop_at_failure=True)
            if row < len(wrenches):  # the row that failed there (or the next): by solve
                batch.run(row, _row, wrenches[row], compliance)
                row += 1
            continue
        count, reason = full_rows(auto, wrenches[row:])
        if count:
            auto.run('full', reason, wrenches, range(row, row + count), batch, compliance)
            row += count
            continue
        batch.run(row, _row, wrenches[row], compliance)
        row += 1


def _runs(wrenches: np.ndarray, taken: Callable[[np.ndarray, int], np.ndarray],
          first_taken: Callable[[np.ndarray], bool]) -> int:
    """
    How many leading rows of ``wrenches`` ``taken(part, first)`` takes.

    The first row is looked at alone, by ``first_taken(wrench)`` (what ``taken`` says of
    it, in floats as ``AutoFidelity.solve`` decides: a tenth of the array calls' time): most
    rows that end a run (a check, an expansion) are not taken by the next kind of run
    either. Then windows that double from WINDOW rows, so that a batch whose runs are short
    does not measure every later row at every run; ``first`` is the part's first row.
    """
    if not len(wrenches) or not first_taken(wrenches[0]):
        return 0
    count, window = 1, WINDOW
    while count < len(wrenches):
        part = wrenches[count:count + window]
        accepted = taken(part, count)
        if not accepted.all():
            return count + int(np.argmin(accepted))
        count, window = count + len(part), 2 * window
    return count


def trusted_rows(auto: AutoFidelity, wrenches: np.ndarray) -> int:
    """How many leading rows of ``wrenches`` ``auto.solve`` answers by the expansion, unchecked."""
    origin = auto.linear.tangent.origin
    if origin is None or box_scale(origin) > 1.0:
        return 0
    judge = auto.judge()

    def taken(part: np.ndarray, first: int) -> np.ndarray:
        scales = box_scales(part - origin)
        return _covered_prefix(judge, part, (box_scales(part) <= 1.0)
                               & auto.within_trust(part, scales)
                               & auto.within_linear_target(scales))

    def first_taken(wrench: np.ndarray) -> bool:
        return auto.linear_verdict(wrench) == 'take' and judge.carried(wrench) is not None

    return _runs(wrenches, taken, first_taken)


def _covered_prefix(judge: Judge, part: np.ndarray, taken: np.ndarray) -> np.ndarray:
    """
    ``taken`` and the verdict coverage (``judge.covered``) of the rows of ``part``.

    Coverage is looked up only for the rows before the first one not ``taken``: ``_runs``
    reads no row after that, and the lookup is the costliest of the conditions.
    """
    ahead = len(taken) if taken.all() else int(np.argmin(taken))
    if ahead:
        taken[:ahead] = judge.covered(part[:ahead])
    return taken


def _stepped(auto: AutoFidelity, wrenches: np.ndarray, first: int, part: np.ndarray,
             alternative: Optional[float]) -> np.ndarray:
    """
    Per row of ``part`` (rows ``first`` on of ``wrenches``): whether an expansion pays there.

    As ``AutoFidelity.solve`` decides whether an expansion pays after the row before it (the
    policy's last wrench for the first row), the state unchanged; rows outside the box count
    too.
    """
    before = wrenches[first - 1] if first else auto.last_wrench
    if before is None:  # the first solve of a solver: no step, no expansion
        expands = np.zeros(len(part), bool)
        expands[1:] = auto.expansion_pays_at(box_scales(np.diff(part, axis=0)), alternative)
        return expands
    return auto.expansion_pays_at(box_scales(part - np.vstack([before, part[:-1]])),
                                  alternative)


def reduced_rows(auto: AutoFidelity, wrenches: np.ndarray, compliance: bool
                 ) -> Tuple[int, str]:
    """
    (count, level): the leading rows ``auto.solve`` first tries at one reduced level.

    Told in advance only without an expansion (nothing can refute a reduced answer then)
    and for compiled runs; each row is taken while that level answers it (the run stops
    at a row it fails, which ``solve`` then answers by the next level).
    """
    if (auto.linear.tangent.ready or compliance or not compiled_runs(auto.full.time_limit_s)
            or not auto.costs):
        return 0, ''
    reaches = auto.admission.reaches
    levels = [level for level in sorted(('cc', 'rod'), key=auto.costs.__getitem__)
              if not math.isnan(reaches.get(level, -math.inf))]
    scale = box_scale(wrenches[0])
    chosen = next((level for level in levels if scale <= reaches.get(level, -math.inf)), None)
    if len(levels) < 2 or chosen is None or scale > 1.0:
        return 0, ''
    cheaper = levels[:levels.index(chosen)]
    judge = auto.judge()

    def taken(part: np.ndarray, first: int) -> np.ndarray:
        scales = box_scales(part)
        admitted = (scales <= 1.0) & (scales <= reaches[chosen])
        for level in cheaper:
            admitted &= scales > reaches[level]
        return _covered_prefix(judge, part, admitted & ~_stepped(auto, wrenches, first, part,
                                                                 auto.costs[chosen]))

    return _runs(wrenches, taken, lambda wrench: bool(taken(wrench[None, :], 0)[0])), chosen


def full_rows(auto: AutoFidelity, wrenches: np.ndarray) -> Tuple[int, str]:
    """
    (count, reason): the leading rows ``auto.solve`` answers by a full solve, as it is.

    The rows share the reason their full answers give; 0 when the first row may be
    answered otherwise, or its decision is not one this tells in advance (bounds that do
    not grow with the box scale).
    """
    level, reason = auto.validated_choice(wrenches[0])
    if reason in (NO_BUDGET, NO_DATA):
        return len(wrenches), reason
    reaches = auto.admission.reaches
    if any(math.isnan(reaches.get(level, -math.inf)) for level in ('cc', 'rod')):
        return 0, ''
    origin = auto.linear.tangent.origin
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

    reach = max(reaches.get('cc', -math.inf), reaches.get('rod', -math.inf))
    expansion = origin if origin is not None and box_scale(origin) <= 1.0 else None

    def first_taken(wrench: np.ndarray) -> bool:
        scale = box_scale(wrench)
        inside = scale <= 1.0
        if inside and (scale <= reach or (expansion is not None and bool(
                auto.within_linear_target(np.array([box_scale(wrench - expansion)]))[0]))):
            return False
        if inside and auto.last_wrench is not None and bool(auto.expansion_pays_at(
                np.array([box_scale(wrench - auto.last_wrench)]), None)[0]):
            return False
        return not inside if outside else inside

    return _runs(wrenches, taken, first_taken), OUTSIDE if outside else NO_CHEAPER
