"""
The payload on the Continuum Delta Robot's platform from its measured pose and the sliders.

Force sensing with a parallel continuum robot (Black, Till & Rucker, IEEE T-RO 34(1),
2018): the payload is the one whose forward-statics solution puts the platform at the
measured pose. The same search as the translator's (cdr_translator/estimation:
Levenberg-Marquardt steps on the payload within a trust radius, warm along a stream),
each iterate a forward solve with the compliance, whose ``input_sensitivity`` columns for
the payload force and moment (d platform pose / d payload, in {w}: the twist convention of
cdr_translator/analysis/compliance.py) are the exact derivative. With the platform orientation all
six components are estimated; with its position only, the force under no moment.

The estimate is flagged, never raised, when no payload matches (``converged`` False) or
the matching equilibrium is not known to be stable (``accuracy_met`` False): the robot's
verdict covers the platform stiffness and each leg held at both ends (robot/linearization.py).
"""

from dataclasses import dataclass, field, fields
import math
import time
from typing import Any, Callable, Dict, Optional

import numpy as np
from numpy.typing import ArrayLike

from .params import check_sliders
from .result import DeltaResult, INPUT_NAMES
from ..analysis.compliance import analyse
from ..analysis.stability import load_scale, Reference
from ..estimation import (estimate_along, Evaluation, json_safe, LOAD_LIMIT, measured_target,
                          WrenchEstimate)

#: A robot solve with the compliance: (sliders (3, m), payload (6), time limit in s) -> result.
SolveWithCompliance = Callable[[np.ndarray, np.ndarray, float], DeltaResult]

__all__ = ['estimate_payload', 'PayloadEstimate']

#: Names of the payload components (force at the platform origin and moment, in {w}).
PAYLOAD_LABELS = tuple(f'payload {name}' for name in INPUT_NAMES[3:9])


@dataclass
class PayloadEstimate(WrenchEstimate):
    """
    The payload [f; m] on the platform (N, N m; in {w}, force at the platform origin).

    The fields of WrenchEstimate (cdr_translator/estimation/wrench_estimate.py), the measured body
    being the platform: ``position`` and ``quaternion_xyzw`` are the solved platform pose,
    ``solution`` the DeltaResult, ``stability_margin`` NaN (``stable`` is the robot's
    verdict); plus the ``sliders`` (m) it was estimated at.
    """

    sliders: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))

    def to_dict(self) -> Dict[str, Any]:
        """JSON-ready form: WrenchEstimate's keys and 'sliders'."""
        return {**super().to_dict(), 'sliders': json_safe(self.sliders)}


def _evaluation(solve: SolveWithCompliance, length: float, sliders: np.ndarray,
                payload: np.ndarray, deadline: float) -> Optional[Evaluation]:
    """Solve the robot under ``payload`` with its linearization (None: failed)."""
    result = solve(sliders, payload, max(deadline - time.perf_counter(), 0.0))
    if not result.converged or result.input_sensitivity is None:
        return None
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = result.platform_rotation, result.platform_position
    sensitivity = result.input_sensitivity[:, 3:9].copy()
    analysis = analyse(sensitivity, length)
    return Evaluation(payload.copy(), frame, sensitivity, result.stable, float('nan'),
                      True, result.message, analysis, result)


def estimate_payload(owner: object, solve: SolveWithCompliance, leg_reference: Reference,
                     legs: int, length: float, slider_stroke: float, time_limit_s: float,
                     warm: bool, reset: Callable[[], None], platform_position: ArrayLike,
                     sliders: ArrayLike, platform_quaternion_xyzw: Optional[ArrayLike] = None,
                     *, covariance: Optional[ArrayLike] = None, max_force: float = math.inf,
                     max_moment: float = math.inf) -> PayloadEstimate:
    """
    Return the payload matching a measured platform pose (DeltaRobot.estimate_payload).

    The robot comes as callables: ``solve`` (with the compliance, within a time limit),
    ``reset`` (forget the warm start; ``warm``: whether there is one); the unloaded
    ``leg_reference`` of one of its ``legs`` legs, the stack height ``length`` (m) and the
    ``slider_stroke`` (m). ``owner`` keys the last estimate, the next one's warm start
    (estimation.estimate_along). The whole estimate is limited to ``time_limit_s``, its
    search to payloads within ``max_force`` and ``max_moment`` (N, N m).
    """
    started = time.perf_counter()
    sliders = check_sliders(sliders, slider_stroke)
    target = measured_target(platform_position, platform_quaternion_xyzw, covariance, None,
                             None, length, PAYLOAD_LABELS,
                             ('platform_position', 'platform_quaternion_xyzw', 'covariance'),
                             load_limit=legs * LOAD_LIMIT * load_scale(leg_reference),
                             max_force=max_force, max_moment=max_moment)
    deadline = started + time_limit_s
    found = estimate_along(
        owner, lambda payload: _evaluation(solve, length, sliders, payload, deadline),
        target, started, deadline, warm, reset)
    values = {item.name: getattr(found, item.name) for item in fields(WrenchEstimate)}
    return PayloadEstimate(**values, sliders=sliders)
