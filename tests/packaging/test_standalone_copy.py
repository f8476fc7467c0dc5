"""
The packaging tests pass in a copy of the tracked files with nothing beside it.

CI clones the repository next to other folders, so a test that read a file outside the
repository would pass there and fail in a plain clone. This copies ``git ls-files`` into an
empty temporary folder and runs tests/packaging in it (the copy first on PYTHONPATH, no
CDR_ROSDEP_DIR). Left out, to keep it under a minute: this file (it would run itself), the
linters and the colcon build (minutes; the colcon test builds from such a copy itself), the
import graph and the size limits (they read only the three libraries' folders), and the
README's solve (the copy has no compiled numba kernels: minutes of compiling).
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]

#: tests/packaging files not run in the copy (see the module docstring).
LEFT_OUT = ('test_standalone_copy.py', 'test_flake8.py', 'test_pep257.py', 'test_packaging.py',
            'test_import_graph.py', 'test_unit_sizes.py')
DESELECTED = ('tests/packaging/test_docs.py::test_readme_solve_example_runs',)
#: Seconds the run in the copy may take: the guide's solves compile their kernels cold there,
#: and the docs are built (test_docs_build.py).
COPY_TIMEOUT_S = 300


def test_packaging_tests_pass_in_a_copy_with_nothing_beside_it(tmp_path):
    """``pytest tests/packaging`` in a copy of the tracked files alone passes."""
    copy = tmp_path / 'alone' / 'cdr_translator'
    tracked = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, capture_output=True,
                             text=True, check=True, timeout=30).stdout.split('\0')
    for name in filter(None, tracked):
        target = copy / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    assert sorted(path.name for path in copy.parent.iterdir()) == ['cdr_translator']
    env = {name: value for name, value in os.environ.items() if name != 'CDR_ROSDEP_DIR'}
    env['PYTHONPATH'] = str(copy)
    command = [sys.executable, '-m', 'pytest', 'tests/packaging', '-q', '-p', 'no:cacheprovider']
    command += [f'--ignore=tests/packaging/{name}' for name in LEFT_OUT]
    command += [f'--deselect={test}' for test in DESELECTED]
    process = subprocess.run(command, cwd=copy, env=env, capture_output=True, text=True,
                             timeout=COPY_TIMEOUT_S)
    assert process.returncode == 0, process.stdout[-5000:] + process.stderr[-3000:]
    assert ' passed' in process.stdout.splitlines()[-1], process.stdout[-1000:]
