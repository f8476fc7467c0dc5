"""
The samples of a Continuum Delta Robot atlas and their solution, chunk by chunk (no Dask).

An atlas sweeps the slider box (an N x N x N grid over each variant's stroke) x a list of
payloads x a list of params files (design variants). Samples are numbered variant-major,
then payload, then grid point; the grid points of one (variant, payload) block run in a
serpentine (boustrophedon) order, so consecutive samples are neighbours one grid step apart
and a chunk of consecutive samples is solved with warm starts all along. Each chunk starts
cold (``DeltaRobot.reset``), so its results do not depend on which chunks a worker solved
before: a chunk is a pure function of (spec, start, stop).

cdr_translator.robot.atlas runs the chunks on Dask and stores them in Zarr; this module is
the part a worker runs and needs only the solver.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .delta import DeltaRobot
from .levels import check_fidelity
from .params import DeltaParams
from ..params.translator_params import DEFAULT_PARAMS_PATH

#: Characters of a sample's message kept in the atlas.
MESSAGE_LENGTH = 160
#: Samples of one atlas at most (a 100^3 grid): its inputs are built in memory (about 0.4 GB
#: at this size) and it takes hours on one worker; a --grid of 1e5 once took 24 GB.
MAX_ATLAS_SAMPLES = 1_000_000

#: Per-sample result variables: name -> (trailing shape, dtype, units, description).
RESULT_VARIABLES: Dict[str, Tuple[Tuple[int, ...], str, str, str]] = {
    'platform_position': ((3,), 'float64', 'm', 'platform origin in the world frame {w}'),
    'platform_rotation_vector': ((3,), 'float64', 'rad',
                                 'platform rotation from home, rotation vector in {w}'),
    'parasitic_rotation': ((), 'float64', 'rad', 'platform rotation angle from home'),
    'leg_bending': ((3, 2), 'float64', 'rad', 'PJ and DJ bending angle of each leg'),
    'leg_axial_force': ((3,), 'float64', 'N',
                        'tension of each leg at its end disk (tip force along {pe_i} z)'),
    'compliance_eigenvalues_translation': (
        (3,), 'float64', 'm/N',
        'ascending eigenvalues of the symmetric translational block of the platform '
        'compliance (force at the platform origin, {w})'),
    'compliance_eigenvalues_rotation': (
        (3,), 'float64', 'rad/(N m)',
        'ascending eigenvalues of the symmetric rotational block of the platform compliance'),
    'slider_jacobian': ((3, 3), 'float64', 'm/m',
                        'd platform_position / d sliders (rows x, y, z; columns slider 1-3)'),
    'stiffness_margin': ((), 'float64', 'N/m',
                         'smallest eigenvalue of the symmetric part of the platform stiffness, '
                         'rotations as displacements over the leg stack height'),
    'stable': ((), 'bool', '', 'closed-chain stability verdict (stiffness_margin > 0)'),
    'converged': ((), 'bool', '', 'the forward statics converged'),
    'message': ((), f'<U{MESSAGE_LENGTH}', '', 'solver message (truncated)'),
    'iterations': ((), 'int32', '', 'Newton iterations of the forward solve'),
    'solve_time_s': ((), 'float64', 's', 'forward solve time including the compliance'),
    'leg_fidelity': ((3,), 'int8', '',
                     'level each leg was solved at: index into the leg_levels attribute'),
    'leg_error_bound_position': ((3,), 'float64', 'm',
                                 "validated end-disk position error of each leg's level at its "
                                 'tip wrench (NaN: full leg, or outside the validated box)'),
    'leg_error_bound_angle': ((3,), 'float64', 'deg',
                              "validated angle error of each leg's level at its tip wrench"),
}

#: Codes of the leg levels in ``leg_fidelity`` (stored as the leg_levels attribute).
LEG_LEVELS = ('full', 'rod', 'cc')
LEVEL_CODES = {level: code for code, level in enumerate(LEG_LEVELS)}


@dataclass(frozen=True)
class AtlasSpec:
    """
    What an atlas sweeps.

    ``grid`` points per slider axis, ``payloads`` (P, 3) in N in {w}, ``params_files``
    (the design variants), ``strokes`` (each variant's slider stroke, m), ``fidelity``
    the legs' level with its budget (DeltaRobot's; robot/levels.py).
    """

    grid: int
    payloads: Tuple[Tuple[float, float, float], ...]
    params_files: Tuple[str, ...]
    strokes: Tuple[float, ...]
    time_limit_s: float = 30.0
    fidelity: str = 'full'
    max_position_error: float = 0.0
    max_angle_error: float = 0.0

    @classmethod
    def build(cls, grid: int, payloads: Sequence[Sequence[float]] = ((0.0, 0.0, 0.0),),
              params_files: Sequence[str] = (str(DEFAULT_PARAMS_PATH),),
              time_limit_s: float = 30.0, fidelity: str = 'full',
              max_position_error: float = 0.0, max_angle_error: float = 0.0) -> 'AtlasSpec':
        """Validate the sweep (ValueError naming a bad value) and read each variant's stroke."""
        if isinstance(grid, bool) or not isinstance(grid, int) or grid < 2:
            raise ValueError(f'grid must be an integer of at least 2, got {grid!r}')
        size = grid ** 3 * max(len(payloads), 1) * max(len(params_files), 1)
        if size > MAX_ATLAS_SAMPLES:
            raise ValueError(f'--grid {grid} with {len(payloads)} payload(s) and '
                             f'{len(params_files)} params file(s) is {size:.3g} samples '
                             f'(grid^3 each); an atlas holds at most {MAX_ATLAS_SAMPLES:.0e}')
        checked: List[Tuple[float, float, float]] = []
        for payload in payloads:
            array = np.asarray(payload, dtype=float)
            if array.shape != (3,) or not np.all(np.isfinite(array)):
                raise ValueError(f'payload must be 3 finite force components (N), got {payload}')
            checked.append((float(array[0]), float(array[1]), float(array[2])))
        if not checked:
            raise ValueError('at least one payload is needed')
        files = tuple(str(Path(path).resolve()) for path in params_files)
        if not files:
            raise ValueError('at least one params file is needed')
        if not (math.isfinite(time_limit_s) and time_limit_s > 0.0):
            raise ValueError(f'time limit must be a positive number of seconds, got '
                             f'{time_limit_s}')
        check_fidelity(fidelity, max_position_error, max_angle_error)
        strokes = tuple(DeltaParams.from_yaml(path).slider_stroke for path in files)
        return cls(grid, tuple(checked), files, strokes, float(time_limit_s), fidelity,
                   float(max_position_error), float(max_angle_error))

    @property
    def block(self) -> int:
        """Return the samples per (variant, payload) block: grid^3."""
        return self.grid ** 3

    @property
    def size(self) -> int:
        """Return the number of samples."""
        return self.block * len(self.payloads) * len(self.params_files)

    def to_attrs(self) -> dict:
        """
        JSON-ready description, stored with the atlas to recognise it on a restart.

        The level's keys only when not full: a full-leg atlas keeps the description it had
        before there were levels (and resumes stores made then).
        """
        attrs = {'grid': self.grid, 'payloads': [list(p) for p in self.payloads],
                 'params_files': list(self.params_files), 'strokes': list(self.strokes),
                 'time_limit_s': self.time_limit_s}
        if self.fidelity != 'full':
            attrs.update(fidelity=self.fidelity, max_position_error=self.max_position_error,
                         max_angle_error=self.max_angle_error)
        return attrs

    def inputs(self, start: int = 0, stop: int = -1) -> Dict[str, np.ndarray]:
        """Sliders (n, 3) m, payload (n, 3) N, variant (n,) and grid_index (n, 3) of samples."""
        stop = self.size if stop < 0 else stop
        if not 0 <= start <= stop <= self.size:
            raise ValueError(f'sample range {start}:{stop} is outside 0:{self.size}')
        order = serpentine(self.grid)
        index = np.arange(start, stop)
        point = index % self.block
        payload = (index // self.block) % len(self.payloads)
        variant = index // (self.block * len(self.payloads))
        grid_index = order[point]
        levels = np.array([np.linspace(-stroke, stroke, self.grid) for stroke in self.strokes])
        sliders = levels[variant[:, None], grid_index]
        return {'sliders': sliders, 'payload': np.array(self.payloads)[payload],
                'variant': variant, 'grid_index': grid_index}


def serpentine(grid: int) -> np.ndarray:
    """
    Return the grid indices (grid^3, 3) of an N x N x N grid in serpentine order.

    Slider 1 runs fastest, back and forth; consecutive rows differ by one step of one index.
    """
    rows: List[Tuple[int, int, int]] = []
    for k in range(grid):
        plane = []
        for j in range(grid):
            line = [(i, j, k) for i in range(grid)]
            plane.append(line if j % 2 == 0 else line[::-1])
        if k % 2 == 1:
            plane = [line[::-1] for line in plane[::-1]]
        rows.extend(point for line in plane for point in line)
    return np.array(rows, dtype=int)


#: Robots of this process, one per params file (a worker keeps them across chunks).
_ROBOTS: Dict[Tuple[str, AtlasSpec], DeltaRobot] = {}


def _robot(path: str, spec: AtlasSpec) -> DeltaRobot:
    key = (path, spec)
    if key not in _ROBOTS:
        _ROBOTS[key] = DeltaRobot.from_yaml(
            path, time_limit_s=spec.time_limit_s, fidelity=spec.fidelity,
            max_position_error=spec.max_position_error, max_angle_error=spec.max_angle_error)
    return _ROBOTS[key]


def empty_results(count: int) -> Dict[str, np.ndarray]:
    """Return result arrays for ``count`` samples: NaN, False, empty messages."""
    arrays = {}
    for name, (shape, dtype, _, _) in RESULT_VARIABLES.items():
        array = np.zeros((count,) + shape, dtype=dtype)
        if array.dtype.kind == 'f':
            array[...] = np.nan
        arrays[name] = array
    return arrays


def solve_chunk(spec: AtlasSpec, start: int, stop: int) -> Dict[str, np.ndarray]:
    """
    Solve samples ``start:stop`` of ``spec`` in order, warm-started from each other.

    The chunk starts cold. Every sample's outcome is recorded, converged or not (its
    ``message`` says why); an exception inside a solve is a bug and propagates. 'cc' legs
    are solved in one compiled loop (DeltaRobot.solve_columns), other levels sample by
    sample.
    """
    inputs = spec.inputs(start, stop)
    out = empty_results(stop - start)
    variant = int(inputs['variant'][0]) if stop > start else 0
    robot = _robot(spec.params_files[variant], spec)
    robot.reset()
    if np.all(inputs['variant'] == variant) and robot.solve_columns(
            inputs['sliders'], inputs['payload'], out, store):
        out['leg_fidelity'][:] = LEVEL_CODES[spec.fidelity]
        return out
    rows = zip(inputs['sliders'], inputs['payload'], inputs['variant'])
    for row, (sliders, payload, which) in enumerate(rows):
        if which != variant:
            variant = int(which)
            robot = _robot(spec.params_files[variant], spec)
            robot.reset()
        result = robot.solve(sliders, payload, compliance=True)
        store(out, row, result)
    return out


def store(out: Dict[str, np.ndarray], row: int, result) -> None:
    """Copy one DeltaResult into row ``row`` of the result arrays."""
    out['converged'][row] = result.converged
    out['message'][row] = result.message[:MESSAGE_LENGTH]
    out['iterations'][row] = result.iterations
    out['solve_time_s'][row] = result.solve_time_s
    if len(result.leg_results) != 3:
        return
    out['platform_position'][row] = result.platform_position
    out['platform_rotation_vector'][row] = result.platform_rotation_vector
    out['parasitic_rotation'][row] = result.platform_rotation_angle
    out['leg_bending'][row] = result.leg_bending
    out['leg_axial_force'][row] = result.leg_axial_forces
    if result.platform_compliance is not None:
        translation, rotation = result.compliance_eigenvalues
        out['compliance_eigenvalues_translation'][row] = translation
        out['compliance_eigenvalues_rotation'][row] = rotation
        out['slider_jacobian'][row] = result.input_sensitivity[:3, :3]
        out['stiffness_margin'][row] = result.stiffness_margin
    out['stable'][row] = bool(result.stable) and result.converged
    out['leg_fidelity'][row] = [LEVEL_CODES[level] for level in result.leg_fidelity]
    out['leg_error_bound_position'][row] = result.leg_error_bound_m
    out['leg_error_bound_angle'][row] = result.leg_error_bound_deg


def chunk_bounds(size: int, chunk_size: int) -> List[Tuple[int, int]]:
    """Return (start, stop) of each chunk of ``chunk_size`` consecutive samples."""
    if chunk_size < 1:
        raise ValueError(f'chunk size must be at least 1, got {chunk_size}')
    return [(start, min(start + chunk_size, size)) for start in range(0, size, chunk_size)]


def workspace_volumes(spec: AtlasSpec, results: Dict[str, np.ndarray]) -> List[dict]:
    """
    Return the workspace volume (m^3) of each (variant, payload) block, two ways.

    ``convex_hull_m3``: the convex hull of the platform positions of converged, stable
    samples (scipy.spatial.ConvexHull); exact for a convex workspace, an over-estimate
    otherwise. ``jacobian_m3``: the image volume of the slider box, the integral of
    |det dp/dq| over it by the trapezoidal rule on the grid (needs every sample of the block
    converged with a finite Jacobian, else NaN: not assessed; it does not assume
    convexity). Both count only what the sliders reach.
    """
    volumes = []
    for variant, stroke in enumerate(spec.strokes):
        weights1 = np.full(spec.grid, 2.0 * stroke / (spec.grid - 1))
        weights1[[0, -1]] *= 0.5
        for payload_index, payload in enumerate(spec.payloads):
            first = (variant * len(spec.payloads) + payload_index) * spec.block
            block = slice(first, first + spec.block)
            good = results['converged'][block] & results['stable'][block]
            positions = results['platform_position'][block][good]
            hull = math.nan
            if len(positions) >= 4:
                try:
                    hull = float(ConvexHull(positions).volume)
                except QhullError:
                    hull = 0.0
            jacobian = math.nan
            if np.all(results['converged'][block]) and np.all(
                    np.isfinite(results['slider_jacobian'][block])):
                grid_index = spec.inputs(first, first + spec.block)['grid_index']
                weights = np.prod(weights1[grid_index], axis=1)
                determinants = np.abs(np.linalg.det(results['slider_jacobian'][block]))
                jacobian = float(np.sum(weights * determinants))
            volumes.append({'variant': variant, 'params_file': spec.params_files[variant],
                            'payload_n': list(payload), 'samples': int(spec.block),
                            'converged_stable': int(good.sum()),
                            'convex_hull_m3': hull, 'jacobian_m3': jacobian})
    return volumes
