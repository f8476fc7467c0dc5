"""
The same params file gives the same outcome in translator_node, ``solve`` and ``replay``.

A partial file or a ``/**:`` one is taken key by key over the shipped defaults by all three
(the node answers with the library's pose for those parameters); a misspelt key or an
integer where ROS declares a double stops all three with exit code 2 and the same message.
"""

from pathlib import Path
import subprocess
import sys

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.interface import messages
from cdr_translator.ros.client import NodeProcess, TranslatorClient
import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT_S = 120.0
ANSWER_TIMEOUT_S = 30.0
POSE = messages.END_DISK_POSE_TOPIC

GOOD = {
    'partial': {'translator_node': {'ros__parameters': {'youngs_modulus': 7.0e10,
                                                        'tube_length': 0.12}}},
    'wildcard': {'/**': {'ros__parameters': {'youngs_modulus': 6.0e10,
                                             'slider_stroke': 0.02}}},
}
BAD = {
    'misspelt': ({'translator_node': {'ros__parameters': {'youngs_modulous': 7.0e10}}},
                 'youngs_modulous (did you mean youngs_modulus?)'),
    'integer': ({'/**': {'ros__parameters': {'max_force': 50}}},
                'max_force must be a double, got integer 50 (write 50.0)'),
    'components': ({'translator_node': {'ros__parameters': {'estimate_components': 'fx fq'}}},
                   "estimate_components: estimate must be one of ['force', 'lateral'"),
    'prior': ({'translator_node': {'ros__parameters': {
        'estimate_prior_covariance': [1.0] * 35}}},
        'estimate_prior_covariance must be a list of 0 or 36 doubles'),
}
FORCE = (6.0, 0.0, 0.0)


def write(tmp_path, document):
    """Write a params document and return its path."""
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


def cli(*args, env=None):
    """Run ``python -m`` with ``args``; return the finished process."""
    return subprocess.run([sys.executable, '-m', *args], capture_output=True, text=True,
                          timeout=START_TIMEOUT_S, env=env, cwd=ROOT)


@pytest.mark.parametrize('case', sorted(GOOD))
def test_good_files_give_the_same_model_everywhere(tmp_path, ros_env, case):
    """Node, CLI and replay all solve with the file's values over the shipped ones."""
    path = write(tmp_path, GOOD[case])
    expected = TranslatorSolver(TranslatorParams.from_yaml(path)).solve(FORCE)
    solved = cli('cdr_translator', 'solve', '--force', *map(str, FORCE), '--params',
                 str(path), '--json')
    assert solved.returncode == 0, solved.stderr
    assert np.allclose(yaml.safe_load(solved.stdout)['end_disk_position_m'],
                       expected.end_disk_position, atol=1e-9)
    replayed = cli('msg_tools', 'replay', str(ROOT / 'bags' / 'step_12N.mcap'),
                   '--out', str(tmp_path / 'out.mcap'), '--params', str(path),
                   '--no-compliance')
    assert replayed.returncode == 0, replayed.stderr
    with NodeProcess(['--params-file', str(path), '-p', 'log_to_mcap:=false'], ros_env,
                     tmp_path / 'node.log') as node:
        client = TranslatorClient((POSE, messages.DIAGNOSTICS_TOPIC))
        try:
            assert client.handshake(START_TIMEOUT_S), node.text()
            stamp = client.publish(FORCE)
            assert client.wait_for(lambda: client.messages_stamped(POSE, stamp),
                                   ANSWER_TIMEOUT_S), node.text()
            point = client.messages_stamped(POSE, stamp)[0].pose.position
            position = np.array([point.x, point.y, point.z])
        finally:
            client.close()
    assert np.allclose(position, expected.end_disk_position, atol=1e-9)


@pytest.mark.parametrize('case', sorted(BAD))
def test_bad_files_stop_everything_with_the_same_message(tmp_path, ros_env, case):
    """Exit code 2 and the same reason from the node, the CLI and replay."""
    document, reason = BAD[case]
    path = write(tmp_path, document)
    solved = cli('cdr_translator', 'solve', '--force', '1', '0', '0', '--params', str(path))
    replayed = cli('msg_tools', 'replay', str(ROOT / 'bags' / 'step_12N.mcap'),
                   '--out', str(tmp_path / 'out.mcap'), '--params', str(path))
    with NodeProcess(['--params-file', str(path)], ros_env, tmp_path / 'node.log') as node:
        assert node.process.wait(START_TIMEOUT_S) == 2, node.text()
        node_text = node.text()
    for process in (solved, replayed):
        assert process.returncode == 2, process.stdout + process.stderr
        assert reason in process.stderr
    assert reason in node_text
