"""Deprecated alias of ``cdr_translator.ros.client``, where this module moved (0.2)."""

import warnings

from cdr_translator.ros.client import *  # noqa: F401,F403

warnings.warn('cdr_translator.node_client is deprecated; import cdr_translator.ros.client',
              DeprecationWarning, stacklevel=2)
