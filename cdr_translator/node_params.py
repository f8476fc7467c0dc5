"""
Parameters of translator_node: descriptors, defaults from the one YAML, run-time checks.

Every parameter the node declares is listed here with its description and bounds; the
values (and so the defaults when no ``--params-file`` is given) come from
config/translator.yaml, the file the library reads too. Geometry, material and
discretization are read-only once the node runs (the solver is built from them), and so
are the logging settings (the MCAP file is opened at start).
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Optional, Tuple, Union

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from .params import ACCURACY_KEYS, DEFAULT_PARAMS_PATH, FIDELITY_KEYS, NODE_ONLY_KEYS
from .params import MAX_SPACERS_PER_JOINT, ParameterError
from .params import read_params_file
from .params import TranslatorParams


@dataclass(frozen=True)
class ParameterSpec:
    """Name, human description and closed bounds (both or neither) of one parameter."""

    name: str
    description: str
    read_only: bool = False
    bounds: Optional[Tuple[float, float]] = None

    def descriptor(self, value: Any) -> ParameterDescriptor:
        """Return the ROS descriptor; the range typed like ``value`` (int or float)."""
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.bounds is None:
            return descriptor
        low, high = self.bounds
        if isinstance(value, int):
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high),
                                                     step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(low), to_value=float(high), step=0.0)]
        return descriptor


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
                  bounds=(1, 1024)),
)

_NODE = (
    ParameterSpec('base_frame', 'frame_id of {pe}, the PJ end disk; wrenches in it or with '
                  'an empty frame_id are used as they are; poses are published in it'),
    ParameterSpec('end_disk_frame', 'frame_id of {de}, the DJ end disk; wrenches in it are '
                  'rotated into base_frame with the solved end-disk pose'),
    ParameterSpec('max_force', 'N, wrenches with a larger |force| are rejected',
                  bounds=(0.0, 1e6)),
    ParameterSpec('max_moment', 'N m, wrenches with a larger |moment| are rejected',
                  bounds=(0.0, 1e6)),
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
)

_FIDELITY = (
    ParameterSpec('fidelity', 'model level: full, rod, cc, linear, or auto (cheapest within '
                  'max_position_error / max_angle_error)', read_only=True),
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

#: Every parameter translator_node declares, by name.
SPECS: Mapping[str, ParameterSpec] = {spec.name: spec
                                      for spec in _MODEL + _NODE + _FIDELITY + _ACCURACY}

#: The model's keys (TranslatorParams fields), as opposed to the node-only ones.
MODEL_KEYS = frozenset(spec.name for spec in _MODEL)


def default_values(path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> dict:
    """
    Read every declared parameter's value from a params file (default: the shipped one).

    ParameterError names keys that are missing or that no spec knows.
    """
    values = read_params_file(path)
    unknown = sorted(set(values) - set(SPECS))
    missing = sorted(set(SPECS) - set(values))
    if unknown or missing:
        raise ParameterError(f'{path}: unknown parameter(s) {unknown}, missing {missing}')
    return values


def check_value(name: str, value: Any, others: Mapping[str, Any]) -> Optional[str]:
    """
    Return why ``name`` may not take ``value`` (None if it may), given the other values.

    Checks what descriptors cannot express: frame names non-empty, without white space and
    distinct (ranges and read-only are the descriptors' business, the model's values the
    library's).
    """
    if name in ('base_frame', 'end_disk_frame'):
        other = others.get('end_disk_frame' if name == 'base_frame' else 'base_frame')
        if not value.strip():
            return f'{name} must not be empty'
        if any(character.isspace() for character in value):
            return f'{name} {value!r} must not contain white space'
        if value == other:
            return f'{name} {value!r} must differ from the other frame'
    return None


@dataclass(frozen=True)
class NodeSettings:
    """The node-only parameter values, as one immutable snapshot (replaced on a change)."""

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
    fidelity: str
    max_position_error: float
    max_angle_error: float
    accuracy_position_m: float
    accuracy_angle_deg: float

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> 'NodeSettings':
        """Pick the node-only, fidelity and accuracy keys out of all parameter values."""
        return cls(**{key: values[key]
                      for key in NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS})


def model_params(values: Mapping[str, Any]) -> TranslatorParams:
    """Build the validated model parameters out of all parameter values."""
    return TranslatorParams.from_mapping({key: values[key] for key in MODEL_KEYS})
