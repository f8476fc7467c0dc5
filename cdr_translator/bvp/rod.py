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

from .._jit import jit, jit_inline


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


#: Doubles of scratch ``integrate_segment`` needs: p(0), m(0), the four stage slopes of p
#: and R, and a stage pose.
SEGMENT_SCRATCH = 3 + 3 + 4 * 3 + 4 * 9 + 3 + 9


@jit
def integrate_segment(p, rot, n, m, length, steps, inv_kse, inv_kbt, points, first_row,
                      scratch):
    """
    Integrate one load-free rod segment of arc length ``length`` with RK4, in place.

    On entry (p, rot, n, m) is the state at the segment start; on exit p, rot and m hold
    the state at its end (n is unchanged). When ``points`` has rows, the positions at the
    ``steps + 1`` grid points are written to ``points[first_row:first_row + steps + 1]``.
    ``scratch`` (SEGMENT_SCRATCH doubles, the caller's) holds the stages: a shot
    integrates 20 or more segments, and allocating them per segment added about 3 us to a
    20-30 us shot (a tenth).
    """
    h = length / steps
    p_start = scratch[0:3]
    m_start = scratch[3:6]
    k_p = scratch[6:18].reshape((4, 3))
    k_rot = scratch[18:54].reshape((4, 3, 3))
    p_stage = scratch[54:57]
    rot_stage = scratch[57:66].reshape((3, 3))
    for i in range(3):
        p_start[i] = p[i]
        m_start[i] = m[i]
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
#: Rows of a tangent state: p, R (row-major), n, m(0); row 3 + j holds local direction j's
#: input. A tangent rate has the first TANGENT_POSE rows (p', R').
TANGENT_P = 0
TANGENT_ROT = 3
TANGENT_N = 12
TANGENT_M = 15
TANGENT_ROWS = 18
TANGENT_POSE = 12
#: Rows of the local derivative that ``integrate_segment_tangent`` returns: p and R at
#: their tangent-state rows, then m at LOCAL_OUT_M.
LOCAL_OUT_M = 12
LOCAL_OUTPUTS = 15


@jit_inline
def _moment_tangent(tstate, d, n0, n1, n2, dx, dy, dz):
    """
    Tangent (column d of ``tstate``) of m = m(0) - (p - p(0)) x n, (dx, dy, dz) = p - p(0).

    dm = dm(0) - dp x n - (p - p(0)) x dn, as in ``carry_moment``.
    """
    tpx = tstate[TANGENT_P, d]
    tpy = tstate[TANGENT_P + 1, d]
    tpz = tstate[TANGENT_P + 2, d]
    tnx = tstate[TANGENT_N, d]
    tny = tstate[TANGENT_N + 1, d]
    tnz = tstate[TANGENT_N + 2, d]
    return (tstate[TANGENT_M, d] - (tpy * n2 - tpz * n1) - (dy * tnz - dz * tny),
            tstate[TANGENT_M + 1, d] - (tpz * n0 - tpx * n2) - (dz * tnx - dx * tnz),
            tstate[TANGENT_M + 2, d] - (tpx * n1 - tpy * n0) - (dx * tny - dy * tnx))


@jit_inline
def _transposed_tangent(t, r, a, ta, scale):
    """
    Tangent scale * (T^T a + R^T ta) of scale * R^T a, as three values.

    ``t`` and ``r`` hold T and R column by column (9-tuples), ``a``, ``ta`` and ``scale``
    are 3-tuples (the scale is elementwise).
    """
    return ((t[0] * a[0] + t[1] * a[1] + t[2] * a[2] + r[0] * ta[0] + r[1] * ta[1]
             + r[2] * ta[2]) * scale[0],
            (t[3] * a[0] + t[4] * a[1] + t[5] * a[2] + r[3] * ta[0] + r[4] * ta[1]
             + r[5] * ta[2]) * scale[1],
            (t[6] * a[0] + t[7] * a[1] + t[8] * a[2] + r[6] * ta[0] + r[7] * ta[1]
             + r[8] * ta[2]) * scale[2])


@jit_inline
def _rate_row_tangent(rot, tstate, strains, tstrains, row, trate):
    """
    Tangents of row ``row`` of p' = R v and R' = R [u]x into ``trate``, all directions.

    ``strains`` = (v, u), ``tstrains`` (6, nd) their tangents. A loop of its own, with four
    rows written, so that the compiler can vectorize it (with more it gives up).
    """
    r0 = rot[row, 0]
    r1 = rot[row, 1]
    r2 = rot[row, 2]
    v0, v1, v2 = strains[0], strains[1], strains[2]
    u0, u1, u2 = strains[3], strains[4], strains[5]
    for d in range(tstate.shape[1]):
        t0 = tstate[TANGENT_ROT + 3 * row, d]
        t1 = tstate[TANGENT_ROT + 3 * row + 1, d]
        t2 = tstate[TANGENT_ROT + 3 * row + 2, d]
        tv0 = tstrains[0, d]
        tv1 = tstrains[1, d]
        tv2 = tstrains[2, d]
        tu0 = tstrains[3, d]
        tu1 = tstrains[4, d]
        tu2 = tstrains[5, d]
        trate[TANGENT_P + row, d] = t0 * v0 + t1 * v1 + t2 * v2 + r0 * tv0 + r1 * tv1 + r2 * tv2
        trate[TANGENT_ROT + 3 * row, d] = t1 * u2 - t2 * u1 + r1 * tu2 - r2 * tu1
        trate[TANGENT_ROT + 3 * row + 1, d] = t2 * u0 - t0 * u2 + r2 * tu0 - r0 * tu2
        trate[TANGENT_ROT + 3 * row + 2, d] = t0 * u1 - t1 * u0 + r0 * tu1 - r1 * tu0


@jit_inline
def pose_derivative_tangent(p, rot, n, m_start, p_start, inv_kse, inv_kbt, tstate, dp, drot,
                            trate, strains, tstrains):
    """
    Eq. (6) and its tangent-linear map: dp, drot as ``pose_derivative``; ``trate``.

    ``tstate`` (TANGENT_ROWS, nd) holds the tangents of p, R, the segment's constant n and
    initial m along nd directions (p_start's tangent is zero in the local directions);
    ``trate`` (TANGENT_POSE, nd) receives those of p' and R'. Differentiating the
    constitutive law gives dm = dm_start - dp x n - (p - p_start) x dn,
    dv = Kse^-1 (dR^T n + R^T dn), du = Kbt^-1 (dR^T m + R^T dm), d(p') = dR v + R dv,
    d(R') = dR [u]x + R [du]x. ``strains`` (6) and ``tstrains`` (6, nd) are scratch: (v, u)
    and their tangents. The loops over the directions have bodies of scalars, so the
    compiler turns them into vector instructions.
    """
    dx, dy, dz, mx, my, mz, v0, v1, v2, u0, u1, u2 = local_strains(p, rot, n, m_start,
                                                                   p_start, inv_kse, inv_kbt)
    pose_rates(rot, v0, v1, v2, u0, u1, u2, dp, drot)
    n0, n1, n2 = n[0], n[1], n[2]
    r00, r01, r02 = rot[0, 0], rot[0, 1], rot[0, 2]
    r10, r11, r12 = rot[1, 0], rot[1, 1], rot[1, 2]
    r20, r21, r22 = rot[2, 0], rot[2, 1], rot[2, 2]
    se0, se1, se2 = inv_kse[0], inv_kse[1], inv_kse[2]
    bt0, bt1, bt2 = inv_kbt[0], inv_kbt[1], inv_kbt[2]
    r_columns = (r00, r10, r20, r01, r11, r21, r02, r12, r22)
    for d in range(tstate.shape[1]):
        tmx, tmy, tmz = _moment_tangent(tstate, d, n0, n1, n2, dx, dy, dz)
        t00 = tstate[TANGENT_ROT, d]
        t01 = tstate[TANGENT_ROT + 1, d]
        t02 = tstate[TANGENT_ROT + 2, d]
        t10 = tstate[TANGENT_ROT + 3, d]
        t11 = tstate[TANGENT_ROT + 4, d]
        t12 = tstate[TANGENT_ROT + 5, d]
        t20 = tstate[TANGENT_ROT + 6, d]
        t21 = tstate[TANGENT_ROT + 7, d]
        t22 = tstate[TANGENT_ROT + 8, d]
        tnx = tstate[TANGENT_N, d]
        tny = tstate[TANGENT_N + 1, d]
        tnz = tstate[TANGENT_N + 2, d]
        # v = e3 + Kse^-1 R^T n, u = Kbt^-1 R^T m
        t_columns = (t00, t10, t20, t01, t11, t21, t02, t12, t22)
        (tstrains[0, d], tstrains[1, d], tstrains[2, d]) = _transposed_tangent(
            t_columns, r_columns, (n0, n1, n2), (tnx, tny, tnz), (se0, se1, se2))
        (tstrains[3, d], tstrains[4, d], tstrains[5, d]) = _transposed_tangent(
            t_columns, r_columns, (mx, my, mz), (tmx, tmy, tmz), (bt0, bt1, bt2))
    strains[0] = v0
    strains[1] = v1
    strains[2] = v2
    strains[3] = u0
    strains[4] = u1
    strains[5] = u2
    for row in range(3):
        _rate_row_tangent(rot, tstate, strains, tstrains, row, trate)


@jit
def integrate_segment_tangent(p, rot, n, m, length, steps, inv_kse, inv_kbt, active, local):
    """
    ``integrate_segment`` (no points) plus the exact derivative of the discrete map.

    On exit (p, rot, m) hold the end state as in ``integrate_segment`` and ``local``
    (LOCAL_OUTPUTS, LOCAL_DIRECTIONS) its derivatives (rows: p, R row-major, m) along the
    local directions: the 9 entries of R(0), n, m(0) and the segment length. (The
    derivative with respect to p(0) is the identity on p and zero on R and m: the map is
    translation invariant.) Only the directions flagged in ``active`` (bool, 16) are
    computed; the others are left zero (e.g. R(0) at a rod's first segment, where it is
    fixed). It is the tangent-linear (forward-mode) form of the very RK4 steps taken, so it
    equals the derivative of the discretized map to rounding, not that of the continuous
    one (variational equations of Eq. 6 discretized by the same Runge-Kutta scheme, whose
    derivative they are: Hairer, Norsett & Wanner, Solving ODEs I, Sec. II.6 / I.14).
    """
    directions = np.empty(LOCAL_DIRECTIONS, dtype=np.int64)
    nd = 0
    for j in range(LOCAL_DIRECTIONS):
        if active[j]:
            directions[nd] = j
            nd += 1
    h = length / steps
    dh = 1.0 / steps  # d h / d length
    p_start = p.copy()
    m_start = m.copy()
    # compact tangents: slot s holds local direction directions[s]
    state = np.zeros((TANGENT_ROWS, nd))
    length_slot = -1
    for slot in range(nd):
        j = directions[slot]
        if j == LOCAL_LENGTH:
            length_slot = slot
        else:
            state[TANGENT_ROT + j, slot] = 1.0
    stage_state = state.copy()  # its n and m(0) rows stay those of state
    k_p = np.empty((4, 3))
    k_rot = np.empty((4, 3, 3))
    rates = np.empty((4, TANGENT_POSE, nd))
    p_stage = np.empty(3)
    rot_stage = np.empty((3, 3))
    strains = np.empty(6)
    tstrains = np.empty((6, nd))
    # the pose rows (p, R) of the tangents as one run each: one loop, not twelve
    pose_size = TANGENT_POSE * nd
    state_flat = state.reshape(TANGENT_ROWS * nd)
    stage_flat = stage_state.reshape(TANGENT_ROWS * nd)
    rates_flat = rates.reshape((4, pose_size))
    for step in range(steps):
        pose_derivative_tangent(p, rot, n, m_start, p_start, inv_kse, inv_kbt, state, k_p[0],
                                k_rot[0], rates[0], strains, tstrains)
        for stage, weight in ((1, 0.5), (2, 0.5), (3, 1.0)):
            rk4_stage_pose(p, rot, k_p[stage - 1], k_rot[stage - 1], weight * h, p_stage,
                           rot_stage)
            dt = weight * h
            for e in range(pose_size):
                stage_flat[e] = state_flat[e] + dt * rates_flat[stage - 1, e]
            if length_slot >= 0:
                dt = weight * dh
                for i in range(3):
                    stage_state[TANGENT_P + i, length_slot] += dt * k_p[stage - 1, i]
                    for j in range(3):
                        stage_state[TANGENT_ROT + 3 * i + j, length_slot] += (
                            dt * k_rot[stage - 1, i, j])
            pose_derivative_tangent(p_stage, rot_stage, n, m_start, p_start, inv_kse, inv_kbt,
                                    stage_state, k_p[stage], k_rot[stage], rates[stage],
                                    strains, tstrains)
        for e in range(pose_size):
            state_flat[e] += h / 6.0 * (rates_flat[0, e] + 2.0 * rates_flat[1, e]
                                        + 2.0 * rates_flat[2, e] + rates_flat[3, e])
        if length_slot >= 0:
            for i in range(3):
                state[TANGENT_P + i, length_slot] += dh / 6.0 * (
                    k_p[0, i] + 2.0 * k_p[1, i] + 2.0 * k_p[2, i] + k_p[3, i])
                for j in range(3):
                    state[TANGENT_ROT + 3 * i + j, length_slot] += dh / 6.0 * (
                        k_rot[0, i, j] + 2.0 * k_rot[1, i, j] + 2.0 * k_rot[2, i, j]
                        + k_rot[3, i, j])
        rk4_advance_pose(p, rot, k_p, k_rot, h)
    dx, dy, dz = carry_moment(p, p_start, n, m_start, m)
    for r in range(LOCAL_OUTPUTS):
        for j in range(LOCAL_DIRECTIONS):
            local[r, j] = 0.0
    for slot in range(nd):
        j = directions[slot]
        for r in range(TANGENT_POSE):
            local[r, j] = state[r, slot]
        (local[LOCAL_OUT_M, j], local[LOCAL_OUT_M + 1, j],
         local[LOCAL_OUT_M + 2, j]) = _moment_tangent(state, slot, n[0], n[1], n[2], dx, dy,
                                                      dz)


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
    scratch = np.empty(SEGMENT_SCRATCH)

    def shoot(base_moment):
        p = np.zeros(3)
        rot = np.eye(3)
        m = base_moment.copy()
        integrate_segment(p, rot, force.copy(), m, length, steps, inv_kse, inv_kbt, points, 0,
                          scratch)
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
