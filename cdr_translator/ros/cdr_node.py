"""
Console script ``cdr_node`` (also ``python -m cdr_translator.ros.cdr_node``).

Ctrl-C is made quiet first: rclpy and the solver take seconds to load, and an interrupt
meanwhile would print the import chain; a SIGINT inherited as ignored (a background job of
a script) is taken over too, so that one sent during start-up is not lost. The node itself
is cdr_translator.ros.cdr_robot.
"""

import sys

from ..console import quiet_sigint

quiet_sigint(even_if_ignored=True)

from .cdr_robot import main  # noqa: E402,I100 - rclpy and the solver load slowly

__all__ = ['main']

if __name__ == '__main__':
    sys.exit(main())
