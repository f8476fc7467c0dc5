"""
The unknowns of a pose fit (pose_fit.py): which keys may be fitted, and their scaled units.

A fit moves scaled unknowns of comparable size, one "unit" each: log(p / p0) for a
positive model key (p = p0 exp(x), so it stays positive and a unit is a relative change),
(nu - nu0) / 0.5 for ``poisson_ratio``, 0.1 m for a translation of the tracker frame and
0.5 rad for one of its rotation-vector components. pose_fit.py refuses a fit whose
predicted standard error exceeds one unit.
"""

import difflib
import math
from typing import Any, Dict, List, Mapping, Sequence, Tuple

import numpy as np

from .pose_error import FRAME_NAMES
from ..params.translator_params import TranslatorParams

__all__ = ['FITTABLE', 'FitParameters', 'SI_UNITS', 'check_fit_names']

#: Model keys a fit may move: the continuous numbers of the model (TranslatorParams).
FITTABLE = ('pitch_radius', 'backbone_diameter', 'disk_spacing', 'tube_length',
            'youngs_modulus', 'poisson_ratio')
#: SI unit of every name a fit reports: the model keys, then the tracker frame's six numbers.
SI_UNITS = {'pitch_radius': 'm', 'backbone_diameter': 'm', 'disk_spacing': 'm',
            'tube_length': 'm', 'youngs_modulus': 'Pa', 'poisson_ratio': '1',
            'frame_x': 'm', 'frame_y': 'm', 'frame_z': 'm',
            'frame_rx': 'rad', 'frame_ry': 'rad', 'frame_rz': 'rad'}
#: Physical size of one unit of a scaled unknown that is not positive (see the module text).
ADDITIVE_UNITS = {'poisson_ratio': 0.5, 'frame_x': 0.1, 'frame_y': 0.1, 'frame_z': 0.1,
                  'frame_rx': 0.5, 'frame_ry': 0.5, 'frame_rz': 0.5}

#: Open ranges of the model keys that are not merely positive (TranslatorParams checks them).
RANGES = {'poisson_ratio': (-1.0, 0.5)}
#: A fitted value this close to the end of its range (in units) has run into it.
EDGE = 1e-3


def check_fit_names(names: Sequence[str], values: Mapping[str, Any]) -> Tuple[str, ...]:
    """
    Return ``names`` as a tuple if each is a fittable model key of the translator section.

    ``values`` are every translator_node parameter (the section of the params file). A
    ValueError names every offending key and why: unknown (with a close match), not a
    number, a whole number (discrete), a key that does not change the model's pose, or
    given twice.
    """
    names = tuple(names)
    problems = []
    for name in sorted(set(names)):
        if name not in values:
            close = difflib.get_close_matches(name, list(values) + list(FITTABLE), n=1)
            problems.append(f'{name}: not a translator_node parameter'
                            + (f' (did you mean {close[0]}?)' if close else ''))
        elif isinstance(values[name], bool) or not isinstance(values[name], (int, float)):
            problems.append(f'{name}: not numeric ({type(values[name]).__name__})')
        elif isinstance(values[name], int):
            problems.append(f'{name}: a whole number, not a continuous one')
        elif name not in FITTABLE:
            problems.append(f'{name}: does not change the predicted pose (fittable: '
                            f'{", ".join(FITTABLE)})')
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        problems.append(f'given more than once: {", ".join(repeated)}')
    if problems:
        raise ValueError('cannot fit ' + '; '.join(problems))
    return names


class FitParameters:
    """Scaled unknowns: the model keys, then (with ``fit_frame``) the six frame numbers."""

    def __init__(self, params: TranslatorParams, names: Sequence[str], fit_frame: bool,
                 frame: np.ndarray) -> None:
        """Start at ``params`` and the tracker frame ``frame`` (fixed unless fitted)."""
        unknown = [name for name in names if name not in FITTABLE]
        if unknown:
            raise ValueError(f'cannot fit {", ".join(unknown)}: fittable keys are '
                             f'{", ".join(FITTABLE)}')
        self.model_names = tuple(names)
        self.model_count = len(self.model_names)
        self.fit_frame = fit_frame
        self.names = self.model_names + (FRAME_NAMES if fit_frame else ())
        if not self.names:
            raise ValueError('nothing to fit: name a parameter or fit the frame')
        self.start_values = {name: float(getattr(params, name)) for name in self.model_names}
        self.frame = np.array(frame, dtype=float)
        self.frame_units = np.array([ADDITIVE_UNITS[name] for name in FRAME_NAMES])

    def start(self) -> np.ndarray:
        """Return the scaled unknowns at the start."""
        frame = self.frame / self.frame_units if self.fit_frame else np.zeros(0)
        return np.concatenate([np.zeros(self.model_count), frame])

    def model_part(self, x: np.ndarray) -> np.ndarray:
        """Return the model keys' part of ``x``."""
        return np.asarray(x[:self.model_count], dtype=float)

    def with_frame(self, x: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """Return ``x`` with its frame part set to ``frame`` (6 physical numbers)."""
        return np.concatenate([self.model_part(x), np.asarray(frame) / self.frame_units])

    def model_values(self, model_x: np.ndarray) -> Dict[str, float]:
        """Return the physical values of the model keys at their scaled unknowns."""
        values = {}
        for name, scaled in zip(self.model_names, model_x):
            start = self.start_values[name]
            values[name] = (start + ADDITIVE_UNITS[name] * float(scaled)
                            if name in ADDITIVE_UNITS else start * math.exp(float(scaled)))
        return values

    def frame_values(self, x: np.ndarray) -> np.ndarray:
        """Return the tracker frame (6 physical numbers) at ``x``."""
        if not self.fit_frame:
            return self.frame
        return np.asarray(x[self.model_count:], dtype=float) * self.frame_units

    def physical(self, x: np.ndarray) -> Dict[str, float]:
        """Return every unknown's physical value at ``x``, keyed by name."""
        values = self.model_values(self.model_part(x))
        if self.fit_frame:
            values.update(zip(FRAME_NAMES, self.frame_values(x).tolist()))
        return values

    def at_edge(self, x: np.ndarray) -> List[str]:
        """Name the model keys whose value at ``x`` lies at an end of its valid range."""
        values = self.model_values(self.model_part(x))
        return [name for name, (low, high) in RANGES.items() if name in values and min(
            values[name] - low, high - values[name]) < EDGE * ADDITIVE_UNITS[name]]

    def physical_errors(self, x: np.ndarray, deviations: np.ndarray) -> Dict[str, float]:
        """Return standard errors in physical units from those of the scaled unknowns."""
        values = self.physical(x)
        return {name: float(deviation) * (ADDITIVE_UNITS[name] if name in ADDITIVE_UNITS
                                          else abs(values[name]))
                for name, deviation in zip(self.names, deviations)}
