"""
Where the compiled kernels are cached, in subprocesses on copies of the package.

A read-only package (as colcon installs it into a root-owned prefix) must cache into the
per-user folder; a writable one into its own ``__pycache__``; ``NUMBA_CACHE_DIR`` always
wins; kernels cached with other numba options are compiled anew. Read-only means the mode
bits for an ordinary user and, for root (who writes whatever the mode bits say), a read-only
bind mount in a private mount namespace (``unshare -m``).
"""

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
from typing import Dict, Iterator, List, Optional

import cdr_translator._jit
from cdr_translator._jit import kernel_sources_digest, OPTIONS_STAMP, options_text
from cdr_translator.kernel_sources import kernel_source_files
import pytest

ROOT = Path(__file__).resolve().parents[2]

#: Calls the smallest kernel, then reports the cache location and what happened.
PROBE = """
import json
import numpy as np
from cdr_translator import _jit
from cdr_translator.bvp import rod
p, rot = np.zeros(3), np.eye(3)
rod.rk4_stage_pose(p, rot, np.ones(3), np.zeros((3, 3)), 0.5, np.empty(3), np.empty((3, 3)))
counts = _jit.kernel_counts()
print(json.dumps({'location': _jit.CACHE_LOCATION, 'compiled': counts.compiled,
                  'loaded': counts.loaded,
                  'uncached': 'cdr_translator.bvp.rod.rk4_stage_pose' in _jit.uncached_kernels()}))
"""


@pytest.fixture
def copy() -> Iterator[Path]:
    """Yield a world-readable folder with a copy of the package sources (no caches)."""
    folder = Path(tempfile.mkdtemp(prefix='cdr_kernel_cache_'))
    try:
        for package in ('cdr_translator', 'msg_tools', 'config'):
            shutil.copytree(ROOT / package, folder / 'src' / package,
                            ignore=shutil.ignore_patterns('__pycache__'))
        (folder / 'cache').mkdir()
        for path in [folder, *folder.rglob('*')]:
            path.chmod(0o777 if path.is_dir() else 0o644)
        yield folder
    finally:
        for path in [folder, *folder.rglob('*')]:
            if path.is_dir():
                path.chmod(0o777)
        shutil.rmtree(folder)


def _read_only_command(source: Path, command: List[str]) -> List[str]:
    """Make ``source`` read-only for ``command`` (mode bits, or a ro bind mount for root)."""
    for path in [source, *source.rglob('*')]:
        if path.is_dir():
            path.chmod(0o555)
    if os.geteuid() != 0:
        return command
    unshare = shutil.which('unshare')
    if unshare is None:
        pytest.fail('running as root without unshare(1): cannot make a read-only folder')
    return [unshare, '-m', 'sh', '-c', 'mount --bind -o ro "$0" "$0" && exec "$@"',
            str(source), *command]


def _probe(source: Path, cache_home: Path, numba_cache_dir: Optional[Path] = None,
           read_only: bool = False) -> Dict:
    """Run PROBE with ``source`` first on the path; return its report."""
    env = {key: value for key, value in os.environ.items()
           if key not in ('NUMBA_CACHE_DIR', 'PYTHONPATH')}
    env.update(PYTHONPATH=str(source), XDG_CACHE_HOME=str(cache_home), HOME=str(cache_home))
    if numba_cache_dir is not None:
        env['NUMBA_CACHE_DIR'] = str(numba_cache_dir)
    command = [sys.executable, '-c', PROBE]
    if read_only:
        command = _read_only_command(source, command)
    process = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300,
                             cwd=str(cache_home))
    assert process.returncode == 0, process.stderr
    return json.loads(process.stdout.strip().splitlines()[-1])


def test_read_only_package_caches_per_user(copy):
    """Read-only sources: the kernels go to $XDG_CACHE_HOME/cdr_translator/numba, twice."""
    source, cache_home = copy / 'src', copy / 'cache'
    first = _probe(source, cache_home, read_only=True)
    expected = cache_home / 'cdr_translator' / 'numba'
    assert first['location'] == str(expected)
    assert first['compiled'] >= 1
    assert list(expected.rglob('rod.rk4_stage_pose-*.nbi')), 'nothing cached'
    assert not list(source.rglob('__pycache__')), 'wrote into the read-only package'
    second = _probe(source, cache_home, read_only=True)
    assert (second['compiled'], second['uncached']) == (0, False), second
    assert second['loaded'] >= 1


def test_writable_package_caches_in_tree(copy):
    """Writable sources: numba's default, the package's own __pycache__."""
    source, cache_home = copy / 'src', copy / 'cache'
    report = _probe(source, cache_home)
    assert report['location'] == str(source / 'cdr_translator' / '__pycache__')
    assert list((source / 'cdr_translator').rglob('__pycache__/rod.rk4_stage_pose-*.nbi'))
    assert not (cache_home / 'cdr_translator').exists()


def test_numba_cache_dir_wins(copy):
    """NUMBA_CACHE_DIR set by the user is where the kernels go."""
    source, cache_home = copy / 'src', copy / 'cache'
    chosen = copy / 'chosen'
    report = _probe(source, cache_home, numba_cache_dir=chosen)
    assert report['location'] == str(chosen)
    assert list(chosen.rglob('rod.rk4_stage_pose-*.nbi'))


@pytest.mark.parametrize('stamp_text', [None, 'cache=True, nogil=False\n'],
                         ids=['no stamp', 'other options'])
def test_kernels_cached_with_other_options_are_compiled_anew(copy, stamp_text):
    """A folder stamped with other options (or none) is cleared: numba's index ignores them."""
    source, cache_home = copy / 'src', copy / 'cache'
    stamp = source / 'cdr_translator' / 'bvp' / '__pycache__' / OPTIONS_STAMP  # rod's folder
    assert _probe(source, cache_home)['compiled'] >= 1
    assert stamp.read_text() == options_text()
    assert _probe(source, cache_home)['compiled'] == 0  # loaded: same options
    if stamp_text is None:
        stamp.unlink()  # as left by a checkout from before the stamp
    else:
        stamp.write_text(stamp_text)
    again = _probe(source, cache_home)
    assert again['compiled'] >= 1 and again['loaded'] == 0, again
    assert stamp.read_text() == options_text()


def test_a_change_a_kernel_depends_on_clears_the_cache(tmp_path):
    """A module a kernel module imports (bvp/problem.py) changed: new digest; the CLI: same."""
    package = tmp_path / 'cdr_translator'
    shutil.copytree(Path(cdr_translator._jit.__file__).parent, package,
                    ignore=shutil.ignore_patterns('__pycache__'))
    before = kernel_sources_digest(package)
    (package / 'cli.py').write_text((package / 'cli.py').read_text() + '# unrelated\n')
    assert kernel_sources_digest.__wrapped__(package) == before
    imported = package / 'bvp' / 'problem.py'
    assert '@jit' not in imported.read_text()
    imported.write_text(imported.read_text() + '# changed\n')
    assert kernel_sources_digest.__wrapped__(package) != before


def test_make_recompiles_for_every_file_the_digest_covers():
    """
    The Makefile's kernel sources are the digest's files: a changed one recompiles at set-up.

    Listed by ``kernel_sources.py`` run as a script with the system interpreter's standard
    library only (make reads them before the environment exists); a module a kernel module
    imports (solve/solver.py, no kernel of its own) is among them.
    """
    listed = subprocess.run([sys.executable, '-I', 'cdr_translator/kernel_sources.py'],
                            capture_output=True, text=True, cwd=ROOT, timeout=60, check=True)
    files = [ROOT / line for line in listed.stdout.split()]
    assert files == kernel_source_files()
    assert ROOT / 'cdr_translator' / 'solve' / 'solver.py' in files
    assert '@jit' not in (ROOT / 'cdr_translator' / 'solve' / 'solver.py').read_text()
    dry = subprocess.run(['make', '-pn', 'setup'], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    rule = next(line for line in dry.stdout.splitlines()
                if line.startswith('.venv/.kernels-stamp:'))
    assert all(str(path.relative_to(ROOT)) in rule.split() for path in files), rule
