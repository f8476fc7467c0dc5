"""
The CSV table of a replay (``python -m msg_tools replay --csv``): one row per input message.

A WrenchStamped's row holds the input wrench and what the node answered: status, the
joint angles, the end-disk pose, the compliance eigenvalues with the axis and the unit of
each, the level that answered and the verdicts (stable, error estimate, accuracy met). A
measured pose's row holds the node's wrench estimate and its standard deviations. SI units
and radians; an empty cell is a value that does not exist or was not assessed.
"""

import math
from typing import Any, Dict, Iterable, List, Mapping, Optional

from cdr_translator.estimation.wrench_estimate import WrenchEstimate
from cdr_translator.interface import messages
from cdr_translator.interface.wrench_processing import Outcome
from cdr_wire.reader import RawMessage

#: Units of the compliance eigenvalues, by the kind of axis their eigenvector mostly moves
#: along (``ComplianceAnalysis.labels``: 'translation x' ... 'rotation z').
EIGENVALUE_UNITS = {'translation': 'm/N', 'rotation': 'rad/(N m)'}

#: CSV columns, one row per input message (SI units, radians). Columns are only ever added
#: (at the end): scripts read them by name. A measured pose's row leaves the wrench and
#: the joints empty and fills the ``estimate*`` columns, its pose columns holding the pose
#: the estimated wrench gives.
CSV_COLUMNS = (
    ['index', 'topic', 'stamp_ns', 'log_time_ns', 'frame_id', 'fx_n', 'fy_n', 'fz_n',
     'mx_nm', 'my_nm', 'mz_nm', 'status', 'message', 'iterations', 'residual_norm',
     'solve_time_ms']
    + [f'{name}_rad' for name in messages.JOINT_NAMES]
    + ['x_m', 'y_m', 'z_m', 'qx', 'qy', 'qz', 'qw']
    # each in m/N or rad/(N m), as its compliance_eigenvalue_k_unit says
    + [f'compliance_eigenvalue_{k}' for k in range(1, 7)]
    # the level that answered; the verdicts: 'true', 'false', or empty when not assessed
    + ['fidelity', 'stable', 'error_estimate_m', 'error_estimate_rad', 'accuracy_met']
    + [f'compliance_eigenvalue_{k}_axis' for k in range(1, 7)]
    + [f'compliance_eigenvalue_{k}_unit' for k in range(1, 7)]
    + [f'estimated_{name}' for name in ('fx_n', 'fy_n', 'fz_n', 'mx_nm', 'my_nm', 'mz_nm')]
    + [f'estimate_sd_{name}' for name in ('fx_n', 'fy_n', 'fz_n', 'mx_nm', 'my_nm', 'mz_nm')]
    + ['estimate_flags'])


def verdict_cell(verdict: Optional[bool]) -> str:
    """Return a verdict as the CSV writes it: 'true', 'false', or '' (not assessed)."""
    return '' if verdict is None else str(bool(verdict)).lower()


def csv_row(cells: Mapping[str, Any]) -> List[Any]:
    """Return the row of ``cells`` (column name: value) in CSV_COLUMNS order, '' elsewhere."""
    unknown = set(cells) - set(CSV_COLUMNS)
    if unknown:
        raise ValueError(f'not CSV columns: {sorted(unknown)}')
    return [cells.get(name, '') for name in CSV_COLUMNS]


def wrench_row(index: int, raw: RawMessage, force: Iterable[float], moment: Iterable[float],
               frame_id: str, stamp_ns: int, outcome: Outcome) -> List[Any]:
    """Return the CSV row of wrench message ``index`` (empty cells where there is no value)."""
    cells: Dict[str, Any] = dict(zip(CSV_COLUMNS[:11], [
        index, raw.topic, stamp_ns, raw.log_time_ns, frame_id, *force, *moment]))
    result = outcome.result
    if result is None:
        cells.update(status=outcome.error.split(':')[0], message=outcome.error)
        return csv_row(cells)
    cells.update(status='solved' if result.converged else 'not converged',
                 message=result.message, iterations=result.iterations,
                 residual_norm=result.residual_norm, solve_time_ms=1e3 * result.solve_time_s,
                 fidelity=result.fidelity)
    if not result.converged:
        return csv_row(cells)
    cells.update(zip((f'{name}_rad' for name in messages.JOINT_NAMES),
                     messages.joint_positions(result)))
    cells.update(zip(('x_m', 'y_m', 'z_m', 'qx', 'qy', 'qz', 'qw'),
                     result.end_disk_position.tolist()
                     + result.end_disk_quaternion_xyzw.tolist()))
    compliance = getattr(result, 'compliance', None)
    # the solve's own stability verdict wins over the compliance's, as in SolveResult.to_dict
    stable = result.stable if result.stable is not None else (
        compliance.stable if compliance is not None else None)
    cells.update(stable=verdict_cell(stable), accuracy_met=verdict_cell(result.accuracy_met))
    if math.isfinite(result.error_estimate_m):
        cells['error_estimate_m'] = result.error_estimate_m
    if math.isfinite(result.error_estimate_deg):
        cells['error_estimate_rad'] = math.radians(result.error_estimate_deg)
    if compliance is not None:
        for k, (value, axis) in enumerate(zip(compliance.eigenvalues, compliance.labels), 1):
            cells[f'compliance_eigenvalue_{k}'] = float(value)
            cells[f'compliance_eigenvalue_{k}_axis'] = axis
            cells[f'compliance_eigenvalue_{k}_unit'] = EIGENVALUE_UNITS[axis.split()[0]]
    return csv_row(cells)


def pose_row(index: int, raw: RawMessage, stamp_ns: Optional[int], frame_id: str,
             estimate: Optional[WrenchEstimate], error: str) -> List[Any]:
    """
    Return the CSV row of measured pose ``index``: the node's estimate, or why none.

    ``estimate`` None: the pose was rejected (``error`` says why). Status 'estimated',
    'flagged' (converged, with reasons not to act on it, in ``estimate_flags``) or 'not
    converged'.
    """
    cells: Dict[str, Any] = {'index': index, 'topic': raw.topic, 'stamp_ns': stamp_ns,
                             'log_time_ns': raw.log_time_ns, 'frame_id': frame_id}
    if estimate is None:
        cells.update(status='rejected', message=error)
        return csv_row(cells)
    cells.update(
        status=('not converged' if not estimate.converged
                else 'flagged' if estimate.flagged else 'estimated'),
        message=estimate.message, iterations=estimate.iterations,
        residual_norm=estimate.residual_m, solve_time_ms=1e3 * estimate.estimate_time_s,
        stable=verdict_cell(estimate.stable), accuracy_met=verdict_cell(estimate.accuracy_met),
        estimate_flags='; '.join(estimate.flags))
    names = ('fx_n', 'fy_n', 'fz_n', 'mx_nm', 'my_nm', 'mz_nm')
    wrench = [float(value) for value in list(estimate.force) + list(estimate.moment)]
    cells.update({f'estimated_{name}': value for name, value in zip(names, wrench)})
    cells.update({f'estimate_sd_{name}': float(value) for name, value
                  in zip(names, estimate.standard_deviation) if math.isfinite(value)})
    if estimate.converged:
        cells.update(zip(('x_m', 'y_m', 'z_m', 'qx', 'qy', 'qz', 'qw'),
                         [float(value) for value in list(estimate.position)
                          + list(estimate.quaternion_xyzw)]))
    return csv_row(cells)
