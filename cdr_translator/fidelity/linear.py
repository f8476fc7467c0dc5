"""
Fidelity level 'linear': the full model's first-order expansion about a cached solution.

At a converged full solution x0 under w0, the end-disk pose moves by the twist C (w - w0)
(C the compliance there, ``compliance.implicit_compliance``): the {de} frame is
exp([C_w (w - w0)]) R0 with its centre moved by C_v (w - w0). The tube frames {pm}, {dm}
and the backbone points move likewise by their own first-order sensitivities, central
differences of the full model's shot along the tangent dx/dw = -J^-1 dr/dw (the same
implicit derivative, with the fresh factorization of J the compliance computation made).
Nothing is solved at a new wrench: the cost is a few small matrix products.
"""

import time
from typing import Callable, Optional, Tuple

import numpy as np

from .linear_kernels import linear_frames, linear_poses
from .._blas import one_blas_thread
from .._linalg import solve_lu
from ..analysis.compliance import analyse, ComplianceAnalysis, DIRECTIONAL_STEP, frame_twist
from ..analysis.compliance import analysis_options, implicit_compliance
from ..bvp.problem import Problem


class TangentModel:
    """The cached full solution and its first-order sensitivities to the wrench."""

    def __init__(self, problem: Problem) -> None:
        """Bind the full model's ``problem`` (the one TranslatorSolver uses)."""
        self.problem = problem
        self.origin: Optional[np.ndarray] = None  # the cached wrench w0
        self.origin_text = ''
        #: LU factorization of the full model's Jacobian at the cached solution (what the
        #: 'auto' fidelity's chord-step check of a prediction uses)
        self.factorization: tuple = ()
        #: and the end-disk frame's derivative there (Problem.pose_jacobian)
        self.pose_jacobian: np.ndarray = np.empty(0)
        self.build_time_s = 0.0
        # the expansion, set by build(): unknowns, their derivative, C, frames, their twists
        # (derivatives), backbone points and theirs; all empty until then
        empty: np.ndarray = np.empty(0)
        self._unknowns = self._dxdw = self._compliance = empty
        self._frames = self._twists = self._points = self._dpdw = empty

    @property
    def ready(self) -> bool:
        """Whether a tangent has been built."""
        return self.origin is not None

    def clear(self) -> None:
        """Forget the cached solution."""
        self.origin = None

    @one_blas_thread  # 90x90 factorizations: more BLAS threads only spin on a busy machine
    def build(self, xs0: np.ndarray, wrench0: np.ndarray) -> None:
        """
        Cache the converged nondimensional unknowns ``xs0`` under ``wrench0``.

        ArithmeticError (from the compliance) if the equilibrium is nearly singular; the
        previous cache is then kept.
        """
        started = time.perf_counter()
        problem = self.problem
        compliance, lu, _ = implicit_compliance(problem, xs0, wrench0)
        dxdw = -solve_lu(lu, problem.wrench_sensitivity)
        points, frames = problem.shape(xs0, wrench0)
        twists = np.zeros((4, 6, 6))  # d(twist of each frame)/dw; {pe} is fixed
        dpdw = np.empty(points.shape + (6,))
        for column in range(6):
            direction = dxdw[:, column]
            step = DIRECTIONAL_STEP / max(np.abs(direction).max(), 1e-300)
            plus_points, plus = problem.shape(xs0 + step * direction, wrench0)
            minus_points, minus = problem.shape(xs0 - step * direction, wrench0)
            for k in (1, 2):
                twists[k, :, column] = frame_twist(minus[k], plus[k]) / (2.0 * step)
            dpdw[..., column] = (plus_points - minus_points) / (2.0 * step)
        twists[3] = compliance
        self._unknowns = xs0 * problem.x_scale
        self._dxdw = dxdw * problem.x_scale[:, None]
        self._compliance = compliance
        self._frames, self._twists, self._points, self._dpdw = frames, twists, points, dpdw
        self.factorization = lu
        assert problem.pose_jacobian is not None  # the compliance's shot set it at xs0
        self.pose_jacobian = problem.pose_jacobian.copy()
        self.origin = wrench0.copy()
        self.origin_text = str(np.round(wrench0, 6).tolist())  # said by every linear result
        self.build_time_s = time.perf_counter() - started

    def frames(self, wrench: np.ndarray) -> np.ndarray:
        """Return the frames {pe}, {pm}, {dm}, {de} (4, 4, 4) predicted at ``wrench``."""
        if self.origin is None:
            raise RuntimeError('the linear level has no cached full solution yet')
        frames = np.empty((4, 4, 4))
        linear_frames(self._frames, self._twists, wrench - self.origin, frames)
        return frames

    def unknowns(self, wrench: np.ndarray) -> np.ndarray:
        """Return the SI unknowns predicted to first order at ``wrench``."""
        if self.origin is None:
            raise RuntimeError('the linear level has no cached full solution yet')
        return self._unknowns + self._dxdw @ (wrench - self.origin)

    def unknowns_and_points(self, wrench: np.ndarray
                            ) -> Tuple[Callable[[], np.ndarray], Callable[[], np.ndarray]]:
        """
        Return makers of the SI unknowns and of the backbone points predicted at ``wrench``.

        They hold this expansion's arrays (a later ``build`` makes new ones): a result
        built from them says what this expansion predicted, however late it is read.
        """
        if self.origin is None:
            raise RuntimeError('the linear level has no cached full solution yet')
        offset = wrench - self.origin
        unknowns, dxdw, points, dpdw = self._unknowns, self._dxdw, self._points, self._dpdw
        return lambda: unknowns + dxdw @ offset, lambda: points + dpdw @ offset

    def poses(self, wrenches: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the end-disk pose (position, quaternion x, y, z, w) and bending angles per row.

        Arrays (N, 7) and (N, 4); one compiled loop (linear_kernels.linear_poses) over the
        rows of ``wrenches`` (N, 6).
        """
        if self.origin is None:
            raise RuntimeError('the linear level has no cached full solution yet')
        wrenches = np.ascontiguousarray(wrenches, dtype=float)
        pose = np.empty((len(wrenches), 7))
        bending = np.empty((len(wrenches), 4))
        linear_poses(self._frames, self._twists, self.origin, wrenches, pose, bending)
        return pose, bending

    def compliance(self, **options: float) -> ComplianceAnalysis:
        """Return the compliance of the linear level: the cached solution's, analysed."""
        return analyse(self._compliance, self.problem.params.stack_height,
                       method='implicit (cached)', time_s=0.0, **analysis_options(options))
