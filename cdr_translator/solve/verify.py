"""
Independent verification of a solved translator: re-shoot the rods, check statics and clamps.

Given the unknowns of a :class:`~cdr_translator.solve.result.SolveResult`, this module integrates
the five rods again with its own code and measures how well the result satisfies the model,
in SI units. It shares nothing with the solver's residual or convergence test:

* integration: the full Cosserat state (p, R, n, m) of Eq. (1)-(6), the moment balance in
  its differential form m' = -p' x n, by scipy's adaptive DOP853 (8th order, error
  controlled to 1e-11 relative) over each disk interval. The solver integrates the pose
  only, with fixed-step RK4 and the closed form of m;
* constraints, measured as distances and angles: each secondary's offset from its hole and
  the angle between its tangent and the disk normal at every spacer disk and the tube's
  proximal face (Eq. 7-8); its clamp at the end disk as a position offset and a rotation
  angle (Eq. 10);
* end-disk equilibrium: the rods' end wrenches against the applied wrench (Eq. 11);
* global equilibrium: the five wrenches the rods carry at the base plus the applied wrench,
  all about the base origin, sum to zero. It uses only the base unknowns and the end-disk
  position, not the transfer of loads through the disks and the tube, so an error in that
  transfer shows up here even where the end-disk balance holds;
* the frames the solver reported ({pm}, {dm}, {de}) against the re-shot ones: this bounds
  the discretization error of what users read.

Tolerances are absolute, SI, by default the paper's (see :class:`Tolerances`); the end-disk
moment balance also allows the position tolerance times the rod forces whose lever arms it
affects.
"""

from dataclasses import dataclass
import math
from typing import Dict, Optional

import numpy as np
from scipy.integrate import solve_ivp

from .result import PAPER_TOLERANCES, SolveResult, Verification
from ..params.translator_params import SECONDARY_ANGLES_RAD, TranslatorParams

#: Verification is defined beside SolveResult (which holds one) and exported here too.
__all__ = ['INTEGRATION_ATOL', 'INTEGRATION_RTOL', 'Tolerances', 'Verification', 'verify']

#: Relative and absolute error tolerances of the re-integration (DOP853).
INTEGRATION_RTOL = 1e-11
INTEGRATION_ATOL = 1e-14


@dataclass(frozen=True)
class Tolerances:
    """
    Largest accepted deviation of each kind (SI); the defaults are the paper's own.

    The paper stops its iterations at 2e-4 m, 1e-4 rad, 1e-4 N and 1e-4 N m; a verified
    result agrees with the continuum model, integrated afresh, at least that closely. The
    fast solver's residual tolerance (1e-10 nondimensional: about 1e-12 m, 1e-10 rad,
    1e-8 N, 1e-10 N m) is far below these, so what they bound in practice is its RK4
    discretization error, which grows steeply with the load: at the default 8 steps per
    disk interval the secondaries' tangents are off by 5e-6 rad at 20 N lateral and by
    3e-4 rad, beyond the tolerance, at 60 N (more steps per interval fix that).
    """

    position_m: float = PAPER_TOLERANCES['position_m']
    orientation_rad: float = PAPER_TOLERANCES['orientation_rad']
    force_n: float = PAPER_TOLERANCES['force_n']
    moment_nm: float = PAPER_TOLERANCES['moment_nm']


def verify(result: SolveResult, params: TranslatorParams,
           tolerances: Optional[Tolerances] = None) -> Verification:
    """
    Re-check ``result`` (solved with ``params``) independently; see the module docstring.

    ``tolerances`` default to :class:`Tolerances` (the paper's). A non-converged result is
    checked too (its numbers say how far off it is), but never passes.
    """
    if tolerances is None:
        tolerances = Tolerances()
    unknowns = np.asarray(result.unknowns, dtype=float)
    if not np.all(np.isfinite(unknowns)):
        return Verification(False, 'the result holds non-finite unknowns')
    shot = _Reshoot(params, unknowns, np.concatenate([result.force, result.moment]))
    checks = dict(shot.checks)
    checks.update(_global_equilibrium(params, unknowns, result))
    for name in ('pm', 'dm', 'de'):
        mine, theirs = shot.frames[name], result.frames[name]
        checks[f'frame_{name}_position_m'] = float(np.linalg.norm(mine[:3, 3] - theirs[:3, 3]))
        checks[f'frame_{name}_rotation_rad'] = _angle(theirs[:3, :3].T @ mine[:3, :3])
    limits = {name: _limit(name, tolerances, shot.force_sum) for name in checks}
    failed = [name for name in checks
              if not (math.isfinite(checks[name]) and checks[name] <= limits[name])]
    if not result.converged:
        message = f'not converged ({result.message}); ' + (
            f'outside tolerance: {", ".join(failed)}' if failed else 'all checks within tolerance')
        return Verification(False, message, checks, limits)
    if failed:
        details = ', '.join(f'{name} = {checks[name]:.3g} > {limits[name]:.3g}'
                            for name in failed)
        return Verification(False, f'verification failed: {details}', checks, limits)
    return Verification(True, 'verified', checks, limits)


def _limit(name: str, tolerances: Tolerances, force_sum: float) -> float:
    """
    Tolerance of check ``name``.

    The end-disk moment balance is taken with the re-shot lever arms, each within the
    position tolerance, so it also allows that tolerance times the sum of the rod forces.
    """
    if name.endswith('_rad'):
        return tolerances.orientation_rad
    if name.endswith('_m'):
        return tolerances.position_m
    if name == 'end_disk_moment_nm':
        return tolerances.moment_nm + tolerances.position_m * force_sum
    if name.endswith('_nm'):
        return tolerances.moment_nm
    return tolerances.force_n


def _global_equilibrium(params: TranslatorParams, unknowns: np.ndarray,
                        result: SolveResult) -> Dict[str, float]:
    """Sum the base wrenches of all five rods and the applied one about the origin (N, N m)."""
    end_position = result.end_disk_position
    base = unknowns[:30].reshape(5, 6)
    origins = np.vstack([np.zeros(3), _holes(params)])
    force = base[:, :3].sum(axis=0) - result.force
    moment = ((base[:, 3:] + np.cross(origins, base[:, :3])).sum(axis=0)
              - result.moment - np.cross(end_position, result.force))
    return {'global_force_n': float(np.linalg.norm(force)),
            'global_moment_nm': float(np.linalg.norm(moment))}


def _holes(params: TranslatorParams) -> np.ndarray:
    """Hole centres of the four secondaries in a disk frame (4, 3), m."""
    return np.array([[params.pitch_radius * math.cos(angle),
                      params.pitch_radius * math.sin(angle), 0.0]
                     for angle in SECONDARY_ANGLES_RAD])


def _angle(rotation: np.ndarray) -> float:
    """Rotation angle of a rotation matrix, accurate near zero (atan2 of |vee| and trace)."""
    skew = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0],
                     rotation[1, 0] - rotation[0, 1]])
    return math.atan2(0.5 * float(np.linalg.norm(skew)), 0.5 * (np.trace(rotation) - 1.0))


def _tilt(normal: np.ndarray, tangent: np.ndarray) -> float:
    """Angle between two unit vectors, accurate near zero."""
    return math.atan2(float(np.linalg.norm(np.cross(normal, tangent))),
                      float(normal @ tangent))


class _Reshoot:
    """One pass through the translator with DOP853; collects the checks on the way."""

    def __init__(self, params: TranslatorParams, unknowns: np.ndarray,
                 wrench: np.ndarray) -> None:
        area = params.area
        inertia = params.second_moment
        shear = params.shear_modulus
        young = params.youngs_modulus
        self.inv_kse = 1.0 / np.array([shear * area, shear * area, young * area])
        self.inv_kbt = 1.0 / np.array([young * inertia, young * inertia, 2.0 * shear * inertia])
        self.params = params
        self.holes = _holes(params)
        spacers = params.spacers_per_joint
        self.stations = 2 * spacers + 1
        station_values = unknowns[30:].reshape(4, self.stations, 5)
        self.p = np.vstack([np.zeros(3), self.holes])
        self.rot = np.tile(np.eye(3), (5, 1, 1))
        self.n = unknowns[:30].reshape(5, 6)[:, :3].copy()
        self.m = unknowns[:30].reshape(5, 6)[:, 3:].copy()
        self.force_sum = float(np.abs(self.n).sum())
        self.checks = {'hole_offset_m': 0.0, 'tangent_tilt_rad': 0.0}
        self.frames = {}
        total = 2.0 * (spacers + 1) * params.disk_spacing + params.tube_length
        used = np.zeros(4)
        for joint in range(2):
            for station in range(spacers + 1):
                t = joint * (spacers + 1) + station
                end = joint == 1 and station == spacers
                lengths = total - used if end else station_values[:, t, 0]
                used += lengths
                self._interval(np.concatenate([[params.disk_spacing], lengths]))
                if end:
                    self.frames['de'] = self._frame()
                    self._end_disk(wrench)
                    continue
                self._station()
                if joint == 0 and station == spacers:
                    self.frames['pm'] = self._frame()
                    used += self._tube(station_values[:, t, 1:])
                    self.frames['dm'] = self._frame()
                else:
                    self._spacer_disk(station_values[:, t, 1:])

    def _frame(self) -> np.ndarray:
        frame = np.eye(4)
        frame[:3, :3] = self.rot[0]
        frame[:3, 3] = self.p[0]
        return frame

    def _interval(self, lengths: np.ndarray) -> None:
        """Integrate all five rods over one disk interval (arc lengths ``lengths``)."""
        inv_kse, inv_kbt = self.inv_kse, self.inv_kbt
        n = self.n

        def derivative(_, y):
            state = y.reshape(5, 15)
            rot = state[:, 3:12].reshape(5, 3, 3)
            m = state[:, 12:15]
            v = inv_kse * np.einsum('kji,kj->ki', rot, n)
            v[:, 2] += 1.0
            u = inv_kbt * np.einsum('kji,kj->ki', rot, m)
            dp = np.einsum('kij,kj->ki', rot, v)
            drot = np.einsum('kij,kjl->kil', rot, _hat(u))
            dm = -np.cross(dp, n)
            return (lengths[:, None] * np.hstack([dp, drot.reshape(5, 9), dm])).ravel()

        y0 = np.hstack([self.p, self.rot.reshape(5, 9), self.m]).ravel()
        solution = solve_ivp(derivative, (0.0, 1.0), y0, method='DOP853',
                             rtol=INTEGRATION_RTOL, atol=INTEGRATION_ATOL)
        end = solution.y[:, -1].reshape(5, 15)
        self.p = end[:, :3].copy()
        self.rot = end[:, 3:12].reshape(5, 3, 3).copy()
        self.m = end[:, 12:15].copy()

    def _station(self) -> None:
        """Hole offset and tangent tilt of every secondary at a spacer disk or tube face."""
        disk = self.rot[0]
        for i in range(4):
            offset = disk.T @ (self.p[i + 1] - self.p[0]) - self.holes[i]
            self.checks['hole_offset_m'] = max(self.checks['hole_offset_m'],
                                               float(np.linalg.norm(offset)))
            self.checks['tangent_tilt_rad'] = max(self.checks['tangent_tilt_rad'],
                                                  _tilt(disk[:, 2], self.rot[i + 1][:, 2]))

    def _spacer_disk(self, reactions: np.ndarray) -> None:
        """
        Apply a free spacer disk's reactions (disk x/y components, the solver's unknowns).

        The disk changes secondary i's internal force by f_i and moment by mu_i; being a
        massless rigid body it hands the opposite, moved to its centre, to the primary.
        """
        disk = self.rot[0]
        for i in range(4):
            force = disk[:, :2] @ reactions[i, :2]
            moment = disk[:, :2] @ reactions[i, 2:]
            self.n[i + 1] += force
            self.m[i + 1] += moment
            self.n[0] -= force
            self.m[0] -= moment + np.cross(self.p[i + 1] - self.p[0], force)

    def _tube(self, exit_reactions: np.ndarray) -> np.ndarray:
        """
        Cross the rigid tube; return the secondaries' material lengths inside it.

        Each secondary runs straight along its lumen carrying only its axial force and
        torsion (the lumen takes the in-plane rest), twisting by torsion * length / GJ;
        at the distal face it leaves with the in-plane wrench given by the unknowns. The
        tube's own balance (about its proximal centre) sets the primary's exit wrench.
        """
        axis = self.rot[0][:, 2].copy()
        centre = self.p[0].copy()
        length = self.params.tube_length
        inside = np.empty(4)
        change_force = np.zeros(3)
        change_moment = np.zeros(3)
        for i in range(4):
            k = i + 1
            change_force -= self.n[k]
            change_moment -= self.m[k] + np.cross(self.p[k] - centre, self.n[k])
            axial = float(axis @ self.n[k])
            torsion = float(self.rot[k][:, 2] @ self.m[k])
            inside[i] = length / (1.0 + self.inv_kse[2] * axial)
            angle = self.inv_kbt[2] * torsion * inside[i]
            twist = np.array([[math.cos(angle), -math.sin(angle), 0.0],
                              [math.sin(angle), math.cos(angle), 0.0], [0.0, 0.0, 1.0]])
            self.rot[k] = self.rot[k] @ twist
            self.p[k] = self.p[k] + length * axis
            self.n[k] = axial * axis + self.rot[0][:, :2] @ exit_reactions[i, :2]
            self.m[k] = torsion * axis + self.rot[0][:, :2] @ exit_reactions[i, 2:]
            change_force += self.n[k]
            change_moment += self.m[k] + np.cross(self.p[k] - centre, self.n[k])
        self.p[0] = centre + length * axis
        self.n[0] -= change_force
        self.m[0] -= change_moment + np.cross(self.p[0] - centre, self.n[0])
        return inside

    def _end_disk(self, wrench: np.ndarray) -> None:
        """Clamp offsets of the secondaries and the end disk's balance (Eq. 10-11)."""
        disk = self.rot[0]
        position = rotation = 0.0
        moment = np.zeros(3)
        for k in range(5):
            arm = self.p[k] - self.p[0]
            moment += self.m[k] + np.cross(arm, self.n[k])
            if k:
                position = max(position, float(np.linalg.norm(
                    disk.T @ arm - self.holes[k - 1])))
                rotation = max(rotation, _angle(disk.T @ self.rot[k]))
        self.checks['end_clamp_position_m'] = position
        self.checks['end_clamp_rotation_rad'] = rotation
        self.checks['end_disk_force_n'] = float(np.linalg.norm(self.n.sum(axis=0)
                                                               - wrench[:3]))
        self.checks['end_disk_moment_nm'] = float(np.linalg.norm(moment - wrench[3:]))


def _hat(vectors: np.ndarray) -> np.ndarray:
    """Skew matrices [u x] of a stack of 3-vectors (k, 3) -> (k, 3, 3)."""
    hat = np.zeros(vectors.shape[:-1] + (3, 3))
    hat[..., 0, 1] = -vectors[..., 2]
    hat[..., 0, 2] = vectors[..., 1]
    hat[..., 1, 0] = vectors[..., 2]
    hat[..., 1, 2] = -vectors[..., 0]
    hat[..., 2, 0] = -vectors[..., 1]
    hat[..., 2, 1] = vectors[..., 0]
    return hat
