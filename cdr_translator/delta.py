"""Deprecated alias of ``cdr_translator.robot.delta``, where this module moved (0.2)."""

import warnings

from cdr_translator.robot.delta import *  # noqa: F401,F403

warnings.warn('cdr_translator.delta is deprecated; import cdr_translator.robot.delta',
              DeprecationWarning, stacklevel=2)
