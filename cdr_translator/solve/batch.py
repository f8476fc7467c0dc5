"""
BatchResult: the answers of ``solve_many``, one row per wrench, in columns.

``TranslatorSolver.solve_many`` and ``FidelitySolver.solve_many`` solve the rows of (N, 3)
forces and moments in order, warm-started along the sequence, as N ``solve`` calls would;
the columns hold what those calls' results say (``SolveResult.to_dict``'s values).
Unknown is NaN in the float columns (no error estimate; no pose of a row that raised) and
None in the object columns ``stable`` and ``accuracy_met``, where ``to_dict`` says null.
"""

from dataclasses import dataclass
import math
from typing import Any, Callable, Dict, Iterable, NamedTuple, Optional

import numpy as np
from numpy.typing import ArrayLike

from .result import SolveResult
from .. import geometry
from ..analysis.accuracy import ErrorEstimate
from ..analysis.compliance import ComplianceAnalysis
from ..checks import check_vector
from ..errors import InputError


#: How ``solve_many`` solves one row: (batch, row, wrench, compliance) -> solve time (s);
#: it writes the row by ``BatchResult.record`` or ``record_pose``.
RowSolver = Callable[['BatchResult', int, np.ndarray, bool], float]


class SolveDetails(NamedTuple):
    """What a single solve's result says beside the pose (``SolveResult``'s fields)."""

    iterations: int
    residual_norm: float
    #: the solve's own stability verdict (None: not judged) and its margin
    verdict: Optional[bool]
    stability_margin: float
    steps_per_segment: int
    method: str
    #: the result's whole message, also for a good row
    message: str
    analysis: Optional['ComplianceAnalysis']


@dataclass
class BatchResult:
    """
    Columns of N solves: row i is the answer to the i-th wrench (SI units, radians).

    ``stable`` and ``accuracy_met`` hold True, False or None (not assessed: no verdict, no
    error estimate); ``pj_bending``/``dj_bending`` are (angle, direction) per row;
    ``fidelity`` is the level that produced each row; ``compliance`` (N, 6, 6) is there
    when asked for (NaN where it failed). ``message`` is empty for a good row (converged,
    not unstable, not short of its accuracy target, its compliance made when asked) and
    the solve's message for the others.
    """

    force: np.ndarray
    moment: np.ndarray
    converged: np.ndarray
    stable: np.ndarray
    accuracy_met: np.ndarray
    error_estimate_m: np.ndarray
    error_estimate_deg: np.ndarray
    end_disk_position: np.ndarray
    end_disk_quaternion_xyzw: np.ndarray
    pj_bending: np.ndarray
    dj_bending: np.ndarray
    fidelity: np.ndarray
    message: np.ndarray
    solve_time_s: np.ndarray
    #: what a single solve's result says beside the pose, per row (unknown: -1, NaN, None or
    #: ''): its iterations and residual norm, its own stability verdict (None: not judged)
    #: and margin, the steps per segment of its error estimate, its method, its whole
    #: message (also for a good row), the end-disk rotation matrix (N, 3, 3) and its
    #: compliance analysis (None: not made)
    iterations: np.ndarray
    residual_norm: np.ndarray
    verdict: np.ndarray
    stability_margin: np.ndarray
    steps_per_segment: np.ndarray
    method: np.ndarray
    solve_message: np.ndarray
    end_disk_rotation: np.ndarray
    analysis: np.ndarray
    compliance: Optional[np.ndarray] = None

    @classmethod
    def empty(cls, wrenches: np.ndarray, compliance: bool) -> 'BatchResult':
        """Return the columns for ``wrenches`` (N, 6), every row unknown until recorded."""
        count = len(wrenches)

        def unknown(*shape: int) -> np.ndarray:
            """Return a column of NaN."""
            return np.full((count,) + shape, math.nan)

        return cls(wrenches[:, :3].copy(), wrenches[:, 3:].copy(), np.zeros(count, bool),
                   np.full(count, None, object), np.full(count, None, object), unknown(),
                   unknown(), unknown(3), unknown(4), unknown(2), unknown(2),
                   np.full(count, 'full', object), np.full(count, '', object), unknown(),
                   np.full(count, -1), unknown(), np.full(count, None, object), unknown(),
                   np.zeros(count, int), np.full(count, '', object),
                   np.full(count, '', object), unknown(3, 3), np.full(count, None, object),
                   unknown(6, 6) if compliance else None)

    def __len__(self) -> int:
        """Return the number of rows."""
        return len(self.converged)

    def run(self, row: int, solve_row: RowSolver, wrench: np.ndarray, compliance: bool) -> None:
        """Solve ``row`` by ``solve_row``; a row whose solve raises is flagged with the error."""
        try:
            self.solve_time_s[row] = solve_row(self, row, wrench, compliance)
        except Exception as error:  # one row's failure must not cost the rows after it
            self.record_failure(row, f'{type(error).__name__}: {error}')

    def record_failure(self, row: int, message: str) -> None:
        """Flag ``row`` as failed with ``message``; everything else about it unknown."""
        self.converged[row] = False
        self.stable[row] = self.accuracy_met[row] = None
        for column in (self.error_estimate_m, self.error_estimate_deg,
                       self.end_disk_position, self.end_disk_quaternion_xyzw,
                       self.pj_bending, self.dj_bending):
            column[row] = math.nan
        if self.compliance is not None:
            self.compliance[row] = math.nan
        self.message[row] = self.solve_message[row] = message
        self.iterations[row] = 0  # known: the solve ended before any
        self.residual_norm[row] = self.stability_margin[row] = math.nan
        self.end_disk_rotation[row] = math.nan
        self.verdict[row] = self.analysis[row] = None

    def record(self, row: int, result: SolveResult) -> None:
        """Write ``row`` from a solve's result."""
        summary_stable = (result.stable if result.stable is not None
                          else result.compliance.stable if result.compliance is not None
                          else None)
        estimated = math.isfinite(result.error_estimate_m)
        matrix = result.compliance.matrix if result.compliance is not None else None
        frames = result.frames
        self._write(row, bool(result.converged), frames['pe'], frames['pm'], frames['dm'],
                    frames['de'], None if summary_stable is None else bool(summary_stable),
                    bool(result.accuracy_met) if estimated else None,
                    result.error_estimate_m, result.error_estimate_deg, matrix,
                    result.fidelity)
        self.record_details(row, SolveDetails(
            result.iterations, result.residual_norm, result.stable, result.stability_margin,
            result.steps_per_segment, result.method, result.message, result.compliance))
        if not self._good(row):
            self.message[row] = result.message

    def record_details(self, row: int, details: SolveDetails) -> None:
        """Write what a single solve's result of ``row`` says beside its pose."""
        self.iterations[row] = details.iterations
        self.residual_norm[row] = details.residual_norm
        self.verdict[row] = details.verdict
        self.stability_margin[row] = details.stability_margin
        self.steps_per_segment[row] = details.steps_per_segment
        self.method[row] = details.method
        self.solve_message[row] = details.message
        self.analysis[row] = details.analysis

    def record_pose(self, row: int, frames: np.ndarray, stable: Optional[bool],
                    estimate: Optional[ErrorEstimate], matrix: Optional[np.ndarray] = None,
                    message: str = '', fidelity: str = 'full',
                    details: Optional[SolveDetails] = None) -> None:
        """
        Write a converged ``row`` from its frames {pe}, {pm}, {dm}, {de} (4, 4, 4).

        ``estimate`` (None: not made) meets the accuracy target; ``message`` is the one a
        single solve would give when that row is not good (its compliance failed);
        ``details``: the rest of what that solve's result says (None: unknown).
        """
        self._write(row, True, frames[0], frames[1], frames[2], frames[3], stable,
                    None if estimate is None else True,
                    math.nan if estimate is None else estimate.position_m,
                    math.nan if estimate is None else estimate.angle_deg, matrix, fidelity)
        if details is not None:
            self.record_details(row, details)
        if not self._good(row):
            self.message[row] = message

    def record_poses(self, rows: slice, pose: np.ndarray, bending: np.ndarray, fidelity: str,
                     solve_time_s: float, stable: Optional[bool] = None,
                     matrix: Optional[np.ndarray] = None,
                     estimate: Optional[np.ndarray] = None) -> None:
        """
        Write good converged ``rows`` from compiled poses.

        ``pose`` (n, 7: position, quaternion x, y, z, w) and ``bending`` (n, 4: PJ angle,
        direction, DJ angle, direction) as fidelity.level_kernels.poses gives them;
        ``stable`` and the compliance ``matrix`` are shared by the rows (the 'linear'
        level's); ``estimate`` (n, 2: m, deg) is an error estimate within the accuracy
        target, None: none made. A row that is not good goes through ``record_pose``
        instead.
        """
        self.converged[rows] = True
        self.stable[rows] = stable
        if estimate is None:
            self.accuracy_met[rows] = None
            self.error_estimate_m[rows] = self.error_estimate_deg[rows] = math.nan
        else:
            self.accuracy_met[rows] = True
            self.error_estimate_m[rows] = estimate[:, 0]
            self.error_estimate_deg[rows] = estimate[:, 1]
        self.end_disk_position[rows] = pose[:, :3]
        self.end_disk_quaternion_xyzw[rows] = pose[:, 3:]
        self.pj_bending[rows] = bending[:, :2]
        self.dj_bending[rows] = bending[:, 2:]
        self.fidelity[rows] = fidelity
        self.solve_time_s[rows] = solve_time_s
        if self.compliance is not None:
            self.compliance[rows] = math.nan if matrix is None else matrix
        self.message[rows] = ''

    def _write(self, row: int, converged: bool, pe: np.ndarray, pm: np.ndarray,
               dm: np.ndarray, de: np.ndarray, stable: Optional[bool],
               accuracy_met: Optional[bool], error_m: float, error_deg: float,
               matrix: Optional[np.ndarray], fidelity: str) -> None:
        """Set the columns of ``row`` (the bending angles as SolveResult computes them)."""
        self.converged[row] = converged
        self.stable[row] = stable
        self.accuracy_met[row] = accuracy_met
        self.error_estimate_m[row] = error_m
        self.error_estimate_deg[row] = error_deg
        self.end_disk_position[row] = de[:3, 3]
        self.end_disk_quaternion_xyzw[row] = geometry.quaternion_xyzw(de[:3, :3])
        self.end_disk_rotation[row] = de[:3, :3]
        self.pj_bending[row] = geometry.bending_between(pe, pm)
        self.dj_bending[row] = geometry.bending_between(dm, de)
        self.fidelity[row] = fidelity
        if self.compliance is not None:
            self.compliance[row] = math.nan if matrix is None else matrix
        self.message[row] = ''

    def _good(self, row: int) -> bool:
        """Whether ``row`` converged, is not unstable, met its target and has its compliance."""
        return bool(self.converged[row] and self.stable[row] is not False
                    and self.accuracy_met[row] is not False
                    and (self.compliance is None or np.isfinite(self.compliance[row, 0, 0])))

    def row(self, index: int) -> Dict[str, Any]:
        """Row ``index`` with the keys and values of ``SolveResult.to_dict`` for it."""
        pj, dj = self.pj_bending[index], self.dj_bending[index]
        values = {
            'converged': bool(self.converged[index]),
            'message': str(self.message[index]),
            'force_n': self.force[index].tolist(),
            'moment_nm': self.moment[index].tolist(),
            'end_disk_position_m': _plain(self.end_disk_position[index]),
            'end_disk_quaternion_xyzw': _plain(self.end_disk_quaternion_xyzw[index]),
            'pj_bending_deg': _number(math.degrees(pj[0])),
            'pj_direction_deg': _number(math.degrees(pj[1])),
            'dj_bending_deg': _number(math.degrees(dj[0])),
            'dj_direction_deg': _number(math.degrees(dj[1])),
            'fidelity': str(self.fidelity[index]),
            'error_estimate_m': _number(self.error_estimate_m[index]),
            'error_estimate_deg': _number(self.error_estimate_deg[index]),
            'accuracy_met': self.accuracy_met[index],
            'stable': self.stable[index],
            'solve_time_s': _number(self.solve_time_s[index]),
        }
        if self.compliance is not None:
            values['compliance'] = [_plain(line) for line in self.compliance[index]]
        return values

    def to_dict(self) -> Dict[str, list]:
        """JSON-ready columns: each key of ``row`` with its N values (NaN as None)."""
        rows = [self.row(index) for index in range(len(self))]
        keys = rows[0].keys() if rows else self.row_keys()
        return {key: [values[key] for values in rows] for key in keys}

    def row_keys(self) -> list:
        """Return the keys of ``row`` (and of ``to_dict``)."""
        keys = ['converged', 'message', 'force_n', 'moment_nm', 'end_disk_position_m',
                'end_disk_quaternion_xyzw', 'pj_bending_deg', 'pj_direction_deg',
                'dj_bending_deg', 'dj_direction_deg', 'fidelity', 'error_estimate_m',
                'error_estimate_deg', 'accuracy_met', 'stable', 'solve_time_s']
        return keys + (['compliance'] if self.compliance is not None else [])


def _number(value: float) -> Optional[float]:
    """Return a float for JSON: NaN and infinities become None."""
    return float(value) if math.isfinite(value) else None


def _plain(values: Iterable[float]) -> list:
    """Return floats for JSON: NaN and infinities become None."""
    return [_number(value) for value in values]


def check_wrenches(forces: ArrayLike, moments: Optional[ArrayLike] = None) -> np.ndarray:
    """
    Return the wrenches (N, 6) of rows of ``forces`` and ``moments`` (None: no moments).

    InputError (a ValueError) names the first bad row and component, or the shape.
    """
    force_rows = _rows('forces', forces)
    moment_rows = np.zeros_like(force_rows) if moments is None else _rows('moments', moments)
    if moment_rows.shape != force_rows.shape:
        raise InputError(f'moments must have one row per row of forces: got {len(moment_rows)} '
                         f'rows of moments for {len(force_rows)} of forces')
    return np.concatenate([force_rows, moment_rows], axis=1)


def _rows(name: str, values: ArrayLike) -> np.ndarray:
    """Return ``values`` as finite (N, 3) floats; InputError naming the first bad row."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.ndim != 2 or array.shape[1] != 3:
        if isinstance(values, (list, tuple, np.ndarray)):
            for row, item in enumerate(values):
                check_vector(f'{name} row {row}', item)
        shape = getattr(array, 'shape', None)
        raise InputError(f'{name} must be an (N, 3) array of numbers, got '
                         f'{"shape " + str(shape) if shape is not None else repr(values)}')
    finite = np.isfinite(array).all(axis=1)
    if not finite.all():
        row = int(np.argmin(finite))
        check_vector(f'{name} row {row}', array[row])
    return array
