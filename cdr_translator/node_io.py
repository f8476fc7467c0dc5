"""Deprecated alias of ``cdr_translator.ros.runtime``, where this module moved (0.2)."""

import warnings

from cdr_translator.ros.runtime import *  # noqa: F401,F403

warnings.warn('cdr_translator.node_io is deprecated; import cdr_translator.ros.runtime',
              DeprecationWarning, stacklevel=2)
