"""
Compilation switch for the numerical kernels (rod.py, shooting.py, tangent.py, fidelity/).

The kernels are written once. Normally they are compiled with numba; the paper's
baseline method runs the very same source interpreted (``interpreted_kernels``), so
the baseline differs from the fast path in implementation speed only, never in model.

Compiled kernels are cached on disk by numba (``cache=True``): compiling them all takes
about a minute, loading them from the cache well under a second. The cache goes where
numba puts it (``__pycache__`` beside the sources) while that is writable; an installed,
read-only package uses a per-user folder instead, ``$XDG_CACHE_HOME/cdr_translator/numba``
(``~/.cache/...``). ``NUMBA_CACHE_DIR`` set by the user always wins. ``make setup`` fills
the cache (``python -m cdr_translator compile``), so the first node start does not compile.
Kernels cached with other numba options (``JIT_OPTIONS``) or from other kernel sources (any
kernel module or a module it imports changed) are deleted and compiled anew.
"""

import functools
import importlib
import os
from pathlib import Path
import sys
import tempfile
import time
from types import ModuleType
from typing import Any, Callable, Dict, List, NamedTuple, Set

import numba

from .kernel_sources import PACKAGE_DIR, sources_digest

_interpreting = False
#: The modules of the translator's residual and Jacobian (Problem's kernels) and of the
#: kernels they call, which the paper's method runs interpreted (interpreted_kernels).
_KERNEL_MODULES = ('cdr_translator.bvp.rod', 'cdr_translator.bvp.layout',
                   'cdr_translator.bvp.multiple_shooting_kernels', 'cdr_translator.bvp.shooting',
                   'cdr_translator.bvp.tangent')
_interpreted_cache: Dict[str, ModuleType] = {}

#: numba's run-time configuration (CACHE_DIR is read when a cached kernel is defined).
_NUMBA_CONFIG: Any = numba.config

#: Every compiled kernel (numba dispatcher) created by ``jit``, in definition order.
KERNELS: List[Any] = []

#: What compiling every kernel costs on an idle 2-core machine (s; 147 s measured in a fresh
#: clone's `make setup` with the lifted-Newton and CDR kernels, 155 s under load); a busy one
#: takes longer. Said in the log when a node has to compile.
COMPILE_ESTIMATE_S = 150.0


def user_cache_dir() -> Path:
    """Return the per-user kernel cache folder: $XDG_CACHE_HOME (~/.cache)/cdr_translator/numba."""
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'cdr_translator' / 'numba'


def _writable(folder: Path) -> bool:
    """Say whether files can be created in ``folder`` (or in its parent, if it is missing)."""
    try:  # as numba's own locators check: root may write where the mode bits say no
        tempfile.TemporaryFile(dir=folder if folder.is_dir() else folder.parent).close()
    except OSError:
        return False
    return True


def configure_cache(package_dir: Path = Path(__file__).resolve().parent) -> str:
    """
    Point numba's cache at a writable place before any kernel is defined; return where.

    ``NUMBA_CACHE_DIR`` (numba.config.CACHE_DIR) set: kept. Else the package's own
    ``__pycache__`` folders when they are writable (numba's default), else the per-user
    folder of ``user_cache_dir`` (numba.config.CACHE_DIR is set to it for this process).
    """
    if _NUMBA_CONFIG.CACHE_DIR:
        return str(_NUMBA_CONFIG.CACHE_DIR)
    folders = [package_dir] + [path.parent for path in package_dir.glob('*/__init__.py')]
    if all(_writable(folder / '__pycache__') for folder in folders):
        return str(package_dir / '__pycache__')
    _NUMBA_CONFIG.CACHE_DIR = str(user_cache_dir())
    return str(_NUMBA_CONFIG.CACHE_DIR)


#: Where the compiled kernels are cached (see configure_cache).
CACHE_LOCATION = configure_cache()


#: LLVM fast-math flags of the kernels: fused multiply-adds, reassociation, reciprocals and
#: signless zeros (about 20 % off a residual shot, rounding-level changes). Not 'nnan' or
#: 'ninf': the solver relies on non-finite values propagating to its isfinite checks.
FASTMATH = frozenset({'contract', 'reassoc', 'arcp', 'nsz'})

#: numba's options for every kernel. ``nogil`` stays False: releasing the GIL in every kernel
#: let translator_node's callback run during a solve but cost the solver the GIL back after
#: each kernel; at 1-2 kHz it answered 30-50 % fewer wrenches (bench/results/node_rate.md).
#: The one exception is ``jit_releasing_gil``: a single call per solve (warm_fast_path.py).
JIT_OPTIONS: Dict[str, Any] = {'cache': True, 'error_model': 'numpy', 'fastmath': FASTMATH,
                               'nogil': False}

#: numba's cache index keys on the kernel's own source file and the signature, not on the
#: options or on the other files it calls into: each cache folder records the options and the
#: kernel sources' digest its kernels were compiled with in this file (see jit).
OPTIONS_STAMP = 'cdr_translator_jit_options.txt'

_stamped_folders: Set[Path] = set()


@functools.lru_cache(maxsize=None)
def kernel_sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """
    Return a SHA-256 of every kernel module's source and of the modules it imports.

    numba checks a cached kernel against its own file only, so a kernel whose callee or
    constant lives in another, changed file would load stale machine code; the digest
    (kernel_sources.sources_digest, once per process) goes into OPTIONS_STAMP, and a
    changed one clears the cache.
    """
    return sources_digest(package_dir)


def options_text() -> str:
    """Return what OPTIONS_STAMP holds: JIT_OPTIONS (sorted) and the kernel sources' digest."""
    options = ', '.join(f'{name}={sorted(value) if isinstance(value, frozenset) else value!r}'
                        for name, value in sorted(JIT_OPTIONS.items()))
    return f'{options}\nsources={kernel_sources_digest()}\n'


def _clear_if_compiled_otherwise(folder: Path) -> None:
    """
    Delete the cached kernels in ``folder`` unless its stamp matches ``options_text``.

    The stamp holds JIT_OPTIONS and today's kernel sources' digest.

    Done once per folder and process, when its first kernel is defined (before any of its
    kernels is loaded); then the stamp is written. A folder without a stamp holds kernels of
    an older checkout, whose options are unknown. Write errors are ignored: numba does not
    cache into a read-only folder either (configure_cache avoids them).
    """
    if folder in _stamped_folders:
        return
    _stamped_folders.add(folder)
    stamp = folder / OPTIONS_STAMP
    try:
        if stamp.read_text() == options_text():
            return
    except OSError:
        pass
    try:
        for path in sorted(folder.glob('*.nbi')) + sorted(folder.glob('*.nbc')):
            path.unlink()
        folder.mkdir(parents=True, exist_ok=True)
        stamp.write_text(options_text())
    except OSError:
        pass


def jit(func: Callable) -> Callable:
    """Compile ``func`` with numba (cached on disk), or leave it as Python while copying."""
    return _compiled(func, {})


def jit_releasing_gil(func: Callable) -> Callable:
    """
    ``jit`` for a kernel that does a whole solve's work in one call: it runs without the GIL.

    Other threads (a node's subscription callback, its executor) then run beside it instead
    of waiting for the switch interval. Every kernel releasing it cost more than it gave
    (JIT_OPTIONS): the solver took the GIL back after each short call.
    """
    return _compiled(func, {'nogil': True})


def _compiled(func: Callable, overrides: Dict[str, Any]) -> Callable:
    """Compile ``func`` with JIT_OPTIONS and ``overrides``; register it in KERNELS."""
    if _interpreting:
        return func
    kernel = numba.njit(**{**_numba_options(), **overrides})(func)
    if kernel.stats.cache_path:
        _clear_if_compiled_otherwise(Path(kernel.stats.cache_path))
    KERNELS.append(kernel)
    return kernel


def jit_inline(func: Callable) -> Callable:
    """
    ``jit`` for a helper called in a hot loop: numba inlines it into every caller.

    A call of a compiled function costs an atomic reference-count update for every array
    it is handed, a few ns each (more than the helper's own work when the arrays are
    small); inlined, the compiler removes them. Such a helper is never compiled on its
    own, so it is not in KERNELS (it would count as uncached forever).
    """
    if _interpreting:
        return func
    return numba.njit(**_numba_options(), inline='always')(func)


def _numba_options() -> Dict[str, Any]:
    """Return JIT_OPTIONS as numba.njit takes them (sets, not frozensets)."""
    return {name: set(value) if isinstance(value, frozenset) else value
            for name, value in JIT_OPTIONS.items()}


def _index_files(kernel: Any) -> List[Path]:
    """Return the cache index files numba keeps for ``kernel`` (empty: never cached)."""
    func = kernel.py_func
    stem = Path(func.__code__.co_filename).stem
    pattern = f'{stem}.{func.__qualname__}-{func.__code__.co_firstlineno}.py*.nbi'
    return sorted(Path(kernel.stats.cache_path).glob(pattern))


def uncached_kernels() -> List[str]:
    """
    Name the defined kernels that have no entry in numba's cache (so would compile).

    A kernel with an entry can still compile, when its source changed since; what really
    happened is in ``kernel_counts``.
    """
    return [f'{kernel.py_func.__module__}.{kernel.py_func.__qualname__}'
            for kernel in KERNELS if not _index_files(kernel)]


class KernelCounts(NamedTuple):
    """Signatures compiled and signatures loaded from the cache, over all kernels."""

    compiled: int
    loaded: int


def kernel_counts() -> KernelCounts:
    """Count the kernel signatures this process compiled and loaded from the cache so far."""
    compiled = sum(sum(kernel.stats.cache_misses.values()) for kernel in KERNELS)
    loaded = sum(sum(kernel.stats.cache_hits.values()) for kernel in KERNELS)
    return KernelCounts(compiled, loaded)


def timed_warm_up(warm_up: Callable[[], object], say: Callable[[str], object]) -> float:
    """
    Run ``warm_up`` (which calls the kernels), telling ``say`` when it compiles; return s.

    Before: whether the kernels are in the cache, and if not, that compiling takes about
    COMPILE_ESTIMATE_S. After: how long it took and how many signatures were compiled.
    """
    missing = uncached_kernels()
    if missing:
        say(f'compiling {len(missing)} of {len(KERNELS)} numba kernels (not in the cache at '
            f'{CACHE_LOCATION}): about {COMPILE_ESTIMATE_S:.0f} s on an idle 2-core machine, '
            f'once; `make setup` or `python -m cdr_translator compile` does it ahead')
    before = kernel_counts()
    started = time.perf_counter()
    warm_up()
    elapsed = time.perf_counter() - started
    after = kernel_counts()
    compiled, loaded = after.compiled - before.compiled, after.loaded - before.loaded
    if compiled or missing:
        say(f'kernels ready in {elapsed:.1f} s: {compiled} signatures compiled, {loaded} '
            f'loaded from the cache at {CACHE_LOCATION}')
    return elapsed


def interpreted_kernels() -> Dict[str, ModuleType]:
    """
    Return fresh, uncompiled copies of the kernel modules, keyed by short name.

    The copies are imported with the switch off and then taken out of ``sys.modules``
    again, so the compiled modules that the rest of the package uses stay untouched.
    """
    global _interpreting
    if _interpreted_cache:
        return _interpreted_cache
    originals = {name: sys.modules.pop(name, None) for name in _KERNEL_MODULES}
    _interpreting = True
    try:
        for name in _KERNEL_MODULES:
            _interpreted_cache[name.rsplit('.', 1)[1]] = importlib.import_module(name)
    finally:
        _interpreting = False
        package = sys.modules['cdr_translator']
        for name, module in originals.items():
            short = name.rsplit('.', 1)[1]
            if module is None:
                sys.modules.pop(name, None)
                package.__dict__.pop(short, None)
            else:
                sys.modules[name] = module
                setattr(package, short, module)
    return _interpreted_cache
