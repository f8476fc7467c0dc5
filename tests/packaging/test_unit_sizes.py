"""
Size limits of the three libraries: a module at most 500 lines, a class at most 400.

Every ``.py`` file under cdr_translator/, cdr_wire/ and msg_tools/ counts: a module by its
lines, a class from its ``class`` line to its last (ast's ``end_lineno - lineno + 1``,
nested classes too).
"""

import ast
from pathlib import Path
from typing import List

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ('cdr_translator', 'cdr_wire', 'msg_tools')
MAX_MODULE_LINES = 500
MAX_CLASS_LINES = 400


def offenders(path: Path, root: Path = ROOT) -> List[str]:
    """Return a line per limit that ``path`` or one of its classes exceeds."""
    text = path.read_text()
    name = path.relative_to(root).as_posix()
    found = []
    lines = len(text.splitlines())
    if lines > MAX_MODULE_LINES:
        found.append(f'{name}: module of {lines} lines (limit {MAX_MODULE_LINES})')
    for node in ast.walk(ast.parse(text, name)):
        if isinstance(node, ast.ClassDef):
            length = node.end_lineno - node.lineno + 1
            if length > MAX_CLASS_LINES:
                found.append(f'{name}:{node.lineno}: class {node.name} of {length} lines '
                             f'(limit {MAX_CLASS_LINES})')
    return found


def test_modules_and_classes_are_within_the_limits():
    """No module of the libraries is over 500 lines and no class over 400."""
    paths = [path for package in PACKAGES for path in sorted((ROOT / package).rglob('*.py'))]
    assert len(paths) > 20, 'the libraries were not found'
    found = [line for path in paths for line in offenders(path)]
    assert not found, 'over the size limits (split them):\n' + '\n'.join(found)


def test_the_limits_name_an_oversized_module_and_class(tmp_path):
    """A 401-line class in a 501-line module is named twice; 400 and 500 lines pass."""
    body = ''.join(f'    value_{index} = {index}\n' for index in range(399))
    big = tmp_path / 'big.py'
    big.write_text('class Big:\n' + body + '    last = 0\n' + '\n' * 100)
    small = tmp_path / 'small.py'
    small.write_text('class Small:\n' + body + '\n' * 100)
    assert len(big.read_text().splitlines()) == 501
    assert offenders(big, tmp_path) == ['big.py: module of 501 lines (limit 500)',
                                        'big.py:1: class Big of 401 lines (limit 400)']
    assert offenders(small, tmp_path) == []
