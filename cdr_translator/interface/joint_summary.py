"""
How a run's joint angles (``messages.JOINT_NAMES``) are summarized, in constant memory.

Bending angles and the end-disk rotation by their range. The bending directions wrap at
±180°: two loads in the same direction can give 179.99° and -179.99°, whose min..max
(-180 .. 180) says nothing. They are summarized by their circular mean, the direction of
the mean of the unit vectors (cos θ, sin θ), and their circular standard deviation
sqrt(-2 ln R), R the length of that mean (the mean resultant length: 1 when all agree, 0
when they cancel): what scipy.stats.circmean and circstd (high=π, low=-π) give, here
from running sums so that a replay of any length keeps only ten numbers per joint.
"""

import math
from typing import List, Tuple

import numpy as np
from numpy.typing import ArrayLike

from . import messages

#: The joints that are directions (rad, wrapping at ±π): summarized by circular statistics.
CIRCULAR_JOINT_NAMES = ('pj_direction', 'dj_direction')

#: Below this mean resultant length the directions cancel out: no mean direction.
MIN_RESULTANT_LENGTH = 1e-9


class JointSummary:
    """Range of each joint angle, and circular mean and spread of the directions."""

    def __init__(self) -> None:
        """Start empty."""
        size = len(messages.JOINT_NAMES)
        self.count = 0
        self.low = np.full(size, math.inf)
        self.high = np.full(size, -math.inf)
        self._cos = np.zeros(size)
        self._sin = np.zeros(size)

    def add(self, joints: ArrayLike) -> None:
        """Count the joint angles (rad) of one message, or of many as rows."""
        values = np.atleast_2d(np.asarray(joints, dtype=float))
        self.count += len(values)
        self.low = np.minimum(self.low, values.min(axis=0, initial=math.inf))
        self.high = np.maximum(self.high, values.max(axis=0, initial=-math.inf))
        self._cos += np.cos(values).sum(axis=0)
        self._sin += np.sin(values).sum(axis=0)

    def merge(self, other: 'JointSummary') -> None:
        """Count the joint angles ``other`` counted too (as if added here)."""
        self.count += other.count
        self.low = np.minimum(self.low, other.low)
        self.high = np.maximum(self.high, other.high)
        self._cos += other._cos
        self._sin += other._sin

    def mean_resultant_length(self) -> np.ndarray:
        """Return R of each joint: the length of the mean unit vector, 0..1 (NaN if empty)."""
        if not self.count:
            return np.full(len(self.low), math.nan)
        return np.minimum(np.hypot(self._cos, self._sin) / self.count, 1.0)

    def circular_mean(self) -> np.ndarray:
        """Return each joint's circular mean (rad, -π..π; NaN if the directions cancel)."""
        length = self.mean_resultant_length()
        mean = np.arctan2(self._sin, self._cos)
        return np.where(length >= MIN_RESULTANT_LENGTH, mean, math.nan)

    def circular_std(self) -> np.ndarray:
        """Return each joint's circular standard deviation sqrt(-2 ln R) (rad; inf if R ~ 0)."""
        length = self.mean_resultant_length()
        with np.errstate(divide='ignore'):
            spread = np.sqrt(-2.0 * np.log(length))
        return np.where(length >= MIN_RESULTANT_LENGTH, spread, math.inf)

    def rows(self) -> List[Tuple[str, str]]:
        """Return the (name, value) table rows, in degrees: ranges, or circular statistics."""
        if not self.count:
            return []
        rows = []
        mean, spread = np.degrees(self.circular_mean()), np.degrees(self.circular_std())
        low, high = np.degrees(self.low), np.degrees(self.high)
        for column, name in enumerate(messages.JOINT_NAMES):
            if name in CIRCULAR_JOINT_NAMES:
                middle = (f'{mean[column]:.3f}' if math.isfinite(mean[column])
                          else 'none (the directions cancel)')
                rows.append((f'{name} deg', f'circular mean {middle}, '
                                            f'circular std {spread[column]:.3f}'))
            else:
                rows.append((f'{name} deg min..max',
                             f'{low[column]:.3f} .. {high[column]:.3f}'))
        return rows
