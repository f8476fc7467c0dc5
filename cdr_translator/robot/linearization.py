"""
The chain's exact linearization: leg compliances, the platform Jacobian, and what they give.

Each leg enters through its 6x6 compliance at the end disk, from one tangent-linear shot
(its shooting Jacobian and end-disk pose derivative; implicit differentiation). The
platform Jacobian's LU with the legs' factorizations (``Factorization``) serves the coupled
Newton's steps and, at a solution, the platform compliance, the input sensitivity and the
stability verdict of a DeltaResult (``linearize``): the condensed platform stiffness and each
leg held at both ends (cdr_translator/robot/held_leg.py), which the condensation presumes stable.
"""

from dataclasses import dataclass, field
import math
from typing import List, Optional, Tuple

import numpy as np

from .chain import Chain, ChainState, distance, SIZE, skew
from .held_leg import held_verdict, HeldReference, HeldVerdict
from .kernels import secant_update
from .legs import ChainLegs, Deadline
from .reduced_kernels import platform_jacobian as compiled_platform_jacobian
from .result import DeltaResult
from .._linalg import factorize as factorize_matrix, solve_lu
from ..analysis.stability import pose_twist

#: A factorization made within this distance of the solution (largest change of the scaled
#: unknowns, platform and legs) serves the compliance and stability verdict there: it
#: moves the compliance by about as much, relatively, below the 1e-8 to which implicit and
#: finite-difference compliances agree.
REUSE_DISTANCE = 1e-9

#: Broyden updates gathered on one factorization at most (then H stays until a rebuild).
MAX_SECANTS = 24


def inverse_left_jacobian(vector: np.ndarray) -> np.ndarray:
    """
    Inverse left Jacobian of SO(3) at rotation vector ``vector``.

    d log(exp([a]) R) / da at a = 0, for R = exp([vector]); its transpose (the inverse
    right Jacobian) is d log(R exp([a])) / da.
    """
    angle = float(np.linalg.norm(vector))
    cross = skew(vector)
    if angle < 1e-6:
        coefficient = 1.0 / 12.0  # the series limit
    else:
        coefficient = (1.0 / angle ** 2
                       - (1.0 + math.cos(angle)) / (2.0 * angle * math.sin(angle)))
    return np.eye(3) - 0.5 * cross + coefficient * cross @ cross


@dataclass
class LegLinearization:
    """One leg's exact linearization at a state: what the platform Newton needs of it."""

    lu: tuple  # LU factorization of the leg's shooting Jacobian (nondimensional)
    pose: np.ndarray  # d(end-disk frame)/d(unknowns), (12, n): Problem.pose_jacobian
    twist: np.ndarray  # d(end-disk twist)/d(unknowns), (6, n): stability.pose_twist of it
    rotation: np.ndarray  # end-disk rotation in {pe_i} there
    gain: np.ndarray  # J^-1 dr/dw (n, 6): unknowns per SI wrench
    compliance: np.ndarray  # (6, 6) SI, cdr_translator/analysis/compliance.py's convention
    wrench: np.ndarray  # the wrench it was made at


class Secants:
    """
    Good-Broyden updates of the coupled Newton's inverse Jacobian, on one factorization.

    The unknowns' steps are flat and scaled (platform / x_scale, then the legs' (3, n)
    nondimensional unknowns), as the coupled Newton's ``norm`` measures them. Update i maps
    H_i to H_{i+1} = H_i + (s - H_i y) s^T H_i / (s^T H_i y), s the step taken and y the
    change of the residuals (Kelley, "Solving Nonlinear Equations with Newton's Method",
    SIAM 2003, Sec. 1.11, as chord.py holds them for one leg): kept as u = (s - H_i y) /
    (s^T H_i y) and s, H_{i+1} r = H_i r + u (s . H_i r) (chord.apply_updates).
    """

    def __init__(self, size: int) -> None:
        """Room for MAX_SECANTS updates of flat steps of ``size``; none yet."""
        self.updates = np.empty((MAX_SECANTS, size))
        self.steps = np.empty((MAX_SECANTS, size))
        self.count = 0

    def add(self, step: np.ndarray, change: np.ndarray, correction: np.ndarray) -> np.ndarray:
        """
        Add the update of step s (flat, scaled) whose residual change y has H y = ``change``.

        Return ``correction`` (H r for some r, before the update) after it: H_{i+1} r. Once
        MAX_SECANTS are gathered H stays as it is (a rebuild starts afresh).
        """
        updated = np.array(correction, dtype=float)
        self.count = int(secant_update(self.updates, self.steps, self.count,
                                       np.ascontiguousarray(step, dtype=float),
                                       np.ascontiguousarray(change, dtype=float), updated))
        return updated


@dataclass
class Factorization:
    """The platform Jacobian's LU (scaled) and the leg linearizations it was built from."""

    platform: tuple
    legs: Tuple[LegLinearization, ...]
    state: ChainState  # where it was made
    #: Broyden updates gathered on it, by this and later solves until it is rebuilt
    secants: Secants = field(init=False)
    # for the chord steps (kernels.coupled_step), stacked over the legs: the LU factors
    # (3, n, n) and pivots (3, n), T_k (3, 6, n) and J_k^-1 dr/dw (3, n, 6); and the scaled
    # platform Jacobian's inverse (24, 24)
    factors: np.ndarray = field(init=False)
    pivots: np.ndarray = field(init=False)
    twists: np.ndarray = field(init=False)
    gains: np.ndarray = field(init=False)
    platform_inverse: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        """Stack the legs' matrices, invert the platform Jacobian, start the secants."""
        # C order: the substitutions run along rows (LAPACK's factors are column-major)
        self.factors = np.ascontiguousarray(np.stack([leg.lu[0] for leg in self.legs]))
        self.pivots = np.stack([leg.lu[1] for leg in self.legs])
        self.twists = np.ascontiguousarray(np.stack([leg.twist for leg in self.legs]))
        self.gains = np.ascontiguousarray(np.stack([leg.gain for leg in self.legs]))
        self.platform_inverse = np.ascontiguousarray(solve_lu(self.platform, np.eye(SIZE)))
        self.secants = Secants(SIZE + self.gains.shape[0] * self.gains.shape[1])


def factorize(chain: Chain, legs: ChainLegs, state: ChainState,
              inputs: np.ndarray) -> Factorization:
    """
    Exact linearization at ``state``: each leg's tangent-linear shot, and the platform LU.

    ArithmeticError when a leg Jacobian or the platform Jacobian is singular.
    """
    if state.frames is None:
        raise RuntimeError('the legs have not been evaluated at this state')
    made = []
    for k, solver in enumerate(legs.solvers):
        problem = solver.problem
        _, jacobian, pose = problem.exact_jacobian(state.unknowns[k], state.wrenches[k])
        lu = factorize_matrix(jacobian)
        gain = solve_lu(lu, problem.wrench_sensitivity)
        rotation = state.frames[k, :3, :3].copy()
        twist = pose_twist(pose, rotation)
        compliance = -twist @ gain
        if not np.all(np.isfinite(compliance)):
            raise ArithmeticError(f'the Jacobian of leg {k + 1} is singular')
        made.append(LegLinearization(lu, pose.copy(), twist, rotation, gain, compliance,
                                     state.wrenches[k].copy()))
    legs.counts['leg_jacobians'] += 3
    jacobian = platform_jacobian(chain, state, inputs, [leg.compliance for leg in made])
    platform = factorize_matrix(jacobian / chain.r_scale[:, None] * chain.x_scale[None, :])
    if not np.all(np.isfinite(platform[0])) or np.any(np.diag(platform[0]) == 0.0):
        raise ArithmeticError('the platform Jacobian is singular')
    return Factorization(platform, tuple(made), state)


def platform_jacobian(chain: Chain, state: ChainState, inputs: np.ndarray,
                      compliances: List[np.ndarray]) -> np.ndarray:
    """
    d(residual)/d(platform unknowns), each leg entering through its ``compliances``.

    Per leg k (columns 6 + 6k.. its wrench; rows 6k.. its compatibility): the compliance
    C_k, its rotation rows through the inverse left Jacobian G_k of the rotation error
    log(R_de R_target^T) (the end disk turns it from the left, the platform from the
    right); -R_k^T and R_k^T [R a_k]x for the platform's position and turn, -G_k^T R_k^T
    for the turn of the target. Equilibrium: -R_k and -[R a_k]x R_k on the leg forces, -R_k
    on its moments, [f_k]x [R a_k]x and [payload]x [R offset]x on the platform's turn.
    One compiled call (reduced_kernels.platform_jacobian, which the reduced legs' chain
    assembles too).
    """
    jacobian = np.empty((SIZE, SIZE))
    compiled_platform_jacobian(state.rotation, state.wrenches, chain.residual(state, inputs),
                               inputs, chain.leg_rotations, chain.attachments,
                               np.ascontiguousarray(np.stack(compliances)), jacobian)
    return jacobian


def chain_verdict(platform_stable: bool,
                  legs: Tuple[HeldVerdict, ...]) -> Optional[bool]:
    """
    Return the closed chain's verdict: the platform stiffness and every leg held at both ends.

    The platform stiffness is the legs' condensed into the platform pose, valid only when
    each leg's internal equilibrium is stable with its ends held: False if any part is
    unstable, else None (unknown) if a leg's verdict could not be made, else True.
    """
    verdicts = [platform_stable] + [leg.stable for leg in legs]
    if False in verdicts:
        return False
    return None if None in verdicts else True


def linearize(result: DeltaResult, chain: Chain, legs: ChainLegs, state: ChainState,
              factorization: Optional[Factorization], inputs: np.ndarray,
              stack_height: float, held: HeldReference) -> Optional[Factorization]:
    """
    Add the compliance, input sensitivity and stability verdict at solution ``state``.

    The legs' held verdicts compare with ``held``, the unloaded leg's reference.

    ``factorization`` (the solve's last) is reused when made within REUSE_DISTANCE of the
    state; else one is made there and returned (exact at the solution: the next solve's
    chord steps start from it). None when none was made.
    """
    made = None
    try:
        if factorization is None or distance(factorization.state, state,
                                             chain.x_scale) > REUSE_DISTANCE:
            factorization = made = factorize(chain, legs, state, inputs)
        right = np.zeros((SIZE, 18))
        right[:, :12] = chain.input_sensitivity(state, inputs)
        right[18:, 12:] = np.eye(6)
        solved = -chain.x_scale[:6, None] * solve_lu(factorization.platform,
                                                     right / chain.r_scale[:, None])[:6]
    except (Deadline, ArithmeticError, np.linalg.LinAlgError, ValueError) as error:
        result.stable = False
        result.message += f'; no platform compliance: {error}'
        return made
    if not np.all(np.isfinite(solved)):
        result.stable = False
        result.message += '; no platform compliance: the Newton Jacobian is singular'
        return made
    result.input_sensitivity = solved[:, :12]
    result.platform_compliance = solved[:, 12:]
    scale = np.concatenate([np.ones(3), np.full(3, 1.0 / stack_height)])
    try:
        stiffness = np.linalg.inv(result.platform_compliance)
    except np.linalg.LinAlgError:
        result.stable = False
        result.message += '; the platform compliance is singular'
        return made
    scaled = scale[:, None] * stiffness * scale[None, :]
    result.stiffness_margin = float(np.linalg.eigvalsh(0.5 * (scaled + scaled.T))[0])
    result.leg_stability = tuple(
        held_verdict(leg.lu, leg.compliance, wrench, held)
        for leg, wrench in zip(factorization.legs, state.wrenches))
    result.stable = chain_verdict(bool(result.stiffness_margin > 0.0), result.leg_stability)
    for k, verdict in enumerate(result.leg_stability, start=1):
        if verdict.stable is not True:
            result.message += f'; leg {k}: {verdict.message}'
    return made
