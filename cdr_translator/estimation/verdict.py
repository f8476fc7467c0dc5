"""
The WrenchEstimate of a search: the posterior, the conditioning and every verdict.

The posterior covariance is (J^T J)^-1 with J the whitened derivative [W C_b; L] at the
estimate, from the SVD of J the search made. ``flags`` says every reason not to act on an
estimate; ``accuracy_met`` is True only when a pose covariance was given and no flag was
raised, None (not assessed) for an exact pose, False otherwise (WrenchEstimate's
docstring).
"""

import math
import time
from typing import List, Optional, Tuple

import numpy as np
# the chi-square tail from scipy.special: scipy.stats takes about a second to import
from scipy.special import chdtrc

from .problem import (estimated_name, Evaluation, Linearization, linearized, Search,
                      Target)
from .wrench_estimate import block_index, COMPONENT_NAMES, WrenchEstimate
from ..analysis.stability import CLOSE_BRANCH_MARGIN
from ..geometry import quaternion_xyzw

__all__ = ['CHI2_TAIL', 'estimate_from']

#: Flag an estimate whose normalized pose residual has a chi-square tail probability below
#: this (the pose is further from the model than its covariance allows).
CHI2_TAIL = 1e-3


def estimate_from(found: Search, target: Target, started: float) -> WrenchEstimate:
    """Build the WrenchEstimate of a search: posterior, conditioning, verdicts, message."""
    solved = best = found.best
    if solved is not None and found.finish is not None:
        best = solved.moved(found.finish)   # the last Gauss-Newton step (search.FINISH_CHI2)
    components = tuple(COMPONENT_NAMES[index] for index in target.free)
    if solved is None or best is None:
        return WrenchEstimate(np.full(3, np.nan), np.full(3, np.nan), None, False, None,
                              False, math.nan, math.nan, [], found.message,
                              estimated=estimated_name(target), components=components,
                              iterations=found.iterations, solves=found.solves,
                              flags=[found.message],
                              estimate_time_s=time.perf_counter() - started)
    linear = found.linearization
    if linear is None or linear.at is not solved:  # a Search not made by search()
        linear = linearized(target, solved)
    posterior, sensitivity = _posterior(linear, target)
    rows, free = target.rows, target.free_index
    covariance = None
    if target.covariance is not None:
        covariance = np.zeros((6, 6))
        covariance[block_index(target.free, target.free)] = 0.5 * (posterior + posterior.T)
    # the compliance's own (best is solved moved by the finish: the same compliance)
    observed = solved.conditioning(target)
    condition, directions = observed.condition, observed.directions_with(covariance)
    if found.finish is None:
        error, whitened = linear.error, linear.residual[:len(rows)]
    else:  # moved by the last step: another pose, the same derivative
        error = target.error(best)
        whitened = target.weights.pose @ error
    chi_square = float(whitened @ whitened)
    tail = float(chdtrc(len(rows), chi_square)) if target.covariance is not None else math.nan
    deviation = np.zeros(6)
    deviation[free] = np.sqrt(np.maximum(np.diag(posterior), 0.0))
    flags = _flags(found, best, target, deviation, tail)
    messages = [found.message, *flags]
    if directions:
        messages.append('poorly observable: ' + ', '.join(
            f"{direction['label']} ({direction['ratio']:.3g} x)" for direction in directions))
    accuracy_met: Optional[bool] = False
    if not found.converged:
        flags.insert(0, found.message)
    elif target.covariance is None:
        accuracy_met = None  # an exact pose: nothing to compare a spread with
        messages.append('accuracy not assessed: no pose covariance')
    else:
        accuracy_met = not flags
    rotation = quaternion_xyzw(best.frame[:3, :3])
    return WrenchEstimate(
        force=best.wrench[:3].copy(), moment=best.wrench[3:].copy(), covariance=covariance,
        converged=found.converged, stable=best.stable, accuracy_met=accuracy_met,
        residual_m=math.hypot(*error[:3].tolist()),
        residual_deg=math.degrees(math.hypot(*error[3:].tolist())) if len(rows) == 6
        else math.nan,
        conditioning=directions, message='; '.join(messages), estimated=estimated_name(target),
        components=components, condition_number=condition,
        ill_conditioned=bool(directions), stability_margin=best.margin,
        iterations=found.iterations, solves=found.solves, alternative=found.alternative,
        estimate_time_s=time.perf_counter() - started, position=best.frame[:3, 3].copy(),
        quaternion_xyzw=rotation, sensitivity=sensitivity, solution=best.solution,
        standard_deviation=deviation if covariance is not None else np.full(6, np.nan),
        target_sd=_on(free, target.target_sd),
        chi_square=chi_square, chi_square_p=tail, flags=flags)


def _posterior(linear: Linearization, target: Target) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the posterior covariance of the estimated components and the sensitivity (6, m).

    From the SVD J = U diag(s) V^T of the whitened derivative by the scaled components
    (w_f = S_f u): the posterior (J^T J)^-1 is S_f V diag(s^-2) V^T S_f in SI units, and
    the estimate's derivative by the measured pose (J^T J)^-1 J_pose^T W is
    S_f V diag(s^-1) U_pose^T W; no J^T J is formed, which would square J's condition
    number. The prior term keeps every s positive.
    """
    derivative = linear.derivative
    left, values, right = derivative.left, derivative.values, derivative.right
    free = target.free_index
    spread = target.scale[free, None] * right.T / values  # S_f V diag(s^-1)
    sensitivity = np.zeros((6, len(target.rows)))
    sensitivity[free] = spread @ left[:len(target.rows)].T @ target.weights.pose
    return spread @ spread.T, sensitivity


def _on(free: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Return ``values`` at the ``free`` components (index array), NaN elsewhere."""
    shown = np.full(6, math.nan)
    shown[free] = values[free]
    return shown


def _flags(found: Search, best: Evaluation, target: Target, deviation: np.ndarray,
           tail: float) -> List[str]:
    """Say why an estimate is not to be acted on (empty: nothing found wrong)."""
    flags = []
    if best.stable is False:
        flags.append('past buckling: the matching equilibrium is unstable')
    elif best.stable is None:
        flags.append('stability unknown')
    elif best.margin < CLOSE_BRANCH_MARGIN:
        flags.append(f'near a bifurcation (stability margin {best.margin:.3g}): another '
                     'wrench may match this pose')
    if best.accuracy_met is False:
        flags.append('the forward solve misses its accuracy target')
    if found.alternative is not None:
        flags.append('ambiguous: the moment ' + ', '.join(
            f'{value:.4g}' for value in found.alternative[3:]) + ' N m matches too')
    if target.covariance is None:
        return flags
    if tail < CHI2_TAIL:
        flags.append(f'the pose is further from the model than its covariance allows '
                     f'(chi-square {_chi_text(tail, len(target.rows))})')
    free = set(target.free)
    # floats: math.hypot of a few costs a tenth of np.linalg.norm, and estimates run per pose
    deviations, targets = deviation.tolist(), target.target_sd.tolist()
    loads = best.wrench.tolist()
    for name, part, unit in (('force', range(0, 3), 'N'), ('moment', range(3, 6), 'N m')):
        indices = [index for index in part if index in free]
        if not indices:
            continue
        spread = math.hypot(*(deviations[index] for index in indices))
        load = math.hypot(*(loads[index] for index in part))
        if spread > load and spread > math.hypot(*(targets[index] for index in indices)):
            flags.append(f'uninformative: the {name} spread {spread:.3g} {unit} exceeds the '
                         f'{name} it reports ({load:.3g} {unit})')
    missed = [f'{COMPONENT_NAMES[index]} {deviations[index]:.3g} > {targets[index]:.3g}'
              for index in target.free if deviations[index] > targets[index]]
    if missed:
        flags.append('accuracy target missed (posterior standard deviation): '
                     + ', '.join(missed))
    return flags


def _chi_text(tail: float, dof: int) -> str:
    """Say a chi-square test's tail probability and degrees of freedom."""
    return f'tail probability {tail:.2g} at {dof} degrees of freedom'
