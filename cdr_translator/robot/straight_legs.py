"""
The CDR with its legs as rigid links: the closed-form slider inverse.

Each leg straight, of its stack height H, between its base-disk centre b_i + q_i s_i (on
its inclined slider) and its end-disk centre p + a_i (the platform at its home
orientation): |p + a_i - b_i - q_i s_i| = H, a quadratic in q_i. The true legs bend (their
end-to-end distance shrinks, the payload deflects them, the platform turns a little), so
this is the inverse statics' cold initial guess, not an answer (about a millimetre off
near the stroke limits, under 1 kg).
"""

import math
from typing import Sequence

import numpy as np

from .params import Leg


def straight_leg_sliders(legs: Sequence[Leg], stack_height: float,
                         position: np.ndarray) -> np.ndarray:
    """
    Slider positions (m) putting the platform origin at ``position`` with straight legs.

    Of the two roots of |d_i - q s_i| = H (d_i = p + a_i - b_i(0)) the one nearer home;
    a leg that cannot reach (no real root) takes the q_i nearest to reaching, d_i . s_i.
    """
    sliders = np.empty(3)
    for k, leg in enumerate(legs):
        offset = position + leg.attachment - leg.home_base
        along = float(offset @ leg.slider_axis)
        discriminant = along * along - float(offset @ offset) + stack_height ** 2
        root = math.sqrt(max(discriminant, 0.0))
        sliders[k] = along - math.copysign(root, along)
    return sliders
