"""
Compiled forward statics of the CDR with reduced legs ('cc', 'rod'): the chain's Newton.

The unknowns and residual are robot/delta.py's platform 24 (pose, three leg wrenches;
compatibility and equilibrium, kernels.platform_residual). Every iterate solves each leg's
reduced model under its wrench (fidelity.level_kernels.solve_row, warm from the leg's last
solution, its factorization carried) and differentiates it implicitly for the leg's 6x6
compliance (``leg_compliance``), which enters the platform Jacobian as the full legs'
compliances do (robot/linearization.platform_jacobian). A whole solve of 3 x 7-8 leg
unknowns and 24 platform unknowns runs in one compiled call: the Python around a Newton
iterate would cost more than the iterate.
"""

import math

import numpy as np

from .kernels import platform_residual, within
from .._jit import jit
from ..fidelity.cc import BENDING_STIFFNESS, cc_frames, JOINT_LENGTH
from ..fidelity.equivalent_rod import rod_frames
from ..fidelity.level_kernels import solve_row
from ..fidelity.newton import CC, CONVERGED, lu_factor, lu_solve, residual, system

#: Outcomes of ``chain_newton``.
SOLVED = 0
NOT_SOLVED = 1  # no convergence in the iterations allowed
LEG_FAILED = 2  # a leg's reduced model did not converge under its wrench
NO_DESCENT = 3  # the line search found no decrease of the scaled residual

#: Central-difference steps of the 'rod' leg's wrench and pose derivatives: relative to the
#: bending force EI / L^2 and moment EI / L, and nondimensional unknowns.
WRENCH_STEP = 1e-5
UNKNOWN_STEP = 1e-6

#: Step halvings of the chain's line search.
HALVINGS = 10

#: A chord step (reused platform Jacobian) must cut the scaled residual norm at least this
#: much, else the Jacobian is rebuilt (the legs' compliances made anew).
CHORD_RATE = 0.25


@jit
def leg_frames(model, x, data, frames):
    """Frames {pe}, {pm}, {dm}, {de} (4, 4, 4) of reduced model ``model`` at x."""
    if model == CC:
        cc_frames(x, data, frames)
    else:
        rod_frames(x, data, frames)


@jit
def _twist(before, after, out):
    """First-order twist [dp; vee(dR R^T)] from frame ``before`` to ``after`` (4x4)."""
    for i in range(3):
        out[i] = after[i, 3] - before[i, 3]
    turned = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for a in range(3):
                turned[i, j] += (after[i, a] - before[i, a]) * before[j, a]
    out[3] = 0.5 * (turned[2, 1] - turned[1, 2])
    out[4] = 0.5 * (turned[0, 2] - turned[2, 0])
    out[5] = 0.5 * (turned[1, 0] - turned[0, 1])


@jit
def determinant_sign(lu, pivots):
    """Sign of the determinant of a matrix factorized by newton.lu_factor (nonsingular)."""
    sign = 1
    for k in range(lu.shape[0]):
        if pivots[k] != k:
            sign = -sign
        if lu[k, k] < 0.0:
            sign = -sign
    return sign


@jit
def leg_compliance(model, x, data, wrench, frame, compliance, lu, pivots, sensitivity):
    """
    End-disk frame (4x4, {pe}) and 6x6 compliance of a reduced leg solved at x; sign of det.

    Implicit differentiation of the leg's residual r(x, w) = 0: dx/dw = -H^-1 dr/dw with
    H = dr/dx exact (fidelity.newton.system), and the compliance d twist / d w =
    T dx/dw + d twist/dw at fixed x (T = d twist / dx; twist [dp; vee(dR R^T)] in {pe},
    compliance.py's convention). 'cc': its residual (grad U - Q) L / EI is affine in the
    wrench, Q = T^T w (cc_derivatives), so dr/dw = -(L / EI) T^T is exact from residual
    differences at unit wrenches, T follows from it, and the frames do not depend on the
    wrench. 'rod' (a shooting residual, nonlinear in the wrench): dr/dw, T and the
    frames' wrench derivative by central differences of its compiled shots. Returns the
    sign of det H (0: singular); ``lu``/``pivots`` hold H's factorization and
    ``sensitivity`` (n, 6) dx/dw.
    """
    size = x.shape[0]
    rs = np.empty(size)
    data[:6] = wrench
    system(model, x, data, rs, lu, True)
    frame_set = np.empty((4, 4, 4))
    leg_frames(model, x, data, frame_set)
    frame[:, :] = frame_set[3]
    if not lu_factor(lu, pivots):
        return 0
    sign = determinant_sign(lu, pivots)
    gradient = np.empty((size, 6))  # dr/dw
    twist = np.empty((6, size))  # d twist / dx
    direct = np.zeros((6, 6))  # d twist / dw at fixed x
    ei = data[BENDING_STIFFNESS]
    length = data[JOINT_LENGTH]
    plus = np.empty(size)
    minus = np.empty(size)
    if model == CC:
        data[:6] = 0.0
        residual(model, x, data, minus)
        for j in range(6):
            data[:6] = 0.0
            data[j] = 1.0
            residual(model, x, data, plus)
            for i in range(size):
                gradient[i, j] = plus[i] - minus[i]
        for i in range(size):
            for j in range(6):
                twist[j, i] = -gradient[i, j] * ei / length
    else:
        frame_plus = np.empty((4, 4, 4))
        frame_minus = np.empty((4, 4, 4))
        column = np.empty(6)
        for j in range(6):
            step = WRENCH_STEP * ei / (length * length if j < 3 else length)
            data[:6] = wrench
            data[j] += step
            residual(model, x, data, plus)
            rod_frames(x, data, frame_plus)
            data[j] -= 2.0 * step
            residual(model, x, data, minus)
            rod_frames(x, data, frame_minus)
            for i in range(size):
                gradient[i, j] = (plus[i] - minus[i]) / (2.0 * step)
            _twist(frame_minus[3], frame_plus[3], column)
            for i in range(6):
                direct[i, j] = column[i] / (2.0 * step)
        data[:6] = wrench
        moved = x.copy()
        for c in range(size):
            moved[c] = x[c] + UNKNOWN_STEP
            rod_frames(moved, data, frame_plus)
            moved[c] = x[c] - UNKNOWN_STEP
            rod_frames(moved, data, frame_minus)
            moved[c] = x[c]
            _twist(frame_minus[3], frame_plus[3], column)
            for i in range(6):
                twist[i, c] = column[i] / (2.0 * UNKNOWN_STEP)
    data[:6] = wrench
    solved = np.empty(size)
    for j in range(6):
        lu_solve(lu, pivots, gradient[:, j], solved)
        for c in range(size):
            sensitivity[c, j] = -solved[c]
        for i in range(6):
            total = direct[i, j]
            for c in range(size):
                total -= twist[i, c] * solved[c]
            compliance[i, j] = total
    return sign


@jit
def _skew(vector, out):
    out[0, 0] = 0.0
    out[0, 1] = -vector[2]
    out[0, 2] = vector[1]
    out[1, 0] = vector[2]
    out[1, 1] = 0.0
    out[1, 2] = -vector[0]
    out[2, 0] = -vector[1]
    out[2, 1] = vector[0]
    out[2, 2] = 0.0


@jit
def _inverse_left_jacobian(vector, out):
    """linearization.inverse_left_jacobian, compiled: I - [v]/2 + c [v]^2."""
    angle = math.sqrt(vector[0] ** 2 + vector[1] ** 2 + vector[2] ** 2)
    cross = np.empty((3, 3))
    _skew(vector, cross)
    if angle < 1e-6:
        coefficient = 1.0 / 12.0
    else:
        coefficient = (1.0 / angle ** 2
                       - (1.0 + math.cos(angle)) / (2.0 * angle * math.sin(angle)))
    for i in range(3):
        for j in range(3):
            square = cross[i, 0] * cross[0, j] + cross[i, 1] * cross[1, j] \
                + cross[i, 2] * cross[2, j]
            out[i, j] = (1.0 if i == j else 0.0) - 0.5 * cross[i, j] + coefficient * square


@jit
def _block(left, right, transpose_left, transpose_right, factor, out, row, column, add):
    """Set (``add``: add to) out[row:row+3, column:column+3] factor op(left) op(right)."""
    for i in range(3):
        for j in range(3):
            total = 0.0
            for a in range(3):
                total += (left[a, i] if transpose_left else left[i, a]) \
                    * (right[j, a] if transpose_right else right[a, j])
            if add:
                out[row + i, column + j] += factor * total
            else:
                out[row + i, column + j] = factor * total


@jit
def _turn(rotation, vector, factor, out):
    """Set ``out`` (3) to factor R v."""
    for i in range(3):
        out[i] = factor * (rotation[i, 0] * vector[0] + rotation[i, 1] * vector[1]
                           + rotation[i, 2] * vector[2])


@jit
def platform_jacobian(rotation, wrenches, residual_now, inputs, leg_rotations, attachments,
                      compliances, jacobian):
    """robot/linearization.platform_jacobian, compiled: d residual / d platform unknowns."""
    jacobian[:, :] = 0.0
    vector = np.empty(3)
    cross_force = np.empty((3, 3))
    cross_arm = np.empty((3, 3))
    cross_leg = np.empty((3, 3))
    inverse = np.empty((3, 3))
    _skew(inputs[3:6], cross_force)
    _turn(rotation, inputs[9:12], 1.0, vector)
    _skew(vector, cross_arm)
    _block(cross_force, cross_arm, False, False, 1.0, jacobian, 21, 3, False)
    for k in range(3):
        leg = leg_rotations[k]
        _turn(rotation, attachments[k], 1.0, vector)
        _skew(vector, cross_arm)
        _turn(leg, wrenches[k, :3], -1.0, vector)
        _skew(vector, cross_leg)
        _inverse_left_jacobian(residual_now[6 * k + 3:6 * k + 6], inverse)
        columns = 6 + 6 * k
        for i in range(3):
            for j in range(6):
                jacobian[6 * k + i, columns + j] = compliances[k, i, j]
                jacobian[6 * k + 3 + i, columns + j] = inverse[i, 0] * compliances[k, 3, j] \
                    + inverse[i, 1] * compliances[k, 4, j] + inverse[i, 2] * compliances[k, 5, j]
            for j in range(3):
                jacobian[6 * k + i, j] = -leg[j, i]
                jacobian[18 + i, columns + j] = -leg[i, j]
                jacobian[21 + i, columns + 3 + j] = -leg[i, j]
        _block(leg, cross_arm, True, False, 1.0, jacobian, 6 * k, 3, False)
        _block(inverse, leg, True, True, -1.0, jacobian, 6 * k + 3, 3, False)
        _block(cross_arm, leg, False, False, -1.0, jacobian, 21, columns, False)
        _block(cross_leg, cross_arm, False, False, 1.0, jacobian, 21, 3, True)


@jit
def _evaluate(model, data, leg_tolerance, leg_iterations, leg_x, leg_origin, leg_lu,
              leg_pivots, wrenches, trial_x, frames):
    """Solve each leg under its wrench warm from ``leg_x``; False if one fails."""
    frame_set = np.empty((4, 4, 4))
    for k in range(3):
        answer, _, _, status = solve_row(model, leg_x[k], data, leg_origin[k], wrenches[k],
                                         leg_tolerance, leg_iterations, leg_lu[k],
                                         leg_pivots[k])
        if status != CONVERGED:
            return False
        trial_x[k] = answer
        data[:6] = wrenches[k]
        leg_frames(model, answer, data, frame_set)
        frames[k] = frame_set[3]
    return True


@jit
def move_platform(position, rotation, wrenches, step, scale, x_scale, out_position,
                  out_rotation, out_wrenches):
    """Apply scale * step (scaled platform unknowns); the platform turns by exp([dphi])."""
    for i in range(3):
        out_position[i] = position[i] + scale * step[i] * x_scale[i]
    phi = np.empty(3)
    for i in range(3):
        phi[i] = scale * step[3 + i] * x_scale[3 + i]
    angle = math.sqrt(phi[0] ** 2 + phi[1] ** 2 + phi[2] ** 2)
    cross = np.empty((3, 3))
    _skew(phi, cross)
    if angle < 1e-8:
        first, second = 1.0, 0.5
    else:
        first, second = math.sin(angle) / angle, (1.0 - math.cos(angle)) / angle ** 2
    turn = np.empty((3, 3))  # exp([phi]), Rodrigues
    for i in range(3):
        for j in range(3):
            square = cross[i, 0] * cross[0, j] + cross[i, 1] * cross[1, j] \
                + cross[i, 2] * cross[2, j]
            turn[i, j] = (1.0 if i == j else 0.0) + first * cross[i, j] + second * square
    _block(turn, rotation, False, False, 1.0, out_rotation, 0, 0, False)
    for k in range(3):
        for i in range(6):
            index = 6 + 6 * k + i
            out_wrenches[k, i] = wrenches[k, i] + scale * step[index] * x_scale[index]


@jit
def scaled_norm(values, scale):
    """Euclidean norm of values / scale."""
    total = 0.0
    for i in range(values.shape[0]):
        total += (values[i] / scale[i]) ** 2
    return math.sqrt(total)


@jit
def _linearize(model, data, leg_x, wrenches, rotation, residual_now, inputs, leg_rotations,
               attachments, compliances, signs, jacobian):
    """Each leg's compliance and sign of det H at ``leg_x``, and the platform Jacobian."""
    size = leg_x.shape[1]
    compliance = np.empty((6, 6))
    frame = np.empty((4, 4))
    h_lu = np.empty((size, size))
    h_pivots = np.zeros(size, dtype=np.int64)
    sensitivity = np.empty((size, 6))
    for k in range(3):
        signs[k] = leg_compliance(model, leg_x[k], data, wrenches[k], frame, compliance, h_lu,
                                  h_pivots, sensitivity)
        compliances[k] = compliance
    platform_jacobian(rotation, wrenches, residual_now, inputs, leg_rotations, attachments,
                      compliances, jacobian)


@jit
def chain_newton(model, data, leg_tolerance, leg_iterations, leg_x, leg_origin, leg_lu,
                 leg_pivots, position, rotation, wrenches, inputs, platform, tolerances,
                 max_iterations, factors, factor_pivots, linearized, frames, compliances,
                 signs, residual_now, jacobian):
    """
    Damped Newton of the chain with reduced legs, in place; return (outcome, iterations).

    ``leg_x`` (3, n) / ``leg_origin`` (3, 6): each leg's last solution and its wrench,
    ``leg_lu`` (3, n, n) / ``leg_pivots`` (3, n + 1) its factorization (fidelity.newton);
    all are updated to the accepted iterate. ``platform``: chain.Chain.platform;
    ``tolerances``: equilibrium (N, N m), position (m), rotation (rad). ``factors`` (24,
    24) / ``factor_pivots`` (25): the scaled platform Jacobian's LU, kept across calls
    (``factor_pivots[24]`` says whether it is usable): chord steps on it while they
    contract by CHORD_RATE, else it is rebuilt from the legs' compliances. On return
    ``frames`` (3, 4, 4) hold the end disks and ``residual_now`` (24) the residual at the
    final iterate; with ``linearized`` also ``compliances`` (3, 6, 6), ``signs`` (3, each
    leg's sign of det H) and ``jacobian`` (24, 24, SI) there.
    """
    leg_rotations, attachments, home_bases, slider_axes, r_scale, x_scale = platform
    trial_x = np.empty_like(leg_x)
    trial_frames = np.empty_like(frames)
    trial_position = np.empty(3)
    trial_rotation = np.empty((3, 3))
    trial_wrenches = np.empty_like(wrenches)
    trial_residual = np.empty(24)
    step = np.empty(24)
    rhs = np.empty(24)
    if not _evaluate(model, data, leg_tolerance, leg_iterations, leg_x, leg_origin, leg_lu,
                     leg_pivots, wrenches, trial_x, frames):
        return LEG_FAILED, 0
    leg_x[:, :] = trial_x
    leg_origin[:, :] = wrenches
    if not platform_residual(position, rotation, wrenches, frames, inputs, leg_rotations,
                             attachments, home_bases, slider_axes, residual_now):
        return NO_DESCENT, 0
    norm = scaled_norm(residual_now, r_scale)
    fresh = False
    iteration = 0
    while iteration <= max_iterations:
        if within(residual_now, tolerances[0], tolerances[1], tolerances[2]):
            if linearized:
                _linearize(model, data, leg_x, wrenches, rotation, residual_now, inputs,
                           leg_rotations, attachments, compliances, signs, jacobian)
            return SOLVED, iteration
        if iteration == max_iterations:
            break
        if factor_pivots[24] == 0:
            _linearize(model, data, leg_x, wrenches, rotation, residual_now, inputs,
                       leg_rotations, attachments, compliances, signs, jacobian)
            for i in range(24):
                for j in range(24):
                    factors[i, j] = jacobian[i, j] / r_scale[i] * x_scale[j]
            if not lu_factor(factors, factor_pivots):
                return NO_DESCENT, iteration
            factor_pivots[24] = 1
            fresh = True
        for i in range(24):
            rhs[i] = residual_now[i] / r_scale[i]
        lu_solve(factors, factor_pivots, rhs, step)
        scale = 1.0
        accepted = False
        trial_norm = norm
        for _ in range(HALVINGS):
            move_platform(position, rotation, wrenches, step, -scale, x_scale, trial_position,
                          trial_rotation, trial_wrenches)
            if _evaluate(model, data, leg_tolerance, leg_iterations, leg_x, leg_origin,
                         leg_lu, leg_pivots, trial_wrenches, trial_x, trial_frames) \
                    and platform_residual(trial_position, trial_rotation, trial_wrenches,
                                          trial_frames, inputs, leg_rotations, attachments,
                                          home_bases, slider_axes, trial_residual):
                trial_norm = scaled_norm(trial_residual, r_scale)
                if trial_norm < (1.0 - 1e-4 * scale) * norm:
                    accepted = True
                    break
            if not fresh:
                break  # a stale Jacobian: rebuild rather than damp
            scale *= 0.5
        iteration += 1
        if not accepted:
            if fresh:
                return NO_DESCENT, iteration
            factor_pivots[24] = 0
            continue
        if not fresh and trial_norm > CHORD_RATE * norm:
            factor_pivots[24] = 0  # chord steps converge too slowly
        fresh = False
        position[:] = trial_position
        rotation[:, :] = trial_rotation
        wrenches[:, :] = trial_wrenches
        leg_x[:, :] = trial_x
        leg_origin[:, :] = trial_wrenches
        frames[:, :, :] = trial_frames
        residual_now[:] = trial_residual
        norm = trial_norm
    return NOT_SOLVED, max_iterations
