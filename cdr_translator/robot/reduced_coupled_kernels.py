"""
Compiled coupled Newton of the CDR with reduced legs ('cc', 'rod'), and its loop over samples.

The unknowns are the platform's 24 (pose, three leg wrenches w_k; robot/delta.py) joined
with each leg's reduced unknowns x_k; the residual is the platform's 24 (compatibility and
equilibrium, kernels.platform_residual) and each leg's own r_k(x_k, w_k). Newton's system
is reduced to the platform's by eliminating each leg with the LU of its H_k = dr_k/dx_k
(the Schur complement): with S_k = dx_k/dw_k = -H_k^-1 dr_k/dw_k and the leg's compliance
C_k = d twist / dw_k (reduced_kernels.leg_compliance), an iterate

1. corrects each leg at its wrench, x_k <- x_k - H_k^-1 r_k (one residual per leg), and
   takes its end disk there;
2. solves the platform's 24 with each leg entering through C_k
   (reduced_kernels.platform_jacobian): the leg's rows eliminated;
3. moves each leg with its wrench change, x_k <- x_k + S_k dw_k (the eliminated unknowns
   back-substituted).

Chord steps: H_k, S_k, C_k and the platform factorization are kept across iterations and
solves (a warm start iterates on the previous solution's) and made anew at the current
state when an iterate contracts by less than CHORD_RATE. A solved state's frames are kept,
so a warm solve's first iterate costs no leg evaluation. There is no line search: a solve
that does not contract with fresh Jacobians returns, and the caller walks there by damped
continuation (robot/reduced_chain.py).

``solve_samples`` runs the solve and the linearization at each solution (the leg
compliances, the platform compliance and the slider Jacobian) over a sequence of inputs,
warm-started from sample to sample: the atlas's columns without a Python object per sample.
"""

import math

import numpy as np

from .chain_path import extrapolate, push, restore
from .kernels import platform_residual, small_rotation_vector, within
from .reduced_kernels import (determinant_sign, leg_compliance, leg_frames, move_platform,
                              platform_jacobian, scaled_norm)
from .._jit import jit
from ..fidelity.cc import BENDING_STIFFNESS, JOINT_LENGTH, TUBE_LENGTH
from ..fidelity.cc_derivatives import joint_twists
from ..fidelity.level_kernels import frames_pose
from ..fidelity.newton import CC, lu_factor, lu_solve, residual, system

#: Outcomes of ``coupled_newton`` (and ``solve_samples``' rows).
SOLVED = 0
NOT_SOLVED = 1  # no convergence in the iterations allowed
NOT_FINITE = 2  # a leg residual or the platform residual is not finite
SINGULAR = 3  # a leg's H or the platform Jacobian is singular
NO_CONTRACTION = 4  # a step with fresh Jacobians did not decrease the residual

#: An iterate on kept (chord) Jacobians must cut the residual norm at least this much, else
#: they are made anew at the current state.
CHORD_RATE = 0.25

#: Size of the platform's unknowns and residual.
PLATFORM = 24


@jit
def cc_twist(x, data, twist):
    """
    Write T = d twist / dx (6, 8) of the 'cc' leg's end disk at x, in {pe}.

    Column c: [dp/dx_c; vee(dR/dx_c R^T)].

    From each joint's first derivatives as twists (cc_derivatives.joint_twists): the end
    disk is at p = p1 + R1 (L_m e_z + p2) with R = R1 R2 (fidelity.cc's kinematics), so a
    proximal unknown with tip velocity v and angular velocity w moves it by v + w x r
    (r = R1 (L_m e_z + p2)) and turns it by w; a distal one by R1 v and R1 w.
    """
    length = data[JOINT_LENGTH]
    rot1, _, d_bx1, d_by1, d_e1, turn_bx1, turn_by1, turn_psi1 = joint_twists(
        x[0], x[1], x[4], length * (1.0 + x[6]), length)
    _, tip2, d_bx2, d_by2, d_e2, turn_bx2, turn_by2, turn_psi2 = joint_twists(
        x[2], x[3], x[5], length * (1.0 + x[7]), length)
    lever = (tip2[0], tip2[1], tip2[2] + data[TUBE_LENGTH])
    r = (rot1[0] * lever[0] + rot1[1] * lever[1] + rot1[2] * lever[2],
         rot1[3] * lever[0] + rot1[4] * lever[1] + rot1[5] * lever[2],
         rot1[6] * lever[0] + rot1[7] * lever[1] + rot1[8] * lever[2])
    still = (0.0, 0.0, 0.0)
    _proximal_column(twist, 0, d_bx1, turn_bx1, r)
    _proximal_column(twist, 1, d_by1, turn_by1, r)
    _proximal_column(twist, 4, still, turn_psi1, r)
    _proximal_column(twist, 6, d_e1, still, r)
    _distal_column(twist, 2, d_bx2, turn_bx2, rot1)
    _distal_column(twist, 3, d_by2, turn_by2, rot1)
    _distal_column(twist, 5, still, turn_psi2, rot1)
    _distal_column(twist, 7, d_e2, still, rot1)


@jit
def _proximal_column(twist, column, velocity, angular, lever):
    """Twist column of a proximal joint's unknown: [v + w x r; w]."""
    twist[0, column] = velocity[0] + angular[1] * lever[2] - angular[2] * lever[1]
    twist[1, column] = velocity[1] + angular[2] * lever[0] - angular[0] * lever[2]
    twist[2, column] = velocity[2] + angular[0] * lever[1] - angular[1] * lever[0]
    for i in range(3):
        twist[3 + i, column] = angular[i]


@jit
def _distal_column(twist, column, velocity, angular, rot1):
    """Twist column of a distal joint's unknown: [R1 v; R1 w] (rot1 row-major, 9)."""
    for i in range(3):
        twist[i, column] = rot1[3 * i] * velocity[0] + rot1[3 * i + 1] * velocity[1] \
            + rot1[3 * i + 2] * velocity[2]
        twist[3 + i, column] = rot1[3 * i] * angular[0] + rot1[3 * i + 1] * angular[1] \
            + rot1[3 * i + 2] * angular[2]


@jit
def refresh_leg(model, x, data, wrench, lu, pivots, sensitivity, compliance):
    """
    Make a leg's H LU (``lu``, ``pivots``), S = dx/dw (n, 6) and C (6, 6) at (x, wrench).

    Implicit differentiation, as reduced_kernels.leg_compliance: S = -H^-1 dr/dw and C =
    T S (+ d twist / dw at fixed x for 'rod'). 'cc': its residual (grad U - T^T w) L / EI
    gives dr/dw = -(L / EI) T^T with T in closed form (``cc_twist``), no residual
    differences. ``pivots[n]`` says whether the factorization is usable. Returns the sign
    of det H (0: singular, C then NaN).
    """
    size = x.shape[0]
    if model != CC:
        frame = np.empty((4, 4))
        sign = leg_compliance(model, x, data, wrench, frame, compliance, lu, pivots[:size],
                              sensitivity)
    else:
        data[:6] = wrench
        rs = np.empty(size)
        system(model, x, data, rs, lu, True)
        sign = determinant_sign(lu, pivots) if lu_factor(lu, pivots) else 0
        if sign != 0:
            twist = np.empty((6, size))
            cc_twist(x, data, twist)
            scale = data[JOINT_LENGTH] / data[BENDING_STIFFNESS]
            column = np.empty(size)
            solved = np.empty(size)
            for j in range(6):
                for c in range(size):
                    column[c] = -scale * twist[j, c]
                lu_solve(lu, pivots, column, solved)
                for c in range(size):
                    sensitivity[c, j] = -solved[c]
            for i in range(6):
                for j in range(6):
                    total = 0.0
                    for c in range(size):
                        total += twist[i, c] * sensitivity[c, j]
                    compliance[i, j] = total
    pivots[size] = 0 if sign == 0 else 1
    if sign == 0:
        compliance[:, :] = math.nan
    return sign


@jit
def _factor_platform(jacobian, r_scale, x_scale, factors, factor_pivots):
    """Scale the platform Jacobian and factorize it into ``factors``; False if singular."""
    for i in range(PLATFORM):
        for j in range(PLATFORM):
            factors[i, j] = jacobian[i, j] / r_scale[i] * x_scale[j]
    usable = lu_factor(factors, factor_pivots)
    factor_pivots[PLATFORM] = 1 if usable else 0
    return usable


@jit
def coupled_newton(model, data, leg_tolerance, leg_x, wrenches, position, rotation, frames,
                   evaluated, inputs, platform, tolerances, max_iterations, leg_lu, leg_pivots,
                   sensitivities, compliances, factors, factor_pivots, residual_now):
    """
    Coupled Newton of the chain with reduced legs, in place; return its work and outcome.

    Returns (outcome, iterations, legs linearized anew).

    State: ``leg_x`` (3, n), ``wrenches`` (3, 6), ``position``, ``rotation``, ``frames``
    (3, 4, 4: each leg's end disk at its x). ``evaluated``: the state is a solution of
    other inputs (its legs' residuals within ``leg_tolerance``, ``frames`` made there), so
    the first iterate needs no leg evaluation. Kept Jacobians: ``leg_lu`` (3, n, n),
    ``leg_pivots`` (3, n + 1; column n: usable), ``sensitivities`` (3, n, 6),
    ``compliances`` (3, 6, 6), ``factors`` (24, 24, the scaled platform Jacobian's LU) and
    ``factor_pivots`` (25; entry 24: usable). ``platform``: chain.Chain.platform;
    ``tolerances``: equilibrium (N, N m), position (m), rotation (rad). Converged: every
    leg residual within ``leg_tolerance`` and the platform residual (``residual_now`` on
    return) within the tolerances, at the returned state.
    """
    leg_rotations, attachments, home_bases, slider_axes, r_scale, x_scale = platform
    size = leg_x.shape[1]
    rs = np.empty(size)
    correction = np.empty(size)
    frame_set = np.empty((4, 4, 4))
    jacobian = np.empty((PLATFORM, PLATFORM))
    rhs = np.empty(PLATFORM)
    step = np.empty(PLATFORM)
    new_position = np.empty(3)
    new_rotation = np.empty((3, 3))
    new_wrenches = np.empty((3, 6))
    previous = math.inf
    fresh = False
    refreshes = 0
    for iteration in range(max_iterations + 1):
        worst = 0.0
        leg_norm = 0.0
        if iteration > 0 or not evaluated:
            for k in range(3):
                data[:6] = wrenches[k]
                residual(model, leg_x[k], data, rs)
                largest = 0.0
                for i in range(size):
                    largest = max(largest, abs(rs[i]))
                    leg_norm += rs[i] * rs[i]
                if not math.isfinite(leg_norm):
                    return NOT_FINITE, iteration, refreshes
                worst = max(worst, largest)
                if largest > leg_tolerance:
                    if leg_pivots[k, size] == 0:
                        if refresh_leg(model, leg_x[k], data, wrenches[k], leg_lu[k],
                                       leg_pivots[k], sensitivities[k], compliances[k]) == 0:
                            return SINGULAR, iteration, refreshes
                        refreshes += 1
                        factor_pivots[PLATFORM] = 0
                    lu_solve(leg_lu[k], leg_pivots[k], rs, correction)
                    for i in range(size):
                        leg_x[k, i] -= correction[i]
                leg_frames(model, leg_x[k], data, frame_set)
                frames[k] = frame_set[3]
        if not platform_residual(position, rotation, wrenches, frames, inputs, leg_rotations,
                                 attachments, home_bases, slider_axes, residual_now):
            return NOT_FINITE, iteration, refreshes
        if worst <= leg_tolerance and within(residual_now, tolerances[0], tolerances[1],
                                             tolerances[2]):
            return SOLVED, iteration, refreshes
        if iteration == max_iterations:
            break
        norm = math.sqrt(scaled_norm(residual_now, r_scale) ** 2 + leg_norm)
        if not math.isfinite(norm):
            return NOT_FINITE, iteration, refreshes
        if norm > CHORD_RATE * previous:
            if fresh and norm >= previous:
                return NO_CONTRACTION, iteration, refreshes
            if not fresh:  # the kept Jacobians are too far off: make them here
                for k in range(3):
                    if refresh_leg(model, leg_x[k], data, wrenches[k], leg_lu[k],
                                   leg_pivots[k], sensitivities[k], compliances[k]) == 0:
                        return SINGULAR, iteration, refreshes
                    refreshes += 1
                factor_pivots[PLATFORM] = 0
        fresh = factor_pivots[PLATFORM] == 0
        if fresh:
            for k in range(3):  # legs not linearized yet (a solved state's start)
                if leg_pivots[k, size] == 0:
                    if refresh_leg(model, leg_x[k], data, wrenches[k], leg_lu[k],
                                   leg_pivots[k], sensitivities[k], compliances[k]) == 0:
                        return SINGULAR, iteration, refreshes
                    refreshes += 1
            platform_jacobian(rotation, wrenches, residual_now, inputs, leg_rotations,
                              attachments, compliances, jacobian)
            if not _factor_platform(jacobian, r_scale, x_scale, factors, factor_pivots):
                return SINGULAR, iteration, refreshes
        for i in range(PLATFORM):
            rhs[i] = residual_now[i] / r_scale[i]
        lu_solve(factors, factor_pivots, rhs, step)
        move_platform(position, rotation, wrenches, step, -1.0, x_scale, new_position,
                      new_rotation, new_wrenches)
        for k in range(3):
            for i in range(size):
                total = 0.0
                for j in range(6):
                    total += sensitivities[k, i, j] * (new_wrenches[k, j] - wrenches[k, j])
                leg_x[k, i] += total
        position[:] = new_position
        rotation[:, :] = new_rotation
        wrenches[:, :] = new_wrenches
        previous = norm
    return NOT_SOLVED, max_iterations, refreshes


@jit
def follow(model, data, leg_tolerance, leg_x, wrenches, position, rotation, frames, inputs,
           platform, tolerances, max_iterations, leg_lu, leg_pivots, sensitivities,
           compliances, factors, factor_pivots, residual_now, points, seen, count,
           input_scale, predict):
    """
    Warm solve along a path: ``coupled_newton`` from the path's predictor, else its last point.

    ``predict``: try the predictor. Not when the kept Jacobians were made at the last
    point: from there Newton's first step is the first-order predictor with an exact
    Jacobian, and the chord steps that follow contract faster than from the polynomial's
    start (along the atlas's grid lines 5 iterations a sample against 7).

    The state arrays are overwritten, from the latest point of ``points`` (chain_path.py;
    ``seen`` their inputs, ``count`` (1) how many) or its polynomial predictor at
    ``inputs`` (chain_path.extrapolate); a predicted start that does not converge is
    solved again from the latest point. A solution joins the points. Returns
    (outcome, iterations, legs linearized anew), the iterations and legs of both tries.
    """
    restore(points, count, position, rotation, wrenches, leg_x, frames)
    predicted = predict and extrapolate(points, seen, count, inputs, input_scale, position,
                                        rotation, wrenches, leg_x)
    code, iterations, refreshes = coupled_newton(
        model, data, leg_tolerance, leg_x, wrenches, position, rotation, frames,
        not predicted, inputs, platform, tolerances, max_iterations, leg_lu, leg_pivots,
        sensitivities, compliances, factors, factor_pivots, residual_now)
    if code != SOLVED and predicted:
        restore(points, count, position, rotation, wrenches, leg_x, frames)
        leg_pivots[:, -1] = 0
        factor_pivots[PLATFORM] = 0
        code, more, made = coupled_newton(
            model, data, leg_tolerance, leg_x, wrenches, position, rotation, frames, True,
            inputs, platform, tolerances, max_iterations, leg_lu, leg_pivots, sensitivities,
            compliances, factors, factor_pivots, residual_now)
        iterations += more
        refreshes += made
    if code == SOLVED:
        push(points, seen, count, position, rotation, wrenches, leg_x, frames, inputs)
    return code, iterations, refreshes


@jit
def linearize_solution(model, data, leg_x, wrenches, rotation, inputs, platform, residual_now,
                       leg_lu, leg_pivots, sensitivities, compliances, factors, factor_pivots,
                       signs, jacobian):
    """
    Make the legs' Jacobians and the platform Jacobian exact at a solution; False: singular.

    ``signs`` (3): each leg's sign of det H (0: singular); ``jacobian`` (24, 24, SI) and
    its scaled factorization (``factors``), which later chord steps start from.
    """
    leg_rotations, attachments, home_bases, slider_axes, r_scale, x_scale = platform
    usable = True
    for k in range(3):
        signs[k] = refresh_leg(model, leg_x[k], data, wrenches[k], leg_lu[k], leg_pivots[k],
                               sensitivities[k], compliances[k])
        usable = usable and signs[k] != 0
    platform_jacobian(rotation, wrenches, residual_now, inputs, leg_rotations, attachments,
                      compliances, jacobian)
    return _factor_platform(jacobian, r_scale, x_scale, factors, factor_pivots) and usable


@jit
def platform_linearization(factors, factor_pivots, r_scale, x_scale, slider_columns,
                           compliance, slider_jacobian):
    """
    Platform compliance (6, 6) and d position / d sliders (3, 3) from the factorized Jacobian.

    -J^-1 applied to the residual's derivative in the payload wrench (the equilibrium rows,
    unit) and in the sliders (``slider_columns`` (24, 3), Chain.input_sensitivity's).
    """
    rhs = np.empty(PLATFORM)
    solved = np.empty(PLATFORM)
    for column in range(9):
        for i in range(PLATFORM):
            if column < 6:
                rhs[i] = (1.0 if i == 18 + column else 0.0) / r_scale[i]
            else:
                rhs[i] = slider_columns[i, column - 6] / r_scale[i]
        lu_solve(factors, factor_pivots, rhs, solved)
        for i in range(6):
            value = -solved[i] * x_scale[i]
            if column < 6:
                compliance[i, column] = value
            elif i < 3:
                slider_jacobian[i, column - 6] = value


@jit
def solve_samples(model, data, leg_tolerance, rows, start, leg_x, wrenches, position, rotation,
                  frames, platform, tolerances, max_iterations, leg_lu, leg_pivots,
                  sensitivities, compliances, factors, factor_pivots, points, seen, count,
                  input_scale, slider_columns, out_x, out_wrenches, out_position,
                  out_rotation, out_rotation_vector, out_bending, out_signs,
                  out_leg_compliances, out_compliance, out_sliders, out_iterations):
    """
    Solve rows ``start:`` of ``rows`` (N, 12 inputs) along the path of solved ``points``.

    Each row is solved by ``follow`` (from the path's predictor or its last point; its
    solution joins the path) and linearized there (``linearize_solution``,
    ``platform_linearization``); its outputs go into row i of the ``out_`` arrays: leg
    unknowns, leg wrenches, platform position and rotation, rotation vector (NaN beyond 90
    degrees: kernels.small_rotation_vector), each leg's PJ and DJ bending angle (3, 2),
    each leg's sign of det H, the leg compliances (3, 6, 6), the platform compliance (6,
    6; NaN if the Jacobian is singular), the slider Jacobian and the iterations. The state
    arrays (``leg_x`` ... ``frames``) are scratch, left at the path's last point. Stops at
    the first row that does not converge and returns its index (its outputs unset, the
    kept Jacobians to be made anew), else N.
    """
    r_scale, x_scale = platform[4], platform[5]
    residual_now = np.empty(PLATFORM)
    jacobian = np.empty((PLATFORM, PLATFORM))
    frame_set = np.empty((4, 4, 4))
    pose = np.empty(7)
    bending = np.empty(4)
    signs = np.empty(3, dtype=np.int64)
    for row in range(start, rows.shape[0]):
        inputs = rows[row]
        code, iterations, _ = follow(
            model, data, leg_tolerance, leg_x, wrenches, position, rotation, frames, inputs,
            platform, tolerances, max_iterations, leg_lu, leg_pivots, sensitivities,
            compliances, factors, factor_pivots, residual_now, points, seen, count,
            input_scale, False)
        if code != SOLVED:
            restore(points, count, position, rotation, wrenches, leg_x, frames)
            leg_pivots[:, -1] = 0
            factor_pivots[PLATFORM] = 0
            return row
        out_iterations[row] = iterations
        out_x[row] = leg_x
        out_wrenches[row] = wrenches
        out_position[row] = position
        out_rotation[row] = rotation
        if not small_rotation_vector(rotation, out_rotation_vector[row]):
            out_rotation_vector[row] = math.nan
        for k in range(3):
            data[:6] = wrenches[k]
            leg_frames(model, leg_x[k], data, frame_set)
            frames_pose(frame_set, pose, bending)
            out_bending[row, k, 0] = bending[0]
            out_bending[row, k, 1] = bending[2]
        if linearize_solution(model, data, leg_x, wrenches, rotation, inputs, platform,
                              residual_now, leg_lu, leg_pivots, sensitivities, compliances,
                              factors, factor_pivots, signs, jacobian):
            platform_linearization(factors, factor_pivots, r_scale, x_scale, slider_columns,
                                   out_compliance[row], out_sliders[row])
        else:
            out_compliance[row] = math.nan
            out_sliders[row] = math.nan
        out_signs[row] = signs
        out_leg_compliances[row] = compliances
    return rows.shape[0]
