"""
Compiled prediction of the 'linear' level (fidelity.linear): frames and poses per wrench.

Each frame k of {pm}, {dm}, {de} moves by the twist T_k (w - w0): its rotation becomes
exp([T_k,rot (w - w0)]) R_k and its centre moves by T_k,pos (w - w0). A few 6x6 products
and three Rodrigues rotations per wrench.
"""

import math

import numpy as np

from .level_kernels import frames_pose
from .._jit import jit

#: Below this rotation angle (rad) Rodrigues' formula is its second-order series.
SMALL_ANGLE = 1e-8


@jit
def _rotate(vector, rotation, out):
    """Set 3x3 ``out`` to exp([vector]) ``rotation`` (Rodrigues)."""
    angle = math.sqrt(vector[0] ** 2 + vector[1] ** 2 + vector[2] ** 2)
    if angle < SMALL_ANGLE:
        first = 1.0
        second = 0.5
    else:
        first = math.sin(angle) / angle
        second = (1.0 - math.cos(angle)) / angle ** 2
    skew = np.zeros((3, 3))
    skew[0, 1] = -vector[2]
    skew[0, 2] = vector[1]
    skew[1, 0] = vector[2]
    skew[1, 2] = -vector[0]
    skew[2, 0] = -vector[1]
    skew[2, 1] = vector[0]
    turn = np.eye(3)
    for i in range(3):
        for j in range(3):
            square = skew[i, 0] * skew[0, j] + skew[i, 1] * skew[1, j] + skew[i, 2] * skew[2, j]
            turn[i, j] += first * skew[i, j] + second * square
    for i in range(3):
        for j in range(3):
            out[i, j] = (turn[i, 0] * rotation[0, j] + turn[i, 1] * rotation[1, j]
                         + turn[i, 2] * rotation[2, j])


@jit
def linear_frames(base_frames, twists, offset, frames):
    """Frames (4, 4, 4) at wrench offset ``offset`` from the cached frames and twists."""
    frames[:] = base_frames
    twist = np.empty(6)
    for k in range(1, 4):
        for i in range(6):
            total = 0.0
            for j in range(6):
                total += twists[k, i, j] * offset[j]
            twist[i] = total
        _rotate(twist[3:], base_frames[k, :3, :3], frames[k, :3, :3])
        for i in range(3):
            frames[k, i, 3] += twist[i]


@jit
def linear_poses(base_frames, twists, origin, wrenches, pose, bending):
    """Pose (N, 7) and bending (N, 4) rows (level_kernels.poses' columns) of each wrench."""
    frames = np.empty((4, 4, 4))
    offset = np.empty(6)
    for row in range(wrenches.shape[0]):
        for i in range(6):
            offset[i] = wrenches[row, i] - origin[i]
        linear_frames(base_frames, twists, offset, frames)
        frames_pose(frames, pose[row], bending[row])
