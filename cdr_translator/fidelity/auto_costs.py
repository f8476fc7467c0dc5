"""
The costs 'auto' weighs its levels by (fidelity.auto), measured once per process.

Each level answers a step of CALIBRATION_STEP box scales from a solution at
CALIBRATION_SCALE; 'full step' a further step of CALIBRATION_SMALL_STEP (a warm solve along
a slow sequence); 'expansion' expands about the full solution, and 'linear' answers one
more such step from it; 'check' checks that answer (the full model's residual at its
predicted unknowns, fidelity.auto). The fastest of CALIBRATION_REPEATS timings counts,
robust to a busy machine; kept per parameter set so that the choices depend on the wrenches
alone and a batch takes the levels its single solves take.
"""

import time
from typing import Callable, Dict, List, Mapping

import numpy as np

from .level import Asked, Level
from .linear_level import LinearLevel
from .validation import box_half_widths

#: Timings per level whose fastest is its cost; the wrench step an expansion is timed at,
#: and the small step a warm full solve is timed at (box scales).
CALIBRATION_REPEATS = 5
CALIBRATION_STEP = 0.1
CALIBRATION_SMALL_STEP = 0.005

#: Where the costs are timed: a load of this box scale along CALIBRATION_DIRECTION.
CALIBRATION_SCALE = 0.2
CALIBRATION_DIRECTION = np.array([1.0, 0.5, -0.5, 0.3, 0.2, 0.4])

#: Costs measured so far, per parameter set (``measure_costs``).
_MEASURED_COSTS: Dict[str, Dict[str, float]] = {}


def measure_costs(levels: Mapping[str, Level], linear: LinearLevel,
                  asked: Callable[[], Asked], reset: Callable[[], None],
                  key: str) -> Dict[str, float]:
    """
    Time each level (s per answer; 'expansion': one expansion), once per ``key``.

    ``asked`` gives each answer's Asked, ``reset`` forgets every level's memory (called
    before each repeat and at the end).
    """
    if key not in _MEASURED_COSTS:
        direction = CALIBRATION_DIRECTION * box_half_widths()
        start = CALIBRATION_SCALE * direction
        end = start + CALIBRATION_STEP * direction
        times: Dict[str, List[float]] = {level: [] for level in (
            'full', 'full step', 'expansion', 'linear', 'check', 'cc', 'rod')}
        for _ in range(CALIBRATION_REPEATS):
            reset()
            for level in ('full', 'cc', 'rod'):
                levels[level].solve(start, False, {}, asked())
                times[level].append(levels[level].solve(end, False, {}, asked()).solve_time_s)
            further = end + CALIBRATION_SMALL_STEP * direction
            result = levels['full'].solve(further, False, {}, asked())
            times['full step'].append(result.solve_time_s)
            linear.expand_about(result, further)
            times['expansion'].append(linear.tangent.build_time_s)
            nearby = further + CALIBRATION_SMALL_STEP * direction
            times['linear'].append(linear.solve(nearby, False, {}, asked()).solve_time_s)
            problem = linear.full.problem
            started = time.perf_counter()
            problem.residual(linear.tangent.unknowns(nearby) / problem.x_scale, nearby)
            times['check'].append(time.perf_counter() - started)
        _MEASURED_COSTS[key] = {level: min(values) for level, values in times.items()}
        reset()
    return dict(_MEASURED_COSTS[key])
