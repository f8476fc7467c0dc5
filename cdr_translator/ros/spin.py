"""
Starting a node, spinning it until SIGINT/SIGTERM and closing it cleanly (``run``).

The exit codes are node_help's; a node's ``close()`` stops its threads within
``SHUTDOWN_JOIN_S`` and finalizes its log.
"""

import gc
import signal
import sys
import threading
from typing import Any, Callable, List, Optional, Sequence

import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as rclpy_extension
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .node_help import EXIT_CANNOT_START, wants_help
from .parameters import check_command_line
from ..console import run_command
from ..params.translator_params import ParameterError

#: How long main() waits for the solver thread to finish its solve at shutdown.
SHUTDOWN_JOIN_S = 5.0

#: How long a thread that wants the GIL waits before the running one is asked to drop it
#: (CPython's default is 5 ms): the executor's wrench callback behind a busy solver thread.
GIL_SWITCH_INTERVAL_S = 0.0005


def freeze_heap() -> int:
    """
    Collect, then move every object alive now out of the cyclic garbage collector's reach.

    A started node holds about 150 000 long-lived objects (numba, scipy, rclpy, the
    solver); a full collection traverses them all, 130 ms measured, and the collector runs
    one every so often under the allocations of a 1 kHz wrench stream: the ~200 ms
    latency spikes of bench/results/node_rate.md. Frozen (``gc.freeze``), they are skipped;
    what is allocated afterwards is collected as before. Returns the number frozen.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def run(factory: Callable[..., Node], name: str, args: Optional[Sequence[str]] = None,
        help_text: Optional[Callable[[], str]] = None) -> int:
    """
    Run the node ``factory(ros_arguments=...)`` builds until SIGINT or SIGTERM.

    ``ros_arguments`` is the command line (``args``, or sys.argv), from which the node reads
    its ``--params-file`` and ``-p`` values. ``-h``/``--help`` (outside ``--ros-args``)
    prints ``help_text()`` and returns 0 before anything starts. The exit code is
    EXIT_CANNOT_START (2, one line on stderr) when it cannot start (a missing or
    unparsable params file, a bad ``-p``, bad parameters, an unwritable log),
    EXIT_INTERRUPTED (130) after a Ctrl-C during start-up (console.run_command), else 0
    after its ``close()`` (which must stop its threads and finalize its log) and a clean
    shutdown. What the started node holds is frozen (``freeze_heap``) before it spins.
    """
    arguments = list(sys.argv if args is None else args)
    return run_command(lambda: _start(factory, name, arguments, help_text))


def _cannot_start(name: str, error: BaseException) -> int:
    """Print why node ``name`` cannot start, on one line; return EXIT_CANNOT_START."""
    print(f'{name}: {" ".join(str(error).split())}', file=sys.stderr)
    return EXIT_CANNOT_START


def _start(factory: Callable[..., Node], name: str, arguments: List[str],
           help_text: Optional[Callable[[], str]]) -> int:
    """Answer ``--help``, check the parameter sources, then initialize rclpy and spin."""
    if help_text is not None and wants_help(arguments):
        print(help_text())
        return 0
    try:
        # rcl would refuse these with a traceback: the CLI's checks name the file or -p
        check_command_line(arguments)
        rclpy.init(args=arguments, signal_handler_options=SignalHandlerOptions.NO)
    except (ParameterError, rclpy_extension.RCLError) as error:
        return _cannot_start(name, error)
    try:
        return _spin(factory, name, arguments)
    finally:
        rclpy.try_shutdown()


def _spin(factory: Callable[..., Node], name: str, arguments: List[str]) -> int:
    """
    Build the node and spin it until SIGINT or SIGTERM; return the exit code.

    SIGTERM during start-up stops the node once built; SIGINT is a KeyboardInterrupt until
    the node is built (Ctrl-C need not wait for the warm-up), then a stop request.
    """
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        node: Any = factory(ros_arguments=arguments)
    except (ParameterError, InvalidParameterTypeException, InvalidParameterValueException,
            OSError) as error:
        return _cannot_start(name, error)
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    freeze_heap()
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
    return 0
