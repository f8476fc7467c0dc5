"""
A sequence of forward solves with reduced legs, with compliance and verdicts, as columns.

The atlas's samples of one chunk (robot/samples.py: its RESULT_VARIABLES) without a
DeltaResult each: one compiled loop (reduced_coupled_kernels.solve_samples) solves the samples in
order, each warm from the last, and linearizes each solution (leg compliances, platform
compliance, slider Jacobian); the eigenvalues, the stiffness margin and the legs' verdicts
held at both ends (held.held_verdict's rule) are then made over all rows at once with
numpy. A row the loop cannot solve (and a cold first row) is solved by the robot's own
``solve`` (continuation), stored by the caller's ``store``, and the loop goes on from it.
The columns equal what ``DeltaRobot.solve(..., compliance=True)`` gives sample by sample.
"""

import time
from typing import Callable, Dict, Optional

import numpy as np

from .held_leg import held_verdict, HeldReference
from .levels import BoundTable
from .reduced_chain import ReducedChain
from .reduced_coupled_kernels import solve_samples
from .result import DeltaResult, rotation_vector

#: A row's outputs from the compiled loop: name -> (trailing shape, dtype); 'leg_x' is (3, n).
_LOOP_OUTPUTS = {'leg_x': None, 'wrenches': ((3, 6), float), 'position': ((3,), float),
                 'rotation': ((3, 3), float), 'rotation_vector': ((3,), float),
                 'bending': ((3, 2), float), 'signs': ((3,), np.int64),
                 'leg_compliances': ((3, 6, 6), float), 'compliance': ((6, 6), float),
                 'sliders': ((3, 3), float), 'iterations': ((), np.int64)}


def solve_rows(chain: ReducedChain, rows: np.ndarray, tolerances: np.ndarray,
               critical_load_n: Optional[float], table: BoundTable,
               fallback: Callable[[int], DeltaResult], out: Dict[str, np.ndarray],
               store: Callable[[Dict[str, np.ndarray], int, DeltaResult], None]) -> None:
    """
    Solve ``rows`` (N, 12 inputs: sliders, payload force, moment, offset) into ``out``.

    ``chain``: the robot's reduced chain, warm from its previous solution (none: the first
    row is solved by ``fallback``, the robot's ``solve`` of a row with compliance). Rows are
    solved in order; ``out`` holds samples.RESULT_VARIABLES for N samples (all but
    ``leg_fidelity``, the caller's: one level here).
    """
    count = len(rows)
    size = chain.model.size
    loop = {name: np.zeros((count,) + ((3, size) if spec is None else spec[0]),
                           dtype=float if spec is None else spec[1])
            for name, spec in _LOOP_OUTPUTS.items()}
    slider_columns = np.ascontiguousarray(
        chain.chain.input_sensitivity(chain.home(np.zeros(3)).chain_state(), rows[0])[:, :3])
    row = 0
    while row < count:
        if chain.previous is None:
            store(out, row, fallback(row))
            row += 1
            continue
        previous = chain.previous[0].copy()
        frames = chain.previous_frames.copy()
        started = time.perf_counter()
        stop = solve_samples(
            chain.model.code, chain.data, chain.model.tolerance, rows, row, previous.leg_x,
            previous.wrenches, previous.position, previous.rotation, frames,
            chain.chain.platform, tolerances, chain.max_iterations, *chain.kept, chain.points,
            chain.seen, chain.count, chain.input_scale, slider_columns, *loop.values())
        if stop > row:
            share = (time.perf_counter() - started) / (stop - row)
            _columns(chain, loop, slice(row, stop), share, critical_load_n, table, out)
            chain.previous = (previous, rows[stop - 1])
            chain.previous_frames = frames
            chain.kept_at_last = True  # each row was linearized at its solution
        if stop < count:
            store(out, stop, fallback(stop))
        row = stop + 1


def _columns(chain: ReducedChain, loop: Dict[str, np.ndarray], rows: slice, share: float,
             critical_load_n: Optional[float], table: BoundTable,
             out: Dict[str, np.ndarray]) -> None:
    """Fill ``out``'s rows from the loop's outputs (DeltaResult's derived values, in bulk)."""
    count = rows.stop - rows.start
    rotation = loop['rotation'][rows]
    out['converged'][rows] = True
    out['iterations'][rows] = loop['iterations'][rows]
    out['solve_time_s'][rows] = share
    out['platform_position'][rows] = loop['position'][rows]
    vectors = loop['rotation_vector'][rows]
    for index in np.flatnonzero(np.isnan(vectors[:, 0])):  # at 90 degrees or beyond
        vectors[index] = rotation_vector(rotation[index])
    out['platform_rotation_vector'][rows] = vectors
    sine = 0.5 * np.sqrt((rotation[:, 2, 1] - rotation[:, 1, 2]) ** 2
                         + (rotation[:, 0, 2] - rotation[:, 2, 0]) ** 2
                         + (rotation[:, 1, 0] - rotation[:, 0, 1]) ** 2)
    out['parasitic_rotation'][rows] = np.arctan2(
        sine, 0.5 * (np.trace(rotation, axis1=1, axis2=2) - 1.0))  # geometry.rotation_angle
    wrenches = loop['wrenches'][rows]
    out['leg_bending'][rows] = loop['bending'][rows]
    out['leg_axial_force'][rows] = wrenches[:, :, 2]
    compliance = loop['compliance'][rows]
    known = np.all(np.isfinite(compliance), axis=(1, 2))
    symmetric = 0.5 * (compliance + compliance.transpose(0, 2, 1))
    translation = np.full((count, 3), np.nan)
    turning = np.full((count, 3), np.nan)
    margin = np.full(count, np.nan)
    if np.any(known):
        translation[known] = np.linalg.eigvalsh(symmetric[known, :3, :3])
        turning[known] = np.linalg.eigvalsh(symmetric[known, 3:, 3:])
        height = chain.params.stack_height
        scale = np.concatenate([np.ones(3), np.full(3, 1.0 / height)])
        stiffness = scale[:, None] * np.linalg.inv(compliance[known]) * scale[None, :]
        margin[known] = np.linalg.eigvalsh(0.5 * (stiffness + stiffness.transpose(0, 2, 1)))[:, 0]
    out['compliance_eigenvalues_translation'][rows] = translation
    out['compliance_eigenvalues_rotation'][rows] = turning
    out['slider_jacobian'][rows] = loop['sliders'][rows]
    out['stiffness_margin'][rows] = margin
    reference = chain.unloaded_reference(critical_load_n)
    legs = _held_verdicts(loop['signs'][rows], loop['leg_compliances'][rows], wrenches,
                          reference)
    # the chain is stable when the platform stiffness and every leg are (chain_verdict);
    # an unknown leg verdict is not stable either in the atlas
    stable = known & (margin > 0.0) & np.all(legs == 1, axis=1)
    messages = np.full(count, 'converged', dtype=out['message'].dtype)
    for index in np.flatnonzero(~known):
        messages[index] += '; no platform compliance: the Newton Jacobian is singular'
    for index in np.flatnonzero(known & np.any(legs != 1, axis=1)):
        messages[index] += _leg_messages(chain, loop, rows.start + index, reference)
    out['stable'][rows] = stable
    out['message'][rows] = messages
    bounds = table.bounds(wrenches.reshape(-1, 6)).reshape(count, 3, 2)
    out['leg_error_bound_position'][rows] = bounds[:, :, 0]
    out['leg_error_bound_angle'][rows] = bounds[:, :, 1]


def _held_verdicts(signs: np.ndarray, compliances: np.ndarray, wrenches: np.ndarray,
                   reference: HeldReference) -> np.ndarray:
    """
    held.held_verdict's ``stable`` of every leg (N, 3): 1 stable, 0 unstable, -1 unknown.

    From each leg's sign of det H, its compliance (scaled as held_leg.held_reference does)
    and its compression against the held buckling load.
    """
    scale = np.repeat([1.0, reference.length], 3)
    scaled = scale[:, None] * compliances * scale[None, :]
    finite = np.all(np.isfinite(compliances), axis=(2, 3))
    compliance_signs = np.zeros(signs.shape)
    compliance_signs[finite] = np.linalg.slogdet(scaled[finite])[0]
    critical = np.nan if reference.critical_load_n is None else reference.critical_load_n
    margin = 1.0 - (-wrenches[:, :, 2]) / critical
    parity = signs * compliance_signs == reference.jacobian_sign * reference.compliance_sign
    verdict = np.where(parity, np.where(np.isnan(margin), -1, np.where(margin <= 0.0, 0, 1)), 0)
    return np.where((signs == 0) | (compliance_signs == 0), -1, verdict)


def _leg_messages(chain: ReducedChain, loop: Dict[str, np.ndarray], row: int,
                  reference: HeldReference) -> str:
    """Return the '; leg k: ...' message parts of a row whose legs are not all stable."""
    text = ''
    for k in range(3):
        wrench = loop['wrenches'][row, k]
        _, compliance, lu = chain.leg_linearization(loop['leg_x'][row, k], wrench)
        verdict = held_verdict(lu, compliance, wrench, reference)
        if verdict.stable is not True:
            text += f'; leg {k + 1}: {verdict.message}'
    return text
