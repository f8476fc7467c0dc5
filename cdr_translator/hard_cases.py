"""Deprecated alias of ``cdr_translator.studies.hard_cases``, where this module moved (0.2)."""

import warnings

from cdr_translator.studies.hard_cases import *  # noqa: F401,F403

warnings.warn('cdr_translator.hard_cases is deprecated; import cdr_translator.studies.hard_cases',
              DeprecationWarning, stacklevel=2)
