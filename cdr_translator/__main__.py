"""Entry point of ``python -m cdr_translator``."""

import sys

from .cli import main

sys.exit(main())
