"""
The translator's wrench from its measured end-disk pose (TranslatorSolver.estimate_wrench).

Each evaluation is a solve with the compliance; its stability margin comes from the exact
compliance there, since the solve's may come from a factorization made at another wrench
(docs/explanation/solution_quality.md), and near zero it decides the ambiguity.
"""

import math
import time
from typing import Callable, Optional

import numpy as np
from numpy.typing import ArrayLike

from .result import SolveResult
from ..analysis.stability import load_scale, margin, Reference
from ..estimation import (Components, DEFAULT_TARGET_FORCE_SD, DEFAULT_TARGET_MOMENT_SD,
                          estimate_along, estimate_from, Evaluation, LOAD_LIMIT,
                          measured_target, Search, WrenchEstimate)

#: A solve of the translator with its compliance: (wrench (6), time limit in s) -> result.
SolveWithCompliance = Callable[[np.ndarray, float], SolveResult]

__all__ = ['estimate_wrench', 'REACH']

#: No equilibrium puts the end-disk centre further from the base than this many stack
#: heights (the backbones would have to stretch by a percent: kilonewtons).
REACH = 1.01


def _translator_evaluation(solve: SolveWithCompliance, reference: Reference,
                           wrench: np.ndarray, deadline: float) -> Optional[Evaluation]:
    """Solve the translator at ``wrench`` with its compliance by ``deadline`` (None: failed)."""
    result = solve(wrench, max(deadline - time.perf_counter(), 0.0))
    if not result.converged or result.compliance is None:
        return None
    # the margin from the exact compliance here: the solve's may come from a factorization
    # made at another wrench (docs/explanation/solution_quality.md), and near zero it
    # decides the ambiguity
    compliance = result.compliance.matrix
    return Evaluation(wrench.copy(), result.frames['de'], compliance, result.stable,
                      margin(compliance, reference), result.accuracy_met, result.message,
                      result.compliance, result)


def estimate_wrench(owner: object, solve: SolveWithCompliance, reference: Reference,
                    length: float, time_limit_s: float, warm: bool, reset: Callable[[], None],
                    position: ArrayLike, quaternion_xyzw: Optional[ArrayLike] = None, *,
                    pose_covariance: Optional[ArrayLike] = None,
                    moment: Optional[ArrayLike] = None,
                    force: Optional[ArrayLike] = None,
                    estimate: Optional[Components] = None,
                    prior_mean: Optional[ArrayLike] = None,
                    prior_covariance: Optional[ArrayLike] = None,
                    target_force_sd: float = DEFAULT_TARGET_FORCE_SD,
                    target_moment_sd: float = DEFAULT_TARGET_MOMENT_SD,
                    max_force: float = math.inf,
                    max_moment: float = math.inf) -> WrenchEstimate:
    """
    Return the end-disk wrench matching a measured pose (TranslatorSolver.estimate_wrench).

    The translator comes as callables: ``solve`` (with the compliance, within a time
    limit), ``reset`` (forget the warm start; ``warm``: whether there is one); its
    unloaded ``reference`` and stack height ``length`` (m). ``owner`` keys the last
    estimate, the next one's warm start (estimation.estimate_along). The whole estimate is
    limited to ``time_limit_s``.
    """
    started = time.perf_counter()
    target = measured_target(position, quaternion_xyzw, pose_covariance, moment, force, length,
                             estimate=estimate, prior_mean=prior_mean,
                             prior_covariance=prior_covariance, target_force_sd=target_force_sd,
                             target_moment_sd=target_moment_sd,
                             load_limit=LOAD_LIMIT * load_scale(reference),
                             max_force=max_force, max_moment=max_moment)
    reach = math.hypot(*target.frame[:3, 3].tolist())
    if reach > REACH * length:
        return estimate_from(
            Search(None, False, f'unreachable: the end disk cannot be {reach:.4g} m from the '
                   f'base (stack height {length:.4g} m)'), target, started)
    deadline = started + time_limit_s
    return estimate_along(
        owner, lambda wrench: _translator_evaluation(solve, reference, wrench, deadline),
        target, started, deadline, warm, reset)
