"""
The paper's published numbers (Tables II and III), the acceptance data of this project.

Source: "Mobility Characteristics Analysis of a Dual-Continuum-Joint Translator",
Section IV.A, Table II. Forces in N, angles in degrees, deviations in mm.
"""

from dataclasses import dataclass
from typing import Tuple


@dataclass(frozen=True)
class TableIICase:
    """One column of Table II: a lateral force on the end disk and the deflection it gives."""

    force: Tuple[float, float, float]
    pj_bending_deg: float
    dj_bending_deg: float
    end_disk_rotation_deg: float
    max_arc_deviation_mm: float


TABLE_II = (
    TableIICase((12.0, 0.0, 0.0), 22.448, 22.063, 0.385, 0.016),
    TableIICase((20.0, 0.0, 0.0), 32.871, 31.982, 0.889, 0.012),
)

#: Acceptance tolerances of the reproduction (issue: bending angles 0.5 deg, rotation 0.2 deg).
TABLE_II_TOLERANCE_DEG = {'bending': 0.5, 'rotation': 0.2}
