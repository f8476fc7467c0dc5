"""
Errors of the fidelity levels against a reference, and the validated ranges they hold on.

The **reference** is the full model at REFERENCE_STEPS RK4 steps per disk interval and a
1e-12 nondimensional residual (its own discretization error is below 1e-10 m).

**Errors** of a result: the end-disk position error |p - p_ref| (m) and the angle error, the
largest of the PJ and DJ bending-angle errors and the end-disk orientation error (the
rotation angle of R_ref^T R).

**Validated range** of a reduced level: nested wrench boxes |f_i| <= s F_i, |m_i| <= s M_i
(half-widths F, M = BOX_FORCE_N, BOX_MOMENT_NM; scales s in SCALES). For each box, the largest
errors over fixed samples inside it (the 12 axis extremes, the 64 corners and Halton points)
are stored. A wrench belongs to the smallest box that holds it; outside the largest it is
unvalidated. For 'linear' the boxes are offsets w - w0 from the cached wrench w0
(LINEAR_SCALES, same half-widths), sampled around cached solutions spread over the largest
box. ``cdr_translator.studies.fidelity_validation.validate`` computes all of it (about a
minute); ``bench/speed_vs_error.py`` (``make bench``) stores the result in
config/fidelity_validation.yaml, which the FidelitySolver reads. The data hold only for
the model parameters they were computed with (stored beside them); with other parameters
no reduced level is validated.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Tuple, Union

import numpy as np
import yaml

from .. import geometry
from .._jit import jit
from ..params.translator_params import Accuracy, DEFAULT_PARAMS_PATH, TranslatorParams
from ..solve.result import FRAME_NAMES, SolveResult
from ..solve.solver import TranslatorSolver

#: RK4 steps per disk interval and tolerance of the reference solution.
REFERENCE_STEPS = 32
REFERENCE_TOLERANCE = 1e-12

#: Half-widths of the largest validated wrench box.
BOX_FORCE_N = (20.0, 20.0, 20.0)
BOX_MOMENT_NM = (0.5, 0.5, 0.5)

#: Nested boxes (fractions of the largest) with an error bound each.
SCALES = (0.125, 0.25, 0.5, 1.0)

#: Offset boxes around a cached solution for the 'linear' level.
LINEAR_SCALES = (1.0 / 256.0, 1.0 / 128.0, 1.0 / 64.0, 1.0 / 32.0, 1.0 / 16.0)

#: Interior (Halton) samples per box, cached solutions and offsets per offset box of 'linear'.
INTERIOR_SAMPLES = 24
LINEAR_BASES = 8
LINEAR_OFFSETS = 16

#: Where the shipped validation data live (beside config/translator.yaml).
DEFAULT_VALIDATION_PATH = DEFAULT_PARAMS_PATH.parent / 'fidelity_validation.yaml'

#: The model parameters the data depend on (the full model's discretization does not count).
KEYED_PARAMS = ('pitch_radius', 'backbone_diameter', 'disk_spacing', 'tube_length',
                'youngs_modulus', 'poisson_ratio', 'spacers_per_joint')


def reference_solver(params: TranslatorParams) -> TranslatorSolver:
    """Return the full model at the reference discretization and tolerance."""
    return TranslatorSolver(params.with_changes(steps_per_segment=REFERENCE_STEPS),
                            tolerance=REFERENCE_TOLERANCE, time_limit_s=60.0,
                            accuracy=Accuracy(0.0, 0.0))  # the reference stays put


def pose_errors(result: SolveResult, reference: SolveResult) -> Tuple[float, float]:
    """Return (end-disk position error in m, angle error in rad) of ``result``."""
    return frame_errors(np.stack([result.frames[name] for name in FRAME_NAMES]),
                        np.stack([reference.frames[name] for name in FRAME_NAMES]))


def frame_errors(frames: np.ndarray, reference: np.ndarray) -> Tuple[float, float]:
    """
    ``pose_errors`` of frames {pe}, {pm}, {dm}, {de} (4, 4, 4) against ``reference`` frames.

    (end-disk position error in m, angle error in rad: the largest of the PJ and DJ
    bending-angle errors and the end-disk orientation error).
    """
    position = float(np.linalg.norm(frames[3, :3, 3] - reference[3, :3, 3]))
    orientation = geometry.rotation_angle(geometry.relative_rotation(reference[3], frames[3]))
    pj = geometry.bending_between(frames[0], frames[1])[0]
    dj = geometry.bending_between(frames[2], frames[3])[0]
    angle = max(abs(pj - geometry.bending_between(reference[0], reference[1])[0]),
                abs(dj - geometry.bending_between(reference[2], reference[3])[0]), orientation)
    return position, angle


def box_half_widths() -> np.ndarray:
    """Half-widths (6,) of the largest validated box, [force N; moment N m]."""
    return np.array(BOX_FORCE_N + BOX_MOMENT_NM)


#: box_half_widths() once: every solve of 'auto' measures its wrench against them.
_HALF_WIDTHS = box_half_widths()


def box_scale(wrench: np.ndarray) -> float:
    """Smallest s with the wrench (6,) inside the box of scale s (compiled: ~0.3 us)."""
    return _box_scale(np.asarray(wrench, dtype=float), _HALF_WIDTHS)


def box_scales(wrenches: np.ndarray) -> np.ndarray:
    """``box_scale`` of each row of finite ``wrenches`` (N, 6), the same floats."""
    return (np.abs(wrenches) / _HALF_WIDTHS).max(axis=1, initial=0.0)


@jit
def _box_scale(wrench, half_widths):
    """Return max |w_i| / h_i, NaN if any component is NaN (as numpy's max would)."""
    largest = 0.0
    for i in range(6):
        ratio = abs(wrench[i]) / half_widths[i]
        if math.isnan(ratio):
            return math.nan
        largest = max(largest, ratio)
    return largest


def _halton(seed: int, count: int) -> np.ndarray:
    """Return ``count`` points of the 6-D scrambled Halton sequence in [0, 1)^6."""
    from scipy.stats import qmc  # here, not at the top: importing scipy.stats takes ~1 s
    return qmc.Halton(d=6, seed=seed).random(count)


def box_samples(scale: float, seed: int) -> np.ndarray:
    """
    Wrenches (n, 6) inside the box of ``scale``: axis extremes, corners, Halton points.

    The corners come in Gray-code order (neighbours differ in one component) so that a
    warm-started reference walks short steps.
    """
    half = scale * box_half_widths()
    axes = [sign * half[i] * np.eye(6)[i] for i in range(6) for sign in (1.0, -1.0)]
    corners = []
    for index in range(64):
        gray = index ^ (index >> 1)
        signs = np.array([1.0 if gray >> bit & 1 else -1.0 for bit in range(6)])
        corners.append(signs * half)
    interior = (2.0 * _halton(seed, INTERIOR_SAMPLES) - 1.0) * half
    return np.vstack([axes, corners, interior])


def offset_samples(scale: float, rng: np.random.Generator) -> np.ndarray:
    """Offsets (LINEAR_OFFSETS, 6) on the surface of the offset box of ``scale``."""
    half = scale * box_half_widths()
    samples = rng.uniform(-1.0, 1.0, (LINEAR_OFFSETS, 6))
    # push one component of each sample to the face so that every sample is on the surface
    faces = rng.integers(0, 6, LINEAR_OFFSETS)
    samples[np.arange(LINEAR_OFFSETS), faces] = np.sign(
        samples[np.arange(LINEAR_OFFSETS), faces])
    return samples * half


@dataclass(frozen=True)
class LevelBound:
    """Largest measured errors of one level in each of its nested boxes."""

    scales: Tuple[float, ...]
    max_position_error_m: Tuple[float, ...]
    max_angle_error_deg: Tuple[float, ...]
    samples: Tuple[int, ...]

    def within(self, scale: float, max_position_error: float,
               max_angle_error_deg: float) -> bool:
        """Whether the box holding ``scale`` has its errors inside the budget."""
        for index, bound in enumerate(self.scales):
            if scale <= bound * (1.0 + 1e-12):
                return (self.max_position_error_m[index] <= max_position_error
                        and self.max_angle_error_deg[index] <= max_angle_error_deg)
        return False

    def reach(self, max_position_error: float, max_angle_error_deg: float) -> float:
        """
        Scale up to which ``within`` holds, for a lookup per wrench in O(1) (-inf: none).

        The boxes are nested and each bound pools the smaller boxes' samples (level_bound),
        so the errors grow with the scale and the boxes inside the budget come first:
        ``within(s)`` is ``s <= reach`` then. Returns math.nan for bounds that do not grow
        (data not made by level_bound): ``within`` must decide those.
        """
        if (any(np.diff(self.max_position_error_m) < 0.0)
                or any(np.diff(self.max_angle_error_deg) < 0.0)):
            return math.nan
        reach = -math.inf
        for index, bound in enumerate(self.scales):
            if not (self.max_position_error_m[index] <= max_position_error
                    and self.max_angle_error_deg[index] <= max_angle_error_deg):
                break
            reach = bound * (1.0 + 1e-12)
        return reach

    def errors_at(self, scales: Union[float, np.ndarray]) -> np.ndarray:
        """
        Return the validated errors (..., 2: m, deg) of the boxes holding ``scales`` (inf: none).

        The box ``within`` judges a scale by: the smallest that holds it.
        """
        limits = np.array(self.scales) * (1.0 + 1e-12)
        index = np.searchsorted(limits, np.asarray(scales, dtype=float), side='left')
        table = np.vstack([np.column_stack([self.max_position_error_m,
                                            self.max_angle_error_deg]),
                           np.full((1, 2), math.inf)])
        return table[np.minimum(index, len(self.scales))]

    def largest_scale(self, max_position_error: float, max_angle_error_deg: float) -> float:
        """Largest box scale whose errors stay inside the budget (0 if none)."""
        admissible = [bound for index, bound in enumerate(self.scales)
                      if self.max_position_error_m[index] <= max_position_error
                      and self.max_angle_error_deg[index] <= max_angle_error_deg]
        # the boxes are nested, so a larger admissible box implies the smaller ones
        return max(admissible, default=0.0)

    def to_dict(self) -> dict:
        """Plain dict for YAML."""
        return {'scales': [float(v) for v in self.scales],
                'max_position_error_m': [float(v) for v in self.max_position_error_m],
                'max_angle_error_deg': [float(v) for v in self.max_angle_error_deg],
                'samples': [int(v) for v in self.samples]}

    @classmethod
    def from_dict(cls, values: dict) -> 'LevelBound':
        """Inverse of ``to_dict``."""
        return cls(tuple(float(v) for v in values['scales']),
                   tuple(float(v) for v in values['max_position_error_m']),
                   tuple(float(v) for v in values['max_angle_error_deg']),
                   tuple(int(v) for v in values['samples']))


@dataclass(frozen=True)
class Validation:
    """Validated ranges and measured errors of the reduced levels for one parameter set."""

    params: Dict[str, float]
    rod_steps: int
    box: Tuple[float, ...]
    levels: Dict[str, LevelBound]

    def matches(self, params: TranslatorParams, rod_steps: int) -> bool:
        """Whether these data were computed for ``params`` and the 'rod' discretization."""
        values = params.to_dict()
        return (rod_steps == self.rod_steps
                and all(values[key] == self.params.get(key) for key in KEYED_PARAMS)
                and np.array_equal(np.array(self.box), box_half_widths()))

    def admissible(self, level: str, wrench: np.ndarray, max_position_error: float,
                   max_angle_error_deg: float, origin: Optional[np.ndarray] = None) -> bool:
        """
        Whether ``level`` meets the budget at ``wrench``.

        For 'linear' ``origin`` is the cached wrench: it must lie in the largest box and the
        offset in an offset box whose errors are inside the budget.
        """
        bound = self.levels.get(level)
        if bound is None:
            return False
        if level == 'linear':
            if origin is None or box_scale(origin) > 1.0:
                return False
            return bound.within(box_scale(wrench - origin), max_position_error,
                                max_angle_error_deg)
        return bound.within(box_scale(wrench), max_position_error, max_angle_error_deg)

    def save(self, path: Union[str, Path], header: str = '') -> None:
        """Write the data as YAML, with ``header`` as leading comment lines."""
        document = {'params': {key: self.params[key] for key in KEYED_PARAMS},
                    'rod_steps': self.rod_steps,
                    'reference': {'steps_per_segment': REFERENCE_STEPS,
                                  'tolerance': REFERENCE_TOLERANCE},
                    'box_half_widths': {'force_n': [float(v) for v in self.box[:3]],
                                        'moment_nm': [float(v) for v in self.box[3:]]},
                    'levels': {name: bound.to_dict() for name, bound in self.levels.items()}}
        comments = ''.join(f'# {line}\n' for line in header.splitlines())
        Path(path).write_text(comments + yaml.safe_dump(document, sort_keys=False))

    @classmethod
    def load(cls, path: Union[str, Path] = DEFAULT_VALIDATION_PATH) -> Optional['Validation']:
        """Read data written by ``save``; None if the file does not exist."""
        path = Path(path)
        if not path.is_file():
            return None
        document = yaml.safe_load(path.read_text())
        box = document['box_half_widths']
        return cls(dict(document['params']), int(document['rod_steps']),
                   tuple(float(v) for v in box['force_n'] + box['moment_nm']),
                   {name: LevelBound.from_dict(values)
                    for name, values in document['levels'].items()})


def level_bound(scales: Iterable[float],
                errors: Dict[float, List[Tuple[float, float]]]) -> LevelBound:
    """Largest errors per nested box: every sample of a box counts for the larger ones."""
    scales = tuple(scales)
    positions, angles, counts = [], [], []
    for index, scale in enumerate(scales):
        pooled = [pair for inner in scales[:index + 1] for pair in errors[inner]]
        positions.append(max(pair[0] for pair in pooled))
        angles.append(math.degrees(max(pair[1] for pair in pooled)))
        counts.append(len(pooled))
    return LevelBound(scales, tuple(positions), tuple(angles), tuple(counts))
