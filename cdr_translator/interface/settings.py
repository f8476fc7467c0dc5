"""
The one settings type of each node section, for the nodes, the CLI and replay alike.

``TranslatorSettings`` holds every ``translator_node`` parameter, ``CdrSettings`` every
``cdr_node`` one, each validated in one place (``from_values``): the model through
TranslatorParams / DeltaParams, the rest against the specs below (ranges, frames). They are
read with ROS 2 params-file semantics (cdr_translator.params.params_file): the shipped
config/translator.yaml, then each given file key by key; ``/**`` and the node's fully
qualified name both apply; an unknown key or a value of the wrong ROS type is an error
naming it. The specs are ROS-free; cdr_translator.ros.parameters turns them into
descriptors.
"""

from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Dict, Iterable, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ..checks import check_covariance, check_integer, check_number
from ..errors import InputError, ParameterError
from ..estimation import Components, estimated_components
from ..fidelity import FIDELITIES
from ..params.params_file import Layer, layered_values
from ..params.translator_params import (Accuracy, ACCURACY_KEYS, DEFAULT_PARAMS_PATH,
                                        FIDELITY_KEYS, NODE_NAME)
from ..params.translator_params import MAX_SPACERS_PER_JOINT, MAX_STEPS_PER_SEGMENT, NODE_ONLY_KEYS
from ..params.translator_params import TranslatorParams
from ..robot.params import CDR_NODE_NAME, CDR_NODE_ONLY_KEYS, cdr_values, DeltaParams

__all__ = ['CDR_SPECS', 'CdrSettings', 'check_value', 'ESTIMATE_KEYS', 'estimate_components',
           'MODEL_KEYS', 'ParameterSpec', 'SPECS', 'TranslatorSettings']

PathLike = Union[str, Path]

#: Units a spec's description may open with, before a comma ('m, radius of ...').
UNITS = ('m', 'Pa', 'N', 'N m', 's', 'deg', 'rad')


@dataclass(frozen=True)
class ParameterSpec:
    """Name, human description, read-only flag, closed bounds (both or neither), choices."""

    name: str
    description: str
    read_only: bool = False
    bounds: Optional[Tuple[float, float]] = None
    choices: Optional[Tuple[str, ...]] = None

    @property
    def unit(self) -> str:
        """Return the unit the description opens with ('' for none)."""
        head, separator, _ = self.description.partition(', ')
        return head if separator and head in UNITS else ''

    @property
    def meaning(self) -> str:
        """Return the description without its unit."""
        unit = self.unit
        return self.description[len(unit) + 2:] if unit else self.description

    def check(self, value: Any) -> None:
        """Raise ParameterError naming the key for a value outside its bounds or choices."""
        if self.choices is not None and value not in self.choices:
            raise ParameterError(f'{self.name} must be one of {", ".join(self.choices)}, got '
                                 f'{value!r}')
        if self.bounds is None:
            return
        low, high = self.bounds
        if isinstance(value, int) and not isinstance(value, bool):
            check_integer(self.name, value, low=int(low), high=int(high), error=ParameterError)
        else:
            check_number(self.name, value, low=low, high=high, error=ParameterError)


_MODEL = (
    ParameterSpec('pitch_radius', 'm, radius of the circle the 4 secondary backbones sit on',
                  read_only=True),
    ParameterSpec('backbone_diameter', 'm, diameter of every backbone', read_only=True),
    ParameterSpec('disk_spacing', 'm, distance between adjacent disks of one joint',
                  read_only=True),
    ParameterSpec('tube_length', 'm, length L_m of the multi-lumen tube', read_only=True),
    ParameterSpec('youngs_modulus', 'Pa, Young modulus E of the backbones', read_only=True),
    ParameterSpec('poisson_ratio', 'Poisson ratio; G = E / (2 (1 + nu))', read_only=True),
    ParameterSpec('spacers_per_joint', 'spacer disks per continuum joint', read_only=True,
                  bounds=(0, MAX_SPACERS_PER_JOINT)),
    ParameterSpec('steps_per_segment', 'RK4 steps per disk interval', read_only=True,
                  bounds=(1, MAX_STEPS_PER_SEGMENT)),
)

_NODE = (
    ParameterSpec('base_frame', 'frame_id of {pe}, the PJ end disk; wrenches in it or with '
                  'an empty frame_id are used as they are; poses are published in it'),
    ParameterSpec('end_disk_frame', 'frame_id of {de}, the DJ end disk; wrenches in it are '
                  'rotated into base_frame with the solved end-disk pose'),
    ParameterSpec('max_force', 'N, wrenches with a larger |force| are rejected, and '
                  'estimates search no further', bounds=(0.0, 1e6)),
    ParameterSpec('max_moment', 'N m, wrenches with a larger |moment| are rejected, and '
                  'estimates search no further', bounds=(0.0, 1e6)),
    ParameterSpec('solve_time_limit_s', 's, a solve running longer gives up (no pose)',
                  bounds=(1e-3, 60.0)),
    ParameterSpec('log_compliance', 'compute and publish the compliance for every solve, '
                  'not only while compliance topics have subscribers'),
    ParameterSpec('log_backbones', 'publish backbone markers for every solve, not only while '
                  'backbones has subscribers'),
    ParameterSpec('log_to_mcap', 'log every received wrench and published output to MCAP',
                  read_only=True),
    ParameterSpec('mcap_path', 'MCAP file to write; empty: an auto-named file in log_dir',
                  read_only=True),
    ParameterSpec('log_dir', 'folder of the auto-named MCAP files', read_only=True),
    ParameterSpec('mcap_flush_messages', 'finish an MCAP chunk after this many messages',
                  read_only=True, bounds=(1, 1_000_000)),
    ParameterSpec('mcap_flush_s', 's, finish an MCAP chunk at least this often',
                  read_only=True, bounds=(0.01, 3600.0)),
    ParameterSpec('wrench_queue_depth', 'wrenches the subscription holds while the node is '
                  'busy (best effort, keep last); 100 absorbs a 0.1 s stall at 1 kHz',
                  read_only=True, bounds=(1, 100_000)),
    ParameterSpec('pending_wrenches', 'received wrenches that may wait for the solver; when '
                  'one more arrives the oldest waiting one is skipped. 1: latest wins (only '
                  'the newest waits); 2: two wrenches arriving within one solve are both '
                  'answered', read_only=True, bounds=(1, 1000)),
    ParameterSpec('diagnostics_period_s', 's, publish one aggregated DiagnosticArray on '
                  '/diagnostics this often (REP 107: about 1 s); each wrench has its status '
                  'on solve_status', read_only=True, bounds=(1e-3, 3600.0)),
)

_FIDELITY = (
    ParameterSpec('fidelity', 'model level: full, rod, cc, linear, or auto (cheapest within '
                  'max_position_error / max_angle_error)', read_only=True,
                  choices=FIDELITIES),
    ParameterSpec('max_position_error', "m, end-disk position error budget of fidelity 'auto'",
                  read_only=True, bounds=(0.0, 1.0)),
    ParameterSpec('max_angle_error', "deg, bending-angle error budget of fidelity 'auto'",
                  read_only=True, bounds=(0.0, 90.0)),
)

_ACCURACY = (
    ParameterSpec('accuracy_position_m', 'm, largest estimated discretization error of the '
                  'end-disk position before a solve is refined (0: never refine)',
                  read_only=True, bounds=(0.0, 1.0)),
    ParameterSpec('accuracy_angle_deg', 'deg, largest estimated discretization error of the '
                  'end-disk orientation before a solve is refined (0: never refine)',
                  read_only=True, bounds=(0.0, 90.0)),
)

_ESTIMATE = (
    ParameterSpec('estimate_prior_force_sd', 'N, standard deviation of the zero-mean '
                  'Gaussian prior on each force component of an estimated wrench',
                  bounds=(1e-6, 1e6)),
    ParameterSpec('estimate_prior_moment_sd', 'N m, standard deviation of the prior on each '
                  'moment component', bounds=(1e-6, 1e6)),
    ParameterSpec('estimate_prior_covariance', '36 doubles, row-major 6x6 prior covariance of '
                  '[f; m] (symmetric positive semidefinite); empty: the two prior sds'),
    ParameterSpec('estimate_target_force_sd', 'N, posterior standard deviation of each '
                  'estimated force component that meets the accuracy target',
                  bounds=(1e-6, 1e6)),
    ParameterSpec('estimate_target_moment_sd', 'N m, the same for each moment component',
                  bounds=(1e-6, 1e6)),
    ParameterSpec('estimate_components', "wrench components estimated from a pose: '' (all "
                  'six), wrench, force, moment, lateral, or names from fx fy fz mx my mz; '
                  'the others are held at estimate_held_force / estimate_held_moment'),
    ParameterSpec('estimate_held_force', 'N, [fx, fy, fz] of the force components not '
                  'estimated'),
    ParameterSpec('estimate_held_moment', 'N m, [mx, my, mz] of the moment components not '
                  'estimated'),
    ParameterSpec('estimate_pose_position_sd', 'm, position standard deviation assumed for a '
                  'PoseStamped (no covariance); 0 with estimate_pose_orientation_sd 0: exact '
                  'pose, accuracy not assessed', bounds=(0.0, 1.0)),
    ParameterSpec('estimate_pose_orientation_sd', 'rad, orientation standard deviation '
                  'assumed for a PoseStamped (about each base axis)', bounds=(0.0, 3.2)),
)

#: Every parameter translator_node declares, by name.
SPECS: Mapping[str, ParameterSpec] = {
    spec.name: spec for spec in _MODEL + _NODE + _FIDELITY + _ACCURACY + _ESTIMATE}

#: The estimate's parameters: how a wrench is estimated from a measured pose.
ESTIMATE_KEYS = frozenset(spec.name for spec in _ESTIMATE)

#: The model's keys (TranslatorParams fields), as opposed to the node-only ones.
MODEL_KEYS = frozenset(spec.name for spec in _MODEL)

_GEOMETRY = (
    ParameterSpec('base_radius', 'm, leg base-disk centres from the robot axis at home',
                  read_only=True),
    ParameterSpec('platform_radius', 'm, end-disk centres from the platform centre',
                  read_only=True),
    ParameterSpec('leg_azimuths_deg', 'deg, radial plane of each leg about the robot axis',
                  read_only=True),
    ParameterSpec('slider_inclination_deg', 'deg, slider axes from the robot axis, tilted '
                  'towards it in each radial plane', read_only=True),
    ParameterSpec('slider_stroke', 'm, slider positions beyond +-this are rejected',
                  read_only=True),
)

_CDR_NODE = (
    ParameterSpec('world_frame', 'frame_id of the platform pose; payload wrenches must be '
                  'in it or have an empty frame_id'),
    ParameterSpec('input_queue_depth', 'messages each input subscription (sliders, '
                  'platform_wrench, target_position) holds while the node is busy (best '
                  'effort, keep last); 100 absorbs a 0.1 s stall at 1 kHz',
                  read_only=True, bounds=(1, 100_000)),
)

#: Every parameter cdr_node declares: the leg model and the run-time and logging settings
#: as translator_node declares them, plus the robot's geometry and world frame.
CDR_SPECS: Mapping[str, ParameterSpec] = {
    **{name: SPECS[name] for name in sorted(MODEL_KEYS)},
    **{name: SPECS[name] for name in sorted(CDR_NODE_ONLY_KEYS) if name in SPECS},
    **{spec.name: spec for spec in _GEOMETRY + _CDR_NODE}}

#: The translator_node keys whose values are lists of doubles.
_LISTS = ('estimate_prior_covariance', 'estimate_held_force', 'estimate_held_moment')

_FRAME_PAIRS = {'base_frame': 'end_disk_frame', 'end_disk_frame': 'base_frame'}


def _doubles(name: str, value: Any, sizes: Tuple[int, ...]) -> Tuple[float, ...]:
    """Return a list of doubles as floats; ParameterError unless ``sizes`` allows its length."""
    items = [] if value is None else value  # an empty double array ROS holds unset
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence) and not hasattr(
            items, 'tolist'):
        raise ParameterError(f'{name} must be a list of {" or ".join(map(str, sizes))} '
                             f'doubles, got {value!r}')
    items = list(items)
    if len(items) not in sizes or not all(isinstance(item, float) for item in items):
        raise ParameterError(f'{name} must be a list of {" or ".join(map(str, sizes))} '
                             f'doubles (1.0, not 1), got {value!r}')
    return tuple(check_number(f'{name}[{index}]', item, error=ParameterError)
                 for index, item in enumerate(items))


def estimate_components(choice: str) -> Optional[Components]:
    """Return ``estimate_components`` as ``estimate=`` takes it; '' (as the pose allows) None."""
    return choice.strip() or None


def _estimate_reason(name: str, value: Any, others: Mapping[str, Any]) -> Optional[str]:
    """Return why an estimate parameter may not take ``value`` (None if it may)."""
    values = {**others, name: value}
    try:
        if name in ('estimate_held_force', 'estimate_held_moment'):
            _doubles(name, value, (3,))
        if name in ('estimate_components', 'estimate_prior_covariance'):
            choice = values.get('estimate_components', '')
            if not isinstance(choice, str):
                return f'estimate_components must be a string, got {choice!r}'
            try:
                free = list(estimated_components(estimate_components(choice), True, None,
                                                 None))
            except InputError as error:
                return f'estimate_components: {error}'
            matrix = _doubles('estimate_prior_covariance',
                              values.get('estimate_prior_covariance', ()), (0, 36))
            if matrix:
                checked = check_covariance('estimate_prior_covariance',
                                           np.reshape(matrix, (6, 6)), 6, ParameterError)
                if np.linalg.eigvalsh(checked[np.ix_(free, free)])[0] <= 0.0:
                    return ('estimate_prior_covariance must be positive definite over the '
                            f'estimated components ({choice or "wrench"})')
    except ParameterError as error:
        return str(error)
    return None


def check_value(name: str, value: Any, others: Mapping[str, Any]) -> Optional[str]:
    """
    Return why ``name`` may not take ``value`` (None if it may), given the other values.

    Bounds as the specs give them, and what a bound cannot say: frame names non-empty,
    without white space and distinct; the estimate's lists and components.
    """
    spec = SPECS.get(name) or CDR_SPECS.get(name)
    try:
        if spec is not None:
            spec.check(value)
    except ParameterError as error:
        return str(error)
    if name in ESTIMATE_KEYS:
        return _estimate_reason(name, value, others)
    if name in ('base_frame', 'end_disk_frame', 'world_frame'):
        if not isinstance(value, str) or not value.strip():
            return f'{name} must not be empty'
        if any(character.isspace() for character in value):
            return f'{name} {value!r} must not contain white space'
        if name in _FRAME_PAIRS and value == others.get(_FRAME_PAIRS[name]):
            return f'{name} {value!r} must differ from the other frame'
    return None


def _checked(values: Mapping[str, Any], specs: Mapping[str, ParameterSpec]) -> None:
    """Raise ParameterError for the first value a spec or frame check refuses."""
    for name in specs:
        reason = check_value(name, values[name], values)
        if reason is not None:
            raise ParameterError(reason)


def _translator_values(paths: Iterable[Layer], namespace: str,
                       defaults_path: PathLike, node_name: str = NODE_NAME,
                       overrides: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
    return layered_values(node_name, paths, defaults_path, namespace, overrides=overrides,
                          defaults_section=NODE_NAME)


@dataclass(frozen=True)
class TranslatorSettings:
    """
    Every translator_node parameter: the model (``params``) and how inputs are handled.

    One immutable snapshot; a run-time change makes a new one (``with_values``).
    """

    params: TranslatorParams
    base_frame: str
    end_disk_frame: str
    max_force: float
    max_moment: float
    solve_time_limit_s: float
    log_compliance: bool
    log_backbones: bool
    log_to_mcap: bool
    mcap_path: str
    log_dir: str
    mcap_flush_messages: int
    mcap_flush_s: float
    wrench_queue_depth: int
    pending_wrenches: int
    diagnostics_period_s: float
    fidelity: str
    max_position_error: float
    max_angle_error: float
    accuracy_position_m: float
    accuracy_angle_deg: float
    estimate_prior_force_sd: float
    estimate_prior_moment_sd: float
    estimate_prior_covariance: Tuple[float, ...]  # empty, or 36 (row-major 6x6)
    estimate_target_force_sd: float
    estimate_target_moment_sd: float
    estimate_components: str
    estimate_held_force: Tuple[float, ...]
    estimate_held_moment: Tuple[float, ...]
    estimate_pose_position_sd: float
    estimate_pose_orientation_sd: float

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> 'TranslatorSettings':
        """Validate a complete flat mapping of the node's parameters (ParameterError)."""
        missing = sorted(set(SPECS) - set(values))
        unknown = sorted(set(values) - set(SPECS))
        if missing or unknown:
            raise ParameterError(f'{NODE_NAME} parameters: missing {missing}, unknown {unknown}')
        _checked(values, SPECS)
        params = TranslatorParams.from_mapping({key: values[key] for key in MODEL_KEYS})
        kept = {key: values[key] for key in NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS}
        for key in _LISTS:  # immutable, as the snapshot is
            kept[key] = _doubles(key, values[key], (0, 3, 36))
        return cls(params=params, **kept)

    @classmethod
    def from_params_files(cls, paths: Iterable[Layer] = (),
                          namespace: str = '/',
                          defaults_path: PathLike = DEFAULT_PARAMS_PATH,
                          node_name: str = NODE_NAME,
                          overrides: Optional[Mapping[str, Any]] = None
                          ) -> 'TranslatorSettings':
        """
        Read the shipped defaults, then each file key by key (ROS 2 semantics).

        ``namespace`` and ``node_name`` say which sections apply (the node's fully qualified
        name). ``-p name:=value`` values stand among ``paths`` as CommandLineValues, in
        their place (rcl's order); ``overrides`` are applied last.
        """
        return cls.from_values(_translator_values(paths, namespace, defaults_path, node_name,
                                                  overrides))

    @classmethod
    def from_params_file(cls, path: Optional[PathLike] = None) -> 'TranslatorSettings':
        """One params file over the shipped defaults (None: the shipped file alone)."""
        return cls.from_params_files([path])

    @property
    def accuracy(self) -> Accuracy:
        """Return the discretization-error target of every solve (the accuracy keys)."""
        return Accuracy(self.accuracy_position_m, self.accuracy_angle_deg)

    def values(self) -> Dict[str, Any]:
        """Return the flat parameter mapping, as written in the params file."""
        flat = {field.name: getattr(self, field.name) for field in fields(self)
                if field.name != 'params'}
        flat.update({key: list(flat[key]) for key in _LISTS})
        flat.update(self.params.to_dict())
        return flat

    def with_values(self, **changes: Any) -> 'TranslatorSettings':
        """Return validated settings with some parameters changed."""
        return self.from_values({**self.values(), **changes})


@dataclass(frozen=True)
class CdrSettings:
    """Every cdr_node parameter: the legs' model, the robot's geometry and input handling."""

    params: TranslatorParams
    geometry: DeltaParams
    world_frame: str
    max_force: float
    max_moment: float
    solve_time_limit_s: float
    log_to_mcap: bool
    mcap_path: str
    log_dir: str
    mcap_flush_messages: int
    mcap_flush_s: float
    input_queue_depth: int

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> 'CdrSettings':
        """Validate a complete flat mapping of the node's parameters (ParameterError)."""
        missing = sorted(set(CDR_SPECS) - set(values))
        unknown = sorted(set(values) - set(CDR_SPECS))
        if missing or unknown:
            raise ParameterError(
                f'{CDR_NODE_NAME} parameters: missing {missing}, unknown {unknown}')
        _checked(values, CDR_SPECS)
        params = TranslatorParams.from_mapping({key: values[key] for key in MODEL_KEYS})
        geometry = DeltaParams.from_mapping({field.name: values[field.name]
                                             for field in fields(DeltaParams)})
        return cls(params=params, geometry=geometry,
                   **{key: values[key] for key in CDR_NODE_ONLY_KEYS})

    @classmethod
    def from_params_files(cls, paths: Iterable[Layer] = (),
                          namespace: str = '/',
                          defaults_path: PathLike = DEFAULT_PARAMS_PATH,
                          node_name: str = CDR_NODE_NAME,
                          overrides: Optional[Mapping[str, Any]] = None) -> 'CdrSettings':
        """
        Read the shipped defaults, then each file key by key (ROS 2 semantics).

        The legs' model comes from the translator_node sections (``cdr_values``).
        """
        values = cdr_values(paths, namespace, node_name, overrides, defaults_path)
        return cls.from_values(values)

    @classmethod
    def from_params_file(cls, path: Optional[PathLike] = None) -> 'CdrSettings':
        """One params file over the shipped defaults (None: the shipped file alone)."""
        return cls.from_params_files([path])

    def values(self) -> Dict[str, Any]:
        """Return the flat parameter mapping, as written in the params file."""
        flat = {field.name: getattr(self, field.name) for field in fields(self)
                if field.name not in ('params', 'geometry')}
        flat.update(self.params.to_dict())
        flat.update(asdict(self.geometry))
        flat['leg_azimuths_deg'] = list(self.geometry.leg_azimuths_deg)
        return flat

    def with_values(self, **changes: Any) -> 'CdrSettings':
        """Return validated settings with some parameters changed."""
        return self.from_values({**self.values(), **changes})
