"""The project's own modules, by dotted name: what the structural tests walk."""

from pathlib import Path
from typing import Dict

ROOT = Path(__file__).resolve().parents[1]

#: The packages whose modules the structural tests (import graph, private access) read.
PACKAGES = ('cdr_translator', 'cdr_wire', 'msg_tools')


def module_files() -> Dict[str, Path]:
    """Map every module of PACKAGES to its file (a package to its ``__init__.py``)."""
    names = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob('*.py')):
            parts = list(path.relative_to(ROOT).with_suffix('').parts)
            if parts[-1] == '__init__':
                parts.pop()
            names['.'.join(parts)] = path
    return names
