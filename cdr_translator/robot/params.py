"""
Geometry of the Continuum Delta Robot (CDR): three translator legs, sliders, platform.

The values live in the ``cdr_node: ros__parameters:`` section of config/translator.yaml,
beside the leg's own ``translator_node`` section (the three legs are identical
translators). Frames, all right-handed, SI:

* world {w}: origin at the centre of the base, z along the robot axis pointing away from
  the platform (up when the platform hangs below the base, as in a pick-and-place robot);
* leg i base frame {pe_i}: at the leg's base disk, z along the unloaded leg towards the
  platform, x in the leg's radial plane pointing towards the robot axis, y tangential
  (counter-clockwise about world z). The translator solver works in this frame;
* platform {p}: at home parallel to {w}, origin at the centre of the three end disks.

At home (all sliders at 0) every leg is straight, so its inclination from the robot axis
follows from the two radii and the leg's stack height: sin(beta) = (R_b - R_p) / H.
"""

from dataclasses import dataclass, fields
import math
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Tuple, Union
import warnings

import numpy as np
from numpy.typing import ArrayLike

from ..checks import check_number
from ..errors import InputError, ParameterError, PlausibilityWarning
from ..params.params_file import (applicable_sections, CommandLineValues, Layer, layered_values,
                                  section_values)
from ..params.translator_params import (DEFAULT_PARAMS_PATH, NODE_NAME, PLAUSIBLE_MAX_LENGTH_M,
                                        TranslatorParams)

#: The section of the params file holding the CDR geometry (also the cdr_node's name).
CDR_NODE_NAME = 'cdr_node'

#: Keys of the cdr_node section that belong to the ROS node, not to the geometry.
CDR_NODE_ONLY_KEYS: frozenset = frozenset((
    'world_frame', 'max_force', 'max_moment', 'solve_time_limit_s', 'log_to_mcap',
    'mcap_path', 'log_dir', 'mcap_flush_messages', 'mcap_flush_s', 'input_queue_depth'))


@dataclass(frozen=True)
class Leg:
    """
    Fixed geometry of one leg in the world frame {w} (SI).

    ``rotation`` is the orientation of the leg base frame {pe_i} in {w} (it never
    changes: the slider only translates the base disk); ``home_base`` the base-disk
    centre at slider position 0; ``slider_axis`` the unit direction along which a
    positive slider position moves it; ``attachment`` the end-disk centre in the
    platform frame {p} (the end disk is fixed to the platform with orientation
    ``rotation`` relative to {p}).
    """

    rotation: np.ndarray
    home_base: np.ndarray
    slider_axis: np.ndarray
    attachment: np.ndarray

    def base(self, slider: float) -> np.ndarray:
        """Base-disk centre in {w} at slider position ``slider`` (m)."""
        return self.home_base + slider * self.slider_axis


@dataclass(frozen=True)
class DeltaParams:
    """
    CDR geometry (lengths in m, angles in degrees as in the YAML; radians via properties).

    ``leg_azimuths_deg``: azimuth of each leg's radial plane about world z, from x.
    ``slider_inclination_deg``: angle of each slider axis from the robot axis, tilted in
    the leg's radial plane towards the axis (0: sliders parallel to the robot axis, the
    positive direction pointing at the platform side, -z). ``slider_stroke``: the largest
    allowed absolute slider position from home.
    """

    base_radius: float
    platform_radius: float
    leg_azimuths_deg: Tuple[float, float, float]
    slider_inclination_deg: float
    slider_stroke: float

    def __post_init__(self) -> None:
        """Validate every field; raise ParameterError naming the offending key."""
        for name in ('base_radius', 'platform_radius', 'slider_stroke'):
            check_number(name, getattr(self, name), low=0.0, low_open=True,
                         error=ParameterError)
        check_number('slider_inclination_deg', self.slider_inclination_deg, low=-90.0,
                     high=90.0, low_open=True, high_open=True, error=ParameterError)
        azimuths = self.leg_azimuths_deg
        if not isinstance(azimuths, (tuple, list)) or len(azimuths) != 3:
            raise ParameterError(
                f'leg_azimuths_deg must be three finite numbers, got {azimuths!r}')
        for index, azimuth in enumerate(azimuths):
            check_number(f'leg_azimuths_deg[{index}]', azimuth, error=ParameterError)
        object.__setattr__(self, 'leg_azimuths_deg', tuple(float(a) for a in azimuths))
        for k in range(3):
            gap = (azimuths[(k + 1) % 3] - azimuths[k]) % 360.0
            if min(gap, 360.0 - gap) < 1.0:
                raise ParameterError(
                    f'leg_azimuths_deg {list(azimuths)!r}: two legs share a radial plane')
        for text in self.implausibilities():
            warnings.warn(text, PlausibilityWarning, stacklevel=3)

    def implausibilities(self) -> List[str]:
        """Say which legal lengths lie far outside the robot's scale (PlausibilityWarning)."""
        return [f'{name} is {getattr(self, name)!r} m, a length of {PLAUSIBLE_MAX_LENGTH_M:g} m '
                'or more: millimetres typed as metres?'
                for name in ('base_radius', 'platform_radius', 'slider_stroke')
                if getattr(self, name) >= PLAUSIBLE_MAX_LENGTH_M]

    @property
    def slider_inclination(self) -> float:
        """Slider inclination from the robot axis (rad)."""
        return math.radians(self.slider_inclination_deg)

    def leg_inclination(self, stack_height: float) -> float:
        """Inclination beta of the straight legs from the robot axis (rad), towards it."""
        ratio = (self.base_radius - self.platform_radius) / stack_height
        if not -1.0 < ratio < 1.0:
            raise ParameterError(
                f'base_radius ({self.base_radius!r}) and platform_radius '
                f'({self.platform_radius!r}) differ by more than the leg stack height '
                f'({stack_height!r} m): straight legs cannot reach the platform')
        return math.asin(ratio)

    def home_height(self, stack_height: float) -> float:
        """Height of the platform origin at home, H cos(beta) below the base (m)."""
        return stack_height * math.cos(self.leg_inclination(stack_height))

    def legs(self, stack_height: float) -> Tuple[Leg, Leg, Leg]:
        """Return the fixed geometry of the three legs, of unloaded length ``stack_height``."""
        beta = self.leg_inclination(stack_height)
        gamma = self.slider_inclination
        legs = []
        for azimuth_deg in self.leg_azimuths_deg:
            azimuth = math.radians(azimuth_deg)
            turn = np.array([[math.cos(azimuth), -math.sin(azimuth), 0.0],
                             [math.sin(azimuth), math.cos(azimuth), 0.0],
                             [0.0, 0.0, 1.0]])
            # columns x, y, z of {pe_i} in the leg's radial plane frame (radial, tangential, up)
            local = np.array([[-math.cos(beta), 0.0, -math.sin(beta)],
                              [0.0, 1.0, 0.0],
                              [math.sin(beta), 0.0, -math.cos(beta)]])
            rotation = turn @ local
            radial = turn[:, 0]
            legs.append(Leg(
                rotation=rotation,
                home_base=self.base_radius * radial,
                slider_axis=turn @ np.array([-math.sin(gamma), 0.0, -math.cos(gamma)]),
                attachment=self.platform_radius * radial))
        return legs[0], legs[1], legs[2]

    # Construction ---------------------------------------------------------------------------
    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> 'DeltaParams':
        """Build from a flat mapping; unknown or missing keys raise ParameterError naming them."""
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(values) - known - CDR_NODE_ONLY_KEYS)
        if unknown:
            raise ParameterError(
                f'unknown {CDR_NODE_NAME} parameter(s) {", ".join(unknown)}; known: '
                f'{", ".join(sorted(known))}')
        missing = sorted(known - set(values))
        if missing:
            raise ParameterError(f'missing {CDR_NODE_NAME} parameter(s) {", ".join(missing)}')
        picked = {key: value for key, value in values.items() if key in known}
        return cls(**picked)

    @classmethod
    def from_yaml(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> 'DeltaParams':
        """Read the cdr_node parameters of a params file over the shipped ones, key by key."""
        values = cdr_values([path])
        return cls.from_mapping({key: values[key] for key in cls.__dataclass_fields__})


def cdr_values(paths: Iterable[Layer], namespace: str = '/',
               node_name: str = CDR_NODE_NAME, overrides: Optional[Mapping[str, Any]] = None,
               defaults_path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> Dict[str, Any]:
    """
    Every cdr_node parameter: shipped defaults, then each file key by key (ROS 2 semantics).

    The legs' model comes from the translator_node sections (the leg's one source of model
    parameters); a section that applies to cdr_node (its name, ``/**``) may override it for
    this node too, as ROS would. ``-p name:=value`` values stand among ``paths`` as
    CommandLineValues, in their place; ``overrides`` are applied last.
    """
    paths = list(paths)
    files = [path for path in paths if not isinstance(path, CommandLineValues)]
    for path in files:
        if path is not None and not (applicable_sections(path, NODE_NAME, namespace)
                                     or applicable_sections(path, node_name, namespace)):
            raise ParameterError(f'{path} has no section for {node_name} or {NODE_NAME} '
                                 '(their names or /**:, with ros__parameters:)')
    # the -p values apply to this node alone, in their place among the files, below
    model = layered_values(NODE_NAME, files, defaults_path, namespace, required=False)
    declared = {**{field.name: model[field.name] for field in fields(TranslatorParams)},
                **section_values(defaults_path, CDR_NODE_NAME)}
    return layered_values(node_name, paths, defaults_path, namespace, defaults=declared,
                          overrides=overrides, required=False)


def check_sliders(sliders: ArrayLike, stroke: float) -> np.ndarray:
    """Return the 3 slider positions (m); ValueError naming a bad or out-of-stroke value."""
    array = np.asarray(sliders, dtype=float)
    if array.shape != (3,):
        raise InputError(f'sliders must have 3 positions (one per leg), got shape {array.shape}')
    for leg, value in enumerate(array, start=1):
        if not math.isfinite(value):
            raise InputError(f'slider {leg} position is {value}: it must be finite')
        if abs(value) > stroke:
            raise InputError(f'slider {leg} position {value} m is outside the stroke '
                             f'+-{stroke} m (cdr_node slider_stroke)')
    return array
