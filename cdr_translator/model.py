"""
The translator's multi-rod boundary-value problem (paper Section III.C, Eq. 7-11).

Rods: k = 0 the primary backbone, k = 1..4 the secondaries at 0/90/180/270 deg on the
pitch circle. Everything is in the base frame {pe}. One shooting pass integrates all five
rods disk interval by disk interval and applies the disk conditions on the way.

Unknowns ``x`` (SI), for S spacer disks per joint and ``nst = 2 S + 1`` stations:
  x[6k:6k+3], x[6k+3:6k+6]   n_k(0), m_k(0) of rod k at the base disk (30 values);
  x[30 + 5 (i nst + t) + c]  secondary i (0..3) at station t (0..nst-1):
        c = 0      material length of the segment that ends at station t;
        c = 1, 2   in-plane reaction force (disk x, y) applied there;
        c = 3, 4   in-plane reaction moment (disk x, y) applied there.
Stations t < S are PJ spacer disks, t = S the tube's proximal face (its reaction is the
in-plane wrench the lumen hands back at the distal face), t > S the DJ spacer disks.

Residuals ``out`` (SI), as many as unknowns (30 + 20 nst):
  out[5 (i nst + t) + c]  at station t: c = 0, 1 hole offset in the disk plane (Eq. 7),
        c = 2 offset normal to the disk (Eq. 8), c = 3, 4 tilt of the secondary's tangent
        in the disk frame (zero exactly when R_0^T R_i is a pure twist, as Eq. 7 asks);
  out[20 nst + 6 i + c]   end-disk clamp of secondary i: position (3), orientation (3) (Eq. 10);
  out[20 nst + 24 + c]    end-disk equilibrium, force (3) then moment about its centre (3)
                          (Eq. 11).

Modelling choices where the paper is silent (see ../shared/paper/NOTES.md):
* A thin spacer disk is a rigid body in full 6-D equilibrium: whatever in-plane wrench it
  applies to the secondaries, the primary backbone (clamped to it) supplies.
* The tube is rigid. The primary is clamped to both faces; each secondary runs straight
  along its lumen, free to slide and twist, so inside the lumen it carries only its axial
  force and torsion. The lumen absorbs the in-plane wrench at the proximal face and hands
  an unknown in-plane wrench back at the distal face; the tube's own 6-D equilibrium fixes
  the primary's wrench leaving the distal face.
"""

import math

import numpy as np

from ._jit import jit, jit_inline
from .rod import (integrate_segment, integrate_segment_tangent, LOCAL_DIRECTIONS, LOCAL_LENGTH,
                  LOCAL_M, LOCAL_N, LOCAL_OUT_M, LOCAL_OUTPUTS, LOCAL_ROT, SEGMENT_SCRATCH,
                  TANGENT_P, TANGENT_ROT)

N_RODS = 5
N_BASE_UNKNOWNS = 6 * N_RODS
STATION_WIDTH = 5

#: Layout of a node state (multiple shooting, lifted.py): the rods' state where a disk
#: interval starts, all SI in {pe}: p (5 x 3), R (5 x 3 x 3, row-major), n, m (5 x 3 each)
#: and the material length of each secondary used so far (4).
STATE_P = 0
STATE_ROT = 3 * N_RODS
STATE_N = 12 * N_RODS
STATE_M = 15 * N_RODS
STATE_USED = 18 * N_RODS
STATE_SIZE = 18 * N_RODS + 4

#: What a shot does at the start of each disk interval after the first (``nodes`` argument):
#: nothing (single shooting), start from the given node state and write the defect (carried
#: minus node state: multiple shooting), or record the carried state as the node.
NO_NODES = 0
LIFT_NODES = 1
RECORD_NODES = 2


def station_count(spacers_per_joint: int) -> int:
    """Stations per secondary: the spacer disks of both joints and the tube's proximal face."""
    return 2 * spacers_per_joint + 1


def unknown_count(spacers_per_joint: int) -> int:
    """Size of the unknown vector (and of the residual vector)."""
    return N_BASE_UNKNOWNS + 4 * STATION_WIDTH * station_count(spacers_per_joint)


def interval_count(spacers_per_joint: int) -> int:
    """Disk intervals of one shot (two joints of S + 1 each); nodes start all but the first."""
    return 2 * (spacers_per_joint + 1)


def grid_points_per_rod(spacers_per_joint: int, steps: int) -> int:
    """Rows of centre-line points recorded per rod (each disk interval has steps + 1)."""
    return 2 * (spacers_per_joint + 1) * (steps + 1)


@jit
def _cross_sub(a, b, out):
    """Subtract a x b from out in place."""
    out[0] -= a[1] * b[2] - a[2] * b[1]
    out[1] -= a[2] * b[0] - a[0] * b[2]
    out[2] -= a[0] * b[1] - a[1] * b[0]


@jit
def _cross_add(a, b, out):
    """Add a x b to out in place."""
    out[0] += a[1] * b[2] - a[2] * b[1]
    out[1] += a[2] * b[0] - a[0] * b[2]
    out[2] += a[0] * b[1] - a[1] * b[0]


@jit
def _station_residuals(p, rot, hole, i, out, row):
    """Write the 5 conditions of secondary i at a disk whose frame is the primary's."""
    dx = p[i + 1, 0] - p[0, 0]
    dy = p[i + 1, 1] - p[0, 1]
    dz = p[i + 1, 2] - p[0, 2]
    for c in range(3):
        local = rot[0, 0, c] * dx + rot[0, 1, c] * dy + rot[0, 2, c] * dz
        out[row + c] = local - hole[i, c]
    for c in range(2):
        out[row + 3 + c] = (rot[0, 0, c] * rot[i + 1, 0, 2] + rot[0, 1, c] * rot[i + 1, 1, 2]
                            + rot[0, 2, c] * rot[i + 1, 2, 2])


@jit
def _in_plane(rot, a, b, out):
    """Set out = a * (disk x axis) + b * (disk y axis) for the primary's frame ``rot``."""
    for c in range(3):
        out[c] = a * rot[c, 0] + b * rot[c, 1]


@jit
def _spacer_disk(p, rot, n, m, x, col, out, row, hole):
    """Conditions and reactions of a thin spacer disk clamped to the primary backbone."""
    force = np.empty(3)
    moment = np.empty(3)
    arm = np.empty(3)
    for i in range(4):
        _station_residuals(p, rot, hole, i, out, row + STATION_WIDTH * i)
        u = col + STATION_WIDTH * i
        _in_plane(rot[0], x[u + 1], x[u + 2], force)
        _in_plane(rot[0], x[u + 3], x[u + 4], moment)
        for c in range(3):
            n[i + 1, c] += force[c]
            m[i + 1, c] += moment[c]
            n[0, c] -= force[c]
            m[0, c] -= moment[c]
            arm[c] = p[i + 1, c] - p[0, c]
        _cross_sub(arm, force, m[0])


@jit
def _tube(p, rot, n, m, x, col, out, row, hole, tube_length, inv_kse, inv_kbt, used):
    """Rigid multi-lumen tube: conditions at its proximal face and transfer to the distal."""
    axis = rot[0, :, 2].copy()
    proximal = p[0].copy()
    change_force = np.zeros(3)
    change_moment = np.zeros(3)  # of the secondaries' wrench, about the proximal centre
    arm = np.empty(3)
    lateral = np.empty(3)
    for i in range(4):
        k = i + 1
        _station_residuals(p, rot, hole, i, out, row + STATION_WIDTH * i)
        # the incoming wrench (about the proximal centre) counts negative
        for c in range(3):
            arm[c] = p[k, c] - proximal[c]
            change_force[c] -= n[k, c]
            change_moment[c] -= m[k, c]
        _cross_sub(arm, n[k], change_moment)
        axial_force = axis[0] * n[k, 0] + axis[1] * n[k, 1] + axis[2] * n[k, 2]
        torsion = (rot[k, 0, 2] * m[k, 0] + rot[k, 1, 2] * m[k, 1]
                   + rot[k, 2, 2] * m[k, 2])
        inside = tube_length / (1.0 + inv_kse[2] * axial_force)  # material length in lumen
        used[i] += inside
        twist = inv_kbt[2] * torsion * inside
        cos_t = math.cos(twist)
        sin_t = math.sin(twist)
        for c in range(3):  # R <- R Rz(twist)
            r0 = rot[k, c, 0]
            r1 = rot[k, c, 1]
            rot[k, c, 0] = cos_t * r0 + sin_t * r1
            rot[k, c, 1] = -sin_t * r0 + cos_t * r1
        u = col + STATION_WIDTH * i
        _in_plane(rot[0], x[u + 1], x[u + 2], lateral)
        for c in range(3):
            p[k, c] += tube_length * axis[c]
            n[k, c] = axial_force * axis[c] + lateral[c]
        _in_plane(rot[0], x[u + 3], x[u + 4], lateral)
        for c in range(3):
            m[k, c] = torsion * axis[c] + lateral[c]
            arm[c] = p[k, c] - proximal[c]
            change_force[c] += n[k, c]
            change_moment[c] += m[k, c]
        _cross_add(arm, n[k], change_moment)
    # tube equilibrium gives the primary's wrench leaving the distal face
    for c in range(3):
        n[0, c] -= change_force[c]
        m[0, c] -= change_moment[c]
        arm[c] = tube_length * axis[c]
        p[0, c] = proximal[c] + arm[c]
    _cross_sub(arm, n[0], m[0])


@jit
def _end_disk(p, rot, n, m, wrench, out, row, hole):
    """End-disk clamps of the secondaries (Eq. 10) and the disk's equilibrium (Eq. 11)."""
    arm = np.empty(3)
    moment = wrench[3:6].copy()
    for c in range(3):
        out[row + 24 + c] = wrench[c]
    for k in range(N_RODS):
        for c in range(3):
            arm[c] = p[k, c] - p[0, c]
            out[row + 24 + c] -= n[k, c]
            moment[c] -= m[k, c]
        _cross_sub(arm, n[k], moment)
        if k == 0:
            continue
        r = row + 6 * (k - 1)
        for c in range(3):
            out[r + c] = (rot[0, 0, c] * arm[0] + rot[0, 1, c] * arm[1]
                          + rot[0, 2, c] * arm[2] - hole[k - 1, c])
        # skew part of R_0^T R_k: its vee is sin(angle) * axis, zero when clamped
        q = np.zeros((3, 3))
        for a in range(3):
            for b in range(3):
                q[a, b] = (rot[0, 0, a] * rot[k, 0, b] + rot[0, 1, a] * rot[k, 1, b]
                           + rot[0, 2, a] * rot[k, 2, b])
        out[r + 3] = 0.5 * (q[2, 1] - q[1, 2])
        out[r + 4] = 0.5 * (q[0, 2] - q[2, 0])
        out[r + 5] = 0.5 * (q[1, 0] - q[0, 1])
    for c in range(3):
        out[row + 27 + c] = moment[c]


@jit
def _store_frame(rot, p, frame):
    frame[:3, :3] = rot
    frame[:3, 3] = p
    frame[3, :3] = 0.0
    frame[3, 3] = 1.0


@jit
def _gather_station(x, t, nst):
    """
    Return station t's unknowns contiguously, secondary by secondary.

    In ``x`` they are laid out with stride STATION_WIDTH * nst (see the module docstring).
    """
    col = np.empty(4 * STATION_WIDTH)
    for i in range(4):
        for c in range(STATION_WIDTH):
            col[STATION_WIDTH * i + c] = x[N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t) + c]
    return col


@jit_inline
def _enter(mode, node, defect, index, value):
    """One state value at a node: record it, or return the node's and write the defect."""
    if mode == RECORD_NODES:
        node[index] = value
        defect[index] = 0.0
        return value
    defect[index] = value - node[index]
    return node[index]


@jit
def _enter_node(mode, node, defect, p, rot, n, m, used):
    """
    Apply a node at the start of a disk interval (mode LIFT_NODES or RECORD_NODES).

    LIFT_NODES replaces the carried state (p, rot, n, m, used) by ``node`` and writes
    ``defect`` = carried - node; RECORD_NODES writes the carried state into ``node`` (defect
    zero). Layout: the STATE_* offsets.
    """
    for k in range(N_RODS):
        for c in range(3):
            p[k, c] = _enter(mode, node, defect, STATE_P + 3 * k + c, p[k, c])
            n[k, c] = _enter(mode, node, defect, STATE_N + 3 * k + c, n[k, c])
            m[k, c] = _enter(mode, node, defect, STATE_M + 3 * k + c, m[k, c])
            for b in range(3):
                rot[k, c, b] = _enter(mode, node, defect, STATE_ROT + 9 * k + 3 * c + b,
                                      rot[k, c, b])
    for i in range(4):
        used[i] = _enter(mode, node, defect, STATE_USED + i, used[i])


@jit
def _base_state(x, pitch_radius):
    """Return hole positions and the rods' state (p, R, n, m) at the base disk."""
    hole = np.zeros((4, 3))
    for i in range(4):
        angle = 0.5 * math.pi * i
        hole[i, 0] = pitch_radius * math.cos(angle)
        hole[i, 1] = pitch_radius * math.sin(angle)
    p = np.zeros((N_RODS, 3))
    rot = np.zeros((N_RODS, 3, 3))
    n = np.empty((N_RODS, 3))
    m = np.empty((N_RODS, 3))
    for k in range(N_RODS):
        for c in range(3):
            rot[k, c, c] = 1.0
            n[k, c] = x[6 * k + c]
            m[k, c] = x[6 * k + 3 + c]
        if k > 0:
            p[k, :] = hole[k - 1]
    return hole, p, rot, n, m


@jit
def translator_residual(x, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                        inv_kse, inv_kbt, out, points, frames):
    """
    Shoot once through the translator and write the residual vector into ``out``.

    ``frames`` (4, 4, 4) receives {pe}, {pm}, {dm}, {de}; ``points`` (5, rows, 3) the
    centre-line points of every rod when it has rows (see ``grid_points_per_rod``).
    """
    none = np.empty((0, STATE_SIZE))
    shoot_with_nodes(x, wrench, pitch_radius, spacing, tube_length, spacers, steps, inv_kse,
                     inv_kbt, out, points, frames, NO_NODES, none, none)


@jit
def shoot_with_nodes(x, wrench, pitch_radius, spacing, tube_length, spacers, steps, inv_kse,
                     inv_kbt, out, points, frames, mode, nodes, defects):
    """
    ``translator_residual`` with node states at the starts of the disk intervals 1, 2, ...

    ``nodes`` and ``defects`` are (interval_count - 1, STATE_SIZE), node j at the start of
    interval j + 1; ``mode`` one of NO_NODES, LIFT_NODES, RECORD_NODES (``_enter_node``).
    With LIFT_NODES every interval starts from its node (multiple shooting) and ``defects``
    receives the carried state minus the node's.
    """
    nst = 2 * spacers + 1
    hole, p, rot, n, m = _base_state(x, pitch_radius)
    _store_frame(rot[0], p[0], frames[0])
    secondary_length = 2.0 * (spacers + 1) * spacing + tube_length
    used = np.zeros(4)
    record = points.shape[1] > 0
    segment = 0
    scratch = np.empty(SEGMENT_SCRATCH)
    for joint in range(2):
        for station in range(spacers + 1):
            t = joint * (spacers + 1) + station
            if mode != NO_NODES and t > 0:
                _enter_node(mode, nodes[t - 1], defects[t - 1], p, rot, n, m, used)
            first_row = segment * (steps + 1) if record else 0
            integrate_segment(p[0], rot[0], n[0], m[0], spacing, steps, inv_kse, inv_kbt,
                              points[0], first_row, scratch)
            is_end = joint == 1 and station == spacers
            for i in range(4):
                if is_end:
                    length = secondary_length - used[i]
                else:
                    length = x[N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)]
                used[i] += length
                integrate_segment(p[i + 1], rot[i + 1], n[i + 1], m[i + 1], length, steps,
                                  inv_kse, inv_kbt, points[i + 1], first_row, scratch)
            segment += 1
            if is_end:
                _store_frame(rot[0], p[0], frames[3])
                _end_disk(p, rot, n, m, wrench, out, 4 * STATION_WIDTH * nst, hole)
                continue
            col = _gather_station(x, t, nst)
            res = np.empty(4 * STATION_WIDTH)
            if joint == 0 and station == spacers:
                _store_frame(rot[0], p[0], frames[1])
                _tube(p, rot, n, m, col, 0, res, 0, hole, tube_length, inv_kse, inv_kbt,
                      used)
                _store_frame(rot[0], p[0], frames[2])
            else:
                _spacer_disk(p, rot, n, m, col, 0, res, 0, hole)
            for i in range(4):
                for c in range(STATION_WIDTH):
                    out[STATION_WIDTH * (i * nst + t) + c] = res[STATION_WIDTH * i + c]


@jit
def residual_jacobian(x, step, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                      inv_kse, inv_kbt, base, jac, pose_jac):
    """
    Forward-difference Jacobian d(residual)/dx into ``jac``; ``base`` = residual at x.

    ``step`` holds the perturbation of every unknown. ``pose_jac`` (12, size) receives the
    same differences of the end-disk frame {de} (centre, rotation matrix row-major).
    """
    size = x.shape[0]
    column = np.empty(size)
    probe = x.copy()
    points = np.empty((N_RODS, 0, 3))
    frames = np.empty((4, 4, 4))
    translator_residual(probe, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                        inv_kse, inv_kbt, column, points, frames)
    end = np.empty(12)
    for c in range(3):
        end[c] = frames[3, c, 3]
        for b in range(3):
            end[3 + 3 * c + b] = frames[3, c, b]
    for j in range(size):
        probe[j] = x[j] + step[j]
        translator_residual(probe, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                            inv_kse, inv_kbt, column, points, frames)
        probe[j] = x[j]
        for r in range(size):
            jac[r, j] = (column[r] - base[r]) / step[j]
        for c in range(3):
            pose_jac[c, j] = (frames[3, c, 3] - end[c]) / step[j]
            for b in range(3):
                pose_jac[3 + 3 * c + b, j] = (frames[3, c, b] - end[3 + 3 * c + b]) / step[j]


# exact Jacobian: the tangent-linear (forward-mode) form of translator_residual ---------------
#
# Every state quantity q of the shot carries its tangent dq/dx, one column per unknown:
# tangent arrays have a trailing axis of length size. The rod segments contribute their
# exact local derivative (rod.integrate_segment_tangent, 16 local directions), chained into
# the global tangents here; the disks' algebraic conditions and wrench transfers are
# differentiated by hand, line by line against the primal helpers above, which still do the
# primal update. The result is the derivative of the discrete residual itself (to rounding),
# which central differences confirm (tests/core/test_jacobian.py).
#
# The tangent columns are kept station by station (``_internal_columns``): the base
# unknowns, the lifted column (below), then station 0's 20, station 1's, ... Upstream of
# station t's disk no tangent depends on a later station's unknowns, so every loop runs over
# the prefix of ``live`` columns that can be nonzero, contiguous and innermost (compiled to
# vector instructions); the Jacobian's columns are put back in the unknowns' order at the end.
#
# The lifted column (LIFT_COLUMN) is the condensing direction of the lifted Newton method
# (Albersmeyer & Diehl, SIAM J. Optim. 20(3), 2010; lifted.py): zero at the base, it gains
# each node's defect where the node replaces the carried state (a_t = L a_{t-1} + d_t), so
# its Jacobian column is R_z a, the residual change that the defects' Newton corrections
# cause. Without nodes it stays zero.

#: Tangent column of the lifted direction (between the base unknowns and the stations').
LIFT_COLUMN = N_BASE_UNKNOWNS


@jit
def _internal_columns(size, nst):
    """
    Return the unknown of each tangent column (size + 1 of them; the lifted one is ``size``).

    Base unknowns, the lifted column, then station by station.
    """
    order = np.empty(size + 1, dtype=np.int64)
    for q in range(N_BASE_UNKNOWNS):
        order[q] = q
    order[LIFT_COLUMN] = size
    for t in range(nst):
        for i in range(4):
            for c in range(STATION_WIDTH):
                order[_station_column(t, i) + c] = (N_BASE_UNKNOWNS
                                                    + STATION_WIDTH * (i * nst + t) + c)
    return order


@jit
def _station_column(t, i):
    """Tangent column of secondary i's first unknown at station t (see _internal_columns)."""
    return LIFT_COLUMN + 1 + STATION_WIDTH * (4 * t + i)


@jit
def _segment_inputs(k, tl, tp, trot, tn, tm, stack, active, live):
    """
    Gather rod k's input tangents into ``stack`` (LOCAL_DIRECTIONS, size), columns < live.

    ``active[j]`` says whether local direction j has any nonzero tangent: only those are
    integrated and chained.
    """
    for a in range(3):
        for b in range(3):
            for d in range(live):
                stack[LOCAL_ROT + 3 * a + b, d] = trot[k, a, b, d]
        for d in range(live):
            stack[LOCAL_N + a, d] = tn[k, a, d]
        for d in range(live):
            stack[LOCAL_M + a, d] = tm[k, a, d]
    for d in range(live):
        stack[LOCAL_LENGTH, d] = tl[d]
    for j in range(LOCAL_DIRECTIONS):
        active[j] = False
        for d in range(live):
            if stack[j, d] != 0.0:
                active[j] = True
                break


@jit_inline
def _add4(acc, c0, c1, c2, c3, s0, s1, s2, s3):
    """Return acc + c0 s0 + c1 s1 + c2 s2 + c3 s3, added in this order."""
    return acc + c0 * s0 + c1 * s1 + c2 * s2 + c3 * s3


@jit
def _chain_rows(local, row, out, stack, active, live, keep):
    """
    Set out[c] (c < 3, columns < live) to sum_j local[row + c, j] stack[j], plus out if keep.

    Directions go in blocks of four, so that each pass reads four rows of ``stack`` and
    writes three (a loop that writes few rows is vectorized); blocks with no active
    direction are skipped. The sum runs in direction order, as the plain loop would.
    """
    started = keep
    for j in range(0, LOCAL_DIRECTIONS, 4):
        if not (active[j] or active[j + 1] or active[j + 2] or active[j + 3]):
            continue
        a0, a1, a2, a3 = local[row, j], local[row, j + 1], local[row, j + 2], local[row, j + 3]
        b0, b1, b2, b3 = (local[row + 1, j], local[row + 1, j + 1], local[row + 1, j + 2],
                          local[row + 1, j + 3])
        c0, c1, c2, c3 = (local[row + 2, j], local[row + 2, j + 1], local[row + 2, j + 2],
                          local[row + 2, j + 3])
        if started:
            for d in range(live):
                s0, s1, s2, s3 = stack[j, d], stack[j + 1, d], stack[j + 2, d], stack[j + 3, d]
                out[0, d] = _add4(out[0, d], a0, a1, a2, a3, s0, s1, s2, s3)
                out[1, d] = _add4(out[1, d], b0, b1, b2, b3, s0, s1, s2, s3)
                out[2, d] = _add4(out[2, d], c0, c1, c2, c3, s0, s1, s2, s3)
        else:
            for d in range(live):
                s0, s1, s2, s3 = stack[j, d], stack[j + 1, d], stack[j + 2, d], stack[j + 3, d]
                out[0, d] = a0 * s0 + a1 * s1 + a2 * s2 + a3 * s3
                out[1, d] = b0 * s0 + b1 * s1 + b2 * s2 + b3 * s3
                out[2, d] = c0 * s0 + c1 * s1 + c2 * s2 + c3 * s3
        started = True
    if not started:
        for c in range(3):
            for d in range(live):
                out[c, d] = 0.0


@jit
def _chain_segment(k, local, tp, trot, tm, stack, active, live):
    """Chain rod k's local segment derivative ``local`` into its global tangents."""
    _chain_rows(local, TANGENT_P, tp[k], stack, active, live, True)
    _chain_rows(local, LOCAL_OUT_M, tm[k], stack, active, live, False)
    for a in range(3):
        _chain_rows(local, TANGENT_ROT + 3 * a, trot[k, a], stack, active, live, False)


@jit
def _segment_tangent(k, length, tl, p, rot, n, m, steps, inv_kse, inv_kbt, tp, trot, tn, tm,
                     stack, active, local, live):
    """Integrate rod k over a segment of ``length`` (tangent ``tl``), chaining its tangents."""
    _segment_inputs(k, tl, tp, trot, tn, tm, stack, active, live)
    integrate_segment_tangent(p[k], rot[k], n[k], m[k], length, steps, inv_kse, inv_kbt,
                              active, local)
    _chain_segment(k, local, tp, trot, tm, stack, active, live)


@jit
def _station_tangent(p, rot, tp, trot, i, jac, row, live):
    """Tangents of the 5 conditions of secondary i at a disk (see _station_residuals)."""
    e0 = p[i + 1, 0] - p[0, 0]
    e1 = p[i + 1, 1] - p[0, 1]
    e2 = p[i + 1, 2] - p[0, 2]
    for c in range(3):
        r0 = rot[0, 0, c]
        r1 = rot[0, 1, c]
        r2 = rot[0, 2, c]
        for d in range(live):
            jac[row + c, d] = (trot[0, 0, c, d] * e0 + r0 * (tp[i + 1, 0, d] - tp[0, 0, d])
                               + (trot[0, 1, c, d] * e1
                                  + r1 * (tp[i + 1, 1, d] - tp[0, 1, d]))
                               + (trot[0, 2, c, d] * e2
                                  + r2 * (tp[i + 1, 2, d] - tp[0, 2, d])))
    for c in range(2):
        r0 = rot[0, 0, c]
        r1 = rot[0, 1, c]
        r2 = rot[0, 2, c]
        s0 = rot[i + 1, 0, 2]
        s1 = rot[i + 1, 1, 2]
        s2 = rot[i + 1, 2, 2]
        for d in range(live):
            jac[row + 3 + c, d] = (trot[0, 0, c, d] * s0 + r0 * trot[i + 1, 0, 2, d]
                                   + (trot[0, 1, c, d] * s1 + r1 * trot[i + 1, 1, 2, d])
                                   + (trot[0, 2, c, d] * s2 + r2 * trot[i + 1, 2, 2, d]))


@jit
def _in_plane_tangent(rot, trot, a, b, col_a, out, live):
    """Tangent of a * (disk x axis) + b * (disk y axis); a, b the columns col_a, col_a + 1."""
    for c in range(3):
        for d in range(live):
            out[c, d] = a * trot[c, 0, d] + b * trot[c, 1, d]
        out[c, col_a] += rot[c, 0]
        out[c, col_a + 1] += rot[c, 1]


@jit
def _cross_tangent_sub(a, ta, b, tb, out, live):
    """Subtract the tangent of a x b, (ta x b + a x tb), from out (3, columns < live)."""
    for d in range(live):
        out[0, d] -= ta[1, d] * b[2] - ta[2, d] * b[1] + a[1] * tb[2, d] - a[2] * tb[1, d]
        out[1, d] -= ta[2, d] * b[0] - ta[0, d] * b[2] + a[2] * tb[0, d] - a[0] * tb[2, d]
        out[2, d] -= ta[0, d] * b[1] - ta[1, d] * b[0] + a[0] * tb[1, d] - a[1] * tb[0, d]


@jit
def _spacer_disk_tangent(p, rot, n, m, x, t, nst, tp, trot, tn, tm, jac, live):
    """Tangents of ``_spacer_disk`` at station t; call it before the primal helper."""
    force = np.empty(3)
    arm = np.empty(3)
    tforce = np.empty((3, live))
    tmoment = np.empty((3, live))
    tarm = np.empty((3, live))
    for i in range(4):
        u = N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)
        column = _station_column(t, i)
        _station_tangent(p, rot, tp, trot, i, jac, STATION_WIDTH * (i * nst + t), live)
        _in_plane(rot[0], x[u + 1], x[u + 2], force)
        _in_plane_tangent(rot[0], trot[0], x[u + 1], x[u + 2], column + 1, tforce, live)
        _in_plane_tangent(rot[0], trot[0], x[u + 3], x[u + 4], column + 3, tmoment, live)
        for c in range(3):
            arm[c] = p[i + 1, c] - p[0, c]
            for d in range(live):
                tarm[c, d] = tp[i + 1, c, d] - tp[0, c, d]
                tn[i + 1, c, d] += tforce[c, d]
                tm[i + 1, c, d] += tmoment[c, d]
                tn[0, c, d] -= tforce[c, d]
                tm[0, c, d] -= tmoment[c, d]
        _cross_tangent_sub(arm, tarm, force, tforce, tm[0], live)


@jit
def _tube_tangent(p, rot, n, m, x, t, nst, tube_length, inv_kse, inv_kbt, tp, trot, tn, tm,
                  tused, jac, live):
    """Tangents of ``_tube`` at station t; call it before the primal helper."""
    axis = rot[0, :, 2].copy()
    taxis = np.empty((3, live))
    tproximal = np.empty((3, live))
    for c in range(3):
        for d in range(live):
            taxis[c, d] = trot[0, c, 2, d]
            tproximal[c, d] = tp[0, c, d]
    proximal = p[0].copy()
    tchange_force = np.zeros((3, live))
    tchange_moment = np.zeros((3, live))
    change_force = np.zeros(3)
    change_moment = np.zeros(3)
    arm = np.empty(3)
    tarm = np.empty((3, live))
    nk = np.empty(3)
    mk = np.empty(3)
    tlat = np.empty((3, live))
    tlat2 = np.empty((3, live))
    tscalar = np.empty((4, live))  # tangents of the axial force, torsion, cos and sin
    lat = np.empty(3)
    lat2 = np.empty(3)
    for i in range(4):
        k = i + 1
        u = N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)
        column = _station_column(t, i)
        _station_tangent(p, rot, tp, trot, i, jac, STATION_WIDTH * (i * nst + t), live)
        for c in range(3):
            arm[c] = p[k, c] - proximal[c]
            change_force[c] -= n[k, c]
            change_moment[c] -= m[k, c]
            for d in range(live):
                tarm[c, d] = tp[k, c, d] - tproximal[c, d]
                tchange_force[c, d] -= tn[k, c, d]
                tchange_moment[c, d] -= tm[k, c, d]
        _cross_sub(arm, n[k], change_moment)
        _cross_tangent_sub(arm, tarm, n[k], tn[k], tchange_moment, live)
        axial_force = axis[0] * n[k, 0] + axis[1] * n[k, 1] + axis[2] * n[k, 2]
        torsion = rot[k, 0, 2] * m[k, 0] + rot[k, 1, 2] * m[k, 1] + rot[k, 2, 2] * m[k, 2]
        denominator = 1.0 + inv_kse[2] * axial_force
        inside = tube_length / denominator
        twist = inv_kbt[2] * torsion * inside
        cos_t = math.cos(twist)
        sin_t = math.sin(twist)
        _in_plane(rot[0], x[u + 1], x[u + 2], lat)
        _in_plane(rot[0], x[u + 3], x[u + 4], lat2)
        _in_plane_tangent(rot[0], trot[0], x[u + 1], x[u + 2], column + 1, tlat, live)
        _in_plane_tangent(rot[0], trot[0], x[u + 3], x[u + 4], column + 3, tlat2, live)
        # (loops that write few rows each, so that they are vectorized)
        n0, n1, n2 = n[k, 0], n[k, 1], n[k, 2]
        m0, m1, m2 = m[k, 0], m[k, 1], m[k, 2]
        z0, z1, z2 = rot[k, 0, 2], rot[k, 1, 2], rot[k, 2, 2]
        for d in range(live):
            t_axial = (taxis[0, d] * n0 + axis[0] * tn[k, 0, d]
                       + (taxis[1, d] * n1 + axis[1] * tn[k, 1, d])
                       + (taxis[2, d] * n2 + axis[2] * tn[k, 2, d]))
            t_torsion = (trot[k, 0, 2, d] * m0 + z0 * tm[k, 0, d]
                         + (trot[k, 1, 2, d] * m1 + z1 * tm[k, 1, d])
                         + (trot[k, 2, 2, d] * m2 + z2 * tm[k, 2, d]))
            t_inside = -tube_length * inv_kse[2] * t_axial / denominator ** 2
            tused[i, d] += t_inside
            t_twist = inv_kbt[2] * (t_torsion * inside + torsion * t_inside)
            tscalar[0, d] = t_axial
            tscalar[1, d] = t_torsion
            tscalar[2, d] = -sin_t * t_twist  # of cos(twist)
            tscalar[3, d] = cos_t * t_twist  # of sin(twist)
        for c in range(3):  # R <- R Rz(twist)
            r0 = rot[k, c, 0]
            r1 = rot[k, c, 1]
            for d in range(live):
                t_cos = tscalar[2, d]
                t_sin = tscalar[3, d]
                s0 = trot[k, c, 0, d]
                s1 = trot[k, c, 1, d]
                trot[k, c, 0, d] = t_cos * r0 + cos_t * s0 + t_sin * r1 + sin_t * s1
                trot[k, c, 1, d] = -t_sin * r0 - sin_t * s0 + t_cos * r1 + cos_t * s1
                tp[k, c, d] += tube_length * taxis[c, d]
            for d in range(live):
                tn[k, c, d] = tscalar[0, d] * axis[c] + axial_force * taxis[c, d] + tlat[c, d]
                tm[k, c, d] = tscalar[1, d] * axis[c] + torsion * taxis[c, d] + tlat2[c, d]
                tarm[c, d] = tp[k, c, d] - tproximal[c, d]
                tchange_force[c, d] += tn[k, c, d]
                tchange_moment[c, d] += tm[k, c, d]
        for c in range(3):
            nk[c] = axial_force * axis[c] + lat[c]
            mk[c] = torsion * axis[c] + lat2[c]
            arm[c] = p[k, c] + tube_length * axis[c] - proximal[c]
            change_force[c] += nk[c]
            change_moment[c] += mk[c]
        # change_moment += arm x n_k and its tangent
        for c in range(3):
            lat[c] = -arm[c]
        _cross_sub(lat, nk, change_moment)
        for c in range(3):
            for d in range(live):
                tlat[c, d] = -tarm[c, d]
        _cross_tangent_sub(lat, tlat, nk, tn[k], tchange_moment, live)
    for c in range(3):
        nk[c] = n[0, c] - change_force[c]
        arm[c] = tube_length * axis[c]
        for d in range(live):
            tn[0, c, d] -= tchange_force[c, d]
            tm[0, c, d] -= tchange_moment[c, d]
            tarm[c, d] = tube_length * taxis[c, d]
            tp[0, c, d] = tproximal[c, d] + tarm[c, d]
    _cross_tangent_sub(arm, tarm, nk, tn[0], tm[0], live)


@jit_inline
def _relative_rotation_tangent(rot, trot, k, a, b, d):
    """Tangent (column d) of entry (a, b) of R_0^T R_k."""
    return (trot[0, 0, a, d] * rot[k, 0, b] + rot[0, 0, a] * trot[k, 0, b, d]
            + (trot[0, 1, a, d] * rot[k, 1, b] + rot[0, 1, a] * trot[k, 1, b, d])
            + (trot[0, 2, a, d] * rot[k, 2, b] + rot[0, 2, a] * trot[k, 2, b, d]))


@jit
def _end_disk_tangent(p, rot, n, tp, trot, tn, tm, jac, row, live):
    """Tangents of ``_end_disk`` (the wrench enters linearly and has no x-tangent)."""
    arm = np.empty(3)
    tarm = np.empty((3, live))
    tmoment = np.zeros((3, live))
    for c in range(3):
        for d in range(live):
            jac[row + 24 + c, d] = 0.0
    for k in range(N_RODS):
        for c in range(3):
            arm[c] = p[k, c] - p[0, c]
            for d in range(live):
                tarm[c, d] = tp[k, c, d] - tp[0, c, d]
                jac[row + 24 + c, d] -= tn[k, c, d]
                tmoment[c, d] -= tm[k, c, d]
        _cross_tangent_sub(arm, tarm, n[k], tn[k], tmoment, live)
        if k == 0:
            continue
        r = row + 6 * (k - 1)
        for c in range(3):
            r0 = rot[0, 0, c]
            r1 = rot[0, 1, c]
            r2 = rot[0, 2, c]
            for d in range(live):
                jac[r + c, d] = (trot[0, 0, c, d] * arm[0] + r0 * tarm[0, d]
                                 + (trot[0, 1, c, d] * arm[1] + r1 * tarm[1, d])
                                 + (trot[0, 2, c, d] * arm[2] + r2 * tarm[2, d]))
        # the skew part of R_0^T R_k (see _end_disk)
        for c in range(3):
            a = (c + 2) % 3  # the entries (a, b) - (b, a) of R_0^T R_k give component c
            b = (c + 1) % 3
            for d in range(live):
                jac[r + 3 + c, d] = 0.5 * (_relative_rotation_tangent(rot, trot, k, a, b, d)
                                           - _relative_rotation_tangent(rot, trot, k, b, a, d))
    for c in range(3):
        for d in range(live):
            jac[row + 27 + c, d] = tmoment[c, d]


@jit
def _unknowns_order(internal, nst, jac, lifted):
    """
    Put the Jacobian's columns (tangent-column order) in the unknowns' order.

    ``internal`` (size, size + 1) in tangent-column order goes to ``jac`` (size, size), its
    lifted column to ``lifted`` (size). The rows of station t were written only for the
    columns before station t + 1's (the rest are zero by construction), so nothing else need
    be cleared beforehand.
    """
    size = jac.shape[1]
    for r in range(jac.shape[0]):
        live = size + 1
        if r < 4 * STATION_WIDTH * nst:
            live = _station_column(r // STATION_WIDTH % nst + 1, 0)
        for q in range(N_BASE_UNKNOWNS):
            jac[r, q] = internal[r, q]
        lifted[r] = internal[r, LIFT_COLUMN]
        for t in range(nst):
            for i in range(4):
                source = _station_column(t, i)
                target = N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)
                for c in range(STATION_WIDTH):
                    jac[r, target + c] = internal[r, source + c] if source + c < live else 0.0


@jit
def _record_node_tangents(tp, trot, tn, tm, tused, out, live):
    """Copy the state's tangents (columns < live, tangent-column order) in STATE_* layout."""
    for k in range(N_RODS):
        for c in range(3):
            for d in range(live):
                out[STATE_P + 3 * k + c, d] = tp[k, c, d]
            for d in range(live):
                out[STATE_N + 3 * k + c, d] = tn[k, c, d]
            for d in range(live):
                out[STATE_M + 3 * k + c, d] = tm[k, c, d]
            for b in range(3):
                for d in range(live):
                    out[STATE_ROT + 9 * k + 3 * c + b, d] = trot[k, c, b, d]
    for i in range(4):
        for d in range(live):
            out[STATE_USED + i, d] = tused[i, d]


@jit
def _seed_defect(defect, tp, trot, tn, tm, tused):
    """Add a node's defect to the lifted column of the state's tangents (a_t += d_t)."""
    q = LIFT_COLUMN
    for k in range(N_RODS):
        for c in range(3):
            tp[k, c, q] += defect[STATE_P + 3 * k + c]
            tn[k, c, q] += defect[STATE_N + 3 * k + c]
            tm[k, c, q] += defect[STATE_M + 3 * k + c]
            for b in range(3):
                trot[k, c, b, q] += defect[STATE_ROT + 9 * k + 3 * c + b]
    for i in range(4):
        tused[i, q] += defect[STATE_USED + i]


@jit
def translator_jacobian(x, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                        inv_kse, inv_kbt, out, jac, pose_jac, frames):
    """
    Residual into ``out`` and its exact Jacobian d(out)/dx into ``jac`` from one shot.

    ``pose_jac`` (12, size) receives the derivative of the end-disk frame {de}: rows 0-2 its
    centre, rows 3-11 its rotation matrix (row-major); ``frames`` as in translator_residual.
    """
    none = np.empty((0, STATE_SIZE))
    lifted_jacobian(x, wrench, pitch_radius, spacing, tube_length, spacers, steps, inv_kse,
                    inv_kbt, out, jac, pose_jac, frames, NO_NODES, none, none,
                    np.empty(x.shape[0]), np.empty((0, STATE_SIZE, 0)))


@jit
def lifted_jacobian(x, wrench, pitch_radius, spacing, tube_length, spacers, steps, inv_kse,
                    inv_kbt, out, jac, pose_jac, frames, mode, nodes, defects, lifted,
                    node_tangents):
    """
    ``translator_jacobian`` of the shot with nodes (``shoot_with_nodes``: mode, nodes, defects).

    The tangents are those of single shooting chained through the nodes (Z_t, the derivative
    of the carried state with respect to x), evaluated at the node states; with LIFT_NODES
    the lifted column carries the defects (see LIFT_COLUMN) and ``lifted`` (size) receives
    its residual rows, R_z a. ``node_tangents`` (nodes, STATE_SIZE, size + 1), when it has
    rows, receives at each node the state's tangents in tangent-column order (columns below
    ``_station_column(t, 0)`` for node t - 1; the others are not written): Z_t and a_t.
    """
    size = x.shape[0]
    columns = size + 1
    nst = 2 * spacers + 1
    order = _internal_columns(size, nst)
    hole, p, rot, n, m = _base_state(x, pitch_radius)
    tp = np.zeros((N_RODS, 3, columns))
    trot = np.zeros((N_RODS, 3, 3, columns))
    tn = np.zeros((N_RODS, 3, columns))
    tm = np.zeros((N_RODS, 3, columns))
    tused = np.zeros((4, columns))
    tl = np.zeros(columns)
    stack = np.empty((LOCAL_DIRECTIONS, columns))
    internal = np.empty((size, columns))
    active = np.zeros(LOCAL_DIRECTIONS, dtype=np.bool_)
    local = np.empty((LOCAL_OUTPUTS, LOCAL_DIRECTIONS))
    for k in range(N_RODS):
        for c in range(3):
            tn[k, c, 6 * k + c] = 1.0
            tm[k, c, 6 * k + 3 + c] = 1.0
    _store_frame(rot[0], p[0], frames[0])
    secondary_length = 2.0 * (spacers + 1) * spacing + tube_length
    used = np.zeros(4)
    for joint in range(2):
        for station in range(spacers + 1):
            t = joint * (spacers + 1) + station
            if mode != NO_NODES and t > 0:
                _enter_node(mode, nodes[t - 1], defects[t - 1], p, rot, n, m, used)
                if mode == LIFT_NODES:
                    _seed_defect(defects[t - 1], tp, trot, tn, tm, tused)
                if node_tangents.shape[0] > 0:
                    _record_node_tangents(tp, trot, tn, tm, tused, node_tangents[t - 1],
                                          _station_column(t, 0))
            is_end = joint == 1 and station == spacers
            # columns that can be nonzero up to this station's disk
            live = columns if is_end else _station_column(t + 1, 0)
            _segment_tangent(0, spacing, tl, p, rot, n, m, steps, inv_kse, inv_kbt, tp, trot,
                             tn, tm, stack, active, local, live)
            for i in range(4):
                if is_end:
                    length = secondary_length - used[i]
                    for d in range(live):
                        tl[d] = -tused[i, d]
                else:
                    length = x[N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)]
                    tl[_station_column(t, i)] = 1.0
                used[i] += length
                for d in range(live):
                    tused[i, d] += tl[d]
                _segment_tangent(i + 1, length, tl, p, rot, n, m, steps, inv_kse, inv_kbt, tp,
                                 trot, tn, tm, stack, active, local, live)
                for d in range(live):
                    tl[d] = 0.0
            if is_end:
                _store_frame(rot[0], p[0], frames[3])
                for c in range(3):
                    for d in range(columns):
                        if order[d] < size:
                            pose_jac[c, order[d]] = tp[0, c, d]
                    for b in range(3):
                        for d in range(columns):
                            if order[d] < size:
                                pose_jac[3 + 3 * c + b, order[d]] = trot[0, c, b, d]
                _end_disk_tangent(p, rot, n, tp, trot, tn, tm, internal,
                                  4 * STATION_WIDTH * nst, live)
                _end_disk(p, rot, n, m, wrench, out, 4 * STATION_WIDTH * nst, hole)
                continue
            col = _gather_station(x, t, nst)
            res = np.empty(4 * STATION_WIDTH)
            if joint == 0 and station == spacers:
                _store_frame(rot[0], p[0], frames[1])
                _tube_tangent(p, rot, n, m, x, t, nst, tube_length, inv_kse, inv_kbt, tp,
                              trot, tn, tm, tused, internal, live)
                _tube(p, rot, n, m, col, 0, res, 0, hole, tube_length, inv_kse, inv_kbt,
                      used)
                _store_frame(rot[0], p[0], frames[2])
            else:
                _spacer_disk_tangent(p, rot, n, m, x, t, nst, tp, trot, tn, tm, internal,
                                     live)
                _spacer_disk(p, rot, n, m, col, 0, res, 0, hole)
            for i in range(4):
                for c in range(STATION_WIDTH):
                    out[STATION_WIDTH * (i * nst + t) + c] = res[STATION_WIDTH * i + c]
    _unknowns_order(internal, nst, jac, lifted)


@jit
def _orthonormalize(rot):
    """
    Replace the 3x3 ``rot`` by its orthogonal polar factor, in place (Newton's iteration).

    X <- (X + X^-T) / 2 converges quadratically to the nearest rotation from a near one
    (Higham, Functions of Matrices, SIAM 2008, Sec. 8.3); cof(X) / det(X) is X^-T.
    """
    cof = np.empty((3, 3))
    for _ in range(8):
        for a in range(3):
            a1 = (a + 1) % 3
            a2 = (a + 2) % 3
            for b in range(3):
                b1 = (b + 1) % 3
                b2 = (b + 2) % 3
                cof[a, b] = rot[a1, b1] * rot[a2, b2] - rot[a1, b2] * rot[a2, b1]
        det = rot[0, 0] * cof[0, 0] + rot[0, 1] * cof[0, 1] + rot[0, 2] * cof[0, 2]
        change = 0.0
        for a in range(3):
            for b in range(3):
                new = 0.5 * (rot[a, b] + cof[a, b] / det)
                change = max(change, abs(new - rot[a, b]))
                rot[a, b] = new
        if change <= 1e-15:
            return


#: A node rotation R with max |R^T R - I| above this is projected onto SO(3) after an update
#: (a long Newton step far from the solution). Smaller departures are left as Newton made
#: them: the carried rotations themselves are orthogonal only to the RK4 error (above 1e-7
#: at nine spacer disks and 13 N), and projecting those left defects of that size that
#: Newton could never remove (the iteration stalled at residuals of 1.8e-7).
ORTHOGONALITY_SLACK = 1e-3


@jit
def advance_nodes(nodes, node_tangents, step, spacers, slack):
    """
    Update the nodes as lifted Newton does: z_t += w a_t + Z_t dx, rotations projected.

    ``node_tangents`` as ``lifted_jacobian`` wrote them; ``step`` (size + 1) holds dx, the
    step of the unknowns (SI, unknowns' order), then the weight w of the lifted column. The
    update is linear in the 9 entries of each rotation; one that
    leaves it further than ``slack`` (max |R^T R - I|, e.g. ORTHOGONALITY_SLACK) from
    orthogonal is put back onto SO(3) by its polar factor (``_orthonormalize``).
    """
    size = step.shape[0] - 1
    order = _internal_columns(size, 2 * spacers + 1)
    internal = np.empty(size + 1)
    for d in range(size + 1):
        internal[d] = step[order[d]]
    rot = np.empty((3, 3))
    for j in range(nodes.shape[0]):
        live = _station_column(j + 1, 0)
        for r in range(STATE_SIZE):
            acc = 0.0
            for d in range(live):
                acc += node_tangents[j, r, d] * internal[d]
            nodes[j, r] += acc
        for k in range(N_RODS):
            for a in range(3):
                for b in range(3):
                    rot[a, b] = nodes[j, STATE_ROT + 9 * k + 3 * a + b]
            departure = 0.0
            for a in range(3):
                for b in range(3):
                    gram = rot[0, a] * rot[0, b] + rot[1, a] * rot[1, b] + rot[2, a] * rot[2, b]
                    departure = max(departure, abs(gram - (1.0 if a == b else 0.0)))
            if departure <= slack:
                continue
            _orthonormalize(rot)
            for a in range(3):
                for b in range(3):
                    nodes[j, STATE_ROT + 9 * k + 3 * a + b] = rot[a, b]
