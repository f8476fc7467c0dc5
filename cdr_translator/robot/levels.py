"""
The fidelity levels of the CDR's legs: names, the budget's checks, validated error bounds.

A robot's legs are solved at one level ('full', 'rod', 'cc') or, with 'auto', at the
cheapest reduced level whose validated error (fidelity/validation.py: the largest error
over the smallest validated wrench box that holds a leg's tip wrench) meets the budget for
every leg, else in full. The bounds are the leg's end-disk errors under that wrench, not
the platform's: bench/robot_levels.py measures the robot's own against full legs.
"""

import math
from typing import Optional, Sequence, Tuple

import numpy as np

from .._jit import jit
from ..checks import check_number
from ..fidelity import LEVEL_COST_ORDER, Validation
from ..fidelity.validation import box_half_widths

#: Leg levels a DeltaRobot offers.
ROBOT_FIDELITIES = ('full', 'rod', 'cc', 'auto')

#: The reduced leg levels, cheapest first (the order 'auto' tries them in).
REDUCED_LEVELS = tuple(level for level in LEVEL_COST_ORDER if level in ('cc', 'rod'))


def check_fidelity(fidelity: str, max_position_error: float, max_angle_error: float) -> None:
    """Raise ValueError naming a level not in ROBOT_FIDELITIES, or a bad budget."""
    if fidelity not in ROBOT_FIDELITIES:
        raise ValueError(f'fidelity must be one of {ROBOT_FIDELITIES}, got {fidelity!r}')
    check_number('max_position_error', max_position_error, low=0.0)
    check_number('max_angle_error', max_angle_error, low=0.0)
    if fidelity != 'auto' and (max_position_error > 0.0 or max_angle_error > 0.0):
        raise ValueError(f"an error budget needs fidelity 'auto', got {fidelity!r}")


class BoundTable:
    """
    A level's validated end-disk errors by wrench box, looked up for many leg wrenches.

    The errors of the smallest validated box holding a wrench (fidelity/validation.py's
    nested boxes); NaN outside the largest box, or without validation data for these
    parameters (``validation`` None).
    """

    def __init__(self, validation: Optional[Validation], level: str) -> None:
        """Arrays of ``level``'s box scales and errors (m, deg) in ``validation``."""
        bound = None if validation is None else validation.levels.get(level)
        rows = () if bound is None else tuple(zip(bound.scales, bound.max_position_error_m,
                                                  bound.max_angle_error_deg))
        self.table = np.array(rows, dtype=float).reshape(-1, 3)
        self.half_widths = box_half_widths()

    def bounds(self, wrenches: np.ndarray) -> np.ndarray:
        """Return the (position m, angle deg) bound of each leg wrench (N, 6) as (N, 2)."""
        out = np.empty((len(wrenches), 2))
        _bounds(np.ascontiguousarray(wrenches, dtype=float), self.half_widths, self.table, out)
        return out


@jit
def _bounds(wrenches, half_widths, table, out):
    """BoundTable.bounds, compiled: validation.box_scale of each wrench, then its box."""
    for k in range(wrenches.shape[0]):
        scale = 0.0
        for i in range(6):
            ratio = abs(wrenches[k, i]) / half_widths[i]
            scale = math.nan if math.isnan(ratio) or math.isnan(scale) else max(scale, ratio)
        out[k, 0] = math.nan
        out[k, 1] = math.nan
        for index in range(table.shape[0]):
            if scale <= table[index, 0] * (1.0 + 1e-12):
                out[k, 0] = table[index, 1]
                out[k, 1] = table[index, 2]
                break


def within_budget(bounds: Sequence[Tuple[float, float]], max_position_error: float,
                  max_angle_error: float) -> bool:
    """Whether every leg's validated bound (m, deg) is known and inside the budget."""
    return all(position <= max_position_error and angle <= max_angle_error
               for position, angle in bounds)
