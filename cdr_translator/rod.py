"""
Cosserat rod kernel: the state derivative of Eq. (6) and its RK4 integration.

A rod segment carries no distributed load, so its internal force n is constant and its
internal moment follows algebraically from the position, m(s) = m(a) - (p(s) - p(a)) x n
(integral of Eq. 3). Only the pose (p, R) is integrated; that halves the work per step.

Constitutive law (Eq. 4-5), with straight, unstressed reference rods:
    v = e3 + K_se^-1 R^T n,  u = K_bt^-1 R^T m,  K_se = diag(GA, GA, EA), K_bt = diag(EI, EI, GJ).
Inverse stiffnesses are passed as 3-vectors ``inv_kse`` and ``inv_kbt``. SI units.
"""

import numpy as np

from ._jit import jit


@jit
def local_strains(p, rot, n, m_start, p_start, inv_kse, inv_kbt):
    """
    Return (p - p_start, m, v, u) at pose (p, rot) as 12 scalars (Eq. 3-5).

    m(s) = m_start - (p - p_start) x n; local strains v = e3 + Kse^-1 R^T n,
    u = Kbt^-1 R^T m.
    """
    dx = p[0] - p_start[0]
    dy = p[1] - p_start[1]
    dz = p[2] - p_start[2]
    mx = m_start[0] - (dy * n[2] - dz * n[1])
    my = m_start[1] - (dz * n[0] - dx * n[2])
    mz = m_start[2] - (dx * n[1] - dy * n[0])
    v0 = inv_kse[0] * (rot[0, 0] * n[0] + rot[1, 0] * n[1] + rot[2, 0] * n[2])
    v1 = inv_kse[1] * (rot[0, 1] * n[0] + rot[1, 1] * n[1] + rot[2, 1] * n[2])
    v2 = 1.0 + inv_kse[2] * (rot[0, 2] * n[0] + rot[1, 2] * n[1] + rot[2, 2] * n[2])
    u0 = inv_kbt[0] * (rot[0, 0] * mx + rot[1, 0] * my + rot[2, 0] * mz)
    u1 = inv_kbt[1] * (rot[0, 1] * mx + rot[1, 1] * my + rot[2, 1] * mz)
    u2 = inv_kbt[2] * (rot[0, 2] * mx + rot[1, 2] * my + rot[2, 2] * mz)
    return dx, dy, dz, mx, my, mz, v0, v1, v2, u0, u1, u2


@jit
def pose_rates(rot, v0, v1, v2, u0, u1, u2, dp, drot):
    """Write p' = R v and R' = R [u]x (Eq. 6) into ``dp`` and ``drot``."""
    for i in range(3):
        r0 = rot[i, 0]
        r1 = rot[i, 1]
        r2 = rot[i, 2]
        dp[i] = r0 * v0 + r1 * v1 + r2 * v2
        # row i of R [u x]
        drot[i, 0] = r1 * u2 - r2 * u1
        drot[i, 1] = r2 * u0 - r0 * u2
        drot[i, 2] = r0 * u1 - r1 * u0


@jit
def pose_derivative(p, rot, n, m_start, p_start, inv_kse, inv_kbt, dp, drot):
    """Write dp/ds and dR/ds of Eq. (6) for pose (p, rot) into ``dp`` and ``drot``."""
    _, _, _, _, _, _, v0, v1, v2, u0, u1, u2 = local_strains(p, rot, n, m_start, p_start,
                                                             inv_kse, inv_kbt)
    pose_rates(rot, v0, v1, v2, u0, u1, u2, dp, drot)


@jit
def rk4_stage_pose(p, rot, k_p, k_rot, dt, p_stage, rot_stage):
    """Write the RK4 stage pose (p, rot) + dt (k_p, k_rot) into p_stage, rot_stage."""
    for i in range(3):
        p_stage[i] = p[i] + dt * k_p[i]
        for j in range(3):
            rot_stage[i, j] = rot[i, j] + dt * k_rot[i, j]


@jit
def rk4_advance_pose(p, rot, k_p, k_rot, h):
    """Advance (p, rot) in place by one RK4 step of length h from the four stage slopes."""
    for i in range(3):
        p[i] += h / 6.0 * (k_p[0, i] + 2.0 * k_p[1, i] + 2.0 * k_p[2, i] + k_p[3, i])
        for j in range(3):
            rot[i, j] += h / 6.0 * (k_rot[0, i, j] + 2.0 * k_rot[1, i, j]
                                    + 2.0 * k_rot[2, i, j] + k_rot[3, i, j])


@jit
def carry_moment(p, p_start, n, m_start, m):
    """
    Set ``m`` to the internal moment at ``p``: m(s) = m(0) - (p(s) - p(0)) x n (load-free).

    Returns the chord p(s) - p(0) as (dx, dy, dz), which the tangent kernel reuses.
    """
    dx = p[0] - p_start[0]
    dy = p[1] - p_start[1]
    dz = p[2] - p_start[2]
    m[0] = m_start[0] - (dy * n[2] - dz * n[1])
    m[1] = m_start[1] - (dz * n[0] - dx * n[2])
    m[2] = m_start[2] - (dx * n[1] - dy * n[0])
    return dx, dy, dz


@jit
def integrate_segment(p, rot, n, m, length, steps, inv_kse, inv_kbt, points, first_row):
    """
    Integrate one load-free rod segment of arc length ``length`` with RK4, in place.

    On entry (p, rot, n, m) is the state at the segment start; on exit p, rot and m hold
    the state at its end (n is unchanged). When ``points`` has rows, the positions at the
    ``steps + 1`` grid points are written to ``points[first_row:first_row + steps + 1]``.
    """
    h = length / steps
    p_start = p.copy()
    m_start = m.copy()
    k_p = np.empty((4, 3))
    k_rot = np.empty((4, 3, 3))
    p_stage = np.empty(3)
    rot_stage = np.empty((3, 3))
    record = points.shape[0] > 0
    if record:
        points[first_row, :] = p
    for step in range(steps):
        pose_derivative(p, rot, n, m_start, p_start, inv_kse, inv_kbt, k_p[0], k_rot[0])
        for stage, weight in ((1, 0.5), (2, 0.5), (3, 1.0)):
            rk4_stage_pose(p, rot, k_p[stage - 1], k_rot[stage - 1], weight * h, p_stage,
                           rot_stage)
            pose_derivative(p_stage, rot_stage, n, m_start, p_start, inv_kse, inv_kbt,
                            k_p[stage], k_rot[stage])
        rk4_advance_pose(p, rot, k_p, k_rot, h)
        if record:
            points[first_row + step + 1, :] = p
    carry_moment(p, p_start, n, m_start, m)


#: Local directions of ``integrate_segment_tangent``: R(0) entries (row-major), n, m(0), length.
LOCAL_ROT = 0
LOCAL_N = 9
LOCAL_M = 12
LOCAL_LENGTH = 15
LOCAL_DIRECTIONS = 16


@jit
def pose_derivative_tangent(p, rot, tp, trot, n, m_start, p_start, tn, tm_start, inv_kse,
                            inv_kbt, dp, drot, tdp, tdrot):
    """
    Eq. (6) and its tangent-linear map: dp, drot as ``pose_derivative``; tdp, tdrot.

    ``tp`` (3, nd), ``trot`` (3, 3, nd), ``tn`` and ``tm_start`` (3, nd) are the tangents of
    the pose and of the segment's constant n and initial m along nd directions (p_start's
    tangent is zero in the local directions). Differentiating the constitutive law gives
    dm = dm_start - dp x n - (p - p_start) x dn, dv = Kse^-1 (dR^T n + R^T dn),
    du = Kbt^-1 (dR^T m + R^T dm), d(p') = dR v + R dv, d(R') = dR [u]x + R [du]x.
    """
    dx, dy, dz, mx, my, mz, v0, v1, v2, u0, u1, u2 = local_strains(p, rot, n, m_start,
                                                                   p_start, inv_kse, inv_kbt)
    pose_rates(rot, v0, v1, v2, u0, u1, u2, dp, drot)
    tv = np.empty(3)
    tu = np.empty(3)
    for d in range(tp.shape[1]):
        tnx = tn[0, d]
        tny = tn[1, d]
        tnz = tn[2, d]
        tpx = tp[0, d]
        tpy = tp[1, d]
        tpz = tp[2, d]
        tmx = tm_start[0, d] - (tpy * n[2] - tpz * n[1]) - (dy * tnz - dz * tny)
        tmy = tm_start[1, d] - (tpz * n[0] - tpx * n[2]) - (dz * tnx - dx * tnz)
        tmz = tm_start[2, d] - (tpx * n[1] - tpy * n[0]) - (dx * tny - dy * tnx)
        for c in range(3):
            tv[c] = (trot[0, c, d] * n[0] + trot[1, c, d] * n[1] + trot[2, c, d] * n[2]
                     + rot[0, c] * tnx + rot[1, c] * tny + rot[2, c] * tnz) * inv_kse[c]
            tu[c] = (trot[0, c, d] * mx + trot[1, c, d] * my + trot[2, c, d] * mz
                     + rot[0, c] * tmx + rot[1, c] * tmy + rot[2, c] * tmz) * inv_kbt[c]
        for i in range(3):
            r0 = rot[i, 0]
            r1 = rot[i, 1]
            r2 = rot[i, 2]
            t0 = trot[i, 0, d]
            t1 = trot[i, 1, d]
            t2 = trot[i, 2, d]
            tdp[i, d] = t0 * v0 + t1 * v1 + t2 * v2 + r0 * tv[0] + r1 * tv[1] + r2 * tv[2]
            tdrot[i, 0, d] = t1 * u2 - t2 * u1 + r1 * tu[2] - r2 * tu[1]
            tdrot[i, 1, d] = t2 * u0 - t0 * u2 + r2 * tu[0] - r0 * tu[2]
            tdrot[i, 2, d] = t0 * u1 - t1 * u0 + r0 * tu[1] - r1 * tu[0]


@jit
def integrate_segment_tangent(p, rot, n, m, length, steps, inv_kse, inv_kbt, tp, trot, tm,
                              active):
    """
    ``integrate_segment`` (no points) plus the exact derivative of the discrete map.

    On exit (p, rot, m) hold the end state as in ``integrate_segment`` and ``tp`` (3, 16),
    ``trot`` (3, 3, 16), ``tm`` (3, 16) its derivatives along the LOCAL_DIRECTIONS inputs:
    the 9 entries of R(0), n, m(0) and the segment length. (The derivative with respect to
    p(0) is the identity on p and zero on R and m: the map is translation invariant.) Only
    the directions flagged in ``active`` (bool, 16) are computed; the others are left
    zero (e.g. R(0) at a rod's first segment, where it is fixed). It is
    the tangent-linear (forward-mode) form of the very RK4 steps taken, so it equals the
    derivative of the discretized map to rounding, not that of the continuous one
    (variational equations of Eq. 6 discretized by the same Runge-Kutta scheme, whose
    derivative they are: Hairer, Norsett & Wanner, Solving ODEs I, Sec. II.6 / I.14).
    """
    directions = np.empty(LOCAL_DIRECTIONS, dtype=np.int64)
    nd = 0
    for j in range(LOCAL_DIRECTIONS):
        if active[j]:
            directions[nd] = j
            nd += 1
    length_slot = -1
    h = length / steps
    dh = 1.0 / steps  # d h / d length
    p_start = p.copy()
    m_start = m.copy()
    # compact tangents: slot s holds local direction directions[s]
    tn = np.zeros((3, nd))
    tm_start = np.zeros((3, nd))
    cp = np.zeros((3, nd))
    crot = np.zeros((3, 3, nd))
    for slot in range(nd):
        j = directions[slot]
        if j == LOCAL_LENGTH:
            length_slot = slot
        elif j >= LOCAL_M:
            tm_start[j - LOCAL_M, slot] = 1.0
        elif j >= LOCAL_N:
            tn[j - LOCAL_N, slot] = 1.0
        else:
            crot[(j - LOCAL_ROT) // 3, (j - LOCAL_ROT) % 3, slot] = 1.0
    k_p = np.empty((4, 3))
    k_rot = np.empty((4, 3, 3))
    tk_p = np.empty((4, 3, nd))
    tk_rot = np.empty((4, 3, 3, nd))
    p_stage = np.empty(3)
    rot_stage = np.empty((3, 3))
    tp_stage = np.empty((3, nd))
    trot_stage = np.empty((3, 3, nd))
    for step in range(steps):
        pose_derivative_tangent(p, rot, cp, crot, n, m_start, p_start, tn, tm_start, inv_kse,
                                inv_kbt, k_p[0], k_rot[0], tk_p[0], tk_rot[0])
        for stage, weight in ((1, 0.5), (2, 0.5), (3, 1.0)):
            rk4_stage_pose(p, rot, k_p[stage - 1], k_rot[stage - 1], weight * h, p_stage,
                           rot_stage)
            for i in range(3):
                for d in range(nd):
                    tp_stage[i, d] = cp[i, d] + weight * h * tk_p[stage - 1, i, d]
                if length_slot >= 0:
                    tp_stage[i, length_slot] += weight * dh * k_p[stage - 1, i]
                for j in range(3):
                    for d in range(nd):
                        trot_stage[i, j, d] = (crot[i, j, d]
                                               + weight * h * tk_rot[stage - 1, i, j, d])
                    if length_slot >= 0:
                        trot_stage[i, j, length_slot] += weight * dh * k_rot[stage - 1, i, j]
            pose_derivative_tangent(p_stage, rot_stage, tp_stage, trot_stage, n, m_start,
                                    p_start, tn, tm_start, inv_kse, inv_kbt, k_p[stage],
                                    k_rot[stage], tk_p[stage], tk_rot[stage])
        for i in range(3):
            for d in range(nd):
                cp[i, d] += h / 6.0 * (tk_p[0, i, d] + 2.0 * tk_p[1, i, d]
                                       + 2.0 * tk_p[2, i, d] + tk_p[3, i, d])
            if length_slot >= 0:
                cp[i, length_slot] += dh / 6.0 * (k_p[0, i] + 2.0 * k_p[1, i]
                                                  + 2.0 * k_p[2, i] + k_p[3, i])
            for j in range(3):
                for d in range(nd):
                    crot[i, j, d] += h / 6.0 * (tk_rot[0, i, j, d] + 2.0 * tk_rot[1, i, j, d]
                                                + 2.0 * tk_rot[2, i, j, d]
                                                + tk_rot[3, i, j, d])
                if length_slot >= 0:
                    crot[i, j, length_slot] += dh / 6.0 * (
                        k_rot[0, i, j] + 2.0 * k_rot[1, i, j] + 2.0 * k_rot[2, i, j]
                        + k_rot[3, i, j])
        rk4_advance_pose(p, rot, k_p, k_rot, h)
    tp[:, :] = 0.0
    trot[:, :, :] = 0.0
    tm[:, :] = 0.0
    for slot in range(nd):
        j = directions[slot]
        for i in range(3):
            tp[i, j] = cp[i, slot]
            for b in range(3):
                trot[i, b, j] = crot[i, b, slot]
    dx, dy, dz = carry_moment(p, p_start, n, m_start, m)
    for slot in range(nd):
        d = directions[slot]
        tm[0, d] = (tm_start[0, slot] - (cp[1, slot] * n[2] - cp[2, slot] * n[1])
                    - (dy * tn[2, slot] - dz * tn[1, slot]))
        tm[1, d] = (tm_start[1, slot] - (cp[2, slot] * n[0] - cp[0, slot] * n[2])
                    - (dz * tn[0, slot] - dx * tn[2, slot]))
        tm[2, d] = (tm_start[2, slot] - (cp[0, slot] * n[1] - cp[1, slot] * n[0])
                    - (dx * tn[1, slot] - dy * tn[0, slot]))


def inverse_stiffness(youngs_modulus: float, shear_modulus: float, diameter: float):
    """Return (inv_kse, inv_kbt) of a solid round rod as 3-vectors (Eq. 5)."""
    area = np.pi * diameter ** 2 / 4.0
    second_moment = np.pi * diameter ** 4 / 64.0
    polar_moment = 2.0 * second_moment
    inv_kse = 1.0 / np.array([shear_modulus * area, shear_modulus * area,
                              youngs_modulus * area])
    inv_kbt = 1.0 / np.array([youngs_modulus * second_moment, youngs_modulus * second_moment,
                              shear_modulus * polar_moment])
    return inv_kse, inv_kbt


def solve_cantilever(length: float, tip_force, tip_moment, youngs_modulus: float,
                     shear_modulus: float, diameter: float, steps: int = 64,
                     tolerance: float = 1e-13, max_iterations: int = 50):
    """
    Solve a single straight rod clamped at the origin (z along the rod) with a tip wrench.

    With no distributed load n(s) = tip_force everywhere, so the only unknown is the base
    moment m(0); Newton drives m(L) - tip_moment to zero. Returns (points (steps+1, 3),
    tip rotation matrix). Tip wrench in the base frame, SI units.
    """
    inv_kse, inv_kbt = inverse_stiffness(youngs_modulus, shear_modulus, diameter)
    force = np.asarray(tip_force, dtype=float)
    moment = np.asarray(tip_moment, dtype=float)
    moment_scale = youngs_modulus * np.pi * diameter ** 4 / 64.0 / length
    points = np.empty((steps + 1, 3))

    def shoot(base_moment):
        p = np.zeros(3)
        rot = np.eye(3)
        m = base_moment.copy()
        integrate_segment(p, rot, force.copy(), m, length, steps, inv_kse, inv_kbt, points, 0)
        return (m - moment) / moment_scale, rot

    base = moment + np.cross([0.0, 0.0, length], force)  # rigid-rod guess
    for _ in range(max_iterations):
        error, rot = shoot(base)
        if np.abs(error).max() <= tolerance:
            return points.copy(), rot
        jac = np.empty((3, 3))
        for column in range(3):
            probe = base.copy()
            probe[column] += 1e-7 * moment_scale
            jac[:, column] = (shoot(probe)[0] - error) / 1e-7
        base = base - moment_scale * np.linalg.solve(jac, error)
    raise RuntimeError(f'cantilever shooting did not converge in {max_iterations} iterations')
