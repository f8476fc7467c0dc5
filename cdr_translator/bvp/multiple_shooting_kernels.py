"""
The node states of multiple shooting and their lifted Newton update (numba kernels).

A node is the rods' state where a disk interval starts (layout.STATE_*): the shot
(shooting.shoot_with_nodes) records the state it carries there, or restarts the interval
from the node and writes the defect; its tangent-linear form (tangent.lifted_jacobian)
records the node tangents and seeds the lifted column. The lifted column (layout.LIFT_COLUMN)
is the condensing direction of the lifted Newton method (Albersmeyer & Diehl, SIAM J.
Optim. 20(3), 2010; multiple_shooting.py): zero at the base, it gains each node's defect
where the node replaces the carried state (a_t = L a_{t-1} + d_t), so its Jacobian column
is R_z a, the residual change that the defects' Newton corrections cause. Without nodes it
stays zero. A node holds the rods' state of the paper's Eq. 6 (p, R, n, m; Section III),
so the nodes change how Newton reaches the solution of Eq. 7-11, not the solution.
"""

import numpy as np

from .layout import (internal_columns, LIFT_COLUMN, N_RODS, RECORD_NODES, STATE_M, STATE_N,
                     STATE_P, STATE_ROT, STATE_SIZE, STATE_USED, station_column)
from .._jit import jit, jit_inline


@jit_inline
def _enter(mode, node, defect, index, value):
    """One state value at a node: record it, or return the node's and write the defect."""
    if mode == RECORD_NODES:
        node[index] = value
        defect[index] = 0.0
        return value
    defect[index] = value - node[index]
    return node[index]


@jit
def enter_node(mode, node, defect, p, rot, n, m, used):
    """
    Apply a node at the start of a disk interval (mode LIFT_NODES or RECORD_NODES).

    LIFT_NODES replaces the carried state (p, rot, n, m, used) by ``node`` and writes
    ``defect`` = carried - node; RECORD_NODES writes the carried state into ``node`` (defect
    zero). Layout: the STATE_* offsets.
    """
    for k in range(N_RODS):
        for c in range(3):
            p[k, c] = _enter(mode, node, defect, STATE_P + 3 * k + c, p[k, c])
            n[k, c] = _enter(mode, node, defect, STATE_N + 3 * k + c, n[k, c])
            m[k, c] = _enter(mode, node, defect, STATE_M + 3 * k + c, m[k, c])
            for b in range(3):
                rot[k, c, b] = _enter(mode, node, defect, STATE_ROT + 9 * k + 3 * c + b,
                                      rot[k, c, b])
    for i in range(4):
        used[i] = _enter(mode, node, defect, STATE_USED + i, used[i])


@jit
def record_node_tangents(tp, trot, tn, tm, tused, out, live):
    """Copy the state's tangents (columns < live, tangent-column order) in STATE_* layout."""
    for k in range(N_RODS):
        for c in range(3):
            for d in range(live):
                out[STATE_P + 3 * k + c, d] = tp[k, c, d]
            for d in range(live):
                out[STATE_N + 3 * k + c, d] = tn[k, c, d]
            for d in range(live):
                out[STATE_M + 3 * k + c, d] = tm[k, c, d]
            for b in range(3):
                for d in range(live):
                    out[STATE_ROT + 9 * k + 3 * c + b, d] = trot[k, c, b, d]
    for i in range(4):
        for d in range(live):
            out[STATE_USED + i, d] = tused[i, d]


@jit
def seed_defect(defect, tp, trot, tn, tm, tused):
    """Add a node's defect to the lifted column of the state's tangents (a_t += d_t)."""
    q = LIFT_COLUMN
    for k in range(N_RODS):
        for c in range(3):
            tp[k, c, q] += defect[STATE_P + 3 * k + c]
            tn[k, c, q] += defect[STATE_N + 3 * k + c]
            tm[k, c, q] += defect[STATE_M + 3 * k + c]
            for b in range(3):
                trot[k, c, b, q] += defect[STATE_ROT + 9 * k + 3 * c + b]
    for i in range(4):
        tused[i, q] += defect[STATE_USED + i]


@jit
def _orthonormalize(rot):
    """
    Replace the 3x3 ``rot`` by its orthogonal polar factor, in place (Newton's iteration).

    X <- (X + X^-T) / 2 converges quadratically to the nearest rotation from a near one
    (Higham, Functions of Matrices, SIAM 2008, Sec. 8.3); cof(X) / det(X) is X^-T.
    """
    cof = np.empty((3, 3))
    for _ in range(8):
        for a in range(3):
            a1 = (a + 1) % 3
            a2 = (a + 2) % 3
            for b in range(3):
                b1 = (b + 1) % 3
                b2 = (b + 2) % 3
                cof[a, b] = rot[a1, b1] * rot[a2, b2] - rot[a1, b2] * rot[a2, b1]
        det = rot[0, 0] * cof[0, 0] + rot[0, 1] * cof[0, 1] + rot[0, 2] * cof[0, 2]
        change = 0.0
        for a in range(3):
            for b in range(3):
                new = 0.5 * (rot[a, b] + cof[a, b] / det)
                change = max(change, abs(new - rot[a, b]))
                rot[a, b] = new
        if change <= 1e-15:
            return


#: A node rotation R with max |R^T R - I| above this is projected onto SO(3) after an update
#: (a long Newton step far from the solution). Smaller departures are left as Newton made
#: them: the carried rotations themselves are orthogonal only to the RK4 error (above 1e-7
#: at nine spacer disks and 13 N), and projecting those left defects of that size that
#: Newton could never remove (the iteration stalled at residuals of 1.8e-7).
ORTHOGONALITY_SLACK = 1e-3


@jit
def advance_nodes(nodes, node_tangents, step, spacers, slack):
    """
    Update the nodes as lifted Newton does: z_t += w a_t + Z_t dx, rotations projected.

    ``node_tangents`` as ``lifted_jacobian`` wrote them; ``step`` (size + 1) holds dx, the
    step of the unknowns (SI, unknowns' order), then the weight w of the lifted column. The
    update is linear in the 9 entries of each rotation; one that
    leaves it further than ``slack`` (max |R^T R - I|, e.g. ORTHOGONALITY_SLACK) from
    orthogonal is put back onto SO(3) by its polar factor (``_orthonormalize``).
    """
    size = step.shape[0] - 1
    order = internal_columns(size, 2 * spacers + 1)
    internal = np.empty(size + 1)
    for d in range(size + 1):
        internal[d] = step[order[d]]
    rot = np.empty((3, 3))
    for j in range(nodes.shape[0]):
        live = station_column(j + 1, 0)
        for r in range(STATE_SIZE):
            acc = 0.0
            for d in range(live):
                acc += node_tangents[j, r, d] * internal[d]
            nodes[j, r] += acc
        for k in range(N_RODS):
            for a in range(3):
                for b in range(3):
                    rot[a, b] = nodes[j, STATE_ROT + 9 * k + 3 * a + b]
            departure = 0.0
            for a in range(3):
                for b in range(3):
                    gram = rot[0, a] * rot[0, b] + rot[1, a] * rot[1, b] + rot[2, a] * rot[2, b]
                    departure = max(departure, abs(gram - (1.0 if a == b else 0.0)))
            if departure <= slack:
                continue
            _orthonormalize(rot)
            for a in range(3):
                for b in range(3):
                    nodes[j, STATE_ROT + 9 * k + 3 * a + b] = rot[a, b]
