"""Deprecated alias of ``cdr_translator.robot.params``, where this module moved (0.2)."""

import warnings

from cdr_translator.robot.params import *  # noqa: F401,F403

warnings.warn('cdr_translator.delta_params is deprecated; import cdr_translator.robot.params',
              DeprecationWarning, stacklevel=2)
