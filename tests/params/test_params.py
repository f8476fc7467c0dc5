"""Parameter file reading and validation: every error names the key and the value."""

import contextlib
import io
import math
import warnings

from cdr_translator import ParameterError, PlausibilityWarning, TranslatorParams
from cdr_translator.cli import main as cdr_main
from cdr_translator.console import run_command
from cdr_translator.params import params_file
from cdr_translator.params.translator_params import DEFAULT_PARAMS_PATH, NODE_NAME
from msg_tools.__main__ import main as msg_tools_main
import pytest
import yaml

#: Nesting of the deep params file: far beyond Python's recursion limit (1000).
DEEP = 5000


def write_deep_params(folder):
    """Write a params file whose pitch_radius is a list nested DEEP levels deep."""
    path = folder / 'deep.yaml'
    path.write_text(f'{NODE_NAME}:\n  ros__parameters:\n    pitch_radius: '
                    + '[' * DEEP + '0.01' + ']' * DEEP + '\n')
    return path


def write_params(tmp_path, **changes):
    """Write the shipped params file with some values changed (None deletes a key)."""
    document = yaml.safe_load(DEFAULT_PARAMS_PATH.read_text())
    values = document[NODE_NAME]['ros__parameters']
    for key, value in changes.items():
        if value is None:
            values.pop(key)
        else:
            values[key] = value
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


def test_shipped_file_loads(params):
    """The one parameter file holds the paper's geometry."""
    assert params.pitch_radius == 0.010
    assert params.backbone_diameter == 0.0012
    assert params.disk_spacing == 0.010
    assert params.spacers_per_joint == 1
    assert 0.02 <= params.tube_length <= 0.15
    assert 40e9 <= params.youngs_modulus <= 90e9
    assert math.isclose(params.shear_modulus,
                        params.youngs_modulus / (2 * (1 + params.poisson_ratio)))


@pytest.mark.parametrize('key, value, fragment', [
    ('tube_length', 0.0, 'tube_length must be positive'),
    ('disk_spacing', -0.01, 'disk_spacing must be positive'),
    ('youngs_modulus', -1.0, 'youngs_modulus must be positive'),
    ('poisson_ratio', 0.5, 'poisson_ratio must lie in'),
    ('poisson_ratio', -1.0, 'poisson_ratio must lie in'),
    ('spacers_per_joint', -1, 'spacers_per_joint must be an integer'),
    ('spacers_per_joint', 1.5, 'spacers_per_joint must be an integer'),
    ('steps_per_segment', 0, 'steps_per_segment must be an integer'),
    ('pitch_radius', 0.001, 'pitch_radius'),
    ('backbone_diameter', 0.02, 'backbone_diameter'),
    ('tube_length', 'long', "tube_length must be a double, got string 'long'"),
    ('tube_length', 1, r'tube_length must be a double, got integer 1 \(write 1\.0\)'),
])
def test_invalid_values_name_the_key(tmp_path, key, value, fragment):
    """Each bad value is rejected with the key (and value) in the message."""
    with pytest.raises(ParameterError, match=fragment):
        TranslatorParams.from_yaml(write_params(tmp_path, **{key: value}))


def test_a_partial_file_keeps_the_shipped_values(tmp_path, params):
    """A key a file lacks keeps its shipped value (ROS 2 params files override key by key)."""
    assert TranslatorParams.from_yaml(write_params(tmp_path, tube_length=None)) == params


def test_unknown_key_is_named(tmp_path):
    """A misspelt key is an error, not silently ignored."""
    with pytest.raises(ParameterError, match=r'unknown translator_node parameter.*tube_lenght '
                                             r'\(did you mean tube_length\?\)'):
        TranslatorParams.from_yaml(write_params(tmp_path, tube_lenght=0.1))


def test_missing_section_and_bad_yaml(tmp_path):
    """A file without the ROS params section, or not YAML at all, is a clear error."""
    path = tmp_path / 'other.yaml'
    path.write_text('some_node:\n  ros__parameters: {}\n')
    with pytest.raises(ParameterError, match='has no section for /translator_node'):
        TranslatorParams.from_yaml(path)
    path.write_text('translator_node: [unclosed\n')
    with pytest.raises(ParameterError, match='not valid YAML'):
        TranslatorParams.from_yaml(path)
    with pytest.raises(ParameterError, match='cannot read'):
        TranslatorParams.from_yaml(tmp_path / 'absent.yaml')


def test_with_changes_validates(params):
    """Copies are validated too."""
    assert params.with_changes(spacers_per_joint=3).spacers_per_joint == 3
    with pytest.raises(ParameterError, match='poisson_ratio'):
        params.with_changes(poisson_ratio=0.7)


@pytest.mark.parametrize('changes, fragment', [
    ({'pitch_radius': 10.0}, 'pitch_radius is 10.0 m'),
    ({'tube_length': 138.3}, 'tube_length is 138.3 m'),
    ({'pitch_radius': 0.5}, 'times the joint length'),
    ({'youngs_modulus': 88.4}, 'youngs_modulus is 88.4 Pa'),
    ({'youngs_modulus': 88.4e15}, 'MPa or GPa typed as Pa'),
])
def test_implausible_values_warn_naming_the_likely_slip(params, changes, fragment):
    """Legal values far outside the translator's scale warn, naming the key and the slip."""
    with pytest.warns(PlausibilityWarning, match=fragment):
        changed = params.with_changes(**changes)
    assert any(fragment in text for text in changed.implausibilities())


def test_the_shipped_geometry_is_plausible(params):
    """The paper's translator gives no warning (warnings as errors here)."""
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert params.with_changes(steps_per_segment=4).implausibilities() == []


def test_a_warning_is_one_line_at_the_console(capsys, params):
    """Every command line prints an implausibility as one 'warning:' line on stderr."""
    assert run_command(lambda: len(params.with_changes(pitch_radius=10.0).implausibilities())) == 1
    lines = capsys.readouterr().err.splitlines()
    assert lines == ['warning: pitch_radius is 10.0 m, a length of 1 m or more: millimetres '
                     'typed as metres?']


@pytest.mark.parametrize('what', ['device', 'huge file'])
def test_a_params_file_is_a_regular_file_of_bounded_size(tmp_path, what):
    """A device or a file beyond the bound is refused before being read whole."""
    path = '/dev/zero' if what == 'device' else tmp_path / 'huge.yaml'
    if what == 'huge file':
        with open(path, 'wb') as stream:
            stream.write(b'# ' + b'x' * (params_file.MAX_PARAMS_BYTES + 10) + b'\n')
    with pytest.raises(ParameterError, match='cannot read parameter file') as raised:
        TranslatorParams.from_yaml(path)
    assert '\n' not in str(raised.value)


def test_a_deeply_nested_file_is_refused_naming_the_limit(tmp_path):
    """Nesting beyond MAX_PARAMS_DEPTH: a ParameterError naming the file and the limit."""
    path = write_deep_params(tmp_path)
    with pytest.raises(ParameterError, match=f'more than {params_file.MAX_PARAMS_DEPTH} '
                                             'deep') as raised:
        TranslatorParams.from_yaml(path)
    assert str(path) in str(raised.value) and '\n' not in str(raised.value)
    shallow = tmp_path / 'shallow.yaml'
    shallow.write_text(f'{NODE_NAME}:\n  ros__parameters:\n    pitch_radius: '
                       + '[' * (params_file.MAX_PARAMS_DEPTH - 3) + '0.01'
                       + ']' * (params_file.MAX_PARAMS_DEPTH - 3) + '\n')
    with pytest.raises(ParameterError, match='pitch_radius must be a double'):
        TranslatorParams.from_yaml(shallow)   # read, then refused for its type


@pytest.mark.parametrize('command', [
    ['solve', '--force', '1', '0', '0'], ['calibrate', 'run.mcap', '--fit', 'youngs_modulus']],
    ids=['cdr_translator solve', 'msg_tools calibrate'])
def test_a_deeply_nested_file_is_one_line_and_exit_2(tmp_path, command):
    """The solve and calibrate --params: exit 2, one line naming the depth."""
    path = write_deep_params(tmp_path)
    main = msg_tools_main if command[0] == 'calibrate' else cdr_main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*command, '--params', str(path)])
    lines = err.getvalue().splitlines()
    assert code == 2 and len(lines) == 1, err.getvalue()[-2000:]
    assert lines[0].startswith('error: ') and 'deep' in lines[0] and str(path) in lines[0]
