"""
Exact residual and Jacobian of the 'cc' model (fidelity.cc): virtual work in closed form.

The residual is grad U(x) - Q(x), Q_c = f . dp/dx_c + m . omega_c the generalized force of
the end-disk wrench (p the end-disk centre, omega_c = vee(dR/dx_c R^T) its rotation, both in
{pe}). The residual alone (``cc_residual``: Newton's line search and chord steps) is plain
scalar arithmetic on each joint's pose and twists. Writing m . vee(A R^T) = <A, [m] R> / 2
(Frobenius product), the Jacobian needs the first and second partial derivatives of each
joint's rotation and tip position; they are built from second-order jets (value, d/dbx,
d/dby, d2/dbx2, d2/dbxdby, d2/dby2) of sin(theta)/theta and (1 - cos theta)/theta^2 as
functions of theta^2 = bx^2 + by^2. The energy's Hessian is differentiated by hand from
``cc.energy_gradient``.
"""

import math

import numpy as np

from .cc import (AXIAL_STIFFNESS, BENDING_STIFFNESS, energy_gradient, hole, JOINT_LENGTH,
                 JOINT_TWIST_STIFFNESS, PITCH_RADIUS, SECONDARY_LENGTH,
                 SECONDARY_TWIST_STIFFNESS, SIZE, TUBE_LENGTH, WRENCH)
from .._jit import jit, jit_inline

#: Below this theta^2 the jets of sin(t)/t and (1 - cos t)/t^2 are Taylor series (their
#: closed forms lose digits as 1/theta^4); the series' first neglected term is below 1e-15.
SERIES_LIMIT = 1e-2

#: Entries of a jet: value, d/dbx, d/dby, d2/dbx2, d2/dbxdby, d2/dby2.
JET = 6

#: Global unknowns of each joint's local coordinates (bx, by, psi, e).
JOINT_UNKNOWNS = ((0, 1, 4, 6), (2, 3, 5, 7))


@jit_inline
def _jet_of_square(value, first, second, bx, by, out):
    """Jet in (bx, by) of f(bx^2 + by^2) from f, f' and f''."""
    out[0] = value
    out[1] = 2.0 * bx * first
    out[2] = 2.0 * by * first
    out[3] = 2.0 * first + 4.0 * bx * bx * second
    out[4] = 4.0 * bx * by * second
    out[5] = 2.0 * first + 4.0 * by * by * second


@jit_inline
def _jet_product(a, b, out):
    """Jet of the product of jets a and b."""
    out[0] = a[0] * b[0]
    out[1] = a[1] * b[0] + a[0] * b[1]
    out[2] = a[2] * b[0] + a[0] * b[2]
    out[3] = a[3] * b[0] + 2.0 * a[1] * b[1] + a[0] * b[3]
    out[4] = a[4] * b[0] + a[1] * b[2] + a[2] * b[1] + a[0] * b[4]
    out[5] = a[5] * b[0] + 2.0 * a[2] * b[2] + a[0] * b[5]


@jit
def arc_functions(s):
    """Return sin(t)/t, (1 - cos t)/t^2 and their first two derivatives in s = t^2."""
    if s < SERIES_LIMIT:
        sine = 1.0 - s / 6.0 * (1.0 - s / 20.0 * (1.0 - s / 42.0 * (1.0 - s / 72.0)))
        d_sine = -1.0 / 6.0 + s * (1.0 / 60.0 - s * (1.0 / 1680.0 - s / 90720.0))
        dd_sine = 1.0 / 60.0 - s * (1.0 / 840.0 - s * (1.0 / 30240.0 - s / 1995840.0))
        versine = 0.5 - s / 24.0 * (1.0 - s / 30.0 * (1.0 - s / 56.0 * (1.0 - s / 90.0)))
        d_versine = -1.0 / 24.0 + s * (1.0 / 360.0 - s * (1.0 / 13440.0 - s / 907200.0))
        dd_versine = 1.0 / 360.0 - s * (1.0 / 6720.0 - s * (1.0 / 302400.0 - s / 23950080.0))
        return sine, d_sine, dd_sine, versine, d_versine, dd_versine
    theta = math.sqrt(s)
    cosine = math.cos(theta)
    sine = math.sin(theta) / theta
    versine = (1.0 - cosine) / s
    d_sine = (cosine - sine) / (2.0 * s)  # d cos(t) / ds = -sine / 2
    d_versine = (sine - 2.0 * versine) / (2.0 * s)
    dd_sine = (-0.5 * sine - 3.0 * d_sine) / (2.0 * s)
    dd_versine = (d_sine - 4.0 * d_versine) / (2.0 * s)
    return sine, d_sine, dd_sine, versine, d_versine, dd_versine


@jit
def joint_derivatives(bx, by, psi, length, nominal, rot, pos, d_rot, dd_rot, d_pos, dd_pos):
    """
    Rotation, tip position and their partial derivatives in the local (bx, by, psi, e).

    ``length`` = L (1 + e), ``nominal`` = L. d_rot (4, 3, 3), dd_rot (4, 4, 3, 3), d_pos
    (4, 3), dd_pos (4, 4, 3); the rotation does not depend on e.
    """
    sine, d_sine, dd_sine, versine, d_versine, dd_versine = arc_functions(bx * bx + by * by)
    jets = np.zeros((12, JET))  # S, V, bx, by, then B's nine entries
    _jet_of_square(sine, d_sine, dd_sine, bx, by, jets[0])
    _jet_of_square(versine, d_versine, dd_versine, bx, by, jets[1])
    jets[2, 0] = bx
    jets[2, 1] = 1.0
    jets[3, 0] = by
    jets[3, 2] = 1.0
    tmp = np.empty(JET)
    # B = exp([(-by, bx, 0)]): 1 - V bx^2, -V bx by, S bx / ., 1 - V by^2, S by / -S bx, ...
    _jet_product(jets[1], jets[2], tmp)
    _jet_product(tmp, jets[2], jets[4])
    _jet_product(tmp, jets[3], jets[5])
    _jet_product(jets[1], jets[3], tmp)
    _jet_product(tmp, jets[3], jets[8])
    _jet_product(jets[0], jets[2], jets[6])
    _jet_product(jets[0], jets[3], jets[9])
    b = np.empty((JET, 3, 3))
    for d in range(JET):
        first = 1.0 if d == 0 else 0.0
        b[d, 0, 0] = first - jets[4, d]
        b[d, 0, 1] = -jets[5, d]
        b[d, 0, 2] = jets[6, d]
        b[d, 1, 0] = -jets[5, d]
        b[d, 1, 1] = first - jets[8, d]
        b[d, 1, 2] = jets[9, d]
        b[d, 2, 0] = -jets[6, d]
        b[d, 2, 1] = -jets[9, d]
        b[d, 2, 2] = first - (jets[4, d] + jets[8, d])
    cos_psi = math.cos(psi)
    sin_psi = math.sin(psi)
    twist = np.zeros((3, 3, 3))  # Rz(psi) and its first two derivatives
    for d, (c, s) in enumerate(((cos_psi, sin_psi), (-sin_psi, cos_psi),
                                (-cos_psi, -sin_psi))):
        twist[d, 0, 0] = c
        twist[d, 0, 1] = -s
        twist[d, 1, 0] = s
        twist[d, 1, 1] = c
    twist[0, 2, 2] = 1.0
    # each derivative of R = B Rz(psi): (jet entry of B, derivative of Rz)
    _product(b[0], twist[0], rot, False, False)
    d_rot[3] = 0.0
    for a, (entry, order) in enumerate(((1, 0), (2, 0), (0, 1))):
        _product(b[entry], twist[order], d_rot[a], False, False)
    dd_rot[3] = 0.0
    dd_rot[:, 3] = 0.0
    for a, b_, entry, order in ((0, 0, 3, 0), (0, 1, 4, 0), (1, 1, 5, 0), (0, 2, 1, 1),
                                (1, 2, 2, 1), (2, 2, 0, 2)):
        _product(b[entry], twist[order], dd_rot[a, b_], False, False)
        dd_rot[b_, a] = dd_rot[a, b_]
    # tip position l (V bx, V by, S)
    _jet_product(jets[1], jets[2], jets[10])
    _jet_product(jets[1], jets[3], jets[11])
    d_pos[:] = 0.0
    dd_pos[:] = 0.0
    for c, row in enumerate((10, 11, 0)):
        pos[c] = length * jets[row, 0]
        d_pos[3, c] = nominal * jets[row, 0]
        for a in range(2):
            d_pos[a, c] = length * jets[row, 1 + a]
            dd_pos[a, 3, c] = nominal * jets[row, 1 + a]
            dd_pos[3, a, c] = dd_pos[a, 3, c]
            for e in range(2):  # jet entry 3 + a + e is d2 / (da de)
                dd_pos[a, e, c] = length * jets[row, 3 + a + e]


@jit_inline
def _product(a, b, out, transpose_a, transpose_b):
    """Set 3x3 ``out`` to op(a) op(b), op the transpose where asked (no BLAS call)."""
    for i in range(3):
        for j in range(3):
            total = 0.0
            for k in range(3):
                left = a[k, i] if transpose_a else a[i, k]
                right = b[j, k] if transpose_b else b[k, j]
                total += left * right
            out[i, j] = total


@jit_inline
def _apply(a, v, out, add):
    """Set ``out`` to a v (3x3 times 3-vector), or add a v to it."""
    for i in range(3):
        value = a[i, 0] * v[0] + a[i, 1] * v[1] + a[i, 2] * v[2]
        out[i] = out[i] + value if add else value


@jit_inline
def _dot(u, v):
    """Dot product of two 3-vectors."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@jit_inline
def _frobenius(a, b):
    """Sum of the elementwise products of two 3x3 matrices."""
    total = 0.0
    for i in range(3):
        for j in range(3):
            total += a[i, j] * b[i, j]
    return total


@jit
def energy_hessian(x, data, hessian):
    """Hessian of U with respect to the nondimensional coordinates (of ``energy_gradient``)."""
    length = data[JOINT_LENGTH]
    radius = data[PITCH_RADIUS]
    ei = data[BENDING_STIFFNESS]
    ea = data[AXIAL_STIFFNESS]
    hessian[:] = 0.0
    for j in range(2):
        bx = x[2 * j]
        by = x[2 * j + 1]
        s = bx * bx + by * by
        primary = length * (1.0 + x[6 + j])
        xx = ei / primary
        xy = 0.0
        yy = ei / primary
        xe = -ei * length * bx / primary ** 2
        ye = -ei * length * by / primary ** 2
        ee = ei * s * length ** 2 / primary ** 3 + ea * length
        for k in range(4):
            hx, hy = hole(radius, k)
            arc = primary - (hx * bx + hy * by)
            xx += ei * (1.0 / arc + 2.0 * bx * hx / arc ** 2 + s * hx * hx / arc ** 3)
            xy += ei * ((bx * hy + by * hx) / arc ** 2 + s * hx * hy / arc ** 3)
            yy += ei * (1.0 / arc + 2.0 * by * hy / arc ** 2 + s * hy * hy / arc ** 3)
            xe -= ei * length * (bx / arc ** 2 + s * hx / arc ** 3)
            ye -= ei * length * (by / arc ** 2 + s * hy / arc ** 3)
            ee += ei * s * length ** 2 / arc ** 3
        x_, y_, e_ = 2 * j, 2 * j + 1, 6 + j
        hessian[x_, x_] = xx
        hessian[x_, y_] = hessian[y_, x_] = xy
        hessian[y_, y_] = yy
        hessian[x_, e_] = hessian[e_, x_] = xe
        hessian[y_, e_] = hessian[e_, y_] = ye
        hessian[e_, e_] = ee
        hessian[4 + j, 4 + j] = data[JOINT_TWIST_STIFFNESS] + data[SECONDARY_TWIST_STIFFNESS]
    hessian[4, 5] = hessian[5, 4] = data[SECONDARY_TWIST_STIFFNESS]
    # the secondaries' common stretch: tension (EA / L_s) a . x with a per secondary
    stretch = np.zeros(SIZE)
    for k in range(4):
        hx, hy = hole(radius, k)
        stretch[0] = stretch[2] = -hx
        stretch[1] = stretch[3] = -hy
        stretch[6] = stretch[7] = length
        for a in range(SIZE):
            for b in range(SIZE):
                hessian[a, b] += ea / data[SECONDARY_LENGTH] * stretch[a] * stretch[b]


@jit
def joint_twists(bx, by, psi, length, nominal):
    """
    Pose of a joint and its first derivatives as twists, in scalars (no arrays: hot loop).

    Returns the rotation's nine entries (row-major), the tip position, dp/dbx, dp/dby,
    dp/de (e the nondimensional elongation) and the spatial angular velocities
    vee(dR/da R^T) for a = bx, by, psi. With w = (-by, bx, 0), R = exp([w]) Rz(psi) and
    the left Jacobian of SO(3), I + V [w] + W [w]^2 (W = (theta - sin theta) / theta^3),
    those are J e_y, -J e_x and the bent z axis.
    """
    s = bx * bx + by * by
    sine, d_sine, _, versine, d_versine, _ = arc_functions(s)
    if s < SERIES_LIMIT:
        third = 1.0 / 6.0 - s / 120.0 * (1.0 - s / 42.0 * (1.0 - s / 72.0 * (1.0 - s / 110.0)))
    else:
        third = (1.0 - sine) / s
    b00 = 1.0 - versine * bx * bx
    b01 = -versine * bx * by
    b11 = 1.0 - versine * by * by
    b02 = sine * bx
    b12 = sine * by
    b22 = 1.0 - versine * s
    cos_psi = math.cos(psi)
    sin_psi = math.sin(psi)
    rotation = (cos_psi * b00 + sin_psi * b01, cos_psi * b01 - sin_psi * b00, b02,
                cos_psi * b01 + sin_psi * b11, cos_psi * b11 - sin_psi * b01, b12,
                -cos_psi * b02 - sin_psi * b12, sin_psi * b02 - cos_psi * b12, b22)
    tip = (length * versine * bx, length * versine * by, length * sine)
    d_bx = (length * (versine + 2.0 * bx * bx * d_versine), length * 2.0 * bx * by * d_versine,
            length * 2.0 * bx * d_sine)
    d_by = (length * 2.0 * bx * by * d_versine, length * (versine + 2.0 * by * by * d_versine),
            length * 2.0 * by * d_sine)
    d_e = (nominal * versine * bx, nominal * versine * by, nominal * sine)
    turn_bx = (-third * bx * by, 1.0 - third * by * by, -versine * by)
    turn_by = (-1.0 + third * bx * bx, third * bx * by, versine * bx)
    turn_psi = (b02, b12, b22)
    return rotation, tip, d_bx, d_by, d_e, turn_bx, turn_by, turn_psi


@jit_inline
def _dot3(u, v):
    """Dot product of two 3-tuples."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@jit
def cc_residual(x, data, out):
    """
    Nondimensional residual (grad U - Q) L / EI into ``out``, without the Jacobian's work.

    The generalized force of coordinate c is Q_c = f . dp/dx_c + m . omega_c. For the PJ's
    coordinates, dp/dx_c = dp1/dx_c + omega_c x r (r = R1 lever, the lever from the PJ's
    tip to the end disk), so Q_c = f . dp1/dx_c + omega_c . (r x f + m); the DJ's see the
    wrench turned into {pm}, R1^T f and R1^T m.
    """
    length = data[JOINT_LENGTH]
    rot1, tip1, d_bx1, d_by1, d_e1, turn_bx1, turn_by1, turn_psi1 = joint_twists(
        x[0], x[1], x[4], length * (1.0 + x[6]), length)
    rot2, tip2, d_bx2, d_by2, d_e2, turn_bx2, turn_by2, turn_psi2 = joint_twists(
        x[2], x[3], x[5], length * (1.0 + x[7]), length)
    f = (data[WRENCH], data[WRENCH + 1], data[WRENCH + 2])
    m = (data[WRENCH + 3], data[WRENCH + 4], data[WRENCH + 5])
    lever = (tip2[0], tip2[1], tip2[2] + data[TUBE_LENGTH])
    r = (rot1[0] * lever[0] + rot1[1] * lever[1] + rot1[2] * lever[2],
         rot1[3] * lever[0] + rot1[4] * lever[1] + rot1[5] * lever[2],
         rot1[6] * lever[0] + rot1[7] * lever[1] + rot1[8] * lever[2])
    arm = (r[1] * f[2] - r[2] * f[1] + m[0], r[2] * f[0] - r[0] * f[2] + m[1],
           r[0] * f[1] - r[1] * f[0] + m[2])
    f2 = (rot1[0] * f[0] + rot1[3] * f[1] + rot1[6] * f[2],
          rot1[1] * f[0] + rot1[4] * f[1] + rot1[7] * f[2],
          rot1[2] * f[0] + rot1[5] * f[1] + rot1[8] * f[2])
    m2 = (rot1[0] * m[0] + rot1[3] * m[1] + rot1[6] * m[2],
          rot1[1] * m[0] + rot1[4] * m[1] + rot1[7] * m[2],
          rot1[2] * m[0] + rot1[5] * m[1] + rot1[8] * m[2])
    energy_gradient(x, data, out)
    out[0] -= _dot3(f, d_bx1) + _dot3(turn_bx1, arm)
    out[1] -= _dot3(f, d_by1) + _dot3(turn_by1, arm)
    out[4] -= _dot3(turn_psi1, arm)
    out[6] -= _dot3(f, d_e1)
    out[2] -= _dot3(f2, d_bx2) + _dot3(turn_bx2, m2)
    out[3] -= _dot3(f2, d_by2) + _dot3(turn_by2, m2)
    out[5] -= _dot3(turn_psi2, m2)
    out[7] -= _dot3(f2, d_e2)
    scale = length / data[BENDING_STIFFNESS]
    for c in range(SIZE):
        out[c] *= scale


@jit
def cc_system(x, data, out, jac, want_jacobian):
    """
    Residual of ``cc_residual`` into ``out``; with ``want_jacobian`` its Jacobian into ``jac``.

    The Jacobian is exact (to rounding), also for the moment's non-conservative part.
    """
    cc_residual(x, data, out)
    if not want_jacobian:
        return
    length = data[JOINT_LENGTH]
    rot = np.empty((2, 3, 3))
    pos = np.empty((2, 3))
    d_rot = np.empty((2, 4, 3, 3))
    dd_rot = np.empty((2, 4, 4, 3, 3))
    d_pos = np.empty((2, 4, 3))
    dd_pos = np.empty((2, 4, 4, 3))
    for j in range(2):
        joint_derivatives(x[2 * j], x[2 * j + 1], x[4 + j], length * (1.0 + x[6 + j]), length,
                          rot[j], pos[j], d_rot[j], dd_rot[j], d_pos[j], dd_pos[j])
    force = data[WRENCH:WRENCH + 3]
    moment = data[WRENCH + 3:WRENCH + 6]
    lever = pos[1].copy()  # from the tube's proximal end to the end disk, in {pm}
    lever[2] += data[TUBE_LENGTH]
    end_rot = np.empty((3, 3))
    _product(rot[0], rot[1], end_rot, False, False)
    skew = np.zeros((3, 3))
    skew[0, 1] = -moment[2]
    skew[0, 2] = moment[1]
    skew[1, 2] = -moment[0]
    skew[1, 0] = moment[2]
    skew[2, 0] = -moment[1]
    skew[2, 1] = moment[0]
    weight = np.empty((3, 3))  # m . vee(A R^T) = <A, weight> / 2
    _product(skew, end_rot, weight, False, False)
    d_end_rot = np.zeros((SIZE, 3, 3))  # dR / dx
    for a in range(3):
        _product(d_rot[0, a], rot[1], d_end_rot[JOINT_UNKNOWNS[0][a]], False, False)
        _product(rot[0], d_rot[1, a], d_end_rot[JOINT_UNKNOWNS[1][a]], False, False)
    scale = length / data[BENDING_STIFFNESS]
    energy_hessian(x, data, jac)
    proximal_weight = np.empty((3, 3))  # <A R2, W> = <A, W R2^T>
    _product(weight, rot[1], proximal_weight, False, True)
    distal_weight = np.empty((3, 3))  # <R1 A, W> = <A, R1^T W>
    _product(rot[0], weight, distal_weight, True, False)
    turned = np.empty((SIZE, 3, 3))  # [m] dR/dx for the rotation's own product term
    for c in range(SIZE):
        _product(skew, d_end_rot[c], turned[c], False, False)
    cross = np.empty((3, 3))
    vector = np.empty(3)
    for a in range(4):
        ca = JOINT_UNKNOWNS[0][a]
        _product(d_rot[0, a], weight, cross, True, False)  # <dR1 dR2, W> = <dR2, dR1^T W>
        for b in range(4):
            cb = JOINT_UNKNOWNS[0][b]
            vector[:] = dd_pos[0, a, b]
            _apply(dd_rot[0, a, b], lever, vector, True)
            jac[ca, cb] -= (_dot(force, vector)
                            + 0.5 * _frobenius(dd_rot[0, a, b], proximal_weight))
            cb = JOINT_UNKNOWNS[1][b]
            _apply(d_rot[0, a], d_pos[1, b], vector, False)
            second = _dot(force, vector) + 0.5 * _frobenius(d_rot[1, b], cross)
            jac[ca, cb] -= second
            jac[cb, ca] -= second
            _apply(rot[0], dd_pos[1, a, b], vector, False)
            jac[JOINT_UNKNOWNS[1][a], cb] -= (_dot(force, vector) + 0.5 * _frobenius(
                dd_rot[1, a, b], distal_weight))
    for c in range(SIZE):
        for d in range(SIZE):
            jac[c, d] = scale * (jac[c, d] - 0.5 * _frobenius(d_end_rot[c], turned[d]))
