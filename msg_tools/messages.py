"""Deprecated alias of ``cdr_translator.interface.messages``, where this module moved (0.2)."""

import warnings

from cdr_translator.interface.messages import *  # noqa: F401,F403

warnings.warn('msg_tools.messages is deprecated; import cdr_translator.interface.messages',
              DeprecationWarning, stacklevel=2)
