"""
Compiled entries of the reduced levels for batches: one wrench, a sequence, and the poses.

Arrays in, arrays out, no Python objects: ``solve_row`` solves one wrench warm from a given
solution, ``solve_sequence`` loops over rows of either model warm-started along
the sequence (the factorized Jacobian carried from row to row), and ``poses`` turns the
unknowns of each row into the end-disk pose (position, quaternion x, y, z, w) and the joints'
bending angles (PJ theta, delta, DJ theta, delta), as SolveResult computes them from the
frames (geometry.quaternion_xyzw, geometry.bending_between).

Status per row: newton.CONVERGED (0) or the failure code of the continuation. A row that
fails leaves the warm start at the last converged row; it is retried once from the unloaded
state with a fresh Jacobian (as FidelitySolver does) before it is flagged.
"""

import math

import numpy as np

from .cc import cc_frames
from .equivalent_rod import rod_frames
from .newton import continue_to, CONVERGED, ROD
from .._jit import jit
from ..geometry import bending_between_frames, quaternion_of_rotation

#: Columns of a pose row: end-disk position (3), then its quaternion x, y, z, w.
POSE_SIZE = 7

#: Columns of a bending row: PJ angle, PJ direction, DJ angle, DJ direction (rad).
BENDING_SIZE = 4


@jit
def solve_row(model, x, data, origin, wrench, tolerance, max_iterations, lu, pivots):
    """
    Solve ``wrench`` warm from x (solved under ``origin``); return (x, norm, its, status).

    ``x`` is not changed; the answer is a new array. ``lu``/``pivots`` carry the
    factorized Jacobian (newton.newton) in and out.
    """
    size = x.shape[0]
    rs = np.empty(size)
    answer = x.copy()
    norm, iterations, status, _ = continue_to(model, answer, data, origin, wrench, tolerance,
                                              max_iterations, rs, lu, pivots)
    if status != CONVERGED and (np.any(x != 0.0) or np.any(origin != 0.0)):
        answer[:] = 0.0
        pivots[size] = 0
        norm, more, status, _ = continue_to(model, answer, data, np.zeros(6), wrench,
                                            tolerance, max_iterations, rs, lu, pivots)
        iterations += more
    return answer, norm, iterations, status


@jit
def solve_sequence(model, data, wrenches, start, origin, tolerance, max_iterations, lu, pivots,
                   stop_at_failure, unknowns, norms, status, iterations):
    """
    Solve every row of ``wrenches`` (N, 6), each warm from the last converged row.

    ``start`` solves ``origin`` (zeros: the unloaded state); ``lu``/``pivots`` carry the
    factorized Jacobian in and out. Writes ``unknowns`` (N, size), ``norms`` (N), ``status``
    (N) and ``iterations`` (N); a failed row's unknowns are its last converged continuation
    state. ``stop_at_failure``: end at the first failed row, ``lu``/``pivots`` as they were
    before it (so that a caller can solve it again as the rows before it left things).
    Returns the number of rows written.
    """
    size = start.shape[0]
    saved_lu = np.empty((size, size))
    saved_pivots = np.empty(size + 1, dtype=np.int64)
    x = start.copy()
    base = origin.copy()
    for row in range(wrenches.shape[0]):
        if stop_at_failure:
            saved_lu[:] = lu
            saved_pivots[:] = pivots
        answer, norm, count, code = solve_row(model, x, data, base, wrenches[row], tolerance,
                                              max_iterations, lu, pivots)
        unknowns[row] = answer
        norms[row] = norm
        status[row] = code
        iterations[row] = count
        if code == CONVERGED:
            x[:] = answer
            base[:] = wrenches[row]
        elif stop_at_failure:
            lu[:] = saved_lu
            pivots[:] = saved_pivots
            return row + 1
    return wrenches.shape[0]


@jit
def frames_pose(frames, pose, bending):
    """
    End-disk pose and bending angles of frames {pe}, {pm}, {dm}, {de} (4, 4, 4).

    The quaternion is NaN where the end-disk rotation is too far off SO(3) to project.
    """
    for c in range(3):
        pose[c] = frames[3, c, 3]
    if not quaternion_of_rotation(frames[3, :3, :3].copy(), pose[3:7]):
        pose[3:7] = math.nan
    bending[0], bending[1] = bending_between_frames(frames[0], frames[1])
    bending[2], bending[3] = bending_between_frames(frames[2], frames[3])


@jit
def poses(model, data, wrenches, unknowns, pose, bending):
    """Pose (N, POSE_SIZE) and bending (N, BENDING_SIZE) of each row's unknowns."""
    frames = np.empty((4, 4, 4))
    for row in range(wrenches.shape[0]):
        data[:6] = wrenches[row]
        if model == ROD:
            rod_frames(unknowns[row], data, frames)
        else:
            cc_frames(unknowns[row], data, frames)
        frames_pose(frames, pose[row], bending[row])
