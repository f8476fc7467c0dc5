"""Deprecated alias of ``cdr_translator.ros.parameters``, where this module moved (0.2)."""

import warnings

from cdr_translator.ros.parameters import *  # noqa: F401,F403

warnings.warn('cdr_translator.node_params is deprecated; import cdr_translator.ros.parameters',
              DeprecationWarning, stacklevel=2)
