"""
The reduced models ('cc', 'rod') bound to parameters: warm-started solves and shapes.

Each solve is a load continuation from the previous solution (or the unloaded one), like the
full solver's: Newton (compiled, ``newton.continue_to``) straight to the requested wrench,
halving the step on failure. The factorized Jacobian of the last solve is kept for chord
steps.
"""

from dataclasses import dataclass
import time
from typing import Dict, Optional, Tuple

import numpy as np

from . import cc, equivalent_rod, level_kernels, newton
from ..params.translator_params import TranslatorParams

#: Default RK4 steps per disk interval of the 'rod' model.
ROD_STEPS = 2

_OUTCOMES = {newton.NO_CONVERGENCE: 'no convergence in {} iterations',
             newton.NO_DECREASE: 'line search found no decrease of the residual',
             newton.NOT_FINITE: 'residual became non-finite',
             newton.SINGULAR: 'singular Jacobian'}


@dataclass
class ReducedOutcome:
    """Where a reduced solve ended: unknowns (nondimensional), residual, iterations, why."""

    x: np.ndarray
    rs: np.ndarray
    iterations: int
    converged: bool
    message: str


class ReducedModel:
    """One reduced model of the translator; ``constant_curvature`` or ``equivalent_rod``."""

    def __init__(self, name: str, code: int, data: np.ndarray, size: int,
                 unknown_scale: np.ndarray, residual_scale: Dict[str, np.ndarray],
                 points_per_interval: int, spacers: int, tolerance: float,
                 max_iterations: int) -> None:
        """
        Bind compiled kernel ``code`` (``newton.CC`` / ``newton.ROD``) to its data vector.

        ``unknown_scale`` turns nondimensional unknowns into SI; ``residual_scale`` maps each
        residual kind of SolveResult.residual_by_type to the per-row factor into SI (zero
        for rows of another kind).
        """
        self.name = name
        self.code = code
        self.size = size
        self.unknown_scale = unknown_scale
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self._data = data
        self._residual_scale = residual_scale
        self._points_per_interval = points_per_interval
        self._spacers = spacers
        self._lu = np.empty((size, size))
        self._pivots = np.zeros(size + 1, dtype=np.int64)  # [size]: whether _lu is usable
        # load the compiled kernels (and numba's LAPACK binding) now, not inside the first
        # solve: that takes 10-30 ms once; a tiny load makes Newton factorize a Jacobian
        small = np.array([1e-3, 0.0, 0.0, 0.0, 0.0, 0.0])
        warmed = self.solve(small, None, time.perf_counter() + 60.0).x
        self.frames(warmed, small)
        self.points(warmed, small)
        self._pivots[size] = 0

    @classmethod
    def constant_curvature(cls, params: TranslatorParams, tolerance: float = 1e-9,
                           max_iterations: int = 20) -> 'ReducedModel':
        """Return the 'cc' model (see ``fidelity.cc``); arcs drawn with the full model's steps."""
        length = params.joint_length
        ei = params.bending_stiffness
        moments = np.r_[np.ones(6), np.zeros(2)] * ei / length
        forces = np.r_[np.zeros(6), np.ones(2)] * ei / length ** 2
        return cls('cc', newton.CC, cc.model_data(params), cc.SIZE,
                   np.r_[np.ones(6), length, length], {'moment_nm': moments, 'force_n': forces},
                   params.steps_per_segment, params.spacers_per_joint, tolerance, max_iterations)

    @classmethod
    def equivalent_rod(cls, params: TranslatorParams, steps: int = ROD_STEPS,
                       tolerance: float = 1e-9, max_iterations: int = 20) -> 'ReducedModel':
        """Return the 'rod' model (see ``fidelity.equivalent_rod``), ``steps`` per interval."""
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise ValueError(f'rod steps must be an integer >= 1, got {steps!r}')
        length = params.joint_length
        ei = params.bending_stiffness
        moments = np.r_[np.ones(3), np.zeros(4)] * ei / length
        lengths = np.r_[np.zeros(3), np.ones(4)] * length
        return cls('rod', newton.ROD, equivalent_rod.model_data(params, steps),
                   equivalent_rod.SIZE, np.r_[np.ones(3) * ei / length,
                                              np.ones(4) * ei / length ** 2],
                   {'moment_nm': moments, 'position_m': lengths}, steps,
                   params.spacers_per_joint, tolerance, max_iterations)

    def solve(self, wrench: np.ndarray, start: Optional[Tuple[np.ndarray, np.ndarray]],
              deadline: float) -> ReducedOutcome:
        """
        Continue from ``start`` = (unknowns, wrench) (None: unloaded) to ``wrench``.

        A step that fails is halved; below newton.MIN_CONTINUATION_STEP the outcome is the last
        converged state, not converged. ``deadline`` (perf_counter seconds) already past
        makes the solve fail at once; a compiled continuation is bounded by its smallest
        step instead (a few ms at worst).
        """
        if start is None:
            start = (np.zeros(self.size), np.zeros(6))
            self._pivots[self.size] = 0
        x = start[0].copy()
        rs = np.empty(self.size)
        if time.perf_counter() > deadline:
            self._data[:6] = wrench
            newton.residual(self.code, x, self._data, rs)
            return ReducedOutcome(x, rs, 0, False, f'{self.name}: no time left for the solve')
        _, iterations, code, reached = newton.continue_to(
            self.code, x, self._data, np.asarray(start[1], dtype=float), wrench,
            self.tolerance, self.max_iterations, rs, self._lu, self._pivots)
        if code != newton.CONVERGED:
            message = _OUTCOMES[code].format(self.max_iterations)
            return ReducedOutcome(x, rs, iterations, False,
                                  f'{self.name} continuation stalled at {reached:.1%} of the '
                                  f'way to the wrench: {message}')
        return ReducedOutcome(x, rs, iterations, True, 'converged')

    def solve_sequence(self, wrenches: np.ndarray,
                       start: Optional[Tuple[np.ndarray, np.ndarray]] = None
                       ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """
        Solve each row of ``wrenches`` (N, 6) warm from the last converged row, compiled.

        ``start`` = (unknowns, wrench) (None: unloaded). Returns unknowns (N, size),
        residual norms, status codes (newton.CONVERGED or a failure code) and iterations.
        """
        size = self.size
        unknowns, norms, status, iterations, _ = self._sequence(
            wrenches, start, np.empty((size, size)), np.zeros(size + 1, dtype=np.int64), False)
        return unknowns, norms, status, iterations

    def continue_sequence(self, wrenches: np.ndarray,
                          start: Optional[Tuple[np.ndarray, np.ndarray]]
                          ) -> Tuple[np.ndarray, int]:
        """
        Solve rows of ``wrenches`` as consecutive ``solve`` calls would, up to a failure.

        Each row continues from the last (the first from ``start``, None: unloaded) with the
        model's stored factorized Jacobian, which it leaves as those calls would. Stops at
        the first row that fails even from the unloaded state, the model as before that row.
        Returns the unknowns (N, size) and the number of rows that converged (a prefix).
        """
        if start is None:
            self._pivots[self.size] = 0
        unknowns, _, status, _, count = self._sequence(wrenches, start, self._lu,
                                                       self._pivots, True)
        converged = count if count == 0 or status[count - 1] == newton.CONVERGED else count - 1
        return unknowns, converged

    def _sequence(self, wrenches: np.ndarray, start: Optional[Tuple[np.ndarray, np.ndarray]],
                  lu: np.ndarray, pivots: np.ndarray, stop_at_failure: bool
                  ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """Run level_kernels.solve_sequence; its columns and the number of rows it wrote."""
        wrenches = np.ascontiguousarray(wrenches, dtype=float)
        if start is None:
            start = (np.zeros(self.size), np.zeros(6))
        count = len(wrenches)
        unknowns = np.empty((count, self.size))
        norms = np.empty(count)
        status = np.empty(count, dtype=np.int64)
        iterations = np.empty(count, dtype=np.int64)
        written = level_kernels.solve_sequence(
            self.code, self._data, wrenches, np.asarray(start[0], dtype=float),
            np.asarray(start[1], dtype=float), self.tolerance, self.max_iterations, lu, pivots,
            stop_at_failure, unknowns, norms, status, iterations)
        return unknowns, norms, status, iterations, int(written)

    def poses(self, wrenches: np.ndarray,
              unknowns: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Return the end-disk pose (N, 7: position, quaternion xyzw) and bending angles (N, 4)."""
        wrenches = np.ascontiguousarray(wrenches, dtype=float)
        pose = np.empty((len(wrenches), level_kernels.POSE_SIZE))
        bending = np.empty((len(wrenches), level_kernels.BENDING_SIZE))
        level_kernels.poses(self.code, self._data, wrenches,
                            np.ascontiguousarray(unknowns, dtype=float), pose, bending)
        return pose, bending

    def frames(self, x: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Frames {pe}, {pm}, {dm}, {de} (4, 4, 4) at unknowns x under ``wrench``."""
        frames = np.empty((4, 4, 4))
        self._data[:6] = wrench
        if self.code == newton.CC:
            cc.cc_frames(x, self._data, frames)
        else:
            equivalent_rod.rod_frames(x, self._data, frames)
        return frames

    def points(self, x: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Centre-line points of the five backbones, (5, 2 (S + 1) (steps + 1), 3)."""
        rows = 2 * (self._spacers + 1) * (self._points_per_interval + 1)
        points = np.empty((5, rows, 3))
        self._data[:6] = wrench
        if self.code == newton.CC:
            cc.cc_points(x, self._data, self._spacers, self._points_per_interval, points)
        else:
            equivalent_rod.rod_points(x, self._data, points)
        return points

    def residual_by_kind(self, rs: np.ndarray) -> Dict[str, float]:
        """Largest absolute residual of each kind in SI (kinds the model lacks are 0)."""
        kinds = ('position_m', 'orientation_rad', 'force_n', 'moment_nm')
        return {kind: float(np.max(np.abs(rs) * self._residual_scale[kind]))
                if kind in self._residual_scale else 0.0 for kind in kinds}
