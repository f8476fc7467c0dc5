"""
One row of a ``BatchResult`` read as the ``SolveResult`` of that wrench's single solve.

The node's outputs (``messages.iter_output_messages``), replay's CSV rows and summary read a
result's converged flag, message, iterations, residual, stability verdict and margin, error
estimate, compliance analysis and end-disk pose, and a follower load starts from the
end-disk rotation. ``BatchRow`` offers exactly those from the batch's columns, so that one
code path builds the outputs of a single solve and of a batch row alike.
"""

from typing import Any, Callable, Optional

import numpy as np

from .. import geometry
from ..analysis.compliance import ComplianceAnalysis
from ..solve.batch import BatchResult


def _column(name: str, read: Callable[[Any], Any], doc: str) -> Any:
    """Return a property reading ``read(batch.<name>[index])``."""
    def value(row: 'BatchRow') -> Any:
        return read(getattr(row.batch, name)[row.index])
    return property(value, doc=doc)


def _optional_bool(value: Any) -> Optional[bool]:
    """Return a plain bool, None kept."""
    return None if value is None else bool(value)


class BatchRow:
    """Row ``index`` of ``batch`` with the attributes of a single solve's result."""

    __slots__ = ('batch', 'index')

    def __init__(self, batch: BatchResult, index: int) -> None:
        """View row ``index`` of ``batch`` (nothing copied)."""
        self.batch, self.index = batch, index

    converged = _column('converged', bool, 'Whether the solve converged.')
    message = _column('solve_message', str, "The single solve's whole message.")
    iterations = _column('iterations', int, 'Iterations of the solve.')
    residual_norm = _column('residual_norm', float, 'Norm of the final residual.')
    solve_time_s = _column('solve_time_s', float, 'Solve time of the row (s).')
    method = _column('method', str, "The solver's method.")
    fidelity = _column('fidelity', str, 'The level that produced the row.')
    stable = _column('verdict', _optional_bool,
                     "The solve's own stability verdict (None: not judged).")
    stability_margin = _column('stability_margin', float,
                               'The margin of that verdict (NaN: none).')
    error_estimate_m = _column('error_estimate_m', float,
                               'Estimated end-disk position error (m; NaN: none).')
    error_estimate_deg = _column('error_estimate_deg', float,
                                 'Estimated angle error (deg; NaN: none).')
    accuracy_met = _column('accuracy_met', _optional_bool,
                           'Whether the estimate meets its target (None: none made).')
    steps_per_segment = _column('steps_per_segment', int,
                                "RK4 steps per disk interval of the row's error estimate.")
    force = _column('force', np.copy, 'The force solved for (N, base frame).')
    moment = _column('moment', np.copy, 'The moment solved for (N m, base frame).')
    end_disk_position = _column('end_disk_position', np.copy,
                                'Position of the end-disk centre (m).')
    end_disk_quaternion_xyzw = _column('end_disk_quaternion_xyzw', np.copy,
                                       'Orientation of the end disk: quaternion x, y, z, w.')
    end_disk_rotation_matrix = _column('end_disk_rotation', np.copy,
                                       'Rotation matrix of the end disk in the base frame.')
    pj_bending = _column('pj_bending', tuple, '(bending angle, direction) of the PJ (rad).')
    dj_bending = _column('dj_bending', tuple, '(bending angle, direction) of the DJ (rad).')

    @property
    def compliance(self) -> Optional['ComplianceAnalysis']:
        """Return the compliance analysis (None: not made)."""
        analysis: Optional['ComplianceAnalysis'] = self.batch.analysis[self.index]
        return analysis

    @property
    def end_disk_rotation(self) -> float:
        """Return the total rotation angle of the end disk relative to the base (rad)."""
        return geometry.rotation_angle(self.end_disk_rotation_matrix)
