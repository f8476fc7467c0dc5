"""
Compiled pieces of the CDR's coupled Newton iterate (robot/delta.py).

An iterate of a warm CDR solve is three leg shots (~35 us each) and a little algebra on
24 platform and 3 x n leg unknowns; written with numpy, the algebra's call overhead cost
twice the shots (the platform residual 75 us, the reduced Newton step 80 us, the three
shots' wrappers 40 us on top). Here each is one compiled call.
"""

import math

import numpy as np

from .._jit import jit
from ..chord import apply_updates, lu_solve
from ..model import N_RODS, translator_residual


@jit
def small_rotation_vector(matrix, out):
    """
    Rotation vector of a rotation ``matrix`` turned by less than 90 degrees, into ``out``.

    From the skew part, sin(angle) times the axis, and the trace, 1 + 2 cos(angle).
    Returns False (``out`` untouched) for a turn of 90 degrees or more, where the skew part
    loses the axis near 180 degrees: result.rotation_vector takes those.
    """
    cosine = 0.5 * (matrix[0, 0] + matrix[1, 1] + matrix[2, 2] - 1.0)
    if not cosine > 0.0:
        return False
    x = 0.5 * (matrix[2, 1] - matrix[1, 2])
    y = 0.5 * (matrix[0, 2] - matrix[2, 0])
    z = 0.5 * (matrix[1, 0] - matrix[0, 1])
    sine = math.sqrt(x * x + y * y + z * z)
    factor = math.atan2(sine, cosine) / sine if sine > 1e-8 else 1.0 / cosine
    out[0] = factor * x
    out[1] = factor * y
    out[2] = factor * z
    return True


@jit
def shoot_legs(unknowns, wrenches, x_scale, residual_scale, model_args, residuals, frames):
    """
    One residual shot per leg: nondimensional ``unknowns`` (3, n) under ``wrenches`` (3, 6).

    Writes the nondimensional residuals (3, n) and each leg's end-disk frame {de} (3, 4, 4);
    returns the largest absolute residual (NaN when any residual or frame is not finite).
    """
    pitch_radius, spacing, tube_length, spacers, steps, inv_kse, inv_kbt = model_args
    size = unknowns.shape[1]
    scaled = np.empty(size)
    out = np.empty(size)
    no_points = np.empty((N_RODS, 0, 3))
    leg_frames = np.empty((4, 4, 4))
    largest = 0.0
    finite = True
    for k in range(unknowns.shape[0]):
        for i in range(size):
            scaled[i] = unknowns[k, i] * x_scale[i]
        translator_residual(scaled, wrenches[k], pitch_radius, spacing, tube_length, spacers,
                            steps, inv_kse, inv_kbt, out, no_points, leg_frames)
        for i in range(size):
            value = out[i] / residual_scale[i]
            residuals[k, i] = value
            if not math.isfinite(value):
                finite = False
            elif abs(value) > largest:
                largest = abs(value)
        for i in range(4):
            for j in range(4):
                value = leg_frames[3, i, j]
                frames[k, i, j] = value
                if not math.isfinite(value):
                    finite = False
    return largest if finite else math.nan


@jit
def platform_residual(position, rotation, wrenches, frames, inputs, leg_rotations,
                      attachments, home_bases, slider_axes, out):
    """
    Write the CDR residual (24) of robot/delta.py into ``out``: compatibility, equilibrium.

    Compatibility (18, per leg, in {pe_i}): end-disk centre minus the attachment's position
    R_i^T (p + R a_i - b_i), and the rotation vector of R_de (R_i^T R R_i)^T. Equilibrium
    (6, in {w}): payload force + sum of -R_i f_i; payload moment + (R offset) x force +
    sum of (R a_i) x (-R_i f_i) - sum of R_i m_i. ``inputs``: sliders (3), payload force,
    moment, offset (3 each). Returns False when a rotation error reached 90 degrees (its
    three components then hold NaN: the caller computes them).
    """
    small = True
    force_sum = np.zeros(3)
    moment_sum = np.zeros(3)
    arm = np.empty(3)
    relative = np.empty(3)
    error = np.empty((3, 3))
    turned = np.empty((3, 3))
    leg_force = np.empty(3)
    for k in range(3):
        leg = leg_rotations[k]
        for i in range(3):
            arm[i] = (rotation[i, 0] * attachments[k, 0] + rotation[i, 1] * attachments[k, 1]
                      + rotation[i, 2] * attachments[k, 2])
            relative[i] = (position[i] + arm[i] - home_bases[k, i]
                           - inputs[k] * slider_axes[k, i])
        for i in range(3):  # centre minus R_i^T (p + R a_i - b_i)
            out[6 * k + i] = frames[k, i, 3] - (leg[0, i] * relative[0] + leg[1, i] * relative[1]
                                                + leg[2, i] * relative[2])
        # turned = R^T R_i, then error = R_de R_i^T turned
        for i in range(3):
            for j in range(3):
                turned[i, j] = (rotation[0, i] * leg[0, j] + rotation[1, i] * leg[1, j]
                                + rotation[2, i] * leg[2, j])
        for i in range(3):
            for j in range(3):
                total = 0.0
                for a in range(3):
                    transposed = leg[0, a] * turned[0, j] + leg[1, a] * turned[1, j] \
                        + leg[2, a] * turned[2, j]
                    total += frames[k, i, a] * transposed
                error[i, j] = total
        if not small_rotation_vector(error, out[6 * k + 3:6 * k + 6]):
            small = False
            out[6 * k + 3:6 * k + 6] = math.nan
        for i in range(3):
            leg_force[i] = -(leg[i, 0] * wrenches[k, 0] + leg[i, 1] * wrenches[k, 1]
                             + leg[i, 2] * wrenches[k, 2])
            moment_sum[i] -= (leg[i, 0] * wrenches[k, 3] + leg[i, 1] * wrenches[k, 4]
                              + leg[i, 2] * wrenches[k, 5])
        force_sum += leg_force
        moment_sum[0] += arm[1] * leg_force[2] - arm[2] * leg_force[1]
        moment_sum[1] += arm[2] * leg_force[0] - arm[0] * leg_force[2]
        moment_sum[2] += arm[0] * leg_force[1] - arm[1] * leg_force[0]
    force = inputs[3:6]
    for i in range(3):
        arm[i] = (rotation[i, 0] * inputs[9] + rotation[i, 1] * inputs[10]
                  + rotation[i, 2] * inputs[11])
    out[18:21] = force + force_sum
    out[21] = inputs[6] + arm[1] * force[2] - arm[2] * force[1] + moment_sum[0]
    out[22] = inputs[7] + arm[2] * force[0] - arm[0] * force[2] + moment_sum[1]
    out[23] = inputs[8] + arm[0] * force[1] - arm[1] * force[0] + moment_sum[2]
    return small


@jit
def within(residual, equilibrium_tolerance, position_tolerance, rotation_tolerance):
    """
    Say whether the CDR residual (platform_residual's layout) is within the tolerances.

    Every equilibrium component (N, N m), every compatibility position (m) and rotation
    (rad) component; False when any is not finite.
    """
    for k in range(3):
        for i in range(3):
            if not abs(residual[6 * k + i]) <= position_tolerance:
                return False
            if not abs(residual[6 * k + 3 + i]) <= rotation_tolerance:
                return False
    for i in range(18, 24):
        if not abs(residual[i]) <= equilibrium_tolerance:
            return False
    return True


@jit
def coupled_step(residual, leg_residuals, with_legs, r_scale, x_scale, leg_lu, leg_pivots,
                 twists, gains, platform_inverse, updates, steps, count, out):
    """
    Write the coupled Newton step (robot/delta.py's ``_correction``) into ``out``.

    ``out`` = [platform step / x_scale (24); leg steps (3 x n)], then the ``count``
    Broyden updates applied. Leg k: a_k = J_k^-1 r_k (its LU), its twist T_k a_k taken off
    its compatibility residual; the platform step -P^-1 (r / r_scale) (P the scaled
    platform Jacobian); leg k moves by -(J_k^-1 dr/dw) dw_k - a_k. Without ``with_legs``
    (legs solved in full, the continuation predictor) the leg residuals count as zero.
    """
    legs, size = leg_residuals.shape
    modified = residual / r_scale
    corrections = np.zeros((legs, size))
    if with_legs:
        for k in range(legs):
            lu_solve(leg_lu[k], leg_pivots[k], leg_residuals[k], corrections[k])
            for i in range(6):
                twist = 0.0
                for j in range(size):
                    twist += twists[k, i, j] * corrections[k, j]
                modified[6 * k + i] -= twist / r_scale[6 * k + i]
    count_platform = modified.shape[0]
    for i in range(count_platform):
        total = 0.0
        for j in range(count_platform):
            total += platform_inverse[i, j] * modified[j]
        out[i] = -total
    wrench_step = np.empty(6)
    for k in range(legs):
        base = count_platform + k * size
        for j in range(6):  # leg k's wrench step, SI
            wrench_step[j] = out[6 + 6 * k + j] * x_scale[6 + 6 * k + j]
        for i in range(size):
            total = 0.0
            for j in range(6):
                total += gains[k, i, j] * wrench_step[j]
            out[base + i] = -total - corrections[k, i]
    apply_updates(updates, steps, count, out)
