"""
Fidelity level 'cc': constant-curvature virtual-work model of the translator.

In the manner of Xu & Simaan's statics of multi-backbone continuum joints (the paper's
ref. [18], ASME J. Mechanisms Robotics 2, 011006, 2010): every backbone of a joint is a
circular arc, all with the joint's bending angle, and the equilibrium is the principle of
virtual work, grad U(q) = J(q)^T w, with J the end-disk twist Jacobian. Eight generalized
coordinates (nondimensional in ``x``):

  x[0:2]  b1 = theta1 (cos delta1, sin delta1), the PJ's bending vector in {pe};
  x[2:4]  b2, the DJ's bending vector in {dm};
  x[4:6]  psi1, psi2, the twist of each joint's distal disk about its own axis;
  x[6:8]  e1 / L, e2 / L, the primary backbone's elongation in each joint (L = joint length).

Kinematics of a joint of primary length l = L + e: rotation exp([(-b_y, b_x, 0)]) Rz(psi),
tip at l ((1 - cos theta) / theta^2 b, sin theta / theta). The rigid tube adds L_m along z.

Elastic energy U:
* bending of the five backbones of each joint: sum_k EI theta^2 / (2 l_k), the secondary
  at hole r_k having length l_k = l - r_k . b (shorter on the inside of the bend);
* axial strain of the primary in each joint, EA e^2 / (2 L), and of each secondary over its
  whole clamped length L_s = 2 L + L_m, EA Delta_k^2 / (2 L_s) with
  Delta_k = e1 + e2 - r_k . (b1 + b2): this is the coupling through the tube that makes the
  DJ bend back (the S-shape) and its stretch is what lets the end disk rotate;
* twist: between adjacent disks each secondary is a guided (Timoshenko) beam whose ends the
  relative disk rotation phi offsets by r phi, stiffness 12 EI / (D^3 (1 + 12 EI / (GA D^2))),
  plus the primary's GJ / D; the joint's twist is shared evenly by its S + 1 intervals; the
  secondaries, clamped at both end disks, also twist by psi1 + psi2 over L_s.
Not modelled: shear, the deviation of each backbone from a circular arc (the moment varies
along a joint), and any coupling of twist into the arcs.

The residual and its Jacobian are in closed form: fidelity.cc_derivatives.
"""

import math

import numpy as np

from .._jit import jit

#: Number of generalized coordinates.
SIZE = 8

# layout of the data vector: the wrench, then the model constants
WRENCH = 0
JOINT_LENGTH = 6
TUBE_LENGTH = 7
PITCH_RADIUS = 8
BENDING_STIFFNESS = 9
AXIAL_STIFFNESS = 10
JOINT_TWIST_STIFFNESS = 11
SECONDARY_TWIST_STIFFNESS = 12
SECONDARY_LENGTH = 13
DATA_SIZE = 14


def model_data(params) -> np.ndarray:
    """Return the data vector (zero wrench) of the 'cc' model for TranslatorParams."""
    data = np.zeros(DATA_SIZE)
    ei = params.bending_stiffness
    ga = params.shear_modulus * params.area
    spacing = params.disk_spacing
    polar = params.shear_modulus * 2.0 * params.second_moment
    guided = 12.0 * ei / (spacing ** 3 * (1.0 + 12.0 * ei / (ga * spacing ** 2)))
    data[JOINT_LENGTH] = params.joint_length
    data[TUBE_LENGTH] = params.tube_length
    data[PITCH_RADIUS] = params.pitch_radius
    data[BENDING_STIFFNESS] = ei
    data[AXIAL_STIFFNESS] = params.youngs_modulus * params.area
    interval = 4.0 * guided * params.pitch_radius ** 2 + polar / spacing
    data[JOINT_TWIST_STIFFNESS] = interval / (params.spacers_per_joint + 1)
    secondary_length = 2.0 * params.joint_length + params.tube_length
    data[SECONDARY_TWIST_STIFFNESS] = 4.0 * polar / secondary_length
    data[SECONDARY_LENGTH] = secondary_length
    return data


@jit
def hole(pitch_radius, k):
    """Return x, y of the hole of secondary k = 0..3 (at 0, 90, 180, 270 deg)."""
    angle = 0.5 * math.pi * k
    return pitch_radius * math.cos(angle), pitch_radius * math.sin(angle)


@jit
def joint_pose(bx, by, psi, length, rot, pos):
    """Rotation and tip position of a constant-curvature joint (in its base frame)."""
    theta_sq = bx * bx + by * by
    if theta_sq < 1e-4:  # series: sin(t)/t and (1 - cos(t))/t^2, error below 1e-19
        sine = 1.0 - theta_sq / 6.0 * (1.0 - theta_sq / 20.0 * (1.0 - theta_sq / 42.0))
        versine = 0.5 - theta_sq / 24.0 * (1.0 - theta_sq / 30.0 * (1.0 - theta_sq / 56.0))
    else:
        theta = math.sqrt(theta_sq)
        sine = math.sin(theta) / theta
        versine = (1.0 - math.cos(theta)) / theta_sq
    # exp([w]) with w = (-by, bx, 0): I + sine [w] + versine (w w^T - theta^2 I)
    b00 = 1.0 + versine * (by * by - theta_sq)
    b01 = -versine * bx * by
    b02 = sine * bx
    b10 = b01
    b11 = 1.0 + versine * (bx * bx - theta_sq)
    b12 = sine * by
    b20 = -sine * bx
    b21 = -sine * by
    b22 = 1.0 - versine * theta_sq
    cos_psi = math.cos(psi)
    sin_psi = math.sin(psi)
    rot[0, 0] = cos_psi * b00 + sin_psi * b01
    rot[1, 0] = cos_psi * b10 + sin_psi * b11
    rot[2, 0] = cos_psi * b20 + sin_psi * b21
    rot[0, 1] = cos_psi * b01 - sin_psi * b00
    rot[1, 1] = cos_psi * b11 - sin_psi * b10
    rot[2, 1] = cos_psi * b21 - sin_psi * b20
    rot[0, 2] = b02
    rot[1, 2] = b12
    rot[2, 2] = b22
    pos[0] = length * versine * bx
    pos[1] = length * versine * by
    pos[2] = length * sine


@jit
def compose(frame, rot, pos, out):
    """Set the 4x4 ``out`` to frame * [rot pos; 0 1]."""
    for i in range(3):
        for j in range(3):
            out[i, j] = frame[i, 0] * rot[0, j] + frame[i, 1] * rot[1, j] + frame[i, 2] * rot[2, j]
        out[i, 3] = (frame[i, 0] * pos[0] + frame[i, 1] * pos[1] + frame[i, 2] * pos[2]
                     + frame[i, 3])
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@jit
def cc_frames(x, data, frames):
    """Write {pe}, {pm}, {dm}, {de} (4x4 each, in {pe}) for nondimensional coordinates x."""
    length = data[JOINT_LENGTH]
    rot = np.empty((3, 3))
    pos = np.empty(3)
    frames[0] = np.eye(4)
    joint_pose(x[0], x[1], x[4], length * (1.0 + x[6]), rot, pos)
    compose(frames[0], rot, pos, frames[1])
    frames[2] = frames[1]
    for i in range(3):
        frames[2, i, 3] += data[TUBE_LENGTH] * frames[1, i, 2]
    joint_pose(x[2], x[3], x[5], length * (1.0 + x[7]), rot, pos)
    compose(frames[2], rot, pos, frames[3])


@jit
def energy_gradient(x, data, grad):
    """Gradient of U with respect to the nondimensional coordinates (SI energy)."""
    length = data[JOINT_LENGTH]
    radius = data[PITCH_RADIUS]
    ei = data[BENDING_STIFFNESS]
    ea = data[AXIAL_STIFFNESS]
    grad[:] = 0.0
    for j in range(2):
        bx = x[2 * j]
        by = x[2 * j + 1]
        theta_sq = bx * bx + by * by
        primary = length * (1.0 + x[6 + j])
        elongation = length * x[6 + j]
        # primary backbone: bending and axial strain
        grad[2 * j] += ei * bx / primary
        grad[2 * j + 1] += ei * by / primary
        d_elongation = -0.5 * ei * theta_sq / primary ** 2 + ea * elongation / length
        for k in range(4):
            hx, hy = hole(radius, k)
            arc = primary - (hx * bx + hy * by)
            grad[2 * j] += ei * (bx / arc + 0.5 * theta_sq * hx / arc ** 2)
            grad[2 * j + 1] += ei * (by / arc + 0.5 * theta_sq * hy / arc ** 2)
            d_elongation -= 0.5 * ei * theta_sq / arc ** 2
        grad[6 + j] = length * d_elongation
        grad[4 + j] = (data[JOINT_TWIST_STIFFNESS] * x[4 + j]
                       + data[SECONDARY_TWIST_STIFFNESS] * (x[4] + x[5]))
    # the secondaries' stretch over their whole length couples the joints
    for k in range(4):
        hx, hy = hole(radius, k)
        stretch = (length * (x[6] + x[7]) - hx * (x[0] + x[2]) - hy * (x[1] + x[3]))
        tension = ea * stretch / data[SECONDARY_LENGTH]
        grad[0] -= tension * hx
        grad[1] -= tension * hy
        grad[2] -= tension * hx
        grad[3] -= tension * hy
        grad[6] += tension * length
        grad[7] += tension * length


@jit
def cc_points(x, data, spacers, steps, points):
    """Centre-line points (5, 2 (S + 1) (steps + 1), 3) of the five backbones' arcs."""
    length = data[JOINT_LENGTH]
    radius = data[PITCH_RADIUS]
    frames = np.empty((4, 4, 4))
    cc_frames(x, data, frames)
    rot = np.empty((3, 3))
    pos = np.empty(3)
    frame = np.empty((4, 4))
    intervals = spacers + 1
    row = 0
    for j in range(2):
        base = frames[0] if j == 0 else frames[2]
        for t in range(intervals):
            for i in range(steps + 1):
                fraction = (t + i / steps) / intervals
                joint_pose(fraction * x[2 * j], fraction * x[2 * j + 1],
                           fraction * x[4 + j], fraction * length * (1.0 + x[6 + j]), rot, pos)
                compose(base, rot, pos, frame)
                for c in range(3):
                    points[0, row, c] = frame[c, 3]
                for k in range(4):
                    hx, hy = hole(radius, k)
                    for c in range(3):
                        points[k + 1, row, c] = frame[c, 3] + frame[c, 0] * hx + frame[c, 1] * hy
                row += 1
