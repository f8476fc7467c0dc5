"""
The exact Jacobian of the shot: the tangent-linear (forward-mode) form of shooting.py.

It differentiates the discretized residual of the paper's Section III.C (the rods of
Eq. 1-6 integrated by RK4, the disk conditions of Eq. 7-8, the end disk's Eq. 10-11).
Every state quantity q of the shot carries its tangent dq/dx, one column per unknown:
tangent arrays have a trailing axis of length size + 1. The rod segments contribute their
exact local derivative (rod.integrate_segment_tangent, 16 local directions), chained into
the global tangents here; the disks' algebraic conditions and wrench transfers are
differentiated by hand, line by line against the primal helpers of shooting.py, which
still do the primal update. The result is the derivative of the discrete residual itself
(to rounding), which central differences confirm (tests/bvp/test_jacobian.py).

The tangent columns are kept station by station (layout.internal_columns): the base
unknowns, the lifted column (layout.LIFT_COLUMN), then station 0's 20, station 1's, ...
Upstream of station t's disk no tangent depends on a later station's unknowns, so every
loop runs over the prefix of ``live`` columns that can be nonzero, contiguous and innermost
(compiled to vector instructions); the Jacobian's columns are put back in the unknowns'
order at the end. With node states (multiple shooting) the same shot chains the tangents
through the nodes and seeds the lifted column with their defects
(multiple_shooting_kernels.py).
"""

import math

import numpy as np

from .layout import (internal_columns, LIFT_COLUMN, LIFT_NODES, N_BASE_UNKNOWNS, N_RODS,
                     NO_NODES, STATE_SIZE, station_column, STATION_WIDTH)
from .multiple_shooting_kernels import enter_node, record_node_tangents, seed_defect
from .rod import (integrate_segment_tangent, LOCAL_DIRECTIONS, LOCAL_LENGTH, LOCAL_M, LOCAL_N,
                  LOCAL_OUT_M, LOCAL_OUTPUTS, LOCAL_ROT, TANGENT_P, TANGENT_ROT)
from .shooting import (base_state, cross_sub, end_disk, gather_station, in_plane, spacer_disk,
                       store_frame, tube)
from .._jit import jit, jit_inline


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
    """Tangents of the 5 conditions of secondary i at a disk (shooting.py's station residuals)."""
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
    """Tangents of ``spacer_disk`` at station t; call it before the primal helper."""
    force = np.empty(3)
    arm = np.empty(3)
    tforce = np.empty((3, live))
    tmoment = np.empty((3, live))
    tarm = np.empty((3, live))
    for i in range(4):
        u = N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)
        column = station_column(t, i)
        _station_tangent(p, rot, tp, trot, i, jac, STATION_WIDTH * (i * nst + t), live)
        in_plane(rot[0], x[u + 1], x[u + 2], force)
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
    """Tangents of ``tube`` at station t; call it before the primal helper."""
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
        column = station_column(t, i)
        _station_tangent(p, rot, tp, trot, i, jac, STATION_WIDTH * (i * nst + t), live)
        for c in range(3):
            arm[c] = p[k, c] - proximal[c]
            change_force[c] -= n[k, c]
            change_moment[c] -= m[k, c]
            for d in range(live):
                tarm[c, d] = tp[k, c, d] - tproximal[c, d]
                tchange_force[c, d] -= tn[k, c, d]
                tchange_moment[c, d] -= tm[k, c, d]
        cross_sub(arm, n[k], change_moment)
        _cross_tangent_sub(arm, tarm, n[k], tn[k], tchange_moment, live)
        axial_force = axis[0] * n[k, 0] + axis[1] * n[k, 1] + axis[2] * n[k, 2]
        torsion = rot[k, 0, 2] * m[k, 0] + rot[k, 1, 2] * m[k, 1] + rot[k, 2, 2] * m[k, 2]
        denominator = 1.0 + inv_kse[2] * axial_force
        inside = tube_length / denominator
        twist = inv_kbt[2] * torsion * inside
        cos_t = math.cos(twist)
        sin_t = math.sin(twist)
        in_plane(rot[0], x[u + 1], x[u + 2], lat)
        in_plane(rot[0], x[u + 3], x[u + 4], lat2)
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
        cross_sub(lat, nk, change_moment)
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
    """Tangents of ``end_disk`` (the wrench enters linearly and has no x-tangent)."""
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
        # the skew part of R_0^T R_k (see end_disk)
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
            live = station_column(r // STATION_WIDTH % nst + 1, 0)
        for q in range(N_BASE_UNKNOWNS):
            jac[r, q] = internal[r, q]
        lifted[r] = internal[r, LIFT_COLUMN]
        for t in range(nst):
            for i in range(4):
                source = station_column(t, i)
                target = N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)
                for c in range(STATION_WIDTH):
                    jac[r, target + c] = internal[r, source + c] if source + c < live else 0.0


@jit
def translator_jacobian(x, wrench, pitch_radius, spacing, tube_length, spacers, steps,
                        inv_kse, inv_kbt, out, jac, pose_jac, frames):
    """
    Residual into ``out`` and its exact Jacobian d(out)/dx into ``jac`` from one shot.

    ``pose_jac`` (12, size) receives the derivative of the end-disk frame {de}: rows 0-2 its
    centre, rows 3-11 its rotation matrix (row-major); ``frames`` as in
    shooting.translator_residual.
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
    ``station_column(t, 0)`` for node t - 1; the others are not written): Z_t and a_t.
    """
    size = x.shape[0]
    columns = size + 1
    nst = 2 * spacers + 1
    order = internal_columns(size, nst)
    hole, p, rot, n, m = base_state(x, pitch_radius)
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
    store_frame(rot[0], p[0], frames[0])
    secondary_length = 2.0 * (spacers + 1) * spacing + tube_length
    used = np.zeros(4)
    for joint in range(2):
        for station in range(spacers + 1):
            t = joint * (spacers + 1) + station
            if mode != NO_NODES and t > 0:
                enter_node(mode, nodes[t - 1], defects[t - 1], p, rot, n, m, used)
                if mode == LIFT_NODES:
                    seed_defect(defects[t - 1], tp, trot, tn, tm, tused)
                if node_tangents.shape[0] > 0:
                    record_node_tangents(tp, trot, tn, tm, tused, node_tangents[t - 1],
                                         station_column(t, 0))
            is_end = joint == 1 and station == spacers
            # columns that can be nonzero up to this station's disk
            live = columns if is_end else station_column(t + 1, 0)
            _segment_tangent(0, spacing, tl, p, rot, n, m, steps, inv_kse, inv_kbt, tp, trot,
                             tn, tm, stack, active, local, live)
            for i in range(4):
                if is_end:
                    length = secondary_length - used[i]
                    for d in range(live):
                        tl[d] = -tused[i, d]
                else:
                    length = x[N_BASE_UNKNOWNS + STATION_WIDTH * (i * nst + t)]
                    tl[station_column(t, i)] = 1.0
                used[i] += length
                for d in range(live):
                    tused[i, d] += tl[d]
                _segment_tangent(i + 1, length, tl, p, rot, n, m, steps, inv_kse, inv_kbt, tp,
                                 trot, tn, tm, stack, active, local, live)
                for d in range(live):
                    tl[d] = 0.0
            if is_end:
                store_frame(rot[0], p[0], frames[3])
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
                end_disk(p, rot, n, m, wrench, out, 4 * STATION_WIDTH * nst, hole)
                continue
            col = gather_station(x, t, nst)
            res = np.empty(4 * STATION_WIDTH)
            if joint == 0 and station == spacers:
                store_frame(rot[0], p[0], frames[1])
                _tube_tangent(p, rot, n, m, x, t, nst, tube_length, inv_kse, inv_kbt, tp,
                              trot, tn, tm, tused, internal, live)
                tube(p, rot, n, m, col, 0, res, 0, hole, tube_length, inv_kse, inv_kbt, used)
                store_frame(rot[0], p[0], frames[2])
            else:
                _spacer_disk_tangent(p, rot, n, m, x, t, nst, tp, trot, tn, tm, internal,
                                     live)
                spacer_disk(p, rot, n, m, col, 0, res, 0, hole)
            for i in range(4):
                for c in range(STATION_WIDTH):
                    out[STATION_WIDTH * (i * nst + t) + c] = res[STATION_WIDTH * i + c]
    _unknowns_order(internal, nst, jac, lifted)
