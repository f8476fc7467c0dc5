"""
Fidelity level 'rod': the five backbones of each joint as one equivalent Cosserat rod.

The centre line of the primary backbone is integrated as a Cosserat rod (RK4) from the base
through the PJ, the rigid tube and the DJ, as in the full model, but the four secondaries
are not rods of their own: as with densely spaced disks (a tendon-driven continuum robot
whose tendons are elastic backbones) each secondary runs along the offset curve p + R r_k
with its tangent along the disks' normal, carries one tension tau_k along its whole length
(it slides without friction) and bends with the joint. At a cross-section, with the total
internal force n = F (no loads between the disks) and moment m(s) = m(0) - p(s) x F:

* bending:  EI (1 + sum_k 1 / (1 + (u x r_k)_z)) u_xy = (R^T m)_xy - sum_k tau_k (r_k x e3)_xy
  (each secondary has the joint's bending angle over its own length, hence its curvature
  u / (1 + (u x r_k)_z); solved by fixed-point iteration);
* twist:    (GJ + 48 EI r^2 / (D^2 (1 + 12 EI / (GA D^2))) + r^2 sum_k tau_k) u_z = (R^T m)_z,
  the secondaries between adjacent disks acting as guided Timoshenko beams (smeared over the
  disk interval) plus the tension's helix term;
* stretch and shear: v = e3 + diag(1 / 5GA, 1 / 5GA, 1 / EA) (R^T F - e3 sum_k tau_k).

Unknowns (7, nondimensional in ``x``): the base moment m(0) / (EI / L) and the tensions
tau_k / (EI / L^2). Residuals (7): the moment at the end disk equals the applied one, and each
secondary's path length (PJ + tube lumen + DJ) equals its clamped length stretched by its
tension, L_s (1 + tau_k / EA). Not modelled: the secondaries' own shapes between disks (the
spacer disks are not discrete here), their shear forces and their own twist.

The shot here (residual, frames, points) is scalar arithmetic on tuples, no arrays in its
RK4 steps: Newton's line search and chord steps evaluate it several times per answer. Its
Jacobian, forward mode through the same steps, is in fidelity.equivalent_rod_jacobian.
"""

import math

import numpy as np

from .cc import hole
from .._jit import jit, jit_inline

#: Number of unknowns.
SIZE = 7

# layout of the data vector: the wrench, then the model constants
WRENCH = 0
JOINT_LENGTH = 6
TUBE_LENGTH = 7
PITCH_RADIUS = 8
BENDING_STIFFNESS = 9
INVERSE_SHEAR = 10
INVERSE_AXIAL = 11
TWIST_STIFFNESS = 12
SECONDARY_LENGTH = 13
INTERVALS = 14
STEPS = 15
DATA_SIZE = 16

#: Fixed-point sweeps for the secondaries' curvature factor (it changes by (r u)^2 only).
CURVATURE_SWEEPS = 3


def model_data(params, steps: int) -> np.ndarray:
    """Return the data vector (zero wrench) of the 'rod' model, ``steps`` per interval."""
    data = np.zeros(DATA_SIZE)
    ei = params.bending_stiffness
    ga = params.shear_modulus * params.area
    spacing = params.disk_spacing
    guided = 12.0 * ei / (spacing ** 2 * (1.0 + 12.0 * ei / (ga * spacing ** 2)))
    data[JOINT_LENGTH] = params.joint_length
    data[TUBE_LENGTH] = params.tube_length
    data[PITCH_RADIUS] = params.pitch_radius
    data[BENDING_STIFFNESS] = ei
    data[INVERSE_SHEAR] = 1.0 / (5.0 * ga)
    data[INVERSE_AXIAL] = 1.0 / (params.youngs_modulus * params.area)
    data[TWIST_STIFFNESS] = (params.shear_modulus * 2.0 * params.second_moment
                             + 4.0 * guided * params.pitch_radius ** 2)
    data[SECONDARY_LENGTH] = 2.0 * params.joint_length + params.tube_length
    data[INTERVALS] = params.spacers_per_joint + 1
    data[STEPS] = steps
    return data


@jit_inline
def _slope(p, rot, force, m0, tension, holes, constants):
    """
    Return d/ds of the position, the rotation (row-major 9-tuple) and the path lengths.

    Scalars and tuples only (no arrays): the shot calls it 4 times per RK4 step.
    ``constants`` = (pitch radius, EI, 1 / 5GA, 1 / EA, twist stiffness without tension).
    """
    radius, ei, inverse_shear, inverse_axial, twist = constants
    moment0 = m0[0] - (p[1] * force[2] - p[2] * force[1])
    moment1 = m0[1] - (p[2] * force[0] - p[0] * force[2])
    moment2 = m0[2] - (p[0] * force[1] - p[1] * force[0])
    mb0 = rot[0] * moment0 + rot[3] * moment1 + rot[6] * moment2
    mb1 = rot[1] * moment0 + rot[4] * moment1 + rot[7] * moment2
    mb2 = rot[2] * moment0 + rot[5] * moment1 + rot[8] * moment2
    nb0 = rot[0] * force[0] + rot[3] * force[1] + rot[6] * force[2]
    nb1 = rot[1] * force[0] + rot[4] * force[1] + rot[7] * force[2]
    nb2 = rot[2] * force[0] + rot[5] * force[1] + rot[8] * force[2]
    total = tension[0] + tension[1] + tension[2] + tension[3]
    rhs_x = mb0  # r_k x e3 = (r_y, -r_x, 0)
    rhs_y = mb1
    for k in range(4):
        rhs_x -= tension[k] * holes[2 * k + 1]
        rhs_y += tension[k] * holes[2 * k]
    ux = rhs_x / (5.0 * ei)
    uy = rhs_y / (5.0 * ei)
    for _ in range(CURVATURE_SWEEPS):
        factor = ei * (1.0 + 2.0 / (1.0 - (radius * uy) ** 2) + 2.0 / (1.0 - (radius * ux) ** 2))
        ux = rhs_x / factor
        uy = rhs_y / factor
    uz = mb2 / (twist + radius * radius * total)
    vx = inverse_shear * nb0
    vy = inverse_shear * nb1
    vz = 1.0 + inverse_axial * (nb2 - total)
    dp = (rot[0] * vx + rot[1] * vy + rot[2] * vz, rot[3] * vx + rot[4] * vy + rot[5] * vz,
          rot[6] * vx + rot[7] * vy + rot[8] * vz)
    drot = (rot[1] * uz - rot[2] * uy, rot[2] * ux - rot[0] * uz, rot[0] * uy - rot[1] * ux,
            rot[4] * uz - rot[5] * uy, rot[5] * ux - rot[3] * uz, rot[3] * uy - rot[4] * ux,
            rot[7] * uz - rot[8] * uy, rot[8] * ux - rot[6] * uz, rot[6] * uy - rot[7] * ux)
    dlength = (_path_rate(vx, vy, vz, ux, uy, uz, holes[0], holes[1]),
               _path_rate(vx, vy, vz, ux, uy, uz, holes[2], holes[3]),
               _path_rate(vx, vy, vz, ux, uy, uz, holes[4], holes[5]),
               _path_rate(vx, vy, vz, ux, uy, uz, holes[6], holes[7]))
    return dp, drot, dlength


@jit_inline
def offset_tangent(vx, vy, vz, ux, uy, uz, hx, hy):
    """Return v + u x r for r = (hx, hy, 0): a secondary's tangent (d/ds of p + R r)."""
    return vx - uz * hy, vy + uz * hx, vz + ux * hy - uy * hx


@jit_inline
def _path_rate(vx, vy, vz, ux, uy, uz, hx, hy):
    """Return |v + u x r| for r = (hx, hy, 0): how fast a secondary's path grows."""
    tx, ty, tz = offset_tangent(vx, vy, vz, ux, uy, uz, hx, hy)
    return math.sqrt(tx * tx + ty * ty + tz * tz)


@jit_inline
def _moved3(a, h, b):
    """Return a + h b for 3-tuples."""
    return (a[0] + h * b[0], a[1] + h * b[1], a[2] + h * b[2])


@jit_inline
def _moved9(a, h, b):
    """Return a + h b for 9-tuples."""
    return (a[0] + h * b[0], a[1] + h * b[1], a[2] + h * b[2], a[3] + h * b[3],
            a[4] + h * b[4], a[5] + h * b[5], a[6] + h * b[6], a[7] + h * b[7],
            a[8] + h * b[8])


@jit_inline
def _rk4_3(a, weight, k1, k2, k3, k4):
    """Return a + weight (k1 + 2 k2 + 2 k3 + k4) for 3-tuples."""
    return (a[0] + weight * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            a[1] + weight * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
            a[2] + weight * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]))


@jit_inline
def _rk4_4(a, weight, k1, k2, k3, k4):
    """Return a + weight (k1 + 2 k2 + 2 k3 + k4) for 4-tuples."""
    return (a[0] + weight * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            a[1] + weight * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
            a[2] + weight * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
            a[3] + weight * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]))


@jit_inline
def _rk4_9(a, weight, k1, k2, k3, k4):
    """Return a + weight (k1 + 2 k2 + 2 k3 + k4) for 9-tuples."""
    first = _rk4_3((a[0], a[1], a[2]), weight, (k1[0], k1[1], k1[2]), (k2[0], k2[1], k2[2]),
                   (k3[0], k3[1], k3[2]), (k4[0], k4[1], k4[2]))
    second = _rk4_3((a[3], a[4], a[5]), weight, (k1[3], k1[4], k1[5]), (k2[3], k2[4], k2[5]),
                    (k3[3], k3[4], k3[5]), (k4[3], k4[4], k4[5]))
    third = _rk4_3((a[6], a[7], a[8]), weight, (k1[6], k1[7], k1[8]), (k2[6], k2[7], k2[8]),
                   (k3[6], k3[7], k3[8]), (k4[6], k4[7], k4[8]))
    return (first[0], first[1], first[2], second[0], second[1], second[2], third[0], third[1],
            third[2])


@jit_inline
def _set_frame(frame, p, rot):
    """Write the 4x4 ``frame`` of position p and row-major rotation rot."""
    for i in range(3):
        for j in range(3):
            frame[i, j] = rot[3 * i + j]
        frame[i, 3] = p[i]
        frame[3, i] = 0.0
    frame[3, 3] = 1.0


@jit
def shoot(x, data, frames, points):
    """
    Integrate base to end disk; return (end position, base moment, tensions, path lengths).

    Writes {pe}, {pm}, {dm}, {de} into ``frames`` and, when ``points`` has rows, the
    centre lines of the five backbones.
    """
    length = data[JOINT_LENGTH]
    ei = data[BENDING_STIFFNESS]
    radius = data[PITCH_RADIUS]
    intervals = int(data[INTERVALS])
    steps = int(data[STEPS])
    m0 = (x[0] * ei / length, x[1] * ei / length, x[2] * ei / length)
    unit_tension = ei / length ** 2
    tension = (x[3] * unit_tension, x[4] * unit_tension, x[5] * unit_tension,
               x[6] * unit_tension)
    force = (data[WRENCH], data[WRENCH + 1], data[WRENCH + 2])
    h0x, h0y = hole(radius, 0)
    h1x, h1y = hole(radius, 1)
    h2x, h2y = hole(radius, 2)
    h3x, h3y = hole(radius, 3)
    holes = (h0x, h0y, h1x, h1y, h2x, h2y, h3x, h3y)
    constants = (radius, ei, data[INVERSE_SHEAR], data[INVERSE_AXIAL], data[TWIST_STIFFNESS])
    p = (0.0, 0.0, 0.0)
    rot = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    lengths = (0.0, 0.0, 0.0, 0.0)
    h = length / (intervals * steps)
    half = 0.5 * h
    weight = h / 6.0
    record = points.shape[1] > 0
    row = 0
    _set_frame(frames[0], p, rot)
    for joint in range(2):
        for _ in range(intervals):
            for step in range(steps + 1):
                if record:
                    for c in range(3):
                        points[0, row, c] = p[c]
                        for k in range(4):
                            points[k + 1, row, c] = (p[c] + rot[3 * c] * holes[2 * k]
                                                     + rot[3 * c + 1] * holes[2 * k + 1])
                    row += 1
                if step == steps:
                    break
                p1, r1, l1 = _slope(p, rot, force, m0, tension, holes, constants)
                p2, r2, l2 = _slope(_moved3(p, half, p1), _moved9(rot, half, r1), force, m0,
                                    tension, holes, constants)
                p3, r3, l3 = _slope(_moved3(p, half, p2), _moved9(rot, half, r2), force, m0,
                                    tension, holes, constants)
                p4, r4, l4 = _slope(_moved3(p, h, p3), _moved9(rot, h, r3), force, m0,
                                    tension, holes, constants)
                p = _rk4_3(p, weight, p1, p2, p3, p4)
                rot = _rk4_9(rot, weight, r1, r2, r3, r4)
                lengths = _rk4_4(lengths, weight, l1, l2, l3, l4)
        _set_frame(frames[1 if joint == 0 else 3], p, rot)
        if joint == 0:  # the rigid tube: straight lumens of length L_m
            tube = data[TUBE_LENGTH]
            p = (p[0] + tube * rot[2], p[1] + tube * rot[5], p[2] + tube * rot[8])
            lengths = (lengths[0] + tube, lengths[1] + tube, lengths[2] + tube,
                       lengths[3] + tube)
            _set_frame(frames[2], p, rot)
    return p, m0, tension, lengths


@jit
def rod_residual(x, data, out):
    """Nondimensional residual: end-disk moment / (EI / L), path-length mismatch / L."""
    frames = np.empty((4, 4, 4))
    p, m0, tension, lengths = shoot(x, data, frames, np.empty((5, 0, 3)))
    scale = data[JOINT_LENGTH] / data[BENDING_STIFFNESS]
    force = (data[WRENCH], data[WRENCH + 1], data[WRENCH + 2])
    out[0] = (m0[0] - (p[1] * force[2] - p[2] * force[1]) - data[WRENCH + 3]) * scale
    out[1] = (m0[1] - (p[2] * force[0] - p[0] * force[2]) - data[WRENCH + 4]) * scale
    out[2] = (m0[2] - (p[0] * force[1] - p[1] * force[0]) - data[WRENCH + 5]) * scale
    rest = data[SECONDARY_LENGTH]
    for k in range(4):
        out[3 + k] = (lengths[k] - rest * (1.0 + data[INVERSE_AXIAL] * tension[k])) \
            / data[JOINT_LENGTH]


@jit
def rod_frames(x, data, frames):
    """Write {pe}, {pm}, {dm}, {de} for the unknowns x."""
    shoot(x, data, frames, np.empty((5, 0, 3)))


@jit
def rod_points(x, data, points):
    """Centre-line points (5, 2 (S + 1) (steps + 1), 3) of the five backbones."""
    frames = np.empty((4, 4, 4))
    shoot(x, data, frames, points)
