"""
Compiled pieces of the CDR's coupled Newton iterate (robot/coupled_newton.py).

An iterate of a warm CDR solve is three leg shots (~35 us each) and a little algebra on
24 platform and 3 x n leg unknowns; written with numpy, the algebra's call overhead cost
twice the shots (the platform residual 75 us, the reduced Newton step 80 us, the three
shots' wrappers 40 us on top). Here each is one compiled call, and ``coupled_iterations``
runs the whole loop of chord iterations on one factorization (line searches, Broyden
updates, the chord-rate test) in one call: the Python loop around the pieces cost about
0.1 ms per iteration, half a warm solve.
"""

import math

import numpy as np

from .._jit import jit
from .._linalg import lu_solve, norm
from ..bvp.chord import apply_updates
from ..bvp.layout import N_RODS
from ..bvp.shooting import translator_residual


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
def leg_frames(unknowns, wrenches, x_scale, model_args, frames):
    """
    Each leg's frames {pe}, {pm}, {dm}, {de} (3, 4, 4, 4) from one shot at its unknowns.

    The same shot as ``shoot_legs`` (and as a leg's SolveResult made there), for the joints'
    bending angles without building the legs' results.
    """
    pitch_radius, spacing, tube_length, spacers, steps, inv_kse, inv_kbt = model_args
    size = unknowns.shape[1]
    scaled = np.empty(size)
    out = np.empty(size)
    no_points = np.empty((N_RODS, 0, 3))
    for k in range(unknowns.shape[0]):
        for i in range(size):
            scaled[i] = unknowns[k, i] * x_scale[i]
        translator_residual(scaled, wrenches[k], pitch_radius, spacing, tube_length, spacers,
                            steps, inv_kse, inv_kbt, out, no_points, frames[k])


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
    Write the coupled Newton step (robot/coupled_newton.py's ``correction``) into ``out``.

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


#: Statuses of ``coupled_iterations``: where its loop of chord iterations stopped.
#: CONVERGED_AT_TOP: the state reached was within the tolerances (the caller's next loop top
#: says so); OUT_OF_BUDGET: every iteration allowed was done; REBUILD: the factorization is
#: to be rebuilt (chord steps too slow or too many, or a stale one found no step);
#: NO_STEP: a fresh factorization found no contracting step; FAR: a trial's rotation error
#: reached 90 degrees (the caller redoes that iteration: its residual needs the general
#: rotation vector).
CONVERGED_AT_TOP = 0
OUT_OF_BUDGET = 1
REBUILD = 2
NO_STEP = 3
FAR = 4

#: Step halvings of a line search (robot/coupled_newton.py's line search).
HALVINGS = 10


@jit
def turn_and_move(position, rotation, wrenches, unknowns, step, scale, x_scale, out_position,
                  out_rotation, out_wrenches, out_unknowns):
    """
    Write the state moved by ``scale`` times the flat scaled ``step`` (chain.ChainState.moved).

    Platform position + dp, rotation exp([dphi]) R (Rodrigues' formula; the series below
    an angle of 1e-6 rad, error below angle^3 / 6), leg wrenches + dw, leg unknowns + their
    steps; dp, dphi and dw are the step's first 24 entries times ``x_scale``.
    """
    x = scale * step[3] * x_scale[3]
    y = scale * step[4] * x_scale[4]
    z = scale * step[5] * x_scale[5]
    square = x * x + y * y + z * z
    if square < 1e-12:
        first, second = 1.0, 0.5
    else:
        angle = math.sqrt(square)
        first, second = math.sin(angle) / angle, (1.0 - math.cos(angle)) / square
    turn = np.empty((3, 3))
    turn[0, 0] = 1.0 + second * (x * x - square)
    turn[0, 1] = second * x * y - first * z
    turn[0, 2] = second * x * z + first * y
    turn[1, 0] = second * x * y + first * z
    turn[1, 1] = 1.0 + second * (y * y - square)
    turn[1, 2] = second * y * z - first * x
    turn[2, 0] = second * x * z - first * y
    turn[2, 1] = second * y * z + first * x
    turn[2, 2] = 1.0 + second * (z * z - square)
    for i in range(3):
        out_position[i] = position[i] + scale * step[i] * x_scale[i]
        for j in range(3):
            out_rotation[i, j] = (turn[i, 0] * rotation[0, j] + turn[i, 1] * rotation[1, j]
                                  + turn[i, 2] * rotation[2, j])
    for k in range(3):
        for j in range(6):
            out_wrenches[k, j] = wrenches[k, j] + scale * step[6 + 6 * k + j] * x_scale[
                6 + 6 * k + j]
    legs, size = unknowns.shape
    for k in range(legs):
        for i in range(size):
            out_unknowns[k, i] = unknowns[k, i] + scale * step[24 + k * size + i]


@jit
def secant_update(updates, steps, count, taken, change, correction):
    """
    Add the good-Broyden update of step ``taken`` whose residual change y has H y = ``change``.

    (robot/linearization.py's Secants.) ``correction`` (H r for some r) becomes H+ r in place; the
    new count is returned. Once ``updates`` is full, or for a degenerate step, nothing is
    added and ``correction`` stays as it is.
    """
    denominator = 0.0
    for i in range(taken.shape[0]):
        denominator += taken[i] * change[i]
    if count >= updates.shape[0] or denominator == 0.0 or not math.isfinite(denominator):
        return count
    dot = 0.0
    for i in range(taken.shape[0]):
        updates[count, i] = (taken[i] - change[i]) / denominator
        steps[count, i] = taken[i]
        dot += taken[i] * correction[i]
    for i in range(taken.shape[0]):
        correction[i] += updates[count, i] * dot
    return count + 1


@jit
def chord_verdict(fresh, contraction, step_size, chord_steps, chord_log, slow_chord,
                  chord_rate, chord_floor, chord_limit):
    """
    Count a chord step that contracted by ``contraction``; say whether to rebuild.

    A step on a ``fresh`` factorization starts the count over (and never rebuilds).

    Chord steps contract erratically (the iteration matrix is far from normal: 0.15, 0.01,
    0.35 in a row is typical along the slider circle): their geometric mean is judged, and
    a single step only when it barely contracts on its own; not so close to the solution
    that the contractions are the shots' rounding (``chord_floor``), and not more than
    ``chord_limit`` steps. Returns (chord steps, sum of log contractions, rebuild).
    """
    if fresh:
        return 0, 0.0, False
    chord_steps += 1
    chord_log += math.log(max(contraction, 1e-300))
    slow = contraction > slow_chord or chord_log > chord_steps * math.log(chord_rate)
    rebuild = (slow and contraction * step_size > chord_floor) or chord_steps >= chord_limit
    return chord_steps, chord_log, rebuild


@jit
def _copy_state(source, target):
    """Copy the arrays of a state tuple (see ``coupled_iterations``) into another's."""
    target[0][:] = source[0]
    target[1][:, :] = source[1]
    target[2][:, :] = source[2]
    target[3][:, :] = source[3]
    target[4][:, :, :] = source[4]
    target[5][:, :] = source[5]
    target[6][:] = source[6]


@jit
def coupled_iterations(state, trial, step, has_step, inputs, leg, platform, factorization,
                       updates, steps, count, tolerances, controls, fresh, chord_steps,
                       chord_log, leg_error):
    """
    Run the coupled Newton's chord iterations on one factorization (CoupledNewton.correct).

    ``state`` and ``trial`` are state tuples (position (3), rotation (3, 3), wrenches
    (3, 6), leg unknowns (3, n), leg end-disk frames (3, 4, 4), leg residuals (3, n),
    residual (24)): ``state`` holds the evaluated state on entry and the one reached on
    return, ``trial`` is scratch. ``step`` (flat, scaled) is the next correction when
    ``has_step``. ``leg`` = (x_scale, residual_scale, model_args) of a leg's Problem;
    ``platform`` = (leg rotations, attachments, home bases, slider axes, r_scale, x_scale);
    ``factorization`` = (leg LU factors, pivots, twists, gains, platform inverse);
    ``updates``, ``steps``, ``count`` the Broyden updates on it (kernels.coupled_step);
    ``tolerances`` = (equilibrium, position, rotation, leg); ``controls`` = (SLOW_CHORD,
    CHORD_RATE, CHORD_FLOOR, CHORD_LIMIT, iterations allowed).

    Each iteration: stop if the state is converged; else the correction (if none is
    pending), a line search that halves it until the trial shrinks the simplified
    correction (Deuflhard's restricted monotonicity test), a good-Broyden update on
    acceptance, and the chord-rate test that asks for a rebuild. The same steps, in the
    same order, as the Python loop it replaces, which still runs the rest (rebuilds, the
    nested iteration, rotation errors of 90 degrees or more). Returns (status, iterations
    done, leg shots, leg error, count, chord steps, chord log, has_step, fresh, moved):
    ``moved`` says whether ``state`` changed (an iteration accepted its trial).
    """
    leg_x_scale, leg_residual_scale, model_args = leg
    leg_rotations, attachments, home_bases, slider_axes, r_scale, x_scale = platform
    factors, pivots, twists, gains, platform_inverse = factorization
    equilibrium_tolerance, position_tolerance, rotation_tolerance, leg_tolerance = tolerances
    slow_chord, chord_rate, chord_floor, chord_limit, allowed = controls
    simplified = np.empty(step.shape[0])
    taken = np.empty(step.shape[0])
    change = np.empty(step.shape[0])
    shots = 0
    moved = False
    for done in range(allowed):
        if leg_error <= leg_tolerance and within(state[6], equilibrium_tolerance,
                                                 position_tolerance, rotation_tolerance):
            return (CONVERGED_AT_TOP, done, shots, leg_error, count, chord_steps, chord_log,
                    has_step, fresh, moved)
        if not has_step:
            coupled_step(state[6], state[5], True, r_scale, x_scale, factors, pivots, twists,
                         gains, platform_inverse, updates, steps, count, step)
        step_size = norm(step)
        scale = 1.0
        accepted = False
        contraction = 0.0
        trial_error = math.inf
        for _ in range(HALVINGS):
            turn_and_move(state[0], state[1], state[2], state[3], step, scale, x_scale,
                          trial[0], trial[1], trial[2], trial[3])
            trial_error = shoot_legs(trial[3], trial[2], leg_x_scale, leg_residual_scale,
                                     model_args, trial[5], trial[4])
            shots += 3
            if math.isfinite(trial_error):
                if not platform_residual(trial[0], trial[1], trial[2], trial[4], inputs,
                                         leg_rotations, attachments, home_bases, slider_axes,
                                         trial[6]):
                    return (FAR, done, shots, leg_error, count, chord_steps, chord_log,
                            True, fresh, moved)
                if trial_error <= leg_tolerance and within(
                        trial[6], equilibrium_tolerance, position_tolerance,
                        rotation_tolerance):
                    accepted, contraction, has_step = True, 0.0, False
                    break
                coupled_step(trial[6], trial[5], True, r_scale, x_scale, factors, pivots,
                             twists, gains, platform_inverse, updates, steps, count,
                             simplified)
                contraction = norm(simplified) / step_size
                if contraction < 1.0 - 0.25 * scale:
                    # H y = H r_trial - H r = step - simplified
                    for i in range(step.shape[0]):
                        taken[i] = scale * step[i]
                        change[i] = step[i] - simplified[i]
                    count = secant_update(updates, steps, count, taken, change, simplified)
                    accepted, has_step = True, True
                    break
            scale *= 0.5
        if not accepted:
            status = NO_STEP if fresh else REBUILD
            return (status, done + 1, shots, leg_error, count, chord_steps, chord_log, False,
                    fresh, moved)
        _copy_state(trial, state)
        moved = True
        leg_error = trial_error
        if has_step:
            step[:] = simplified
        chord_steps, chord_log, rebuild = chord_verdict(
            fresh, contraction, step_size, chord_steps, chord_log, slow_chord, chord_rate,
            chord_floor, chord_limit)
        if rebuild:
            return (REBUILD, done + 1, shots, leg_error, count, chord_steps, chord_log,
                    False, False, moved)
        fresh = False
    return (OUT_OF_BUDGET, allowed, shots, leg_error, count, chord_steps, chord_log, has_step,
            fresh, moved)
