"""
The translator kernel bound to one parameter set, in nondimensional coordinates.

Unknowns are divided by natural scales (disk spacing D for lengths, EI/D^2 for forces,
EI/D for moments) and residuals likewise (D for positions, 1 for angles), so that one
tolerance and one finite-difference step suit every component.
"""

from types import ModuleType
from typing import Mapping, Optional, Tuple

import numpy as np

from . import chord, layout, multiple_shooting_kernels, shooting, tangent
from .rod import inverse_stiffness
from ..params.translator_params import TranslatorParams

#: Residual kinds, in the order of ``Problem.residual_kind`` codes.
RESIDUAL_KINDS = ('position_m', 'orientation_rad', 'force_n', 'moment_nm')

#: Forward-difference step in nondimensional unknowns. Smaller than sqrt(machine epsilon)
#: because the residual's curvature grows by orders of magnitude at large loads (a
#: secondary near local buckling): at 250 N lateral a 1e-7 step made the Jacobian so
#: wrong that Newton converged only linearly (factor 0.25) and continuation stalled;
#: 1e-9 keeps Newton quadratic there and costs ~1e-6 relative rounding at small loads.
FD_STEP = 1e-9

#: Broyden updates kept on one factorization at most; more are not gathered (a chord step
#: that converges too slowly then rebuilds the Jacobian, which starts afresh).
MAX_SECANT_UPDATES = 24

#: Ways to compute the Jacobian: 'exact' (tangent-linear shot, tangent.translator_jacobian)
#: or 'fd' (forward differences, one shot per unknown: the paper's way and the check).
JACOBIANS = ('exact', 'fd')

#: The compiled kernel modules a Problem calls, by the short names of
#: _jit.interpreted_kernels.
COMPILED_KERNELS: Mapping[str, ModuleType] = {
    'shooting': shooting, 'tangent': tangent,
    'multiple_shooting_kernels': multiple_shooting_kernels}


class Problem:
    """Residual, Jacobian and shape of the translator for fixed parameters."""

    def __init__(self, params: TranslatorParams,
                 kernels: Optional[Mapping[str, ModuleType]] = None,
                 jacobian: str = 'exact') -> None:
        """
        Bind the kernel modules to params: the compiled ones, or ``kernels`` instead.

        ``kernels`` maps the short names of shooting, tangent and multiple_shooting_kernels
        to modules, as _jit.interpreted_kernels returns them (the interpreted copies).
        ``jacobian`` is one of JACOBIANS: how ``jacobian()`` differentiates the residual.
        """
        if jacobian not in JACOBIANS:
            raise ValueError(f'jacobian must be one of {JACOBIANS}, got {jacobian!r}')
        self.jacobian_method = jacobian
        self.params = params
        if kernels is None:
            kernels = COMPILED_KERNELS
        self.shooting = kernels['shooting']
        self.tangent = kernels['tangent']
        self.node_kernels = kernels['multiple_shooting_kernels']
        spacers = params.spacers_per_joint
        self.size = layout.unknown_count(spacers)
        self.stations = layout.station_count(spacers)
        inv_kse, inv_kbt = inverse_stiffness(params.youngs_modulus, params.shear_modulus,
                                             params.backbone_diameter)
        self._args = (float(params.pitch_radius), float(params.disk_spacing),
                      float(params.tube_length), spacers, params.steps_per_segment,
                      inv_kse, inv_kbt)
        length = params.disk_spacing
        force = params.bending_stiffness / length ** 2
        moment = params.bending_stiffness / length
        x_scale = np.empty(self.size)
        kind = np.empty(self.size, dtype=np.int64)
        for rod in range(layout.N_RODS):
            x_scale[6 * rod:6 * rod + 3] = force
            x_scale[6 * rod + 3:6 * rod + 6] = moment
        station_x = np.array([length, force, force, moment, moment])
        station_kind = np.array([0, 0, 0, 1, 1])
        width = layout.STATION_WIDTH
        n_station_values = 4 * width * self.stations
        x_scale[layout.N_BASE_UNKNOWNS:] = np.tile(station_x, 4 * self.stations)
        kind[:n_station_values] = np.tile(station_kind, 4 * self.stations)
        kind[n_station_values:n_station_values + 24] = np.tile([0, 0, 0, 1, 1, 1], 4)
        kind[n_station_values + 24:] = [2, 2, 2, 3, 3, 3]
        self.x_scale = x_scale
        self.residual_kind = kind
        self.residual_scale = np.array([length, 1.0, force, moment])[kind]
        # the rows grouped by kind (every kind has rows), for one reduction in residual_by_kind
        self._kind_order = np.argsort(kind, kind='stable')
        self._kind_starts = np.searchsorted(kind[self._kind_order],
                                            np.arange(len(RESIDUAL_KINDS)))
        self._kind_scale = self.residual_scale[self._kind_order]
        self.wrench_scale = np.repeat([force, moment], 3)
        #: rows of the end-disk equilibrium, the only residuals the applied wrench enters
        self.wrench_rows = np.arange(self.size - 6, self.size)
        #: d(residual)/d(wrench), nondimensional: the wrench enters Eq. 11 linearly
        self.wrench_sensitivity = np.zeros((self.size, 6))
        self.wrench_sensitivity[self.wrench_rows, np.arange(6)] = \
            1.0 / self.residual_scale[self.wrench_rows]
        self._wrench_gain = self.wrench_sensitivity[self.wrench_rows, np.arange(6)]
        #: x_scale over residual_scale, and wrench_scale over the wrench's gain on its rows
        #: (the diagonal of wrench_sensitivity there): as compiled callers take them
        self.scales = np.stack([self.x_scale, self.residual_scale])
        self.wrench_factors = np.stack([self.wrench_scale, self._wrench_gain])
        #: node states of multiple shooting (multiple_shooting.py): one per disk interval
        #: after the first
        self.node_count = layout.interval_count(spacers) - 1
        node_scale = np.empty(layout.STATE_SIZE)
        node_scale[layout.STATE_P:layout.STATE_ROT] = length
        node_scale[layout.STATE_ROT:layout.STATE_N] = 1.0
        node_scale[layout.STATE_N:layout.STATE_M] = force
        node_scale[layout.STATE_M:layout.STATE_USED] = moment
        node_scale[layout.STATE_USED:] = length
        #: natural scale of each node-state value (SI per nondimensional unit)
        self.node_scale = node_scale
        #: departure from orthogonality beyond which a node rotation is projected
        self.orthogonality_slack = multiple_shooting_kernels.ORTHOGONALITY_SLACK
        #: node tangents (Z_t and a_t, see tangent.lifted_jacobian) of the last lifted_jacobian:
        #: a new array each call, so that a caller may keep one with its factorization
        self.node_tangents = np.empty((self.node_count, layout.STATE_SIZE, self.size + 1))
        self._lifted = np.empty(self.size)
        self._no_points = np.empty((layout.N_RODS, 0, 3))
        self._frames = np.empty((4, 4, 4))
        self._jacobian = np.empty((self.size, self.size))
        self._step = FD_STEP * x_scale
        self._pose_jacobian = np.empty((12, self.size))
        #: derivative of the end-disk frame {de} (centre, then rotation matrix row-major;
        #: SI per nondimensional unknown) at the last Jacobian, or None
        self.pose_jacobian: Optional[np.ndarray] = None
        rows = layout.grid_points_per_rod(spacers, params.steps_per_segment)
        #: two shape buffers (centre lines, frames) that chord_newton's shots alternate on
        self.shape_points = np.empty((2, layout.N_RODS, rows, 3))
        self.shape_frames = np.empty((2, 4, 4, 4))
        #: Broyden updates (chord.broyden_apply's u_i and s_i) on the factorization they
        #: were gathered on, and how many: (factorization or None, count)
        self.secant_updates = np.empty((MAX_SECANT_UPDATES, self.size))
        self.secant_steps = np.empty((MAX_SECANT_UPDATES, self.size))
        self._secant: Tuple[Optional[tuple], int] = (None, 0)

    @property
    def model_args(self) -> tuple:
        """Return the kernel's parameter arguments (shooting.translator_residual, after wrench)."""
        return self._args

    def residual(self, xs: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Nondimensional residual at nondimensional unknowns ``xs``."""
        out = np.empty(self.size)
        self.shooting.translator_residual(xs * self.x_scale, wrench, *self._args, out,
                                          self._no_points, self._frames)
        return out / self.residual_scale

    def residual_and_end_frame(self, xs: np.ndarray,
                               wrench: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Nondimensional residual and the end-disk frame {de} (4x4, SI) from one shot."""
        out = np.empty(self.size)
        frames = np.empty((4, 4, 4))
        self.shooting.translator_residual(xs * self.x_scale, wrench, *self._args, out,
                                          self._no_points, frames)
        return out / self.residual_scale, frames[3]

    def jacobian(self, xs: np.ndarray, wrench: np.ndarray, rs: np.ndarray) -> np.ndarray:
        """
        Nondimensional Jacobian at ``xs`` (``rs`` = residual there), by ``jacobian_method``.

        Both also set ``pose_jacobian`` (the end-disk frame's derivative, the same way).
        """
        if self.jacobian_method == 'exact':
            return self.exact_jacobian(xs, wrench)[1]
        self.shooting.residual_jacobian(xs * self.x_scale, self._step, wrench, *self._args,
                                        rs * self.residual_scale, self._jacobian,
                                        self._pose_jacobian)
        self.pose_jacobian = self._pose_jacobian * self.x_scale
        return self._jacobian * (self.x_scale / self.residual_scale[:, None])

    def exact_jacobian(self, xs: np.ndarray,
                       wrench: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Residual, exact Jacobian and end-disk pose Jacobian from one tangent-linear shot.

        All nondimensional in the unknowns; the residual and Jacobian rows nondimensional too,
        the pose Jacobian's rows SI (m, and rotation-matrix entries). The Jacobian is the
        derivative of the discretized residual (tangent.translator_jacobian), so Newton is
        quadratic up to rounding however curved the residual is.
        """
        out = np.empty(self.size)
        self.tangent.translator_jacobian(xs * self.x_scale, wrench, *self._args, out,
                                         self._jacobian, self._pose_jacobian, self._frames)
        self.pose_jacobian = self._pose_jacobian * self.x_scale
        return (out / self.residual_scale,
                self._jacobian * (self.x_scale / self.residual_scale[:, None]),
                self.pose_jacobian)

    def node_states(self, xs: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Return the node states (node_count, layout.STATE_SIZE; SI) single shooting carries."""
        nodes = np.empty((self.node_count, layout.STATE_SIZE))
        out = np.empty(self.size)
        self.shooting.shoot_with_nodes(xs * self.x_scale, wrench, *self._args, out,
                                       self._no_points, self._frames, layout.RECORD_NODES, nodes,
                                       np.empty_like(nodes))
        return nodes

    def lifted_residual(self, xs: np.ndarray, nodes: np.ndarray,
                        wrench: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Nondimensional residual and node defects of multiple shooting from ``nodes`` (SI)."""
        out = np.empty(self.size)
        defects = np.empty_like(nodes)
        self.shooting.shoot_with_nodes(xs * self.x_scale, wrench, *self._args, out,
                                       self._no_points, self._frames, layout.LIFT_NODES, nodes,
                                       defects)
        return out / self.residual_scale, defects / self.node_scale

    def lifted_jacobian(self, xs: np.ndarray, nodes: np.ndarray, wrench: np.ndarray
                        ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """
        Multiple shooting from ``nodes``: residual, defects, condensed Jacobian, lifted column.

        All nondimensional (defects in ``node_scale`` units). The Jacobian is that of the
        residual with the nodes following the unknowns (dz_t = Z_t dx), the single-shooting
        one when the defects are zero; the lifted column is R_z a (layout.LIFT_COLUMN). The
        node tangents go to ``node_tangents`` (for ``advance_nodes``); ``pose_jacobian`` is
        set.
        """
        self.node_tangents = np.empty((self.node_count, layout.STATE_SIZE, self.size + 1))
        out = np.empty(self.size)
        defects = np.empty_like(nodes)
        self.tangent.lifted_jacobian(xs * self.x_scale, wrench, *self._args, out,
                                     self._jacobian, self._pose_jacobian, self._frames,
                                     layout.LIFT_NODES, nodes, defects, self._lifted,
                                     self.node_tangents)
        self.pose_jacobian = self._pose_jacobian * self.x_scale
        return (out / self.residual_scale, defects / self.node_scale,
                self._jacobian * (self.x_scale / self.residual_scale[:, None]),
                self._lifted / self.residual_scale)

    def advance_nodes(self, nodes: np.ndarray, dxs: np.ndarray, defects: float = 1.0,
                      tangents: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return nodes + defects a + Z dxs (rotations projected): the lifted Newton update.

        ``dxs`` is the nondimensional step of the unknowns; a and Z are the ``tangents``
        (default: the last ``lifted_jacobian``'s, ``node_tangents``). With ``defects`` 0 it
        is the first-order prediction of the nodes alone.
        """
        advanced = nodes.copy()
        step = np.append(dxs * self.x_scale, defects)
        self.node_kernels.advance_nodes(advanced,
                                        self.node_tangents if tangents is None else tangents,
                                        step, self.params.spacers_per_joint,
                                        self.orthogonality_slack)
        return advanced

    def residual_and_shape(self, xs: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Nondimensional residual at ``xs``; its shape goes to slot 0 (``recorded_shape``)."""
        out = np.empty(self.size)
        self.shooting.translator_residual(xs * self.x_scale, wrench, *self._args, out,
                                          self.shape_points[0], self.shape_frames[0])
        return out / self.residual_scale

    def chord_newton(self, xs: np.ndarray, rs: np.ndarray, wrench: np.ndarray, lu: tuple,
                     fresh: bool, tolerance: float, max_iterations: int, chord_rate: float,
                     slot: int, shoot: bool = False) -> Tuple[int, int, float, int]:
        """
        Newton-Broyden iterations on the factorization ``lu`` in one compiled call (chord.py).

        ``xs``, ``rs`` (nondimensional, residual at xs) are updated in place; the shape of
        the accepted iterate is in ``recorded_shape(slot)`` for the slot returned, the
        shape of ``xs`` on entry being in ``slot``. With ``shoot`` the call first computes
        the residual at ``xs`` itself (``rs`` is only written, its shape goes to ``slot``):
        no separate ``residual_and_shape`` shot. The Broyden updates gathered on ``lu``
        are kept for the next call on the same factorization (``inverse_apply``). Returns
        (status, iterations, residual norm, slot); status is one of chord's codes.
        """
        count = self.secant_count(lu)
        status, done, norm, slot, count = chord.chord_iterations(
            xs, rs, wrench, self.x_scale, self.residual_scale, self._args, lu[0], lu[1],
            self.secant_updates, self.secant_steps, count, fresh, tolerance, max_iterations,
            chord_rate, self.shape_points, self.shape_frames, slot, shoot)
        self.keep_secant_count(lu, int(count))
        return int(status), int(done), float(norm), int(slot)

    def wrench_response(self, lu: tuple, change: np.ndarray) -> np.ndarray:
        """
        Return J^-1 (dr/dw) ``change``: the first-order change of the unknowns, negated.

        ``change`` is a wrench change (SI); J^-1 is ``inverse_apply``'s. The same as
        ``inverse_apply(lu, wrench_sensitivity @ change)``, without the product with a
        matrix that has one entry per column.
        """
        rhs = np.zeros(self.size)
        rhs[self.wrench_rows] = self._wrench_gain * change
        return self.inverse_apply(lu, rhs)

    def extrapolate(self, lu: tuple, path_xs: np.ndarray, path_wrenches: np.ndarray,
                    count: int, wrench: np.ndarray,
                    miss_limit: float) -> Optional[np.ndarray]:
        """
        Return the unknowns at ``wrench`` extrapolated from ``count`` solutions, or None.

        chord.extrapolate: the first ``count`` (3 to chord.PATH_LENGTH) rows of ``path_xs``
        (nondimensional) and ``path_wrenches`` (SI) along a path, oldest first, extrapolated
        by a polynomial in its length; the miss corrected to first order with ``lu`` and its
        Broyden updates. None when ``wrench`` does not continue the path.
        """
        out = np.empty(self.size)
        if not chord.extrapolate(path_xs, path_wrenches, count, wrench, self.wrench_scale,
                                 self._wrench_gain, self.wrench_rows, lu[0], lu[1],
                                 self.secant_updates, self.secant_steps,
                                 self.secant_count(lu), miss_limit, out):
            return None
        return out

    def inverse_apply(self, lu: tuple, rhs: np.ndarray) -> np.ndarray:
        """Return J^-1 rhs for the factorization ``lu`` and its Broyden updates so far."""
        out = np.empty(self.size)
        chord.broyden_apply(lu[0], lu[1], self.secant_updates, self.secant_steps,
                            self.secant_count(lu), np.ascontiguousarray(rhs, dtype=float), out)
        return out

    def secant_count(self, lu: tuple) -> int:
        """Return the Broyden updates valid on ``lu``: none for another factorization."""
        bound, count = self._secant
        return count if bound is lu else 0

    def keep_secant_count(self, lu: tuple, count: int) -> None:
        """Record that the first ``count`` rows of the Broyden updates belong to ``lu``."""
        self._secant = (lu, count)

    def recorded_shape(self, slot: int) -> Tuple[np.ndarray, np.ndarray]:
        """Return copies of the centre lines (5, rows, 3) and frames (4, 4, 4) in ``slot``."""
        return self.shape_points[slot].copy(), self.shape_frames[slot].copy()

    def shot_with_steps(self, xs: np.ndarray, wrench: np.ndarray,
                        steps: int) -> Tuple[np.ndarray, np.ndarray]:
        """Nondimensional residual and frames (4, 4, 4) at ``steps`` RK4 steps per interval."""
        out = np.empty(self.size)
        frames = np.empty((4, 4, 4))
        args = self._args[:4] + (steps,) + self._args[5:]
        self.shooting.translator_residual(xs * self.x_scale, wrench, *args, out,
                                          self._no_points, frames)
        return out / self.residual_scale, frames

    def shape(self, xs: np.ndarray, wrench: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Centre-line points (5, rows, 3) and frames (4, 4, 4) at ``xs``."""
        rows = layout.grid_points_per_rod(self.params.spacers_per_joint,
                                          self.params.steps_per_segment)
        points = np.empty((layout.N_RODS, rows, 3))
        frames = np.empty((4, 4, 4))
        out = np.empty(self.size)
        self.shooting.translator_residual(xs * self.x_scale, wrench, *self._args, out, points,
                                          frames)
        return points, frames

    def residual_by_kind(self, rs: np.ndarray) -> dict:
        """Largest absolute residual of each kind, in SI units."""
        si = np.abs(rs[self._kind_order] * self._kind_scale)
        return dict(zip(RESIDUAL_KINDS, np.maximum.reduceat(si, self._kind_starts).tolist()))

    def straight_guess(self, wrench: np.ndarray) -> np.ndarray:
        """Unloaded shape with the whole wrench carried by the primary backbone."""
        x = np.zeros(self.size)
        for i in range(4):
            for t in range(self.stations):
                x[layout.N_BASE_UNKNOWNS + layout.STATION_WIDTH * (i * self.stations + t)] = \
                    self.params.disk_spacing
        height = self.params.stack_height
        force = wrench[:3]
        x[0:3] = force
        x[3:6] = wrench[3:] + np.cross([0.0, 0.0, height], force)
        return x / self.x_scale
