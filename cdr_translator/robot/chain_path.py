"""
The path a warm chain solve with reduced legs follows: its last solutions and their predictor.

A solve along a steadily followed path (a slider circle, a grid line of the atlas) starts
from the polynomial through the last solutions, extrapolated to the new inputs, instead of
the last solution: the coupled Newton (robot/reduced_coupled_kernels.py) then starts within the
path's (m + 1)-th order term instead of its first, and its kept Jacobians (chord steps)
contract that start without being made anew. The full legs' continuation predicts the same
way (robot/continuation.py's ``extrapolate``); here compiled, with the points in one array.

A point is a solved state, flat: platform position (3), rotation (9, row-major), leg
wrenches (18), the legs' reduced unknowns (3 n) and end-disk frames (48).
"""

import math

import numpy as np

from .._jit import jit

#: Highest degree of the polynomial predictor (its points: DEGREE + 1 solutions). Along
#: bench.robot_levels' slider circle the full legs' continuation found degree 3 best.
DEGREE = 3

#: The predictor is used when the input change it does not extrapolate (the inputs' own
#: polynomial's rest) is at most this fraction of the whole input change.
EXTRAPOLATE_WITHIN = 0.5

#: Entries of a point before the legs' unknowns: position, rotation, wrenches.
_PLATFORM = 30


def point_width(size: int) -> int:
    """Length of a flat point with legs of ``size`` reduced unknowns."""
    return _PLATFORM + 3 * size + 48


@jit
def push(points, seen, count, position, rotation, wrenches, leg_x, frames, inputs):
    """Add a solution (its inputs ``inputs``) as the latest point, dropping the oldest."""
    if count[0] == points.shape[0]:
        for row in range(points.shape[0] - 1):
            points[row] = points[row + 1]
            seen[row] = seen[row + 1]
        count[0] -= 1
    row = count[0]
    _pack(position, rotation, wrenches, leg_x, frames, points[row])
    seen[row] = inputs
    count[0] += 1


@jit
def restore(points, count, position, rotation, wrenches, leg_x, frames):
    """Put the latest point into the state arrays."""
    _unpack(points[count[0] - 1], position, rotation, wrenches, leg_x, frames)


@jit
def extrapolate(points, seen, count, inputs, input_scale, position, rotation, wrenches,
                leg_x):
    """
    Put the polynomial predictor at ``inputs`` into the state; False: none applies.

    The polynomial of degree m through the last m + 1 points, one step on: the weights
    (-1)^j C(m + 1, j + 1) on the latest-but-j point (m = 1: 2, -1). The degree, 1 to
    DEGREE, is the one whose inputs so extrapolated leave the smallest rest against
    ``inputs`` (scaled by ``input_scale``; the highest among equals: within 1e-9 of the
    input change); none applies when there are fewer than two points or the rest is above
    EXTRAPOLATE_WITHIN of the input change from the latest point. The rotation is
    extrapolated by its entries and made orthonormal again (Gram-Schmidt on its rows).
    """
    stored = count[0]
    if stored < 2:
        return False
    change = _scaled_distance(inputs, seen[stored - 1], input_scale)
    if not change > 0.0:
        return False
    extrapolated = np.empty(inputs.shape[0])
    weights = np.zeros(DEGREE + 1)
    best = math.inf
    chosen = 0
    for degree in range(1, min(stored - 1, DEGREE) + 1):
        _weights(degree, weights)
        extrapolated[:] = 0.0
        for j in range(degree + 1):
            extrapolated += weights[j] * seen[stored - 1 - j]
        rest = _scaled_distance(inputs, extrapolated, input_scale)
        if rest <= best + 1e-9 * change:  # equal within rounding: the higher degree
            chosen = degree
        best = min(best, rest)
    if best > EXTRAPOLATE_WITHIN * change:
        return False
    _weights(chosen, weights)
    flat = np.zeros(points.shape[1])
    for j in range(chosen + 1):
        flat += weights[j] * points[stored - 1 - j]
    _unpack(flat, position, rotation, wrenches, leg_x, np.empty((3, 4, 4)))
    _orthonormalize(rotation)
    return True


@jit
def _weights(degree, out):
    """Backward-difference extrapolation weights of ``degree`` into ``out[:degree + 1]``."""
    for j in range(degree + 1):
        out[j] = (-1.0) ** j * _binomial(degree + 1, j + 1)


@jit
def _binomial(n, k):
    """C(n, k) for small n."""
    value = 1.0
    for i in range(k):
        value = value * (n - i) / (i + 1)
    return value


@jit
def _scaled_distance(a, b, scale):
    """Euclidean norm of (a - b) / scale."""
    total = 0.0
    for i in range(a.shape[0]):
        total += ((a[i] - b[i]) / scale[i]) ** 2
    return math.sqrt(total)


@jit
def _orthonormalize(rotation):
    """Gram-Schmidt on the rows of a nearly orthonormal 3x3, in place (right-handed)."""
    for row in range(2):
        for previous in range(row):
            dot = 0.0
            for i in range(3):
                dot += rotation[row, i] * rotation[previous, i]
            for i in range(3):
                rotation[row, i] -= dot * rotation[previous, i]
        length = math.sqrt(rotation[row, 0] ** 2 + rotation[row, 1] ** 2
                           + rotation[row, 2] ** 2)
        for i in range(3):
            rotation[row, i] /= length
    rotation[2, 0] = rotation[0, 1] * rotation[1, 2] - rotation[0, 2] * rotation[1, 1]
    rotation[2, 1] = rotation[0, 2] * rotation[1, 0] - rotation[0, 0] * rotation[1, 2]
    rotation[2, 2] = rotation[0, 0] * rotation[1, 1] - rotation[0, 1] * rotation[1, 0]


@jit
def _pack(position, rotation, wrenches, leg_x, frames, out):
    """Write a state as a flat point."""
    out[:3] = position
    for i in range(3):
        out[3 + 3 * i:6 + 3 * i] = rotation[i]
        out[12 + 6 * i:18 + 6 * i] = wrenches[i]
    size = leg_x.shape[1]
    for k in range(3):
        out[_PLATFORM + size * k:_PLATFORM + size * (k + 1)] = leg_x[k]
    at = _PLATFORM + 3 * size
    for k in range(3):
        for i in range(4):
            out[at + 16 * k + 4 * i:at + 16 * k + 4 * i + 4] = frames[k, i]


@jit
def _unpack(flat, position, rotation, wrenches, leg_x, frames):
    """Read a flat point into the state arrays."""
    position[:] = flat[:3]
    for i in range(3):
        rotation[i] = flat[3 + 3 * i:6 + 3 * i]
        wrenches[i] = flat[12 + 6 * i:18 + 6 * i]
    size = leg_x.shape[1]
    for k in range(3):
        leg_x[k] = flat[_PLATFORM + size * k:_PLATFORM + size * (k + 1)]
    at = _PLATFORM + 3 * size
    for k in range(3):
        for i in range(4):
            frames[k, i] = flat[at + 16 * k + 4 * i:at + 16 * k + 4 * i + 4]
