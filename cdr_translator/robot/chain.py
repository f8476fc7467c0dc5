"""
The CDR's closed chain as numbers: its unknowns, their scales, and its residual.

The unknowns are the platform pose, the three leg wrenches and the legs' own shooting
unknowns (``ChainState``); the residual is the legs' pose compatibility and the platform's
equilibrium (``Chain.residual``, robot/delta.py's module docstring). Nothing here iterates.
"""

from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import numpy as np

from .kernels import platform_residual, turn_and_move
from .params import Leg
from .result import rotation_vector
from ..params.translator_params import TranslatorParams
from ..solve.result import SolveResult

#: Size of the unknown and residual vectors: platform pose (6) + three leg wrenches (18).
SIZE = 24


def skew(vector: np.ndarray) -> np.ndarray:
    """Return the cross-product matrix [a]x of a 3-vector a: [a]x b = a x b."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@dataclass
class ChainState:
    """
    Platform pose and leg wrenches (the platform unknowns), and the legs' own unknowns.

    ``unknowns`` (3, n): each leg's nondimensional shooting unknowns (its Problem's);
    ``frames`` (3, 4, 4): each leg's end-disk frame in {pe_i} there; ``leg_error``: the
    largest nondimensional leg residual; ``legs``: the legs' (unjudged) SolveResults when
    they were solved in full at this state (nested iteration), else None.
    """

    position: np.ndarray
    rotation: np.ndarray
    wrenches: np.ndarray
    unknowns: np.ndarray
    frames: Optional[np.ndarray] = None
    leg_residuals: Optional[np.ndarray] = None
    leg_error: float = math.inf
    legs: Optional[List[SolveResult]] = None

    def moved(self, step: np.ndarray, x_scale: np.ndarray) -> 'ChainState':
        """
        Apply a flat scaled step [dp; dphi; dw_1; dw_2; dw_3 (/ x_scale); leg steps (3 x n)].

        The platform turns by exp([dphi]) (kernels.turn_and_move, as the compiled
        iterations move their trials); the result is not yet shot.
        """
        moved = ChainState(np.empty(3), np.empty((3, 3)), np.empty((3, 6)),
                           np.empty_like(self.unknowns))
        turn_and_move(self.position, self.rotation, self.wrenches, self.unknowns,
                      np.ascontiguousarray(step, dtype=float), 1.0, x_scale, moved.position,
                      moved.rotation, moved.wrenches, moved.unknowns)
        return moved


def difference(first: ChainState, second: ChainState, x_scale: np.ndarray) -> np.ndarray:
    """
    ``first`` minus ``second`` in the flat scaled unknowns (platform / x_scale, then legs).

    The rotation's part is the rotation vector of R_first R_second^T (``ChainState.moved``'s).
    """
    platform = np.concatenate([first.position - second.position,
                               rotation_vector(first.rotation @ second.rotation.T),
                               (first.wrenches - second.wrenches).ravel()]) / x_scale
    return np.concatenate([platform, (first.unknowns - second.unknowns).ravel()])


def distance(first: ChainState, second: ChainState, x_scale: np.ndarray) -> float:
    """Largest difference of two states in the scaled unknowns (platform and legs)."""
    return float(np.abs(difference(first, second, x_scale)).max())


class Chain:
    """The chain's fixed numbers: its legs, the Newton system's scales, the residual's data."""

    def __init__(self, legs: Tuple[Leg, Leg, Leg], params: TranslatorParams) -> None:
        """Scales for ``params``' legs (a balanced Newton system), the residual's arrays."""
        self.legs = legs
        # scales for a balanced Newton system: the stack height, and the force that bends
        # the five backbones of a leg noticeably over it
        height = params.stack_height
        length = height
        force = 5.0 * params.bending_stiffness / height ** 2
        self.x_scale = np.concatenate(
            [np.full(3, length), np.ones(3), np.tile(np.repeat([force, force * length], 3), 3)])
        self.r_scale = np.concatenate(
            [np.tile(np.repeat([length, 1.0], 3), 3), np.repeat([force, force * length], 3)])
        self.leg_rotations = np.stack([leg.rotation for leg in legs])
        self.attachments = np.stack([leg.attachment for leg in legs])
        self.home_bases = np.stack([leg.home_base for leg in legs])
        self.slider_axes = np.stack([leg.slider_axis for leg in legs])
        #: the compiled iterations' platform arguments (kernels.coupled_iterations)
        self.platform = (self.leg_rotations, self.attachments, self.home_bases,
                         self.slider_axes, self.r_scale, self.x_scale)
        # the input sensitivity's blocks that depend on neither state nor inputs
        self._constant_sensitivity = np.zeros((SIZE, 12))
        for k, leg in enumerate(legs):
            self._constant_sensitivity[6 * k:6 * k + 3, k] = leg.rotation.T @ leg.slider_axis
        self._constant_sensitivity[18:21, 3:6] = np.eye(3)
        self._constant_sensitivity[21:24, 6:9] = np.eye(3)

    def reactions(self, state: ChainState) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the leg forces on the platform in {w} (3, 3) and their lever arms (3, 3).

        The platform is a free body loaded at its attachment points, the lever arms
        R a_i; the compatibility residual keeps each end disk there.
        """
        forces = np.array([-leg.rotation @ wrench[:3]
                           for leg, wrench in zip(self.legs, state.wrenches)])
        arms = np.array([state.rotation @ leg.attachment for leg in self.legs])
        return forces, arms

    def residual(self, state: ChainState, inputs: np.ndarray) -> np.ndarray:
        """
        Compatibility (18: m, rad, in {pe_i}) and equilibrium (6: N, N m, in {w}).

        ArithmeticError when a leg's end-disk frame is no rotation (a diverged shot).
        """
        if state.frames is None:
            raise RuntimeError('the legs have not been evaluated at this state')
        residual = np.empty(SIZE)
        rotations = self.leg_rotations
        if not platform_residual(state.position, state.rotation, state.wrenches, state.frames,
                                 inputs, rotations, self.attachments, self.home_bases,
                                 self.slider_axes, residual):
            # a rotation error of 90 degrees or more (far from the solution)
            for k in range(3):
                target = rotations[k].T @ state.rotation @ rotations[k]
                try:
                    residual[6 * k + 3:6 * k + 6] = rotation_vector(
                        state.frames[k, :3, :3] @ target.T)
                except ValueError as error:  # an improper matrix: the shot diverged
                    raise ArithmeticError(f'the end-disk frame of leg {k + 1} is no rotation: '
                                          'its shot diverged') from error
        return residual

    def input_sensitivity(self, state: ChainState, inputs: np.ndarray) -> np.ndarray:
        """d(residual)/d(inputs) for inputs [q (3); force (3); moment (3); offset (3)]."""
        sensitivity = self._constant_sensitivity.copy()
        sensitivity[21:24, 3:6] = skew(state.rotation @ inputs[9:])
        sensitivity[21:24, 9:12] = -skew(inputs[3:6]) @ state.rotation
        return sensitivity
