"""
Both nodes as ROS 2 command lines: --help, a bad params file or -p, Ctrl-C at start-up.

The console scripts run as processes beside this interpreter, in their own DDS domain
limited to this machine (ros_env), in a temporary folder that must stay empty: neither
--help nor a refused start may open an MCAP log. Every wait is bounded.
"""

from pathlib import Path
import subprocess
import sys

from cdr_translator.interface.settings import CDR_SPECS, SPECS
from cdr_translator.ros.cdr_robot import CDR_INPUTS, CDR_OUTPUTS
from cdr_translator.ros.node_help import EXIT_CODES
from cdr_translator.ros.topics import OUTPUTS
from interrupting import after, environment, interpreter_start_s, interrupt
import pytest

#: The console scripts of this interpreter's environment.
BIN = Path(sys.executable).parent
NODES = {'translator_node': (SPECS, ['wrench', *OUTPUTS]),
         'cdr_node': (CDR_SPECS, [*CDR_INPUTS, *CDR_OUTPUTS])}
#: Importing rclpy and the solver takes seconds on a loaded machine.
RUN_TIMEOUT_S = 120.0
#: A node interrupted while it imports exits at once; this allows for a loaded machine.
SIGINT_END_TIMEOUT_S = 30.0


def _run(script: str, arguments, env, cwd: Path) -> subprocess.CompletedProcess:
    """Run a node's console script to its end; return the finished process."""
    return subprocess.run([str(BIN / script), *arguments], env=environment(env), cwd=cwd,
                          capture_output=True, text=True, timeout=RUN_TIMEOUT_S)


@pytest.mark.parametrize('script', sorted(NODES))
def test_help_lists_parameters_topics_and_exit_codes_and_starts_nothing(
        script, ros_env, tmp_path):
    """--help: exit 0, every parameter and topic on its own line, no file written."""
    specs, topics = NODES[script]
    process = _run(script, ['--help', '--ros-args', '-p', f'log_dir:={tmp_path / "logs"}'],
                   ros_env, tmp_path)
    assert process.returncode == 0, process.stderr
    lines = process.stdout.splitlines()
    assert lines[0].startswith(f'usage: {script} ')
    for name, spec in specs.items():
        line = next((line for line in lines if line.split()[:1] == [name]), None)
        assert line is not None, name
        assert spec.unit in line
    for topic in topics:
        assert any(line.split()[:1] == [topic] and '/msg/' in line for line in lines), topic
    for code, meaning in EXIT_CODES:
        assert f'{code}  ' in process.stdout and meaning in process.stdout
    assert list(tmp_path.iterdir()) == []


def _one_line(process: subprocess.CompletedProcess, script: str, named: str) -> None:
    """Exit 2 and one line on stderr, naming ``named``, without a traceback."""
    assert process.returncode == 2, process.stdout + process.stderr
    assert 'Traceback' not in process.stderr, process.stderr
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1, process.stderr
    assert lines[0].startswith(f'{script}: ') and named in lines[0], lines[0]


@pytest.mark.parametrize('script', sorted(NODES))
def test_a_missing_or_unparsable_params_file_is_one_line(script, ros_env, tmp_path):
    """--params-file naming no file, not YAML, nested too deep: exit 2, one line naming it."""
    missing = tmp_path / 'missing.yaml'
    _one_line(_run(script, ['--ros-args', '--params-file', str(missing)], ros_env, tmp_path),
              script, str(missing))
    broken = tmp_path / 'broken.yaml'
    broken.write_text(f'{script}:\n  ros__parameters: [max_force\n')
    _one_line(_run(script, ['--ros-args', '--params-file', str(broken)], ros_env, tmp_path),
              script, str(broken))
    deep = tmp_path / 'deep.yaml'   # beyond the recursion limit of YAML's composer and rcl's
    deep.write_text(f'{script}:\n  ros__parameters:\n    max_force: ' + '[' * 5000 + '1.0'
                    + ']' * 5000 + '\n')
    _one_line(_run(script, ['--ros-args', '--params-file', str(deep)], ros_env, tmp_path),
              script, f'{deep} nests mappings and lists more than')
    assert sorted(path.name for path in tmp_path.iterdir()) == ['broken.yaml', 'deep.yaml']


@pytest.mark.parametrize('override', ['max_force', 'max_force:=[1,', 'max_force:=strong',
                                      'no_such_parameter:=1'])
def test_a_bad_parameter_override_is_one_line(override, ros_env, tmp_path):
    """-p without :=, with a value that is not YAML or not a double, or unknown: exit 2."""
    script = 'translator_node'
    process = _run(script, ['--ros-args', '-p', override], ros_env, tmp_path)
    _one_line(process, script, override.partition(':=')[0])
    assert list(tmp_path.iterdir()) == []


def _dds_loaded(process: subprocess.Popen) -> bool:
    """Tell whether the node has initialized rclpy (its DDS library is mapped): warming up."""
    try:
        return 'fastrtps' in Path(f'/proc/{process.pid}/maps').read_text()
    except OSError:
        return False


@pytest.mark.parametrize('script', sorted(NODES))
def test_ctrl_c_during_start_up_is_one_line_and_exit_130(script, ros_env, tmp_path):
    """SIGINT while the node imports: exit 130, one line, no process left behind."""
    start = interpreter_start_s()
    for moment in (start + 0.05, start + 0.3):
        interrupt([str(BIN / script), '--ros-args', '-p', f'log_dir:={tmp_path}'],
                  after(moment), environment(ros_env), tmp_path).assert_quiet()


@pytest.mark.parametrize('script', sorted(NODES))
def test_sigint_at_start_up_ends_a_node_that_inherited_it_ignored(script, ros_env, tmp_path):
    """
    ``node &`` from a script (SIGINT ignored), SIGINT at 0.5 s: exit 130 at once, one line.

    The node stops on SIGINT once running, so a SIGINT sent while it starts must not be
    lost: ``kill -INT $pid; wait $pid`` would wait forever.
    """
    ending = interrupt([sys.executable, '-m', f'cdr_translator.ros.{script}', '--ros-args',
                        '-p', f'log_dir:={tmp_path}'], after(interpreter_start_s() + 0.5),
                       environment(ros_env), tmp_path, inherit_ignored=True,
                       end_timeout_s=SIGINT_END_TIMEOUT_S)
    ending.assert_quiet()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('script', sorted(NODES))
def test_ctrl_c_while_warming_up_is_quiet(script, ros_env, tmp_path):
    """
    SIGINT once rclpy is up: 130 and one line while the node is built, 0 once it runs.

    The warm-up takes a fraction of a second with the kernels cached, so either may come;
    neither leaves a traceback or a process.
    """
    ending = interrupt([str(BIN / script), '--ros-args', '-p', f'log_dir:={tmp_path}'],
                       _dds_loaded, environment(ros_env), tmp_path)
    if ending.returncode == 0:
        assert 'ready: ' in ending.stderr and 'Traceback' not in ending.stderr
        assert not ending.leftovers
    else:
        ending.assert_quiet()
