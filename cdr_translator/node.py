"""Deprecated alias of ``cdr_translator.ros.translator_node``, where this module moved (0.2)."""

import sys
import warnings

from cdr_translator.ros.translator import *  # noqa: F401,F403

warnings.warn('cdr_translator.node is deprecated; import cdr_translator.ros.translator_node',
              DeprecationWarning, stacklevel=2)

if __name__ == '__main__':
    sys.exit(main())  # noqa: F405
