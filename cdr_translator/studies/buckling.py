"""
Axial buckling of the straight translator: the numerical critical load and the Euler estimate.

:func:`critical_compression` finds the load where the shooting Jacobian becomes singular along
the straight compression branch and judges stability on both sides of it;
:func:`~cdr_translator.robot.held_leg.euler_critical_load` gives the closed-form Euler
estimate of the same structure.
:func:`held_critical_compression` does the same with both end disks held (a leg of the
robot, cdr_translator/robot/held_leg.py) and confirms each side by a perturbed held solve
(:func:`perturbed_held_solve`).
"""

from dataclasses import dataclass
import math
import time
from typing import Optional

import numpy as np
from scipy.optimize import minimize_scalar

from .hard_cases import stability, study_solver
from .._blas import one_blas_thread
from ..params.translator_params import TranslatorParams
from ..robot.held_leg import euler_critical_load, held_critical_load, held_jacobian, held_solve
from ..robot.held_leg import HeldCritical

#: Amplitudes (in the unit null vector of J_d, nondimensional unknowns and wrench) of the
#: perturbations a held re-solve starts from: within the buckled branch's reach 2 % past the
#: held buckling load, below the amplitude at which Newton's method leaves every equilibrium.
PERTURBATIONS = (0.1, 0.2, 0.3, 0.5)


@dataclass
class Buckling:
    """
    Axial buckling of the straight translator: numerical critical load and its checks.

    ``critical_load_n`` minimizes the smallest singular value of the (nondimensional)
    shooting Jacobian along the straight, perfectly symmetric compression branch;
    ``smallest_singular_value`` is that minimum (0 for an exactly singular Jacobian) and
    ``unloaded_singular_value`` the same quantity at no load. ``stable_below`` and
    ``stable_above`` are :func:`stability` 2 % below and above the critical load.
    """

    critical_load_n: float
    smallest_singular_value: float
    unloaded_singular_value: float
    euler_estimate_n: float
    stable_below: Optional[bool]
    stable_above: Optional[bool]
    time_s: float


def critical_compression(params: TranslatorParams) -> Buckling:
    """Find the axial buckling load (see :class:`Buckling`), bracketed by the Euler one."""
    started = time.perf_counter()
    solver = study_solver(params)
    problem = solver.problem

    def smallest_singular_value(compression: float) -> float:
        solver.reset()
        result = solver.solve((0.0, 0.0, -compression))
        if not result.converged:
            return math.inf
        wrench = np.array([0.0, 0.0, -compression, 0.0, 0.0, 0.0])
        xs = result.unknowns / problem.x_scale
        jacobian = problem.jacobian(xs, wrench, problem.residual(xs, wrench))
        return float(np.linalg.svd(jacobian, compute_uv=False)[-1])

    euler = euler_critical_load(params)
    found = minimize_scalar(smallest_singular_value, bracket=(0.6 * euler, euler, 1.5 * euler),
                            tol=1e-9)
    judged = []
    for factor in (0.98, 1.02):
        solver.reset()
        result = solver.solve((0.0, 0.0, -factor * found.x), compliance=True)
        judged.append(stability(solver, result)[0])
    return Buckling(float(found.x), float(found.fun), smallest_singular_value(0.0), euler,
                    judged[0], judged[1], time.perf_counter() - started)


@dataclass(frozen=True)
class HeldPerturbation:
    """
    A held re-solve from the straight state perturbed along the held buckling mode.

    ``departure``: the largest change of the nondimensional unknowns from the straight state
    it ended at (0 when it returned there), over the PERTURBATIONS amplitudes that converged;
    ``compression_after_n`` the end-disk compression there. At the same end-disk pose a state
    carrying less compression has the lower energy (dU/d(shortening) is the compression along
    each branch from their common bifurcation point).
    """

    compression_n: float
    departure: float
    compression_after_n: float
    converged: bool

    @property
    def left_straight(self) -> bool:
        """Whether some perturbation ended at another equilibrium than the straight one."""
        return self.converged and self.departure > 1e-6


@one_blas_thread
def perturbed_held_solve(params: TranslatorParams, critical: HeldCritical,
                         factor: float) -> HeldPerturbation:
    """
    Hold the straight state's end disk at ``factor`` times the held buckling load, perturb.

    The perturbation is along the null vector of J_d at the buckling load (its smallest
    right singular vector); each amplitude of PERTURBATIONS is re-solved by Newton's method
    on the held problem (held.held_solve). Below the buckling load the straight state is the
    only equilibrium near it; past it a buckled one appears (a pitchfork).
    """
    solver = study_solver(params)
    problem = solver.problem

    def straight(compression: float) -> tuple:
        solver.reset()
        result = solver.solve((0.0, 0.0, -compression))
        wrench = np.array([0.0, 0.0, -compression, 0.0, 0.0, 0.0])
        return result.unknowns / problem.x_scale, wrench, result.frames['de']

    xs, wrench, frame = straight(critical.load_n)
    _, jacobian, pose = problem.exact_jacobian(xs, wrench)
    mode = np.linalg.svd(held_jacobian(problem, jacobian, pose, frame[:3, :3]))[2][-1]
    compression = factor * critical.load_n
    xs, wrench, frame = straight(compression)
    outcomes = []
    for amplitude in PERTURBATIONS:
        moved, reaction, converged = held_solve(
            problem, xs + amplitude * mode[:problem.size],
            wrench + amplitude * mode[problem.size:] * problem.wrench_scale, frame)
        if converged:
            outcomes.append((float(np.abs(moved - xs).max()), -float(reaction[2])))
    if not outcomes:
        return HeldPerturbation(compression, math.nan, math.nan, False)
    departure, after = max(outcomes)
    return HeldPerturbation(compression, departure, after, True)


@dataclass
class HeldBuckling:
    """
    Axial buckling with both end disks held: held.held_critical_load and its confirmation.

    ``below`` and ``above``: perturbed held re-solves 2 % below and above the load.
    """

    critical_load_n: float
    smallest_singular_value: float
    unloaded_singular_value: float
    estimate_n: float
    below: HeldPerturbation
    above: HeldPerturbation
    time_s: float


def held_critical_compression(params: TranslatorParams) -> HeldBuckling:
    """Find the held buckling load and confirm both sides of it (see :class:`HeldBuckling`)."""
    started = time.perf_counter()
    critical = held_critical_load(params)
    below = perturbed_held_solve(params, critical, 0.98)
    above = perturbed_held_solve(params, critical, 1.02)
    return HeldBuckling(critical.load_n, critical.smallest_singular_value,
                        critical.unloaded_singular_value, critical.estimate_n, below, above,
                        time.perf_counter() - started)
