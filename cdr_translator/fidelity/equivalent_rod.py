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
"""

import math

import numpy as np

from .cc import hole
from .._jit import jit
from ..rod import rk4_advance_pose, rk4_stage_pose

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


@jit
def _derivative(p, rot, tension, data, m0, dp, drot, dlength):
    """d/ds of the position, rotation and the four secondaries' path lengths."""
    force = data[WRENCH:WRENCH + 3]
    radius = data[PITCH_RADIUS]
    ei = data[BENDING_STIFFNESS]
    moment = np.empty(3)
    moment[0] = m0[0] - (p[1] * force[2] - p[2] * force[1])
    moment[1] = m0[1] - (p[2] * force[0] - p[0] * force[2])
    moment[2] = m0[2] - (p[0] * force[1] - p[1] * force[0])
    mb = np.empty(3)
    nb = np.empty(3)
    for c in range(3):
        mb[c] = rot[0, c] * moment[0] + rot[1, c] * moment[1] + rot[2, c] * moment[2]
        nb[c] = rot[0, c] * force[0] + rot[1, c] * force[1] + rot[2, c] * force[2]
    total = 0.0
    rhs_x = mb[0]
    rhs_y = mb[1]
    for k in range(4):
        hx, hy = hole(radius, k)
        total += tension[k]
        rhs_x -= tension[k] * hy  # r_k x e3 = (r_y, -r_x, 0)
        rhs_y += tension[k] * hx
    ux = rhs_x / (5.0 * ei)
    uy = rhs_y / (5.0 * ei)
    for _ in range(CURVATURE_SWEEPS):
        factor = (1.0 + 2.0 / (1.0 - (radius * uy) ** 2) + 2.0 / (1.0 - (radius * ux) ** 2))
        ux = rhs_x / (ei * factor)
        uy = rhs_y / (ei * factor)
    uz = mb[2] / (data[TWIST_STIFFNESS] + radius * radius * total)
    vx = data[INVERSE_SHEAR] * nb[0]
    vy = data[INVERSE_SHEAR] * nb[1]
    vz = 1.0 + data[INVERSE_AXIAL] * (nb[2] - total)
    for i in range(3):
        dp[i] = rot[i, 0] * vx + rot[i, 1] * vy + rot[i, 2] * vz
        drot[i, 0] = rot[i, 1] * uz - rot[i, 2] * uy
        drot[i, 1] = rot[i, 2] * ux - rot[i, 0] * uz
        drot[i, 2] = rot[i, 0] * uy - rot[i, 1] * ux
    for k in range(4):
        hx, hy = hole(radius, k)
        # v + u x r_k with r_k = (hx, hy, 0)
        tx = vx - uz * hy
        ty = vy + uz * hx
        tz = vz + ux * hy - uy * hx
        dlength[k] = math.sqrt(tx * tx + ty * ty + tz * tz)


@jit
def _shoot(x, data, frames, points):
    """
    Integrate base to end disk; return the state used by the residual.

    Writes {pe}, {pm}, {dm}, {de} into ``frames`` and, when ``points`` has rows, the
    centre lines of the five backbones. Returns (end position, base moment, tensions,
    path lengths).
    """
    length = data[JOINT_LENGTH]
    ei = data[BENDING_STIFFNESS]
    radius = data[PITCH_RADIUS]
    intervals = int(data[INTERVALS])
    steps = int(data[STEPS])
    m0 = np.empty(3)
    for c in range(3):
        m0[c] = x[c] * ei / length
    tension = np.empty(4)
    for k in range(4):
        tension[k] = x[3 + k] * ei / length ** 2
    p = np.zeros(3)
    rot = np.eye(3)
    lengths = np.zeros(4)
    k_p = np.empty((4, 3))
    k_rot = np.empty((4, 3, 3))
    k_len = np.empty((4, 4))
    p_stage = np.empty(3)
    rot_stage = np.empty((3, 3))
    h = length / (intervals * steps)
    record = points.shape[1] > 0
    row = 0
    frames[0] = np.eye(4)
    for joint in range(2):
        for _ in range(intervals):
            for step in range(steps + 1):
                if record:
                    for c in range(3):
                        points[0, row, c] = p[c]
                    for k in range(4):
                        hx, hy = hole(radius, k)
                        for c in range(3):
                            points[k + 1, row, c] = p[c] + rot[c, 0] * hx + rot[c, 1] * hy
                    row += 1
                if step == steps:
                    break
                _derivative(p, rot, tension, data, m0, k_p[0], k_rot[0], k_len[0])
                for stage, weight in ((1, 0.5), (2, 0.5), (3, 1.0)):
                    rk4_stage_pose(p, rot, k_p[stage - 1], k_rot[stage - 1], weight * h,
                                   p_stage, rot_stage)
                    _derivative(p_stage, rot_stage, tension, data, m0, k_p[stage],
                                k_rot[stage], k_len[stage])
                rk4_advance_pose(p, rot, k_p, k_rot, h)
                for k in range(4):
                    lengths[k] += h / 6.0 * (k_len[0, k] + 2.0 * k_len[1, k]
                                             + 2.0 * k_len[2, k] + k_len[3, k])
        target = 1 if joint == 0 else 3
        frames[target, :3, :3] = rot
        frames[target, :3, 3] = p
        frames[target, 3, :3] = 0.0
        frames[target, 3, 3] = 1.0
        if joint == 0:  # the rigid tube: straight lumens of length L_m
            for i in range(3):
                p[i] += data[TUBE_LENGTH] * rot[i, 2]
            for k in range(4):
                lengths[k] += data[TUBE_LENGTH]
            frames[2] = frames[1]
            frames[2, :3, 3] = p
    return p, m0, tension, lengths


@jit
def rod_residual(x, data, out):
    """Nondimensional residual: end-disk moment / (EI / L), path-length mismatch / L."""
    frames = np.empty((4, 4, 4))
    no_points = np.empty((5, 0, 3))
    p, m0, tension, lengths = _shoot(x, data, frames, no_points)
    force = data[WRENCH:WRENCH + 3]
    scale = data[JOINT_LENGTH] / data[BENDING_STIFFNESS]
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
    _shoot(x, data, frames, np.empty((5, 0, 3)))


@jit
def rod_points(x, data, points):
    """Centre-line points (5, 2 (S + 1) (steps + 1), 3) of the five backbones."""
    frames = np.empty((4, 4, 4))
    _shoot(x, data, frames, points)
