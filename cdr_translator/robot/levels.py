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

from ..checks import check_number
from ..fidelity import LEVEL_COST_ORDER, Validation
from ..fidelity.validation import box_scale

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


def leg_error_bound(validation: Optional[Validation], level: str,
                    wrench: np.ndarray) -> Tuple[float, float]:
    """
    Return the validated (position m, angle deg) error of ``level`` at a leg's tip ``wrench``.

    The errors of the smallest validated box holding the wrench; NaN outside the largest
    box, or without validation data for these parameters.
    """
    bound = None if validation is None else validation.levels.get(level)
    if bound is None:
        return math.nan, math.nan
    scale = box_scale(np.asarray(wrench, dtype=float))
    for index, limit in enumerate(bound.scales):
        if scale <= limit * (1.0 + 1e-12):
            return bound.max_position_error_m[index], bound.max_angle_error_deg[index]
    return math.nan, math.nan


def within_budget(bounds: Sequence[Tuple[float, float]], max_position_error: float,
                  max_angle_error: float) -> bool:
    """Whether every leg's validated bound (m, deg) is known and inside the budget."""
    return all(position <= max_position_error and angle <= max_angle_error
               for position, angle in bounds)
