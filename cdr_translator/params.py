"""Geometry and material parameters of the translator, read from the one YAML file."""

from dataclasses import asdict, dataclass, fields, replace
import math
from pathlib import Path
from typing import Any, Mapping, Union

import yaml

#: The node name under which the parameters sit in the ROS 2 params file.
NODE_NAME = 'translator_node'


def _shipped_params_path() -> Path:
    """
    Locate config/translator.yaml without the ament index (AMENT_PREFIX_PATH may be unset).

    Source tree and editable installs have it beside the package; colcon and pip installs
    put it in <prefix>/share/cdr_translator/config, the package being in
    <prefix>/lib/pythonX.Y/site-packages/cdr_translator.
    """
    package = Path(__file__).resolve().parent
    candidates = [package.parent / 'config' / 'translator.yaml']
    if len(package.parents) > 3:
        candidates.append(
            package.parents[3] / 'share' / 'cdr_translator' / 'config' / 'translator.yaml')
    return next((path for path in candidates if path.is_file()), candidates[0])


#: The parameter file shipped with the package: the one source of default values.
DEFAULT_PARAMS_PATH = _shipped_params_path()

#: Secondary backbones sit at these angles on the pitch circle (secondary 1 on +x).
SECONDARY_ANGLES_RAD = (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)

#: Keys of the same params file that belong to the ROS node, not to the model.
NODE_ONLY_KEYS: frozenset = frozenset((
    'base_frame', 'end_disk_frame', 'max_force', 'max_moment', 'solve_time_limit_s',
    'log_compliance', 'log_backbones', 'log_to_mcap', 'mcap_path', 'log_dir',
    'mcap_flush_messages', 'mcap_flush_s'))

#: Keys of the same params file that choose the fidelity level and its error budget
#: (read by cdr_translator.fidelity.FidelitySolver.from_params_file, not by TranslatorParams).
FIDELITY_KEYS: frozenset = frozenset(('fidelity', 'max_position_error', 'max_angle_error'))


#: Keys of the same params file that set the accuracy target of every solve (read by
#: ``Accuracy.from_yaml`` and TranslatorSolver, not by TranslatorParams).
ACCURACY_KEYS: frozenset = frozenset(('accuracy_position_m', 'accuracy_angle_deg'))

#: Most spacer disks per joint: the library and the node refuse more. The exact Jacobian's
#: cost grows with (unknowns)^2 x (disk intervals), its factorization with (unknowns)^3;
#: at 16 (690 unknowns) one Newton iteration stays well inside a time limit of a second,
#: so ``time_limit_s`` (checked between iterations) holds.
MAX_SPACERS_PER_JOINT = 16

#: Most RK4 steps per disk interval the automatic refinement may use.
MAX_REFINED_STEPS = 256


class ParameterError(ValueError):
    """A parameter is missing, unknown or has an impossible value."""


@dataclass(frozen=True)
class Accuracy:
    """
    Accuracy target of every solve: the estimated discretization error may not exceed it.

    ``position_m`` bounds the end-disk (and tube-face) position error, ``angle_deg`` their
    orientation error and the defects of the secondaries' angle conditions; a solve whose
    estimate exceeds either is refined (more steps per segment) up to MAX_REFINED_STEPS.
    Zero disables the refinement of that kind (the estimate is still reported).
    The shipped defaults are ten times inside the paper's tolerances that
    ``cdr_translator.verify`` checks (2e-4 m, 1e-4 rad).
    """

    position_m: float = 2e-5
    angle_deg: float = 5e-4

    def __post_init__(self) -> None:
        """Validate; ParameterError names the offending key and value."""
        for name, value in (('accuracy_position_m', self.position_m),
                            ('accuracy_angle_deg', self.angle_deg)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0.0:
                raise ParameterError(f'{name} must be a finite number >= 0, got {value!r}')

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> 'Accuracy':
        """Pick the accuracy keys out of a flat mapping (missing ones take the defaults)."""
        picked = {}
        if 'accuracy_position_m' in values:
            picked['position_m'] = values['accuracy_position_m']
        if 'accuracy_angle_deg' in values:
            picked['angle_deg'] = values['accuracy_angle_deg']
        return cls(**picked)

    @classmethod
    def from_yaml(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> 'Accuracy':
        """Read the accuracy keys of a ROS 2 params file's translator_node section."""
        return cls.from_mapping(read_params_file(path))


def read_params_file(path: Union[str, Path] = DEFAULT_PARAMS_PATH,
                     section: str = NODE_NAME) -> dict:
    """
    Return the ``<section>: ros__parameters:`` mapping of a ROS 2 params file.

    ``section`` is a node name: ``translator_node`` (default) or ``cdr_node`` (the delta
    robot's geometry). Model and node-only keys alike, unvalidated; ParameterError if the
    file cannot be read.
    """
    path = Path(path)
    try:
        document = yaml.safe_load(path.read_text())
    except OSError as error:
        raise ParameterError(f'cannot read parameter file {path}: {error}') from error
    except yaml.YAMLError as error:
        raise ParameterError(f'{path} is not valid YAML: {error}') from error
    try:
        values = document[section]['ros__parameters']
    except (TypeError, KeyError):
        raise ParameterError(
            f'{path} has no {section}: ros__parameters: section') from None
    if not isinstance(values, Mapping):
        raise ParameterError(f'{path}: {section}.ros__parameters must be a mapping')
    return dict(values)


@dataclass(frozen=True)
class TranslatorParams:
    """
    Geometry, material and discretization of one dual-continuum-joint translator (SI).

    The stack is: PJ end disk (the base, frame {pe}), ``spacers_per_joint`` spacer
    disks, the multi-lumen tube of length ``tube_length``, again ``spacers_per_joint``
    spacer disks and the DJ end disk; adjacent disks are ``disk_spacing`` apart.
    There are no defaults here: they live in config/translator.yaml (``from_yaml()``).
    """

    pitch_radius: float
    backbone_diameter: float
    disk_spacing: float
    tube_length: float
    youngs_modulus: float
    poisson_ratio: float
    spacers_per_joint: int
    steps_per_segment: int

    def __post_init__(self) -> None:
        """Validate every field; raise ParameterError naming the offending key."""
        for name in ('pitch_radius', 'backbone_diameter', 'disk_spacing', 'tube_length',
                     'youngs_modulus', 'poisson_ratio'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f'{name} must be a number, got {value!r}')
            if not math.isfinite(value):
                raise ParameterError(f'{name} must be finite, got {value!r}')
        for name in ('pitch_radius', 'backbone_diameter', 'disk_spacing', 'tube_length',
                     'youngs_modulus'):
            if getattr(self, name) <= 0.0:
                raise ParameterError(f'{name} must be positive, got {getattr(self, name)!r}')
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ParameterError(
                f'poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio!r}')
        for name, lowest in (('spacers_per_joint', 0), ('steps_per_segment', 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < lowest:
                raise ParameterError(f'{name} must be an integer >= {lowest}, got {value!r}')
        if self.spacers_per_joint > MAX_SPACERS_PER_JOINT:
            raise ParameterError(f'spacers_per_joint must be at most {MAX_SPACERS_PER_JOINT}, '
                                 f'got {self.spacers_per_joint!r}')
        if self.pitch_radius < self.backbone_diameter:
            # Secondary holes would overlap the central primary backbone.
            raise ParameterError(
                f'pitch_radius ({self.pitch_radius!r}) must be at least backbone_diameter '
                f'({self.backbone_diameter!r}): the secondary backbones would overlap the '
                'primary one')
        if self.backbone_diameter >= self.disk_spacing:
            raise ParameterError(
                f'backbone_diameter ({self.backbone_diameter!r}) must be smaller than '
                f'disk_spacing ({self.disk_spacing!r}): a rod is not slender at that size')

    # Derived quantities -------------------------------------------------------------------
    @property
    def shear_modulus(self) -> float:
        """Shear modulus G = E / (2 (1 + nu)) of an isotropic material (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def area(self) -> float:
        """Cross-section area of one backbone (m^2)."""
        return math.pi * self.backbone_diameter ** 2 / 4.0

    @property
    def second_moment(self) -> float:
        """Second moment of area I about a cross-section diameter (m^4)."""
        return math.pi * self.backbone_diameter ** 4 / 64.0

    @property
    def bending_stiffness(self) -> float:
        """E I of one backbone (N m^2)."""
        return self.youngs_modulus * self.second_moment

    @property
    def joint_length(self) -> float:
        """Length of one continuum joint from end disk to tube face (m)."""
        return (self.spacers_per_joint + 1) * self.disk_spacing

    @property
    def stack_height(self) -> float:
        """Unloaded height of the DJ end disk above the base: two joints plus the tube (m)."""
        return 2.0 * self.joint_length + self.tube_length

    # Construction ---------------------------------------------------------------------------
    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> 'TranslatorParams':
        """Build from a flat mapping; unknown or missing keys raise ParameterError naming them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known - NODE_ONLY_KEYS - FIDELITY_KEYS - ACCURACY_KEYS)
        if unknown:
            raise ParameterError(
                f'unknown parameter(s) {", ".join(unknown)}; known: {", ".join(sorted(known))}')
        missing = sorted(known - set(values))
        if missing:
            raise ParameterError(f'missing parameter(s) {", ".join(missing)}')
        picked = {key: value for key, value in values.items() if key in known}
        for key in ('spacers_per_joint', 'steps_per_segment'):
            value = picked.get(key)
            if isinstance(value, float) and value.is_integer():
                picked[key] = int(value)
        return cls(**picked)

    @classmethod
    def from_yaml(cls, path: Union[str, Path] = DEFAULT_PARAMS_PATH) -> 'TranslatorParams':
        """Read a ROS 2 params file (``translator_node: ros__parameters: {...}``)."""
        return cls.from_mapping(read_params_file(path))

    def with_changes(self, **changes: Any) -> 'TranslatorParams':
        """Return a validated copy with some fields changed."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain dict of the fields, as written in the YAML file."""
        return asdict(self)
