"""One settings type per node section, read with ROS 2 params-file semantics everywhere."""

from cdr_translator import TranslatorParams
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.interface.settings import CDR_SPECS, CdrSettings, check_value, MODEL_KEYS
from cdr_translator.interface.settings import SPECS, TranslatorSettings
from cdr_translator.params.params_file import section_applies
from cdr_translator.params.translator_params import (ACCURACY_KEYS, DEFAULT_PARAMS_PATH,
                                                     FIDELITY_KEYS)
from cdr_translator.params.translator_params import NODE_ONLY_KEYS
from cdr_translator.params.translator_params import ParameterError, read_params_file
from cdr_translator.robot import DeltaParams, DeltaRobot
from cdr_translator.robot.params import CDR_NODE_ONLY_KEYS
import numpy as np
import pytest
import yaml


def write(tmp_path, document, name='params.yaml'):
    """Write a params document and return its path."""
    path = tmp_path / name
    path.write_text(yaml.safe_dump(document))
    return path


def test_specs_name_every_key_of_the_shipped_file():
    """The one YAML, the specs and the settings types name the same parameters."""
    assert set(read_params_file()) == set(SPECS)
    assert set(SPECS) - MODEL_KEYS == NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS
    assert MODEL_KEYS == set(TranslatorParams.__dataclass_fields__)
    assert set(TranslatorSettings.__dataclass_fields__) - {'params'} == \
        NODE_ONLY_KEYS | FIDELITY_KEYS | ACCURACY_KEYS
    assert set(read_params_file(section='cdr_node')) | MODEL_KEYS == set(CDR_SPECS)
    assert set(CdrSettings.__dataclass_fields__) - {'params', 'geometry'} == CDR_NODE_ONLY_KEYS
    assert all(SPECS[key].read_only for key in MODEL_KEYS)
    shipped = TranslatorSettings.from_params_file()
    assert shipped.params == TranslatorParams.from_yaml()
    assert TranslatorSettings.from_values(shipped.values()) == shipped


@pytest.mark.parametrize('pattern, fqn, applies', [
    ('/**', '/translator_node', True), ('/**', '/leg1/translator_node', True),
    ('translator_node', '/translator_node', True),
    ('/translator_node', '/translator_node', True),
    ('translator_node', '/leg1/translator_node', False),
    ('/leg1/translator_node', '/leg1/translator_node', True),
    ('/**/translator_node', '/a/b/translator_node', True),
    ('/*/translator_node', '/leg1/translator_node', True),
    ('/*/translator_node', '/translator_node', False),
    ('cdr_node', '/translator_node', False),
])
def test_section_patterns_follow_rcl(pattern, fqn, applies):
    """Node-name patterns match fully qualified names as rcl matches them."""
    assert section_applies(pattern, fqn) is applies


@pytest.mark.parametrize('key', ['translator_node', '/**'])
def test_a_partial_file_overrides_the_shipped_one_key_by_key(tmp_path, key):
    """Two keys under the node's name or /**: every reader takes them, the rest is shipped."""
    path = write(tmp_path, {key: {'ros__parameters': {'youngs_modulus': 7.0e10,
                                                      'tube_length': 0.12}}})
    params = TranslatorParams.from_yaml(path)
    assert (params.youngs_modulus, params.tube_length) == (7.0e10, 0.12)
    assert params.with_changes(youngs_modulus=8.84e10, tube_length=0.1383) == \
        TranslatorParams.from_yaml()
    assert TranslatorSettings.from_params_file(path).params == params
    assert FidelitySolver.from_params_file(path).params == params
    assert CdrSettings.from_params_file(path).params == params
    assert DeltaRobot.from_yaml(path).params == params


def test_a_misspelt_key_is_named_with_a_suggestion(tmp_path):
    """An unknown key is an error naming it (and the key it probably meant)."""
    path = write(tmp_path, {'translator_node': {'ros__parameters': {
        'youngs_modulous': 7.0e10}}})
    for read in (TranslatorParams.from_yaml, TranslatorSettings.from_params_file,
                 FidelitySolver.from_params_file, CdrSettings.from_params_file):
        with pytest.raises(ParameterError, match=r'youngs_modulous \(did you mean '
                                                 r'youngs_modulus\?\)'):
            read(path)


def test_an_integer_for_a_double_is_refused_as_ros_refuses_it(tmp_path):
    """ROS 2 declares max_force a double: 50 is refused everywhere, saying to write 50.0."""
    path = write(tmp_path, {'/**': {'ros__parameters': {'max_force': 50}}})
    with pytest.raises(ParameterError, match=r'max_force must be a double, got integer 50 '
                                             r'\(write 50\.0\)'):
        TranslatorSettings.from_params_file(path)
    path = write(tmp_path, {'/**': {'ros__parameters': {'youngs_modulus': 70000000000}}})
    with pytest.raises(ParameterError, match='youngs_modulus must be a double'):
        TranslatorParams.from_yaml(path)


def test_namespaces_follow_fully_qualified_names(tmp_path):
    """A translator_node: section does not apply in /leg1 and says so; /leg1/... does."""
    plain = write(tmp_path, {'translator_node': {'ros__parameters': {'max_force': 5.0}}})
    with pytest.raises(ParameterError, match=r"section 'translator_node' does not apply to "
                                             r'/leg1/translator_node'):
        TranslatorSettings.from_params_files([plain], namespace='/leg1')
    keyed = write(tmp_path, {'/leg1/translator_node': {'ros__parameters': {'max_force': 5.0}},
                             '/leg2/translator_node': {'ros__parameters': {'max_force': 7.0}}},
                  'legs.yaml')
    assert TranslatorSettings.from_params_files([keyed], namespace='/leg1').max_force == 5.0
    assert TranslatorSettings.from_params_files([keyed], namespace='/leg2').max_force == 7.0
    with pytest.raises(ParameterError, match='does not apply to /translator_node'):
        TranslatorSettings.from_params_files([keyed])  # nothing for the root namespace


def test_a_wildcard_section_may_hold_the_other_nodes_keys(tmp_path):
    """/** applies to both nodes: each takes its keys, and a key neither knows is an error."""
    path = write(tmp_path, {'/**': {'ros__parameters': {'max_force': 30.0,
                                                        'slider_stroke': 0.02}}})
    assert TranslatorSettings.from_params_file(path).max_force == 30.0
    cdr = CdrSettings.from_params_file(path)
    assert (cdr.max_force, cdr.geometry.slider_stroke) == (30.0, 0.02)
    assert DeltaParams.from_yaml(path).slider_stroke == 0.02
    bad = write(tmp_path, {'/**': {'ros__parameters': {'slider_strok': 0.02}}}, 'bad.yaml')
    with pytest.raises(ParameterError, match='slider_strok'):
        CdrSettings.from_params_file(bad)


def test_later_files_and_command_line_values_win(tmp_path):
    """Files apply in order, -p values last; settings keep every value typed."""
    first = write(tmp_path, {'/**': {'ros__parameters': {'max_force': 30.0}}}, 'a.yaml')
    second = write(tmp_path, {'translator_node': {'ros__parameters': {'max_force': 40.0}}},
                   'b.yaml')
    settings = TranslatorSettings.from_params_files([first, second])
    assert settings.max_force == 40.0
    assert TranslatorSettings.from_params_files(
        [first, second], overrides={'max_force': 45.0}).max_force == 45.0
    with pytest.raises(ParameterError, match='command line: unknown'):
        TranslatorSettings.from_params_files([], overrides={'max_forse': 45.0})


def test_values_are_checked_in_one_place():
    """Bounds and frames: the same reasons for the node's run-time changes and files."""
    settings = TranslatorSettings.from_params_file()
    with pytest.raises(ParameterError, match='max_force must lie in'):
        settings.with_values(max_force=-1.0)
    with pytest.raises(ParameterError, match='must differ'):
        settings.with_values(end_disk_frame=settings.base_frame)
    assert settings.with_values(max_force=5.0).max_force == 5.0
    assert CdrSettings.from_params_file().with_values(world_frame='w').world_frame == 'w'


@pytest.mark.parametrize('name, value, others, reason', [
    ('base_frame', '', {'end_disk_frame': 'e'}, 'must not be empty'),
    ('base_frame', 'a b', {'end_disk_frame': 'e'}, 'white space'),
    ('end_disk_frame', 'b', {'base_frame': 'b'}, 'must differ'),
    ('world_frame', ' ', {}, 'must not be empty'),
    ('mcap_flush_messages', 0, {}, 'mcap_flush_messages must be an integer >= 1'),
    ('wrench_queue_depth', 0, {}, 'wrench_queue_depth must be an integer >= 1'),
    ('input_queue_depth', 0, {}, 'input_queue_depth must be an integer >= 1'),
])
def test_check_value_gives_reasons(name, value, others, reason):
    """Run-time values are refused with a reason."""
    assert reason in check_value(name, value, others)


def test_check_value_accepts_good_values():
    """Valid frames and limits pass."""
    assert check_value('base_frame', 'world', {'end_disk_frame': 'tool'}) is None
    assert check_value('max_force', 5.0, {}) is None


def test_the_shipped_file_is_the_default(tmp_path):
    """Passing the shipped file itself changes nothing; a missing file is named."""
    assert TranslatorSettings.from_params_file(DEFAULT_PARAMS_PATH) == \
        TranslatorSettings.from_params_file()
    with pytest.raises(ParameterError, match='cannot read parameter file'):
        TranslatorSettings.from_params_file(tmp_path / 'missing.yaml')


@pytest.mark.parametrize('name, value, reason', [
    ('estimate_prior_force_sd', 0.0, 'estimate_prior_force_sd must lie in'),
    ('estimate_prior_moment_sd', -1.0, 'estimate_prior_moment_sd must lie in'),
    ('estimate_target_force_sd', 0.0, 'estimate_target_force_sd must lie in'),
    ('estimate_target_moment_sd', 0.0, 'estimate_target_moment_sd must lie in'),
    ('estimate_pose_position_sd', -1e-4, 'estimate_pose_position_sd must lie in'),
    ('estimate_pose_orientation_sd', 4.0, 'estimate_pose_orientation_sd must lie in'),
    ('estimate_components', 'fx fq', 'estimate_components: estimate must be one of'),
    ('estimate_components', 'fx fx', 'estimate_components: estimate names a component twice'),
    ('estimate_held_force', [1.0, 2.0], 'estimate_held_force must be a list of 3 doubles'),
    ('estimate_held_moment', [0.0, float('nan'), 0.0], 'estimate_held_moment[1]'),
    ('estimate_prior_covariance', [1.0] * 35, 'estimate_prior_covariance must be a list of 0 '
                                              'or 36 doubles'),
    ('estimate_prior_covariance', [1] * 36, '(1.0, not 1)'),
    ('estimate_prior_covariance', (np.eye(6) + np.eye(6, k=1)).ravel().tolist(),
     'estimate_prior_covariance must be symmetric'),
    ('estimate_prior_covariance', (-np.eye(6)).ravel().tolist(),
     'estimate_prior_covariance must be positive semidefinite'),
    ('estimate_prior_covariance', np.diag([1.0] * 5 + [0.0]).ravel().tolist(),
     'estimate_prior_covariance must be positive definite over the estimated components'),
])
def test_bad_estimate_parameters_are_named(name, value, reason):
    """Each estimate parameter refuses a bad value with a reason naming it, as ParameterError."""
    settings = TranslatorSettings.from_params_file()
    assert reason in check_value(name, value, settings.values())
    with pytest.raises(ParameterError) as error:
        settings.with_values(**{name: value})
    assert reason in str(error.value)


def test_estimate_parameters_from_a_file(tmp_path):
    """A prior covariance (36 doubles over an empty default) and held values, from a file."""
    prior = np.diag([4.0, 4.0, 1.0, 0.01, 0.01, 0.0]).ravel().tolist()
    path = write(tmp_path, {'translator_node': {'ros__parameters': {
        'estimate_prior_covariance': prior, 'estimate_components': 'force',
        'estimate_held_moment': [0.0, 0.01, 0.0], 'estimate_pose_position_sd': 0.0}}})
    settings = TranslatorSettings.from_params_file(path)
    assert settings.estimate_prior_covariance == tuple(prior)
    assert settings.estimate_held_moment == (0.0, 0.01, 0.0)
    assert settings.estimate_components == 'force'
    assert settings.values()['estimate_prior_covariance'] == prior
    assert TranslatorSettings.from_values(settings.values()) == settings
    # the torsion's zero prior variance is fine while torsion is held, not once estimated
    with pytest.raises(ParameterError, match='positive definite over the estimated'):
        settings.with_values(estimate_components='')
    path = write(tmp_path, {'translator_node': {'ros__parameters': {
        'estimate_held_force': [1, 0, 0]}}})
    with pytest.raises(ParameterError, match=r'estimate_held_force must be a double_array, '
                                             r'got integer_array \[1, 0, 0\]'):
        TranslatorSettings.from_params_file(path)
