"""
The command line at its edges.

The params file read whole, strict JSON, unstable answers, a closed stdout, Ctrl-C,
sweeps too large to hold, and compile's progress.
"""

import json
from pathlib import Path
import re
import subprocess
import sys

from cdr_translator import _jit, cli
from cdr_translator.cli import main
from cdr_translator.console import (EXIT_BROKEN_PIPE, EXIT_INTERRUPTED, json_text,
                                    run_command)
from cdr_translator.fidelity import FidelitySolver
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _params(tmp_path, node: str, **values) -> str:
    """Write a params file setting ``values`` for ``node``; return its path."""
    path = tmp_path / f'{node}.yaml'
    lines = [f'{node}:', '  ros__parameters:'] + [f'    {key}: {value}'
                                                  for key, value in values.items()]
    path.write_text('\n'.join(lines) + '\n')
    return str(path)


def _strict(text: str) -> dict:
    """Parse JSON refusing the NaN and Infinity tokens Python's json would accept."""
    def refuse(token):
        raise AssertionError(f'{token} is not JSON')
    return json.loads(text, parse_constant=refuse)


def test_solve_takes_the_accuracy_target_from_the_params_file(tmp_path, capsys):
    """A tighter target in --params refines further: the keys were ignored before."""
    assert main(['solve', '--force', '20', '0', '0', '--json']) == 0
    default = json.loads(capsys.readouterr().out)
    tight = _params(tmp_path, 'translator_node', accuracy_position_m='1.0e-8',
                    accuracy_angle_deg='1.0e-5')
    assert main(['solve', '--force', '20', '0', '0', '--json', '--params', tight]) == 0
    refined = json.loads(capsys.readouterr().out)
    assert refined['steps_per_segment'] > default['steps_per_segment']
    assert refined['error_estimate_m'] <= 1e-8 < default['error_estimate_m']


@pytest.mark.parametrize('key, value, fragment', [
    ('max_force', '-5.0', 'max_force must lie in'),
    ('accuracy_position_m', '-1.0', 'accuracy_position_m'),
    ('fidelity', 'bogus', 'fidelity'),
])
def test_solve_checks_every_key_of_the_params_file(tmp_path, capsys, key, value, fragment):
    """Node-only keys too, as the node and replay do: exit 2 naming the key."""
    assert main(['solve', '--force', '1', '0', '0', '--params',
                 _params(tmp_path, 'translator_node', **{key: value})]) == 2
    assert fragment in capsys.readouterr().err


@pytest.mark.parametrize('command', [['solve', '--force', '1', '0', '0'],
                                     ['delta', '--sliders', '0.02', '0', '0']])
def test_a_device_as_params_file_is_one_line_and_exit_2(capsys, command):
    """/dev/zero would be read without bound: refused as not a regular file."""
    assert main(command + ['--params', '/dev/zero']) == 2
    error = capsys.readouterr().err
    assert 'not a regular file' in error and error.count('\n') == 1, error


def test_delta_takes_a_params_file_with_only_a_cdr_node_section(tmp_path, capsys):
    """The legs' keys come from the shipped file, the robot's from the user's."""
    path = _params(tmp_path, 'cdr_node', slider_stroke='0.02')
    assert main(['delta', '--sliders', '0.02', '0', '0', '--json', '--params', path]) == 0
    assert json.loads(capsys.readouterr().out)['converged'] is True
    assert main(['delta', '--sliders', '0.025', '0', '0', '--params', path]) == 2
    assert 'stroke' in capsys.readouterr().err


def test_delta_exits_4_on_an_unstable_equilibrium(capsys):
    """12 kN pulling the platform up buckles nothing but is unstable: exit 4, a warning."""
    assert main(['delta', '--sliders', '0', '0', '0', '--payload', '0', '0', '12000',
                 '--json']) == cli.EXIT_UNSTABLE
    captured = capsys.readouterr()
    assert _strict(captured.out)['stable'] is False
    assert 'unstable' in captured.err


@pytest.mark.parametrize('argv', [
    ['solve', '--force', '1e308', '0', '0', '--json'],
    ['solve', '--force', '0', '0', '-500', '--fidelity', 'cc', '--json'],
])
def test_json_is_strict_and_says_what_was_not_assessed(argv, capsys):
    """No NaN or Infinity tokens; stable and accuracy_met are null when not assessed."""
    main(argv)
    data = _strict(capsys.readouterr().out)
    assert 'stable' in data and 'stability_margin' in data
    if not data['converged'] or data['fidelity'] == 'cc':
        assert data['stable'] is None and data['accuracy_met'] is None


def test_a_reduced_model_claims_no_accuracy_it_did_not_estimate(params):
    """The cc level has no error estimate: accuracy_met is null, not true."""
    result = FidelitySolver(params, 'cc').solve([5.0, 0.0, 0.0])
    data = result.to_dict()
    assert result.converged and data['error_estimate_m'] is None
    assert data['accuracy_met'] is None and data['stable'] is None


def test_paper_exits_3_when_a_case_does_not_converge(capsys, monkeypatch):
    """The comparison is still printed; the exit code says it is not to be trusted."""
    original = cli.TranslatorSolver.solve

    def unconverged(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        result.converged = False
        return result

    monkeypatch.setattr(cli.TranslatorSolver, 'solve', unconverged)
    assert main(['paper']) == 3
    assert 'Converged: False' in capsys.readouterr().out


def test_atlas_too_large_is_refused_before_anything_is_built(tmp_path, capsys):
    """A 1e15-sample grid took 24 GB before: now exit 2 naming the size."""
    assert main(['atlas', '--grid', '100000', '--out', str(tmp_path / 'a.zarr'),
                 '--no-progress']) == 2
    assert '1e+15 samples' in capsys.readouterr().err
    assert not (tmp_path / 'a.zarr').exists()


def test_atlas_store_that_cannot_be_written_is_named_as_such(tmp_path, capsys):
    """Not blamed on the Dask cluster: the store path and the reason."""
    (tmp_path / 'file').write_text('x')
    out = tmp_path / 'file' / 'a.zarr'
    assert main(['atlas', '--grid', '2', '--out', str(out), '--no-progress']) == 2
    error = capsys.readouterr().err
    assert f'cannot write the atlas store {out}' in error and 'Dask' not in error


def test_closed_stdout_ends_quietly_with_141():
    """`| head -1`: no BrokenPipeError traceback."""
    process = subprocess.Popen([sys.executable, '-m', 'cdr_translator', 'solve', '--force',
                                '12', '0', '0'], cwd=ROOT, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    process.stdout.close()
    error = process.stderr.read().decode()
    assert process.wait(timeout=300) == EXIT_BROKEN_PIPE, error
    assert 'Traceback' not in error


def test_ctrl_c_is_one_line_and_130(capsys):
    """A KeyboardInterrupt anywhere in a command: 'interrupted', exit 130."""
    def interrupted() -> int:
        raise KeyboardInterrupt
    assert run_command(interrupted) == EXIT_INTERRUPTED
    assert capsys.readouterr().err == 'interrupted (Ctrl-C)\n'


def test_json_text_writes_non_finite_numbers_as_null():
    """Nested too; integers, strings and finite floats unchanged."""
    text = json_text({'a': float('nan'), 'b': [1.5, float('inf'), (2, -float('inf'))],
                      'c': 'x', 'd': 3})
    assert _strict(text) == {'a': None, 'b': [1.5, None, [2, None]], 'c': 'x', 'd': 3}


def test_the_compliance_verdict_counts_when_it_is_the_only_one(capsys):
    """The paper's method judges nothing itself: --compliance's unstable verdict exits 4."""
    assert main(['solve', '--method', 'paper', '--force', '0', '0', '-40', '--compliance',
                 '--json']) == cli.EXIT_UNSTABLE
    data = _strict(capsys.readouterr().out)
    assert data['converged'] is True and data['stable'] is False
    assert data['stability_margin'] is None   # the solve's own margin was not assessed


def test_compile_says_each_stage_as_it_goes(capsys):
    """The compile command prints a line per warm-up stage and the kernels cached so far."""
    assert main(['compile']) == 0
    lines = capsys.readouterr().out.splitlines()
    stages = [line for line in lines if re.match(r'\[\d+/\d+\] ', line)]
    total = int(re.match(r'\[\d+/(\d+)\]', stages[0]).group(1))
    assert total >= 8 and len(stages) == total, lines
    for number, line in enumerate(stages, 1):
        assert line.startswith(f'[{number}/{total}] '), line
        assert re.search(r': \d+ signatures compiled, \d+ loaded from the cache so far, '
                         r'\d+ s$', line), line
    counts = _jit.kernel_counts()
    assert stages[-1].split(': ')[1].startswith(f'{counts.compiled} signatures compiled, '
                                                f'{counts.loaded} loaded')
    assert lines[-1].startswith(f'all {len(_jit.KERNELS)} numba kernels are in the cache')
