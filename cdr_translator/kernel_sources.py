"""
The source files the compiled kernels are built from, and their digest (standard library only).

A cached kernel is valid for one set of sources: every module with a kernel (a ``@jit``
decorator, the package's compile switch) and the package modules those import by relative
imports, whose functions and constants the kernels compile in. The compile switch stamps
numba's cache with their digest and clears the cache when it changes; ``make setup``
compiles anew when any of these files is newer than its last compile. Run as a script, it
prints them one per line relative to the working directory: the Makefile reads them while
it reads its rules, before any environment exists, so this module imports nothing beyond
the standard library.
"""

import ast
import hashlib
import os
from pathlib import Path
from typing import List, Set

#: The package folder.
PACKAGE_DIR = Path(__file__).resolve().parent


def imported_files(path: Path, package_dir: Path) -> Set[Path]:
    """Return the package's own modules that ``path`` imports by relative imports."""
    files = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = path.parent
            for _ in range(node.level - 1):
                base = base.parent
            parts = node.module.split('.') if node.module else []
            names = [parts] if parts else [[alias.name] for alias in node.names]
            for name in names:
                target = base.joinpath(*name)
                for candidate in (target.with_suffix('.py'), target / '__init__.py'):
                    if candidate.is_file() and package_dir in candidate.parents:
                        files.add(candidate)
    return files


def kernel_source_files(package_dir: Path = PACKAGE_DIR) -> List[Path]:
    """Return the kernel modules of ``package_dir`` and the modules they import, sorted."""
    kernels = {path for path in package_dir.rglob('*.py') if '@jit' in path.read_text('utf-8')}
    files = set(kernels)
    for path in kernels:
        files |= imported_files(path, package_dir)
    return sorted(files)


def sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """Return a SHA-256 of the kernel source files (names relative to the package, bytes)."""
    digest = hashlib.sha256()
    for path in kernel_source_files(package_dir):
        digest.update(str(path.relative_to(package_dir)).encode() + b'\0' + path.read_bytes())
    return digest.hexdigest()


if __name__ == '__main__':
    print('\n'.join(os.path.relpath(path) for path in kernel_source_files()))
