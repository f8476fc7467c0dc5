"""
docs/tutorial/getting_started.md over DDS: its node command, its feed.py, the commands on its log.

In a fresh folder and the module's own ROS domain: the guide's translator_node command
line starts the node (this interpreter's console script), the guide's feed.py gets the
pose it shows, Ctrl-C (SIGINT) ends the node with the documented exit code, and the guide's
msg_tools commands on the node's log exit and print as documented.
"""

import signal
import subprocess
import sys

from cdr_translator.ros.client import NodeProcess, SCRIPT_COMMAND
from guide_blocks import assert_shows, checkout_env, COMMAND_TIMEOUT_S, commands, guide_blocks
from guide_blocks import run_commands

#: What a node may take to exit after SIGINT (the solve in hand, closing its log).
STOP_TIMEOUT_S = 30.0


def test_node_feed_and_log_as_documented(tmp_path, ros_env):
    """Start the node as shown, feed it with feed.py, stop it, read and replay its log."""
    [node_block] = guide_blocks('node')
    [(argv, exit_code)] = commands(node_block)
    assert argv[:2] == [*SCRIPT_COMMAND, '--ros-args'], argv
    env = checkout_env(ros_env)
    with NodeProcess(argv[2:], env, tmp_path / 'node.log', SCRIPT_COMMAND, cwd=tmp_path) as node:
        [feed] = guide_blocks('feed')
        (tmp_path / 'feed.py').write_text(feed.text, encoding='utf-8')
        process = subprocess.run([sys.executable, 'feed.py'], cwd=tmp_path, env=env,
                                 capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S)
        assert process.returncode == 0, process.stdout + process.stderr
        assert_shows(feed.expected, process.stdout)
        assert node.stop(signal.SIGINT, STOP_TIMEOUT_S) == exit_code, node.text()
    for block in guide_blocks('node-log'):
        assert_shows(block.expected, run_commands(block, tmp_path, env))
