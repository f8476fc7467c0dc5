"""Geometry and material parameters of the translator, read from the one YAML file."""

from dataclasses import asdict, dataclass, fields, replace
import math
from pathlib import Path
from typing import Any, List, Mapping, Union
import warnings

from .params_file import layered_values, section_values
from ..checks import check_integer, check_number
from ..errors import ParameterError, PlausibilityWarning

#: The node name under which the parameters sit in the ROS 2 params file.
NODE_NAME = 'translator_node'


def _shipped_params_path() -> Path:
    """
    Locate config/translator.yaml without the ament index (AMENT_PREFIX_PATH may be unset).

    Source tree and editable installs have it beside the package; colcon and pip installs
    put it in <prefix>/share/cdr_translator/config, the package being in
    <prefix>/lib/pythonX.Y/site-packages/cdr_translator.
    """
    package = Path(__file__).resolve().parents[1]  # cdr_translator/, above params/
    candidates = [package.parent / 'config' / 'translator.yaml']
    if len(package.parents) > 3:
        candidates.append(
            package.parents[3] / 'share' / 'cdr_translator' / 'config' / 'translator.yaml')
    return next((path for path in candidates if path.is_file()), candidates[0])


#: The parameter file shipped with the package: the one source of default values.
DEFAULT_PARAMS_PATH = _shipped_params_path()

#: Secondary backbones sit at these angles on the pitch circle (secondary 1 on +x).
SECONDARY_ANGLES_RAD = (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)

#: Upper bounds of the discretization, enforced by the library and both nodes alike: past
#: them a solve cannot meet any time limit (cost and memory grow with both). The exact
#: Jacobian costs ~ (unknowns)^2 x (disk intervals) and its factorization (unknowns)^3;
#: at 16 spacer disks per joint (690 unknowns) one Newton iteration stays well inside a
#: second, so ``time_limit_s`` (checked between iterations) holds; at 64 (2610 unknowns)
#: one iteration alone took longer.
MAX_SPACERS_PER_JOINT = 16
MAX_STEPS_PER_SEGMENT = 1024

#: The translator is a desktop-scale mechanism: a length of a metre or more is almost always a
#: length in millimetres typed into a metre field (the paper's prototype: 10 mm pitch radius,
#: 10 mm disk spacing, 138 mm tube).
PLAUSIBLE_MAX_LENGTH_M = 1.0

#: Pitch radius over joint length beyond which the joints are discs rather than continuum
#: joints (the paper's prototype has 0.5).
PLAUSIBLE_MAX_PITCH_RATIO = 10.0

#: Young's modulus range of backbone materials (Pa): polymers (~1 GPa) to steel (~200 GPa),
#: with a decade of slack on each side; outside it a modulus in MPa or GPa is likely.
PLAUSIBLE_MODULUS_PA = (1e8, 1e12)

#: Most RK4 steps per disk interval the automatic refinement may use: any valid count. The
#: hard cases past 90 deg of bending need about 700-1000 to meet the default target; the
#: time limit, not this cap, bounds what a solve spends (refinement.refine).
MAX_REFINED_STEPS = MAX_STEPS_PER_SEGMENT

#: Keys of the same params file that belong to the ROS node, not to the model.
NODE_ONLY_KEYS: frozenset = frozenset((
    'base_frame', 'end_disk_frame', 'max_force', 'max_moment', 'solve_time_limit_s',
    'log_compliance', 'log_backbones', 'log_to_mcap', 'mcap_path', 'log_dir',
    'mcap_flush_messages', 'mcap_flush_s', 'wrench_queue_depth', 'pending_wrenches',
    'diagnostics_period_s',
    'estimate_prior_force_sd', 'estimate_prior_moment_sd', 'estimate_prior_covariance',
    'estimate_target_force_sd', 'estimate_target_moment_sd', 'estimate_components',
    'estimate_held_force', 'estimate_held_moment', 'estimate_pose_position_sd',
    'estimate_pose_orientation_sd'))

#: Keys of the same params file that choose the fidelity level and its error budget
#: (read by cdr_translator.fidelity.FidelitySolver.from_params_file, not by TranslatorParams).
FIDELITY_KEYS: frozenset = frozenset(('fidelity', 'max_position_error', 'max_angle_error'))

#: Keys of the same params file that set the accuracy target of every solve (read by
#: ``Accuracy.from_yaml`` and TranslatorSolver, not by TranslatorParams).
ACCURACY_KEYS: frozenset = frozenset(('accuracy_position_m', 'accuracy_angle_deg'))


def read_params_file(path: Union[str, Path] = DEFAULT_PARAMS_PATH,
                     section: str = NODE_NAME) -> dict:
    """
    Return the parameters a ROS 2 params file gives node ``section`` (root namespace).

    Every section that applies (``/**``, ``section``, ``/section``, ...) merged in file order,
    unvalidated; ParameterError if the file cannot be read or none of it applies.
    """
    values = section_values(path, section)
    if not values:
        raise ParameterError(f'{path} has no section for {section} ({section}: or /**: '
                             'with ros__parameters:)')
    return values


def translator_values(path: Union[str, Path, None] = None) -> dict:
    """
    Every translator_node parameter: the shipped file, then ``path`` key by key.

    ROS 2 params-file semantics (cdr_translator.params.params_file): an unknown key or a value of
    the wrong ROS type is a ParameterError naming it.
    """
    return layered_values(NODE_NAME, [path], DEFAULT_PARAMS_PATH)


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
                     'youngs_modulus'):
            check_number(name, getattr(self, name), low=0.0, low_open=True,
                         error=ParameterError)
        check_number('poisson_ratio', self.poisson_ratio, low=-1.0, high=0.5, low_open=True,
                     high_open=True, error=ParameterError)
        check_integer('spacers_per_joint', self.spacers_per_joint, low=0,
                      high=MAX_SPACERS_PER_JOINT, error=ParameterError)
        check_integer('steps_per_segment', self.steps_per_segment, low=1,
                      high=MAX_STEPS_PER_SEGMENT, error=ParameterError)
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
        for text in self.implausibilities():
            warnings.warn(text, PlausibilityWarning, stacklevel=3)

    def implausibilities(self) -> List[str]:
        """
        Say which legal values lie far outside the translator's scale, naming the likely slip.

        Empty for any real translator; each text names the key, its value and the rule.
        ``__post_init__`` issues each as a PlausibilityWarning.
        """
        texts = []
        for name in ('pitch_radius', 'backbone_diameter', 'disk_spacing', 'tube_length'):
            value = getattr(self, name)
            if value >= PLAUSIBLE_MAX_LENGTH_M:
                texts.append(f'{name} is {value!r} m, a length of {PLAUSIBLE_MAX_LENGTH_M:g} m '
                             'or more: millimetres typed as metres?')
        ratio = self.pitch_radius / self.joint_length
        if ratio > PLAUSIBLE_MAX_PITCH_RATIO and self.pitch_radius < PLAUSIBLE_MAX_LENGTH_M:
            texts.append(f'pitch_radius ({self.pitch_radius!r} m) is {ratio:.3g} times the '
                         f'joint length ({self.joint_length!r} m, over '
                         f'{PLAUSIBLE_MAX_PITCH_RATIO:g}): millimetres typed as metres?')
        low, high = PLAUSIBLE_MODULUS_PA
        if not low <= self.youngs_modulus <= high:
            texts.append(f'youngs_modulus is {self.youngs_modulus!r} Pa, outside '
                         f'{low:g}..{high:g} Pa of backbone materials: MPa or GPa typed as Pa?')
        return texts

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
        """
        Read a ROS 2 params file over the shipped one, key by key (``translator_values``).

        A partial file, a ``/**:`` section and the node's name all work as in the node.
        """
        values = translator_values(path)
        return cls.from_mapping({field.name: values[field.name] for field in fields(cls)})

    def with_changes(self, **changes: Any) -> 'TranslatorParams':
        """Return a validated copy with some fields changed (ParameterError naming a key)."""
        known = {field.name for field in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ParameterError(f'unknown parameter(s) {", ".join(unknown)}; known: '
                                 f'{", ".join(sorted(known))}')
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain dict of the fields, as written in the YAML file."""
        return asdict(self)


@dataclass(frozen=True)
class Accuracy:
    """
    Accuracy target of every solve: the estimated discretization error may not exceed it.

    ``position_m`` bounds the end-disk (and tube-face) position error, ``angle_deg`` their
    orientation error and the defects of the secondaries' angle conditions; a solve whose
    estimate exceeds either is refined (more steps per segment) up to MAX_REFINED_STEPS.
    Zero disables the refinement of that kind (the estimate is still reported).
    The shipped defaults are ten times inside the paper's tolerances that
    ``cdr_translator.solve.verify`` checks (2e-4 m, 1e-4 rad);
    docs/explanation/solution_quality.md.
    """

    position_m: float = 2e-5
    angle_deg: float = 5e-4

    def __post_init__(self) -> None:
        """Validate; ParameterError names the offending key and value."""
        check_number('accuracy_position_m', self.position_m, low=0.0, error=ParameterError)
        check_number('accuracy_angle_deg', self.angle_deg, low=0.0, error=ParameterError)

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
        """Read the accuracy keys of a params file over the shipped one (``translator_values``)."""
        return cls.from_mapping(translator_values(path))
