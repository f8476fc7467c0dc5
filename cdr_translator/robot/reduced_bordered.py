"""
The chain's Newton with 'cc' legs held in the system: no leg eliminated on its own.

The nested walk (reduced_kernels.chain_newton) solves each leg under its tip wrench alone,
and the coupled Newton (reduced_coupled_kernels.coupled_newton) eliminates each leg with
the LU of its H_k = dr_k/dx_k. Both need H_k regular: a leg alone under its tip wrench,
its far end free. Under an upward payload a leg's compression passes the free-end
buckling load of the 'cc' leg (about 29.4 N for the shipped translator), where H_k is
singular: there the nested walk finds no descent and the eliminated Newton no step,
although the chain, each leg held at both ends by the platform, is regular (its held
buckling load is far higher).

Here the Newton system is the whole one, bordered: the platform's 24 unknowns (pose, leg
wrenches) and the three legs' reduced unknowns together,

    [ P   B ] [dp]     [r_p]
    [ C   H ] [dx] = - [r_x],

P the platform residual's derivative at fixed leg unknowns (reduced_kernels.platform_jacobian
with no leg compliance), B its derivative in the legs' unknowns (each leg's end-disk twist
T_k, the rotation rows through the inverse left Jacobian of SO(3)), C = dr_k/dw_k =
-(L / EI) T_k^T (the 'cc' residual is affine in the wrench) and H = diag(H_k), factorized
as one dense matrix (24 + 3 x 8 unknowns). Damped by halving until the scaled residual
norm falls. Python around compiled kernels: it serves the cold walk past that load, not
the warm solves.
"""

import math
from typing import Tuple

import numpy as np

from .kernels import platform_residual, within
from .linearization import inverse_left_jacobian
from .reduced_coupled_kernels import cc_twist
from .reduced_kernels import leg_frames, move_platform, platform_jacobian
from ..fidelity.cc import BENDING_STIFFNESS, JOINT_LENGTH
from ..fidelity.newton import CC, system

#: Step halvings of the line search.
HALVINGS = 12

#: The platform's unknowns and residual.
PLATFORM = 24

#: Outcomes of ``bordered_newton``.
SOLVED = 0
NOT_SOLVED = 1  # no convergence in the iterations allowed
NO_DESCENT = 2  # the line search found no decrease of the scaled residual
SINGULAR = 3  # the bordered Jacobian is singular (the chain itself, not a leg alone)


class BorderedState:
    """A chain state with reduced legs, the arrays a bordered iterate reads and writes."""

    def __init__(self, position: np.ndarray, rotation: np.ndarray, wrenches: np.ndarray,
                 leg_x: np.ndarray) -> None:
        """Copy the platform pose, the leg wrenches (3, 6) and the leg unknowns (3, n)."""
        self.position = np.array(position, dtype=float)
        self.rotation = np.array(rotation, dtype=float)
        self.wrenches = np.array(wrenches, dtype=float)
        self.leg_x = np.array(leg_x, dtype=float)


def bordered_system(model: int, data: np.ndarray, state: BorderedState, inputs: np.ndarray,
                    platform: tuple, jacobian: bool
                    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the scaled residual [r_p / r_scale; r_x] and, with ``jacobian``, its Jacobian.

    Also the SI platform residual (24) and the legs' end disks (3, 4, 4). A rotation error
    of 90 degrees or more, or a non-finite leg, gives a NaN residual.
    """
    leg_rotations, attachments, home_bases, slider_axes, r_scale, x_scale = platform
    legs, size = state.leg_x.shape
    total = PLATFORM + legs * size
    leg_residuals = np.empty((legs, size))
    blocks = np.empty((legs, size, size))
    twists = np.empty((legs, 6, size))
    frames = np.empty((legs, 4, 4))
    frame_set = np.empty((4, 4, 4))
    for k in range(legs):
        data[:6] = state.wrenches[k]
        system(model, state.leg_x[k], data, leg_residuals[k], blocks[k], jacobian)
        leg_frames(model, state.leg_x[k], data, frame_set)
        frames[k] = frame_set[3]
        if jacobian:
            cc_twist(state.leg_x[k], data, twists[k])
    residual = np.empty(PLATFORM)
    if not platform_residual(state.position, state.rotation, state.wrenches, frames, inputs,
                             leg_rotations, attachments, home_bases, slider_axes, residual):
        residual[:] = math.nan
    scaled = np.concatenate([residual / r_scale, leg_residuals.ravel()])
    matrix = np.zeros((total, total))
    if jacobian and np.all(np.isfinite(scaled)):
        fixed = np.empty((PLATFORM, PLATFORM))
        platform_jacobian(state.rotation, state.wrenches, residual, inputs, leg_rotations,
                          attachments, np.zeros((legs, 6, 6)), fixed)
        matrix[:PLATFORM, :PLATFORM] = fixed / r_scale[:, None] * x_scale[None, :]
        stiffness = data[BENDING_STIFFNESS] / data[JOINT_LENGTH]
        for k in range(legs):
            columns = slice(PLATFORM + k * size, PLATFORM + (k + 1) * size)
            rows = slice(6 * k, 6 * k + 6)
            turned = np.vstack([twists[k, :3], inverse_left_jacobian(
                residual[6 * k + 3:6 * k + 6]) @ twists[k, 3:]])
            matrix[rows, columns] = turned / r_scale[rows, None]
            wrench_columns = slice(6 + 6 * k, 12 + 6 * k)
            matrix[columns, wrench_columns] = (-twists[k].T / stiffness
                                               * x_scale[None, wrench_columns])
            matrix[columns, columns] = blocks[k]
    return scaled, matrix, residual, frames


def bordered_newton(model: int, data: np.ndarray, leg_tolerance: float, state: BorderedState,
                    inputs: np.ndarray, platform: tuple, tolerances: np.ndarray,
                    max_iterations: int) -> Tuple[int, int, np.ndarray, np.ndarray]:
    """
    Damped Newton on the bordered system from ``state`` (changed in place): outcome, work.

    Returns (outcome, iterations, SI platform residual (24), end disks (3, 4, 4)) at the
    state reached. Converged: every leg residual within ``leg_tolerance`` and the platform
    residual within ``tolerances`` (equilibrium N / N m, position m, rotation rad). Only
    'cc' legs (``model`` newton.CC): their wrench derivative is in closed form.
    """
    if model != CC:
        raise ValueError(f"the bordered Newton takes 'cc' legs only, got model {model}")
    x_scale = platform[5]
    legs, size = state.leg_x.shape
    scaled, matrix, residual, frames = bordered_system(model, data, state, inputs, platform, True)
    norm = float(np.linalg.norm(scaled))
    position, rotation, wrenches = np.empty(3), np.empty((3, 3)), np.empty((legs, 6))
    for iteration in range(max_iterations + 1):
        if not math.isfinite(norm):
            return NO_DESCENT, iteration, residual, frames
        if (np.abs(scaled[PLATFORM:]).max() <= leg_tolerance
                and within(residual, tolerances[0], tolerances[1], tolerances[2])):
            return SOLVED, iteration, residual, frames
        if iteration == max_iterations:
            break
        try:
            step = np.linalg.solve(matrix, -scaled)
        except np.linalg.LinAlgError:
            return SINGULAR, iteration, residual, frames
        if not np.all(np.isfinite(step)):
            return SINGULAR, iteration, residual, frames
        scale = 1.0
        for _ in range(HALVINGS):
            move_platform(state.position, state.rotation, state.wrenches, step[:PLATFORM],
                          scale, x_scale, position, rotation, wrenches)
            trial = BorderedState(position, rotation, wrenches,
                                  state.leg_x + scale * step[PLATFORM:].reshape(legs, size))
            trial_scaled, _, trial_residual, trial_frames = bordered_system(
                model, data, trial, inputs, platform, False)
            trial_norm = float(np.linalg.norm(trial_scaled))
            if trial_norm < (1.0 - 1e-4 * scale) * norm:
                break
            scale *= 0.5
        else:
            return NO_DESCENT, iteration + 1, residual, frames
        state.position, state.rotation = trial.position, trial.rotation
        state.wrenches, state.leg_x = trial.wrenches, trial.leg_x
        scaled, matrix, residual, frames = bordered_system(model, data, state, inputs,
                                                           platform, True)
        norm = float(np.linalg.norm(scaled))
    return NOT_SOLVED, max_iterations, residual, frames
