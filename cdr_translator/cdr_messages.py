"""Deprecated alias of ``cdr_translator.interface.cdr_messages``, where this module moved (0.2)."""

import warnings

from cdr_translator.interface.cdr_messages import *  # noqa: F401,F403

warnings.warn('cdr_translator.cdr_messages is deprecated; import '
              'cdr_translator.interface.cdr_messages',
              DeprecationWarning, stacklevel=2)
