"""
Axial buckling of the straight translator: the numerical critical load and the Euler estimate.

:func:`critical_compression` finds the load where the shooting Jacobian becomes singular along
the straight compression branch and judges stability on both sides of it;
:func:`euler_critical_load` gives the closed-form Euler estimate of the same structure.
"""

from dataclasses import dataclass
import math
import time
from typing import Optional

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .hard_cases import stability, study_solver
from ..params import TranslatorParams


def euler_critical_load(params: TranslatorParams) -> float:
    """
    Closed-form Euler buckling load (N) of the straight translator under axial compression.

    The translating (S-shaped) mode: each joint is a column of bending stiffness 5 EI (the
    five backbones bend together) and length (S + 1) D; the tube is rigid; the base is
    clamped and the end disk keeps its orientation. By antisymmetry the tube's midpoint is
    an inflection point, so each half is a clamped column of length l carrying a rigid arm
    a = L_m / 2 to a moment-free tip: w = d (1 - cos k s), d = w(l) + a w'(l), which gives
    k l tan(k l) = l / a, and P = 5 EI k^2.
    """
    length = params.joint_length
    arm = 0.5 * params.tube_length
    root = brentq(lambda u: u * math.tan(u) - length / arm, 1e-12, 0.5 * math.pi - 1e-12)
    return 5.0 * params.bending_stiffness * (root / length) ** 2


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
