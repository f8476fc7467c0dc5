"""
Stability verdicts of the reduced levels, carried over from full solutions near their answers.

The reduced levels ('rod', 'cc', 'linear') solve no stability problem of their own. Their
answer at a wrench w carries the verdict of a full solution at a wrench w_r (stability.py)
when the rule by which the full model keeps a verdict made at another wrench
(``branch.judge``) keeps it at w: that solution is stable, its margin is at least
stability.CLOSE_BRANCH_MARGIN, and the drift

    |w - w_r| / max(|w|, branch.LOAD_FLOOR w*)

(sizes by stability.wrench_size, w* = stability.load_scale) is at most
min(branch.STALE_WRENCH, margin / 2). The answer then says which solution, and its
``stability_margin`` is that solution's margin: the distance to the nearest buckling load
measured there. The full solutions at hand are the unloaded state (stable, margin 1 by the
margin's definition), the solution the 'linear' level expands about, and the last full
answer. Where none is near enough the answer has no verdict (``stable`` None) and says so.
"""

from dataclasses import dataclass
import math
from typing import Iterable, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from .._linalg import factorize
from ..analysis import stability
from ..bvp.problem import Problem
from ..solve.batch import BatchResult
from ..solve.branch import LOAD_FLOOR, STALE_WRENCH
from ..solve.result import SolveResult

#: The message tail of an answer no full solution's verdict reaches.
NOT_ASSESSED = ('; stability not assessed: the {level} level has no stability analysis of '
                'its own and no full solution lies near enough to carry its verdict here')


@dataclass(frozen=True, eq=False)  # one per full solution: equal only to itself
class FullVerdict:
    """The verdict of one full solution: its wrench (6,), verdict, margin and what it is."""

    wrench: np.ndarray
    stable: bool
    margin: float
    name: str


def unloaded_verdict() -> FullVerdict:
    """Return the unloaded state's verdict: stable, margin 1 (the margin's unit)."""
    return FullVerdict(np.zeros(6), True, 1.0, 'the unloaded state')


def load_scale_at(problem: Problem, unloaded: np.ndarray) -> float:
    """
    Return w* (N, stability.load_scale) of ``problem`` from its unloaded solution.

    ``unloaded``: the nondimensional unknowns of the converged solution at no load.
    """
    zero = np.zeros(6)
    _, jacobian, pose = problem.exact_jacobian(unloaded, zero)
    _, frames = problem.shape(unloaded, zero)
    origin = stability.reference(factorize(jacobian), pose, frames[3][:3, :3],
                                 problem.wrench_sensitivity, problem.params.stack_height)
    return stability.load_scale(origin)


def _sizes(wrenches: np.ndarray, length: float) -> np.ndarray:
    """stability.wrench_size of each row of ``wrenches`` (..., 6), in the same float steps."""
    return np.sqrt((wrenches[..., :3] ** 2).sum(axis=-1)
                   + (wrenches[..., 3:] ** 2).sum(axis=-1) / length ** 2)


def carried(wrench: np.ndarray, references: Sequence[FullVerdict], load_scale: float,
            length: float) -> Optional[FullVerdict]:
    """Return the reference whose verdict reaches ``wrench`` with the least drift (None: none)."""
    floor = LOAD_FLOOR * load_scale
    size = max(stability.wrench_size(wrench, length), floor)
    best, least = None, math.inf
    for reference in references:
        if not (reference.stable and reference.margin >= stability.CLOSE_BRANCH_MARGIN):
            continue
        drift = stability.wrench_size(wrench - reference.wrench, length) / size
        if drift <= min(STALE_WRENCH, 0.5 * reference.margin) and drift < least:
            best, least = reference, drift
    return best


def carried_rows(wrenches: np.ndarray, references: Sequence[FullVerdict], load_scale: float,
                 length: float) -> np.ndarray:
    """
    Apply ``carried`` to each row of ``wrenches`` (n, 6): reference indices, -1: none.

    The drifts from every reference that may carry a verdict are one array operation (a
    batch asks this of short windows many times: the calls, not the rows, cost).
    """
    chosen = np.full(len(wrenches), -1)
    usable = [index for index, reference in enumerate(references)
              if reference.stable and reference.margin >= stability.CLOSE_BRANCH_MARGIN]
    if not usable or not len(wrenches):
        return chosen
    sizes = np.maximum(_sizes(wrenches, length), LOAD_FLOOR * load_scale)
    origins = np.array([references[index].wrench for index in usable])
    drifts = _sizes(wrenches[None, :, :] - origins[:, None, :], length) / sizes
    least = np.full(len(wrenches), math.inf)
    for index, drift in zip(usable, drifts):
        better = (drift <= min(STALE_WRENCH, 0.5 * references[index].margin)) & (drift < least)
        chosen[better], least[better] = index, drift[better]
    return chosen


def note(level: str, reference: Optional[FullVerdict]) -> str:
    """Return the message tail saying where an answer's verdict comes from, or that none does."""
    if reference is None:
        return NOT_ASSESSED.format(level=level)
    return (f"; stable by the full model's verdict at {reference.name} (stability margin "
            f'{reference.margin:.3g})')


class Judge(NamedTuple):
    """
    How the answers below the full model are judged: verdicts carried, errors against a budget.

    ``references``: the full solutions at hand; ``load_scale`` w* (N) and ``length`` H (m)
    of the drift rule; the budget (m, deg) the errors 'auto' validated are held against.
    """

    references: Tuple[FullVerdict, ...]
    load_scale: float
    length: float
    max_position_error: float = 0.0
    max_angle_error_deg: float = 0.0

    @classmethod
    def of(cls, references: Iterable[Optional[FullVerdict]], load_scale: float, length: float,
           budget: Tuple[float, float] = (0.0, 0.0)) -> 'Judge':
        """Return the Judge of the ``references`` that exist (None: not at hand)."""
        return cls(tuple(reference for reference in references if reference is not None),
                   load_scale, length, *budget)

    def carried(self, wrench: np.ndarray) -> Optional[FullVerdict]:
        """Return the full solution whose verdict an answer at ``wrench`` carries (or None)."""
        return carried(wrench, self.references, self.load_scale, self.length)

    def covered(self, wrenches: np.ndarray) -> np.ndarray:
        """Per row of ``wrenches`` (n, 6): whether some full solution's verdict reaches it."""
        return carried_rows(wrenches, self.references, self.load_scale, self.length) >= 0

    def note(self, level: str, wrench: np.ndarray) -> str:
        """Return the message tail of an answer of ``level`` at ``wrench`` (its verdict's)."""
        return note(level, self.carried(wrench))

    def answer(self, result: SolveResult, wrench: np.ndarray,
               estimate: Optional[np.ndarray]) -> None:
        """
        Judge a converged answer below the full model at ``wrench``.

        Its carried verdict and margin (the message names their solution, or says there is
        none) and ``estimate`` (m, deg; None: none) with ``accuracy_met`` on the budget.
        """
        reference = self.carried(wrench)
        if reference is not None:
            result.stable, result.stability_margin = reference.stable, reference.margin
        result.message += note(result.fidelity, reference)
        if estimate is not None:
            result.error_estimate_m = float(estimate[0])
            result.error_estimate_deg = float(estimate[1])
            result.accuracy_met = bool(estimate[0] <= self.max_position_error
                                       and estimate[1] <= self.max_angle_error_deg)

    def rows(self, batch: BatchResult, wrenches: np.ndarray, rows: np.ndarray,
             estimates: Optional[np.ndarray]) -> None:
        """
        Judge the converged ``rows`` of ``batch`` as ``answer`` judges single answers.

        A carried verdict wins over the compliance's in ``stable``, as in ``to_dict``;
        ``estimates`` (len(rows), 2) or None.
        """
        chosen = carried_rows(wrenches[rows], self.references, self.load_scale, self.length)
        converged = batch.converged[rows].astype(bool)
        for index, reference in enumerate(self.references):
            judged = rows[converged & (chosen == index)]
            batch.stable[judged] = batch.verdict[judged] = reference.stable
            batch.stability_margin[judged] = reference.margin
        if estimates is not None:
            met = ((estimates[:, 0] <= self.max_position_error)
                   & (estimates[:, 1] <= self.max_angle_error_deg))
            batch.error_estimate_m[rows[converged]] = estimates[converged, 0]
            batch.error_estimate_deg[rows[converged]] = estimates[converged, 1]
            batch.accuracy_met[rows[converged]] = [bool(value) for value in met[converged]]
