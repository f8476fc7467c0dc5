"""
Which levels the validation data admit under an error budget, wrench by wrench.

A level is admitted at a wrench when its validated error there (fidelity.validation: the
errors of the smallest box holding the wrench, or for 'linear' the offset from the
expansion's wrench) is inside the budget. The boxes are nested and their errors grow, so
each level's boxes inside the budget end at a reach (LevelBound.reach), looked up in O(1);
bounds that do not grow are judged box by box. 'auto' (fidelity.auto) starts from the
cheapest admitted level.
"""

import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from .validation import box_scale, Validation

#: Reduced levels, cheapest first (the order the validated choice tries them).
LEVEL_COST_ORDER = ('linear', 'cc', 'rod')

#: Reasons of full answers no level is admitted for.
OUTSIDE = 'wrench outside the validated range'
NO_BUDGET = 'no error budget'
NO_DATA = 'no validation data for these parameters'


class Admission:
    """The validation data of one parameter set held against one budget."""

    def __init__(self, validation: Optional[Validation], max_position_error: float,
                 max_angle_error_deg: float) -> None:
        """Hold ``validation`` (None: no data) against the budget (m, deg; 0: none)."""
        self.validation = validation
        self.max_position_error = max_position_error
        self.max_angle_error_deg = max_angle_error_deg
        #: each level's validated reach under the budget (LevelBound.reach; NaN: box by box)
        self.reaches: Dict[str, float] = {} if validation is None else {
            level: bound.reach(max_position_error, max_angle_error_deg)
            for level, bound in validation.levels.items()}

    @property
    def active(self) -> bool:
        """Whether there are a budget and data to hold it against."""
        return (self.max_position_error > 0.0 and self.max_angle_error_deg > 0.0
                and self.validation is not None)

    def choice(self, wrench: np.ndarray, origin: Optional[np.ndarray]) -> Tuple[str, str]:
        """
        Return (level, reason): the cheapest level whose validated error meets the budget.

        ``origin``: the wrench the 'linear' level expands about (None: no expansion); the
        offset from it must lie in a validated offset box.
        """
        if self.max_position_error <= 0.0 or self.max_angle_error_deg <= 0.0:
            return 'full', NO_BUDGET
        validation = self.validation
        if validation is None:
            return 'full', NO_DATA
        scale = box_scale(wrench)
        for level in LEVEL_COST_ORDER:
            if level == 'linear' and origin is None:
                continue
            reach = self.reaches.get(level, -math.inf)
            if math.isnan(reach):  # bounds that do not grow: the box-by-box rule
                admitted = validation.admissible(
                    level, wrench, self.max_position_error, self.max_angle_error_deg,
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

    def reduced(self, wrench: np.ndarray) -> List[str]:
        """Return 'cc' and 'rod' where their validated errors meet the budget."""
        scale = box_scale(wrench)
        if scale > 1.0:
            return []
        validation = self.validation
        assert validation is not None  # a budget without data answers 'full'
        admitted = []
        for level in ('cc', 'rod'):
            reach = self.reaches.get(level, -math.inf)
            if (scale <= reach if not math.isnan(reach) else validation.admissible(
                    level, wrench, self.max_position_error, self.max_angle_error_deg)):
                admitted.append(level)
        return admitted
