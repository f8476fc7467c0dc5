"""
The paper's published numbers (Tables II and III), the acceptance data of this project.

Source: "Mobility Characteristics Analysis of a Dual-Continuum-Joint Translator",
Section IV.A, Table II (forces in N, angles in degrees, deviations in mm) and Section IV.B,
Table III (compliance in SI units).
"""

from dataclasses import dataclass
from typing import Dict, Tuple


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


@dataclass(frozen=True)
class TableIIICase:
    """
    One case of Table III: the compliance C (SI) the paper found, and the eigen-analysis.

    ``eigenvalues`` are the paper's xi of its thresholded C_s, listed under the label of the
    eigenvector they belong to; ``arc_direction`` is its eigenvector of the coupled
    translation x / translation z block (Gamma's first column, components x and z).
    """

    force: Tuple[float, float, float]
    compliance: Tuple[Tuple[float, ...], ...]
    eigenvalues: Dict[str, float]
    arc_direction: Tuple[float, float]


TABLE_III = (
    TableIIICase(
        (12.0, 0.0, 0.0),
        ((0.0046, -1.78e-6, -0.0017, -3.05e-5, -8.68e-4, -2.28e-4),
         (-6.41e-6, 0.0053, 6.77e-6, 3.31e-5, -7.98e-6, -3.16e-4),
         (-0.0018, -7.96e-6, 6.72e-4, 1.02e-5, 3.37e-4, 8.60e-5),
         (4.53e-5, 1.27e-4, -4.84e-5, 0.0093, 6.04e-5, 0.0077),
         (2.30e-4, -3.54e-5, -6.45e-4, -7.92e-4, 0.0019, -6.01e-4),
         (3.38e-4, -6.62e-4, -4.12e-4, 0.0112, 5.11e-4, 0.108)),
        {'translation x': 0.0053, 'translation y': 0.0053, 'translation z': 5.9247e-6,
         'rotation x': 0.0084, 'rotation y': 0.0019, 'rotation z': 0.1089},
        (0.9311, -0.3648)),
    TableIIICase(
        (20.0, 0.0, 0.0),
        ((0.0016, 8.22e-4, -0.001, -4.05e-4, 2.80e-4, -5.28e-4),
         (-1.05e-5, 0.0047, 3.16e-5, -6.55e-4, 1.38e-4, -2.06e-4),
         (-0.001, -4.29e-4, 6.54e-4, 7.42e-4, -1.39e-4, 3.50e-5),
         (-1.49e-6, -8.88e-6, 8.47e-7, 0.0130, -6.04e-5, 0.0095),
         (6.61e-6, 6.12e-5, -4.05e-6, -1.20e-4, 0.0015, -5.63e-4),
         (-6.36e-6, 4.06e-7, 4.38e-6, 0.0083, -1.05e-5, 0.148)),
        {'translation x': 0.0022, 'translation y': 0.0047, 'translation z': 2.0777e-5,
         'rotation x': 0.0124, 'rotation y': 0.0015, 'rotation z': 0.1486},
        (0.8449, -0.5350)),
)

#: Primary mobility the paper reads off Table III (its blue columns of Gamma).
PAPER_PRIMARY_MOBILITY = ('translation x', 'translation y', 'rotation z')
