"""The command line: JSON keys, exit codes, bad input."""

import json
import subprocess
import sys

from cdr_translator.cli import main
import pytest

JSON_KEYS = {'converged', 'message', 'iterations', 'residual_norm', 'pj_bending_deg',
             'pj_direction_deg', 'dj_bending_deg', 'dj_direction_deg', 'end_disk_rotation_deg',
             'end_disk_position_m', 'end_disk_quaternion_xyzw', 'max_arc_deviation_mm',
             'solve_time_s'}


def test_solve_json_reproduces_table_ii(capsys):
    """`solve --force 12 0 0 --json` prints the contract keys and the Table II angles."""
    assert main(['solve', '--force', '12', '0', '0', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert JSON_KEYS <= set(data)
    assert data['converged'] is True
    assert abs(data['pj_bending_deg'] - 22.448) < 0.5
    assert abs(data['dj_bending_deg'] - 22.063) < 0.5
    assert len(data['end_disk_position_m']) == 3
    assert len(data['end_disk_quaternion_xyzw']) == 4
    assert set(data['max_arc_deviation_mm']) == {'pj', 'dj'}


def test_solve_table_output(capsys):
    """Without --json a readable table."""
    assert main(['solve', '--force', '0', '5', '0', '--moment', '0', '0', '0.01']) == 0
    out = capsys.readouterr().out
    assert 'PJ bending / direction' in out and 'deg' in out


def test_not_converged_exit_code(capsys):
    """Exit 3 when the solve does not converge; the JSON is still printed."""
    assert main(['solve', '--force', '20', '0', '0', '--time-limit', '0', '--json']) == 3
    data = json.loads(capsys.readouterr().out)
    assert data['converged'] is False and 'time limit' in data['message']


@pytest.mark.parametrize('argv, fragment', [
    (['solve', '--force', 'nan', '0', '0'], 'force x component is nan'),
    (['solve', '--force', '1', '0', '0', '--params', '/nonexistent.yaml'], 'cannot read'),
])
def test_bad_input_exit_code(capsys, argv, fragment):
    """Exit 2 and a message on stderr for bad input."""
    assert main(argv) == 2
    assert fragment in capsys.readouterr().err


def test_module_entry_point():
    """`python -m cdr_translator` runs as a process with the documented exit codes."""
    process = subprocess.run([sys.executable, '-m', 'cdr_translator', 'solve', '--force',
                              'inf', '0', '0'], capture_output=True, text=True, timeout=120)
    assert process.returncode == 2
    assert 'force x component is inf' in process.stderr


def test_paper_comparison(capsys):
    """`paper` prints the Table II comparison."""
    assert main(['paper']) == 0
    out = capsys.readouterr().out
    assert 'Bending angle of PJ' in out and '22.448' in out and '32.871' in out
