"""
Layout of the translator's boundary-value problem: its unknowns, residuals and node states.

The paper's multi-rod problem (Section III.C, Eq. 7-11) in the sizes and offsets that the
shot (shooting.py), its tangent-linear Jacobian (tangent.py) and multiple shooting
(multiple_shooting_kernels.py) share. Rods: k = 0 the primary backbone, k = 1..4 the
secondaries at 0/90/180/270 deg on the pitch circle; everything in the base frame {pe}.

Unknowns ``x`` (SI), for S spacer disks per joint and ``nst = 2 S + 1`` stations:
  x[6k:6k+3], x[6k+3:6k+6]   n_k(0), m_k(0) of rod k at the base disk (30 values);
  x[30 + 5 (i nst + t) + c]  secondary i (0..3) at station t (0..nst-1):
        c = 0      material length of the segment that ends at station t;
        c = 1, 2   in-plane reaction force (disk x, y) applied there;
        c = 3, 4   in-plane reaction moment (disk x, y) applied there.
Stations t < S are PJ spacer disks, t = S the tube's proximal face (its reaction is the
in-plane wrench the lumen hands back at the distal face), t > S the DJ spacer disks.

Residuals ``out`` (SI), as many as unknowns (30 + 20 nst):
  out[5 (i nst + t) + c]  at station t: c = 0, 1 hole offset in the disk plane (Eq. 7),
        c = 2 offset normal to the disk (Eq. 8), c = 3, 4 tilt of the secondary's tangent
        in the disk frame (zero exactly when R_0^T R_i is a pure twist, as Eq. 7 asks);
  out[20 nst + 6 i + c]   end-disk clamp of secondary i: position (3), orientation (3) (Eq. 10);
  out[20 nst + 24 + c]    end-disk equilibrium, force (3) then moment about its centre (3)
                          (Eq. 11).

The exact Jacobian's tangent columns (tangent.py) go station by station instead
(``internal_columns``): the base unknowns, the lifted column of multiple shooting
(``LIFT_COLUMN``), then the stations' unknowns, station 0's 20 first.
"""

import numpy as np

from .._jit import jit

N_RODS = 5
N_BASE_UNKNOWNS = 6 * N_RODS
STATION_WIDTH = 5

#: Layout of a node state (multiple shooting, multiple_shooting.py): the rods' state where a
#: disk interval starts, all SI in {pe}: p (5 x 3), R (5 x 3 x 3, row-major), n, m (5 x 3
#: each) and the material length of each secondary used so far (4).
STATE_P = 0
STATE_ROT = 3 * N_RODS
STATE_N = 12 * N_RODS
STATE_M = 15 * N_RODS
STATE_USED = 18 * N_RODS
STATE_SIZE = 18 * N_RODS + 4

#: What a shot does at the start of each disk interval after the first (``nodes`` argument):
#: nothing (single shooting), start from the given node state and write the defect (carried
#: minus node state: multiple shooting), or record the carried state as the node.
NO_NODES = 0
LIFT_NODES = 1
RECORD_NODES = 2


def station_count(spacers_per_joint: int) -> int:
    """Stations per secondary: the spacer disks of both joints and the tube's proximal face."""
    return 2 * spacers_per_joint + 1


def unknown_count(spacers_per_joint: int) -> int:
    """Size of the unknown vector (and of the residual vector)."""
    return N_BASE_UNKNOWNS + 4 * STATION_WIDTH * station_count(spacers_per_joint)


def interval_count(spacers_per_joint: int) -> int:
    """Disk intervals of one shot (two joints of S + 1 each); nodes start all but the first."""
    return 2 * (spacers_per_joint + 1)


def grid_points_per_rod(spacers_per_joint: int, steps: int) -> int:
    """Rows of centre-line points recorded per rod (each disk interval has steps + 1)."""
    return 2 * (spacers_per_joint + 1) * (steps + 1)


#: Tangent column of the lifted direction (between the base unknowns and the stations').
LIFT_COLUMN = N_BASE_UNKNOWNS


@jit
def internal_columns(size, nst):
    """
    Return the unknown of each tangent column (size + 1 of them; the lifted one is ``size``).

    Base unknowns, the lifted column, then station by station.
    """
    order = np.empty(size + 1, dtype=np.int64)
    for q in range(N_BASE_UNKNOWNS):
        order[q] = q
    order[LIFT_COLUMN] = size
    for t in range(nst):
        for i in range(4):
            for c in range(STATION_WIDTH):
                order[station_column(t, i) + c] = (N_BASE_UNKNOWNS
                                                   + STATION_WIDTH * (i * nst + t) + c)
    return order


@jit
def station_column(t, i):
    """Tangent column of secondary i's first unknown at station t (see internal_columns)."""
    return LIFT_COLUMN + 1 + STATION_WIDTH * (4 * t + i)
