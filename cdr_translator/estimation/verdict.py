"""
The WrenchEstimate of a search: the posterior, the conditioning and every verdict.

The posterior covariance is (J^T J)^-1 with J the whitened derivative [W C_b; L] at the
estimate. ``flags`` says every reason not to act on an estimate; ``accuracy_met`` is True only
when a pose covariance was given and no flag was raised, None (not assessed) for an exact
pose, False otherwise (WrenchEstimate's docstring).
"""

import math
import time
from typing import List, Optional, Sequence

import numpy as np
# the chi-square tail from scipy.special: scipy.stats takes about a second to import
from scipy.special import chdtrc

from .problem import estimated_name, Evaluation, Search, Target
from .wrench_estimate import COMPONENT_NAMES, observability, WrenchEstimate
from ..analysis.compliance import frame_twist
from ..analysis.stability import CLOSE_BRANCH_MARGIN
from ..geometry import quaternion_xyzw

__all__ = ['CHI2_TAIL', 'estimate_from']

#: Flag an estimate whose normalized pose residual has a chi-square tail probability below
#: this (the pose is further from the model than its covariance allows).
CHI2_TAIL = 1e-3


def estimate_from(found: Search, target: Target, started: float) -> WrenchEstimate:
    """Build the WrenchEstimate of a search: posterior, conditioning, verdicts, message."""
    best = found.best
    if best is not None and found.finish is not None:
        best = best.moved(found.finish)   # the last Gauss-Newton step (search.FINISH_CHI2)
    components = tuple(COMPONENT_NAMES[index] for index in target.free)
    if best is None:
        return WrenchEstimate(np.full(3, np.nan), np.full(3, np.nan), None, False, None,
                              False, math.nan, math.nan, [], found.message,
                              estimated=estimated_name(target), components=components,
                              iterations=found.iterations, solves=found.solves,
                              flags=[found.message],
                              estimate_time_s=time.perf_counter() - started)
    rows, free = list(target.rows), list(target.free)
    weights = target.weights
    pose_block = weights.pose @ best.compliance[np.ix_(rows, free)]
    information = pose_block.T @ pose_block + weights.prior.T @ weights.prior
    posterior = np.linalg.inv(information)
    sensitivity = np.zeros((6, len(rows)))
    sensitivity[free] = posterior @ pose_block.T @ weights.pose
    covariance = None
    if target.covariance is not None:
        covariance = np.zeros((6, 6))
        covariance[np.ix_(free, free)] = 0.5 * (posterior + posterior.T)
    condition, directions = observability(best.compliance, rows, free, target.length,
                                          target.labels, covariance, best.analysis)
    error = frame_twist(target.frame, best.frame)
    whitened = weights.pose @ error[rows]
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
        residual_m=float(np.linalg.norm(error[:3])),
        residual_deg=(math.degrees(float(np.linalg.norm(error[3:]))) if len(rows) == 6
                      else math.nan),
        conditioning=directions, message='; '.join(messages), estimated=estimated_name(target),
        components=components, condition_number=condition,
        ill_conditioned=bool(directions), stability_margin=best.margin,
        iterations=found.iterations, solves=found.solves, alternative=found.alternative,
        estimate_time_s=time.perf_counter() - started, position=best.frame[:3, 3].copy(),
        quaternion_xyzw=rotation, sensitivity=sensitivity, solution=best.solution,
        standard_deviation=deviation if covariance is not None else np.full(6, np.nan),
        target_sd=_on(free, target.target_sd),
        chi_square=chi_square, chi_square_p=tail, flags=flags)


def _on(free: Sequence[int], values: np.ndarray) -> np.ndarray:
    """Return ``values`` at the ``free`` components, NaN (not estimated) elsewhere."""
    shown = np.full(6, math.nan)
    shown[list(free)] = values[list(free)]
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
    for name, part, unit in (('force', slice(0, 3), 'N'), ('moment', slice(3, 6), 'N m')):
        indices = [index for index in range(6)[part] if index in free]
        if not indices:
            continue
        spread = float(np.linalg.norm(deviation[indices]))
        load = float(np.linalg.norm(best.wrench[part]))
        if spread > load and spread > float(np.linalg.norm(target.target_sd[indices])):
            flags.append(f'uninformative: the {name} spread {spread:.3g} {unit} exceeds the '
                         f'{name} it reports ({load:.3g} {unit})')
    missed = [f'{COMPONENT_NAMES[index]} {deviation[index]:.3g} > {target.target_sd[index]:.3g}'
              for index in target.free if deviation[index] > target.target_sd[index]]
    if missed:
        flags.append('accuracy target missed (posterior standard deviation): '
                     + ', '.join(missed))
    return flags


def _chi_text(tail: float, dof: int) -> str:
    """Say a chi-square test's tail probability and degrees of freedom."""
    return f'tail probability {tail:.2g} at {dof} degrees of freedom'
