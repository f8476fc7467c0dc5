"""
Measure the reduced fidelity levels against the reference model: the validation data.

``validate`` computes the error bounds config/fidelity_validation.yaml holds (about a
minute; ``bench/speed_vs_error.py`` writes them). The data types, boxes and samples are
cdr_translator.fidelity.validation's; this module solves many times, so it is a study.
"""

from typing import Dict, List, Tuple

import numpy as np
from scipy.stats import qmc

from ..fidelity.solver import FidelitySolver
from ..fidelity.validation import box_half_widths, box_samples, KEYED_PARAMS, level_bound
from ..fidelity.validation import LINEAR_BASES, LINEAR_SCALES, offset_samples, pose_errors
from ..fidelity.validation import reference_solver, SCALES, Validation
from ..params.translator_params import TranslatorParams
from ..solve.result import SolveResult
from ..solve.solver import TranslatorSolver


def validate(params: TranslatorParams, rod_steps: int, seed: int = 6) -> Validation:
    """
    Measure the reduced levels against the reference over the validated boxes.

    Every reference solve is warm-started from the previous sample. The levels are run
    through FidelitySolver with the level fixed (cold for 'cc' and 'rod', so that the
    errors do not depend on the order of the samples).
    """
    reference = reference_solver(params)
    levels = {name: FidelitySolver(params, fidelity=name, rod_steps=rod_steps)
              for name in ('cc', 'rod', 'linear')}
    errors: Dict[str, Dict[float, List[Tuple[float, float]]]] = {
        name: {scale: [] for scale in SCALES} for name in ('cc', 'rod')}
    for scale in SCALES:
        for wrench in box_samples(scale, seed):
            expected = _reference(reference, wrench)
            for name in ('cc', 'rod'):
                levels[name].reset()
                errors[name][scale].append(_errors(levels[name], wrench, expected))
    rng = np.random.default_rng(seed)
    linear: Dict[float, List[Tuple[float, float]]] = {scale: [] for scale in LINEAR_SCALES}
    bases = np.vstack([np.zeros(6), (2.0 * qmc.Halton(d=6, seed=seed + 1).random(
        LINEAR_BASES - 1) - 1.0) * box_half_widths()])
    solver = levels['linear']
    for base in bases:
        solver.cache_full_solution(base)
        for scale in LINEAR_SCALES:
            for offset in offset_samples(scale, rng):
                expected = _reference(reference, base + offset)
                linear[scale].append(_errors(solver, base + offset, expected))
    bounds = {name: level_bound(SCALES, errors[name]) for name in ('cc', 'rod')}
    bounds['linear'] = level_bound(LINEAR_SCALES, linear)
    return Validation({key: params.to_dict()[key] for key in KEYED_PARAMS}, rod_steps,
                      tuple(box_half_widths()), bounds)


def _reference(reference: TranslatorSolver, wrench: np.ndarray) -> SolveResult:
    result = reference.solve(wrench[:3], wrench[3:])
    if not result.converged:
        reference.reset()
        result = reference.solve(wrench[:3], wrench[3:])
    if not result.converged:
        raise ArithmeticError(f'reference solve failed at {wrench.tolist()}: {result.message}')
    return result


def _errors(solver, wrench: np.ndarray, expected: SolveResult) -> Tuple[float, float]:
    result = solver.solve(wrench[:3], wrench[3:])
    if not result.converged:
        raise ArithmeticError(f'{result.fidelity} solve failed at {wrench.tolist()}: '
                              f'{result.message}')
    return pose_errors(result, expected)
