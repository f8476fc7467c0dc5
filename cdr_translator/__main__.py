"""Entry point of ``python -m cdr_translator``: Ctrl-C is quiet from the first import on."""

import sys

from .console import quiet_sigint

quiet_sigint()

from .cli import main  # noqa: E402,I100 - after quiet_sigint: the solver takes seconds to load

sys.exit(main())
