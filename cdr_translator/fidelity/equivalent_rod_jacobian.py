"""
Exact Jacobian of the 'rod' model's residual (fidelity.equivalent_rod), by forward mode.

Every state of the shot carries its derivative with respect to the unknowns (one column
each) through the same RK4 steps and curvature sweeps as ``equivalent_rod.shoot``, so the
Jacobian is the derivative of the discrete residual itself, to rounding.
"""

import math

import numpy as np

from .cc import hole
from .equivalent_rod import (BENDING_STIFFNESS, CURVATURE_SWEEPS, INTERVALS, INVERSE_AXIAL,
                             INVERSE_SHEAR, JOINT_LENGTH, offset_tangent, PITCH_RADIUS,
                             rod_residual, SECONDARY_LENGTH, SIZE, STEPS, TUBE_LENGTH,
                             TWIST_STIFFNESS, WRENCH)
from .._jit import jit, jit_inline


@jit_inline
def _derivative(p, rot, tp, trot, tension, t_tension, m0, t_m0, data, holes, dp, drot,
                dlength, t_dp, t_drot, t_dlength, sweep):
    """
    d/ds of the position, rotation and the four secondaries' path lengths, with tangents.

    t_* hold the derivatives of each quantity with respect to the unknowns (trailing axis,
    zero columns for none); ``holes`` the secondaries' (x, y) (4, 2); ``sweep`` is
    scratch (3, CURVATURE_SWEEPS + 1).
    """
    force0 = data[WRENCH]
    force1 = data[WRENCH + 1]
    force2 = data[WRENCH + 2]
    radius = data[PITCH_RADIUS]
    ei = data[BENDING_STIFFNESS]
    moment0 = m0[0] - (p[1] * force2 - p[2] * force1)
    moment1 = m0[1] - (p[2] * force0 - p[0] * force2)
    moment2 = m0[2] - (p[0] * force1 - p[1] * force0)
    mb0 = rot[0, 0] * moment0 + rot[1, 0] * moment1 + rot[2, 0] * moment2
    mb1 = rot[0, 1] * moment0 + rot[1, 1] * moment1 + rot[2, 1] * moment2
    mb2 = rot[0, 2] * moment0 + rot[1, 2] * moment1 + rot[2, 2] * moment2
    nb0 = rot[0, 0] * force0 + rot[1, 0] * force1 + rot[2, 0] * force2
    nb1 = rot[0, 1] * force0 + rot[1, 1] * force1 + rot[2, 1] * force2
    nb2 = rot[0, 2] * force0 + rot[1, 2] * force1 + rot[2, 2] * force2
    total, rhs_x, rhs_y = _tension_terms(tension[0], tension[1], tension[2], tension[3], holes,
                                         mb0, mb1)
    ux = rhs_x / (5.0 * ei)
    uy = rhs_y / (5.0 * ei)
    sweep[0, 0] = ux
    sweep[1, 0] = uy
    for s in range(CURVATURE_SWEEPS):
        factor = (1.0 + 2.0 / (1.0 - (radius * uy) ** 2) + 2.0 / (1.0 - (radius * ux) ** 2))
        ux = rhs_x / (ei * factor)
        uy = rhs_y / (ei * factor)
        sweep[0, s + 1] = ux
        sweep[1, s + 1] = uy
        sweep[2, s] = factor
    twist_stiffness = data[TWIST_STIFFNESS] + radius * radius * total
    uz = mb2 / twist_stiffness
    vx = data[INVERSE_SHEAR] * nb0
    vy = data[INVERSE_SHEAR] * nb1
    vz = 1.0 + data[INVERSE_AXIAL] * (nb2 - total)
    for i in range(3):
        dp[i] = rot[i, 0] * vx + rot[i, 1] * vy + rot[i, 2] * vz
        drot[i, 0] = rot[i, 1] * uz - rot[i, 2] * uy
        drot[i, 1] = rot[i, 2] * ux - rot[i, 0] * uz
        drot[i, 2] = rot[i, 0] * uy - rot[i, 1] * ux
    for k in range(4):
        tx, ty, tz = offset_tangent(vx, vy, vz, ux, uy, uz, holes[k, 0], holes[k, 1])
        dlength[k] = math.sqrt(tx * tx + ty * ty + tz * tz)
    for d in range(tp.shape[1]):
        _derivative_column(d, rot, tp, trot, t_tension, t_m0, data, holes, moment0, moment1,
                           moment2, total, rhs_x, rhs_y, sweep, uz, twist_stiffness, vx, vy,
                           vz, dlength, t_dp, t_drot, t_dlength)


@jit_inline
def _tension_terms(t0, t1, t2, t3, holes, moment_x, moment_y):
    """
    Return the total of the tensions t_k and the bending right-hand sides (x, y).

    Those are the body moment's x, y minus sum_k t_k (r_k x e3)_xy, r_k x e3 = (r_y, -r_x).
    Linear in (t, moment): the tangents go through it too.
    """
    total = t0 + t1 + t2 + t3
    rhs_x = moment_x - t0 * holes[0, 1] - t1 * holes[1, 1] - t2 * holes[2, 1] - t3 * holes[3, 1]
    rhs_y = moment_y + t0 * holes[0, 0] + t1 * holes[1, 0] + t2 * holes[2, 0] + t3 * holes[3, 0]
    return total, rhs_x, rhs_y


@jit_inline
def _derivative_column(d, rot, tp, trot, t_tension, t_m0, data, holes, moment0, moment1, moment2,
                       total, rhs_x, rhs_y, sweep, uz, twist_stiffness, vx, vy, vz, dlength,
                       t_dp, t_drot, t_dlength):
    """Column d of the tangent of ``_derivative`` (its primal values passed in)."""
    force = data[WRENCH:WRENCH + 3]
    radius = data[PITCH_RADIUS]
    ei = data[BENDING_STIFFNESS]
    d_moment0 = t_m0[0, d] - (tp[1, d] * force[2] - tp[2, d] * force[1])
    d_moment1 = t_m0[1, d] - (tp[2, d] * force[0] - tp[0, d] * force[2])
    d_moment2 = t_m0[2, d] - (tp[0, d] * force[1] - tp[1, d] * force[0])
    d_mb0 = 0.0
    d_mb1 = 0.0
    d_mb2 = 0.0
    d_nb0 = 0.0
    d_nb1 = 0.0
    d_nb2 = 0.0
    for i, moment, d_moment in ((0, moment0, d_moment0), (1, moment1, d_moment1),
                                (2, moment2, d_moment2)):
        d_mb0 += trot[i, 0, d] * moment + rot[i, 0] * d_moment
        d_mb1 += trot[i, 1, d] * moment + rot[i, 1] * d_moment
        d_mb2 += trot[i, 2, d] * moment + rot[i, 2] * d_moment
        d_nb0 += trot[i, 0, d] * force[i]
        d_nb1 += trot[i, 1, d] * force[i]
        d_nb2 += trot[i, 2, d] * force[i]
    d_total, d_rhs_x, d_rhs_y = _tension_terms(t_tension[0, d], t_tension[1, d],
                                               t_tension[2, d], t_tension[3, d], holes, d_mb0,
                                               d_mb1)
    d_ux = d_rhs_x / (5.0 * ei)
    d_uy = d_rhs_y / (5.0 * ei)
    for s in range(CURVATURE_SWEEPS):
        a = radius * sweep[1, s]
        b = radius * sweep[0, s]
        d_factor = (4.0 * a * radius * d_uy / (1.0 - a * a) ** 2
                    + 4.0 * b * radius * d_ux / (1.0 - b * b) ** 2)
        factor = sweep[2, s]
        d_ux = (d_rhs_x - sweep[0, s + 1] * ei * d_factor) / (ei * factor)
        d_uy = (d_rhs_y - sweep[1, s + 1] * ei * d_factor) / (ei * factor)
    ux = sweep[0, CURVATURE_SWEEPS]
    uy = sweep[1, CURVATURE_SWEEPS]
    d_uz = (d_mb2 - uz * radius * radius * d_total) / twist_stiffness
    d_vx = data[INVERSE_SHEAR] * d_nb0
    d_vy = data[INVERSE_SHEAR] * d_nb1
    d_vz = data[INVERSE_AXIAL] * (d_nb2 - d_total)
    for i in range(3):
        t_dp[i, d] = (trot[i, 0, d] * vx + trot[i, 1, d] * vy + trot[i, 2, d] * vz
                      + rot[i, 0] * d_vx + rot[i, 1] * d_vy + rot[i, 2] * d_vz)
        t_drot[i, 0, d] = (trot[i, 1, d] * uz + rot[i, 1] * d_uz
                           - trot[i, 2, d] * uy - rot[i, 2] * d_uy)
        t_drot[i, 1, d] = (trot[i, 2, d] * ux + rot[i, 2] * d_ux
                           - trot[i, 0, d] * uz - rot[i, 0] * d_uz)
        t_drot[i, 2, d] = (trot[i, 0, d] * uy + rot[i, 0] * d_uy
                           - trot[i, 1, d] * ux - rot[i, 1] * d_ux)
    for k in range(4):
        hx = holes[k, 0]
        hy = holes[k, 1]
        tx, ty, tz = offset_tangent(vx, vy, vz, ux, uy, uz, hx, hy)
        t_dlength[k, d] = (tx * (d_vx - d_uz * hy) + ty * (d_vy + d_uz * hx)
                           + tz * (d_vz + d_ux * hy - d_uy * hx)) / dlength[k]


@jit
def _tangent_shot(x, data):
    """
    Integrate base to end disk with tangents; the state used by the residual and its own.

    Returns (end position, base moment, tensions, path lengths) and their tangents (3,
    SIZE), (3, SIZE), (4, SIZE), (4, SIZE).
    """
    columns = SIZE
    length = data[JOINT_LENGTH]
    ei = data[BENDING_STIFFNESS]
    radius = data[PITCH_RADIUS]
    intervals = int(data[INTERVALS])
    steps = int(data[STEPS])
    m0 = np.empty(3)
    t_m0 = np.zeros((3, columns))
    for c in range(3):
        m0[c] = x[c] * ei / length
        t_m0[c, c] = ei / length
    tension = np.empty(4)
    t_tension = np.zeros((4, columns))
    for k in range(4):
        tension[k] = x[3 + k] * ei / length ** 2
        t_tension[k, 3 + k] = ei / length ** 2
    p = np.zeros(3)
    rot = np.eye(3)
    lengths = np.zeros(4)
    tp = np.zeros((3, columns))
    trot = np.zeros((3, 3, columns))
    t_lengths = np.zeros((4, columns))
    k_p = np.empty((4, 3))
    k_rot = np.empty((4, 3, 3))
    k_len = np.empty((4, 4))
    tk_p = np.empty((4, 3, columns))
    tk_rot = np.empty((4, 3, 3, columns))
    tk_len = np.empty((4, 4, columns))
    p_stage = np.empty(3)
    rot_stage = np.empty((3, 3))
    tp_stage = np.empty((3, columns))
    trot_stage = np.empty((3, 3, columns))
    sweep = np.empty((3, CURVATURE_SWEEPS + 1))
    holes = np.empty((4, 2))
    for k in range(4):
        holes[k, 0], holes[k, 1] = hole(radius, k)
    h = length / (intervals * steps)
    for joint in range(2):
        for _ in range(intervals * steps):
            for stage in range(4):  # one call site: _derivative is inlined
                _stage(p, rot, tp, trot, k_p, k_rot, tk_p, tk_rot, stage, h, p_stage,
                       rot_stage, tp_stage, trot_stage)
                _derivative(p_stage, rot_stage, tp_stage, trot_stage, tension, t_tension,
                            m0, t_m0, data, holes, k_p[stage], k_rot[stage],
                            k_len[stage], tk_p[stage], tk_rot[stage], tk_len[stage], sweep)
            _advance(p, rot, k_p, k_rot, h)
            for k in range(4):
                lengths[k] += h / 6.0 * (k_len[0, k] + 2.0 * k_len[1, k]
                                         + 2.0 * k_len[2, k] + k_len[3, k])
            _advance_tangent(tp, trot, t_lengths, tk_p, tk_rot, tk_len, h)
        if joint == 0:  # the rigid tube: straight lumens of length L_m
            for i in range(3):
                p[i] += data[TUBE_LENGTH] * rot[i, 2]
                for d in range(columns):
                    tp[i, d] += data[TUBE_LENGTH] * trot[i, 2, d]
            for k in range(4):
                lengths[k] += data[TUBE_LENGTH]
    return p, m0, tension, lengths, tp, t_m0, t_tension, t_lengths


@jit_inline
def _stage(p, rot, tp, trot, k_p, k_rot, tk_p, tk_rot, stage, h, p_stage, rot_stage,
           tp_stage, trot_stage):
    """RK4 stage pose (p, rot) + c h k[stage - 1] (c = 0, 1/2, 1/2, 1), with tangents."""
    if stage == 0:  # the slopes of stage -1 are left from the previous step: not read
        p_stage[:] = p
        rot_stage[:] = rot
        tp_stage[:] = tp
        trot_stage[:] = trot
        return
    dt = h if stage == 3 else 0.5 * h
    previous = stage - 1
    for i in range(3):
        p_stage[i] = p[i] + dt * k_p[previous, i]
        for d in range(tp.shape[1]):
            tp_stage[i, d] = tp[i, d] + dt * tk_p[previous, i, d]
        for j in range(3):
            rot_stage[i, j] = rot[i, j] + dt * k_rot[previous, i, j]
            for d in range(tp.shape[1]):
                trot_stage[i, j, d] = trot[i, j, d] + dt * tk_rot[previous, i, j, d]


@jit_inline
def _advance(p, rot, k_p, k_rot, h):
    """Advance (p, rot) in place by one RK4 step of length h from the four stage slopes."""
    weight = h / 6.0
    for i in range(3):
        p[i] += weight * (k_p[0, i] + 2.0 * k_p[1, i] + 2.0 * k_p[2, i] + k_p[3, i])
        for j in range(3):
            rot[i, j] += weight * (k_rot[0, i, j] + 2.0 * k_rot[1, i, j]
                                   + 2.0 * k_rot[2, i, j] + k_rot[3, i, j])


@jit_inline
def _advance_tangent(tp, trot, t_lengths, tk_p, tk_rot, tk_len, h):
    """Tangent of ``_advance`` and of the path lengths' RK4 step."""
    weight = h / 6.0
    for d in range(tp.shape[1]):
        for i in range(3):
            tp[i, d] += weight * (tk_p[0, i, d] + 2.0 * tk_p[1, i, d] + 2.0 * tk_p[2, i, d]
                                  + tk_p[3, i, d])
            for j in range(3):
                trot[i, j, d] += weight * (tk_rot[0, i, j, d] + 2.0 * tk_rot[1, i, j, d]
                                           + 2.0 * tk_rot[2, i, j, d] + tk_rot[3, i, j, d])
        for k in range(4):
            t_lengths[k, d] += weight * (tk_len[0, k, d] + 2.0 * tk_len[1, k, d]
                                         + 2.0 * tk_len[2, k, d] + tk_len[3, k, d])


@jit
def rod_system(x, data, out, jac, want_jacobian):
    """
    Residual of ``equivalent_rod.rod_residual`` into ``out``; its Jacobian into ``jac`` too.

    With ``want_jacobian`` the Jacobian is exact (forward mode through the same shot).
    """
    rod_residual(x, data, out)
    if not want_jacobian:
        return
    p, m0, tension, lengths, tp, t_m0, t_tension, t_lengths = _tangent_shot(x, data)
    force = data[WRENCH:WRENCH + 3]
    scale = data[JOINT_LENGTH] / data[BENDING_STIFFNESS]
    rest = data[SECONDARY_LENGTH]
    for d in range(SIZE):
        jac[0, d] = (t_m0[0, d] - (tp[1, d] * force[2] - tp[2, d] * force[1])) * scale
        jac[1, d] = (t_m0[1, d] - (tp[2, d] * force[0] - tp[0, d] * force[2])) * scale
        jac[2, d] = (t_m0[2, d] - (tp[0, d] * force[1] - tp[1, d] * force[0])) * scale
        for k in range(4):
            jac[3 + k, d] = (t_lengths[k, d] - rest * data[INVERSE_AXIAL] * t_tension[k, d]) \
                / data[JOINT_LENGTH]
