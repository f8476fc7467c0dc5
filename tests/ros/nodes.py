"""A translator_node child process with a connected client, for the node tests."""

from pathlib import Path
import time
from typing import Optional

from cdr_translator.interface import messages
from cdr_translator.ros.client import diagnostic_values, MODULE_COMMAND, NodeProcess
from cdr_translator.ros.client import TranslatorClient
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import serialize_message

#: The first solve may compile the kernels (cached on disk after), DDS discovery takes
#: seconds on a loaded machine: generous bounds, never waited for in full when all is well.
START_TIMEOUT_S = 120.0
ANSWER_TIMEOUT_S = 30.0
POSE = messages.END_DISK_POSE_TOPIC
ANGLES = messages.BENDING_ANGLES_TOPIC
DIAGNOSTICS = messages.DIAGNOSTICS_TOPIC
STATUS = messages.SOLVE_STATUS_TOPIC


class Running:
    """
    A node process and a connected client; both are torn down on exit.

    The node logs to ``mcap`` (default ``tmp_path / 'run.mcap'``) and prints to
    ``tmp_path / '<name>.log'``.
    """

    def __init__(self, tmp_path: Path, env, ros_args=(),
                 topics=(POSE, ANGLES, STATUS, DIAGNOSTICS), command=MODULE_COMMAND,
                 mcap: Optional[Path] = None, name: str = 'node'):
        """Start the node and wait for its first answer."""
        self.mcap = tmp_path / 'run.mcap' if mcap is None else mcap
        # rcl applies --params-file and -p in command-line order: mcap_path comes last, so
        # that a params file among ros_args cannot send the log to the checkout's cdr_runs/
        self.node = NodeProcess([*ros_args, '-p', f'mcap_path:={self.mcap}'], env,
                                tmp_path / f'{name}.log', command)
        self.client = None
        try:
            self.client = TranslatorClient(topics)
            assert self.client.handshake(START_TIMEOUT_S), self.node.text()
        except BaseException:
            self.__exit__()
            raise

    def __enter__(self):
        """Return self."""
        return self

    def __exit__(self, *exc_info):
        """Close the client, kill the node if it still runs."""
        if self.client is not None:
            self.client.close()
        self.node.kill()

    def answered(self, topic, stamp) -> bool:
        """Wait for the message of ``topic`` stamped ``stamp``; False on timeout."""
        return self.client.wait_for(lambda: self.client.messages_stamped(topic, stamp),
                                    ANSWER_TIMEOUT_S)

    def answer(self, topic, stamp):
        """Wait for the message of ``topic`` stamped ``stamp``; return it."""
        assert self.answered(topic, stamp), (topic, stamp, self.node.text())
        return self.client.messages_stamped(topic, stamp)[0]

    def last_diagnostic(self):
        """Return the key/values of the wrenches' status in the last /diagnostics array."""
        return diagnostic_values(self.client.received[DIAGNOSTICS][-1][0])

    def counts_after(self, stamp, topic=STATUS):
        """
        Return the wrenches' status values in the first /diagnostics array after ``stamp``'s.

        That array was published after the status of ``stamp`` (on ``topic``) arrived: its
        counts include that wrench.
        """
        self.answer(topic, stamp)
        array = self.client.diagnostics_after(stamp, ANSWER_TIMEOUT_S, topic)
        assert array is not None, self.node.text()
        return diagnostic_values(array)


def stamped_wrenches(count: int, axis: str, first: float) -> list:
    """Return ``count`` WrenchStamped stamped 1, 2, ... s, force ``axis`` first, first + 1 ..."""
    wrenches = [WrenchStamped() for _ in range(count)]
    for index, wrench in enumerate(wrenches):
        wrench.header.stamp.sec = index + 1
        setattr(wrench.wrench.force, axis, first + (1.0 if first >= 0.0 else -1.0) * index)
    return wrenches


def send_behind_a_slow_first_solve(node, wrenches) -> None:
    """
    Hand ``wrenches`` (WrenchStamped) to a node's wrench callback while its first solve runs.

    The first is sent alone and taken by the solver thread (the node's solve must be slowed
    down by the caller) before the rest arrive, so they wait in the mailbox.
    """
    for index, wrench in enumerate(wrenches):
        node._on_wrench(serialize_message(wrench))
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while index == 0 and node._mailbox._items and time.monotonic() < deadline:
            time.sleep(0.001)   # the solver thread has taken the first
