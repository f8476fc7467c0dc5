"""Deprecated alias of ``cdr_translator.interface.processing``, where this module moved (0.2)."""

import warnings

from cdr_translator.interface.processing import *  # noqa: F401,F403

warnings.warn('msg_tools.processing is deprecated; import cdr_translator.interface.processing',
              DeprecationWarning, stacklevel=2)
