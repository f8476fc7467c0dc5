"""
The translator's residual by shooting (paper Section III.C, Eq. 7-11).

One shooting pass integrates all five rods (the Cosserat rods of Eq. 1-6, rod.py) disk
interval by disk interval and applies the disk conditions on the way: the secondaries'
holes and tangents at every spacer disk and at the tube's proximal face (Eq. 7-8), the
end-disk clamps (Eq. 10) and the end disk's equilibrium under the applied wrench (Eq. 11).
Unknowns and residuals are laid out as layout.py says.

Modelling choices where the paper is silent:
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

from .layout import N_BASE_UNKNOWNS, N_RODS, NO_NODES, STATE_SIZE, STATION_WIDTH
from .multiple_shooting_kernels import enter_node
from .rod import integrate_segment, SEGMENT_SCRATCH
from .._jit import jit


@jit
def cross_sub(a, b, out):
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
def in_plane(rot, a, b, out):
    """Set out = a * (disk x axis) + b * (disk y axis) for the primary's frame ``rot``."""
    for c in range(3):
        out[c] = a * rot[c, 0] + b * rot[c, 1]


@jit
def spacer_disk(p, rot, n, m, x, col, out, row, hole):
    """Conditions and reactions of a thin spacer disk clamped to the primary backbone."""
    force = np.empty(3)
    moment = np.empty(3)
    arm = np.empty(3)
    for i in range(4):
        _station_residuals(p, rot, hole, i, out, row + STATION_WIDTH * i)
        u = col + STATION_WIDTH * i
        in_plane(rot[0], x[u + 1], x[u + 2], force)
        in_plane(rot[0], x[u + 3], x[u + 4], moment)
        for c in range(3):
            n[i + 1, c] += force[c]
            m[i + 1, c] += moment[c]
            n[0, c] -= force[c]
            m[0, c] -= moment[c]
            arm[c] = p[i + 1, c] - p[0, c]
        cross_sub(arm, force, m[0])


@jit
def tube(p, rot, n, m, x, col, out, row, hole, tube_length, inv_kse, inv_kbt, used):
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
        cross_sub(arm, n[k], change_moment)
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
        in_plane(rot[0], x[u + 1], x[u + 2], lateral)
        for c in range(3):
            p[k, c] += tube_length * axis[c]
            n[k, c] = axial_force * axis[c] + lateral[c]
        in_plane(rot[0], x[u + 3], x[u + 4], lateral)
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
    cross_sub(arm, n[0], m[0])


@jit
def end_disk(p, rot, n, m, wrench, out, row, hole):
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
        cross_sub(arm, n[k], moment)
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
def store_frame(rot, p, frame):
    """Write the homogeneous 4x4 ``frame`` of rotation ``rot`` and origin ``p``."""
    frame[:3, :3] = rot
    frame[:3, 3] = p
    frame[3, :3] = 0.0
    frame[3, 3] = 1.0


@jit
def gather_station(x, t, nst):
    """
    Return station t's unknowns contiguously, secondary by secondary.

    In ``x`` they are laid out with stride STATION_WIDTH * nst (see layout.py).
    """
    col = np.empty(4 * STATION_WIDTH)
    for i in range(4):
        for c in range(STATION_WIDTH):
            col[STATION_WIDTH * i + c] = x[N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t) + c]
    return col


@jit
def base_state(x, pitch_radius):
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
    centre-line points of every rod when it has rows (see ``layout.grid_points_per_rod``).
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
    interval j + 1; ``mode`` one of NO_NODES, LIFT_NODES, RECORD_NODES (``enter_node``).
    With LIFT_NODES every interval starts from its node (multiple shooting) and ``defects``
    receives the carried state minus the node's.
    """
    nst = 2 * spacers + 1
    hole, p, rot, n, m = base_state(x, pitch_radius)
    store_frame(rot[0], p[0], frames[0])
    secondary_length = 2.0 * (spacers + 1) * spacing + tube_length
    used = np.zeros(4)
    record = points.shape[1] > 0
    segment = 0
    scratch = np.empty(SEGMENT_SCRATCH)
    for joint in range(2):
        for station in range(spacers + 1):
            t = joint * (spacers + 1) + station
            if mode != NO_NODES and t > 0:
                enter_node(mode, nodes[t - 1], defects[t - 1], p, rot, n, m, used)
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
                store_frame(rot[0], p[0], frames[3])
                end_disk(p, rot, n, m, wrench, out, 4 * STATION_WIDTH * nst, hole)
                continue
            col = gather_station(x, t, nst)
            res = np.empty(4 * STATION_WIDTH)
            if joint == 0 and station == spacers:
                store_frame(rot[0], p[0], frames[1])
                tube(p, rot, n, m, col, 0, res, 0, hole, tube_length, inv_kse, inv_kbt, used)
                store_frame(rot[0], p[0], frames[2])
            else:
                spacer_disk(p, rot, n, m, col, 0, res, 0, hole)
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
