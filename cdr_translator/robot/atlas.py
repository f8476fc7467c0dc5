"""
Workspace / stiffness atlas of the Continuum Delta Robot on Dask, stored in Zarr.

    python -m cdr_translator atlas --grid N [--payload FX FY FZ]... [--params FILE]...
                                   --out PATH.zarr [--workers K] [--scheduler ADDRESS]
                                   [--chunk-size M] [--plot]

The samples (cdr_translator.robot.samples: slider grid x payloads x params files) are cut
into chunks of consecutive, neighbouring samples; each chunk is one Dask task,
``samples.solve_chunk``, warm-started within the chunk. By default the tasks run on an
in-process ``LocalCluster`` with one single-threaded worker process per core;
``--scheduler ADDRESS`` submits them to a running Dask cluster instead (the same code on
many machines: the workers need this package importable, and nothing else).

Results come back to this process, which writes each chunk into its own region of an
xarray Dataset in a Zarr store (dimension ``sample``; zarr chunks = atlas chunks, so region
writes never share a zarr chunk), then marks it in ``chunk_done``. A run that is
interrupted and started again with the same arguments opens the store, checks that it
describes the same sweep, and computes only the chunks not marked done. At most two chunks
per worker are in flight, so memory stays bounded on the workers, the scheduler and here,
whatever the size of the atlas. Only this module (and the ``atlas`` command) imports
Dask, xarray and zarr.
"""

import argparse
from contextlib import contextmanager
import json
import logging
import math
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Dict, Iterator, List, Optional, Tuple

import numpy as np

from .samples import (AtlasSpec, chunk_bounds, LEG_LEVELS, RESULT_VARIABLES, solve_chunk,
                      workspace_volumes)
from ..console import deferred_sigint, json_text, unwritable_reason
from ..params.translator_params import DEFAULT_PARAMS_PATH, ParameterError

#: Exit codes of the atlas command (as the other commands').
EXIT_CONVERGED, EXIT_BAD_INPUT, EXIT_NOT_CONVERGED = 0, 2, 3

#: Chunks in flight per worker.
IN_FLIGHT_PER_WORKER = 2

#: How long to wait for a running cluster to offer a worker (s).
WORKER_WAIT_S = 120.0

#: Zarr format of new stores: 2, whose fixed-length string type (the messages) is specified.
ZARR_FORMAT = 2

#: Trailing dimension names of the result variables, by trailing shape.
_DIMS = {(): (), (3,): ('axis',), (3, 2): ('leg', 'joint'), (3, 3): ('axis', 'slider')}


def _result_dims(name: str) -> Tuple[str, ...]:
    shape = RESULT_VARIABLES[name][0]
    if name == 'leg_axial_force' or name.startswith('leg_error_bound') \
            or name == 'leg_fidelity':
        return ('sample', 'leg')
    if name.startswith('compliance_eigenvalues'):
        return ('sample', 'eigen')
    return ('sample',) + _DIMS[shape]


def _template(spec: AtlasSpec, chunk_size: int):
    """Build the Dataset the store starts from: inputs written, results lazy (not computed)."""
    import dask.array as da
    import xarray as xr
    inputs = spec.inputs()
    size = spec.size
    bounds = chunk_bounds(size, chunk_size)
    data = {
        'sliders': (('sample', 'slider'), inputs['sliders'],
                    {'units': 'm', 'description': 'slider positions from home'}),
        'payload': (('sample', 'axis'), inputs['payload'],
                    {'units': 'N', 'description': 'force on the platform origin, {w}'}),
        'variant': (('sample',), inputs['variant'].astype('int32'),
                    {'description': 'index into the params_files attribute'}),
        'grid_index': (('sample', 'slider'), inputs['grid_index'].astype('int32'),
                       {'description': 'slider grid indices of the sample'}),
    }
    variables = {name: xr.Variable(dims, values, attrs)
                 for name, (dims, values, attrs) in data.items()}
    for name, (shape, dtype, units, description) in RESULT_VARIABLES.items():
        lazy = da.zeros((size,) + shape, dtype=dtype, chunks=(chunk_size,) + shape)
        attrs = {'description': description}
        if units:
            attrs['units'] = units
        variables[name] = xr.Variable(_result_dims(name), lazy, attrs)
    variables['chunk_done'] = xr.Variable(
        ('chunk',), da.zeros(len(bounds), dtype=bool, chunks=1),
        {'description': 'the chunk is solved and written'})
    dataset = xr.Dataset(variables)
    dataset.attrs.update({'atlas_spec': json.dumps(spec.to_attrs()),
                          'chunk_size': chunk_size, 'leg_levels': list(LEG_LEVELS),
                          'frames': 'world frame {w}: z up the robot axis, platform below',
                          'description': 'Continuum Delta Robot atlas (cdr_translator)'})
    return dataset


def open_or_create(path: Path, spec: AtlasSpec, chunk_size: int) -> np.ndarray:
    """
    Return ``chunk_done`` of the store at ``path``, creating the store if it is not there.

    A store made for another sweep or chunk size is ValueError naming the path.
    """
    import xarray as xr
    if path.exists():
        try:
            existing = xr.open_zarr(path, consolidated=False)
        except (OSError, ValueError, KeyError) as error:
            raise ValueError(f'{path} exists but is not an atlas store ({error}); '
                             'choose another --out') from error
        if (existing.attrs.get('atlas_spec') != json.dumps(spec.to_attrs())
                or existing.attrs.get('chunk_size') != chunk_size):
            raise ValueError(f'{path} holds an atlas of another sweep or chunk size; choose '
                             'another --out or repeat its arguments to resume it')
        return existing['chunk_done'].values.astype(bool)
    encoding = {'message': {'chunks': (chunk_size,)}}
    _template(spec, chunk_size).to_zarr(path, mode='w-', compute=False, consolidated=False,
                                        zarr_format=ZARR_FORMAT,
                                        encoding=encoding)
    return np.zeros(len(chunk_bounds(spec.size, chunk_size)), dtype=bool)


def write_chunk(path: Path, index: int, start: int, stop: int,
                results: Dict[str, np.ndarray]) -> None:
    """Write one chunk's results into its region, then mark the chunk done."""
    import xarray as xr
    variables = {name: (_result_dims(name), values) for name, values in results.items()}
    xr.Dataset(variables).to_zarr(path, region={'sample': slice(start, stop)},
                                  consolidated=False)
    xr.Dataset({'chunk_done': (('chunk',), np.ones(1, dtype=bool))}).to_zarr(
        path, region={'chunk': slice(index, index + 1)}, consolidated=False)


@contextmanager
def _sigint_blocked() -> Iterator[None]:
    """
    Block SIGINT in this thread for the block: the worker processes started in it keep it so.

    A Ctrl-C reaches the whole process group: workers that took it would each print a
    traceback, and one dying mid-task would be restarted by its nanny. The signal mask is
    inherited through fork and exec by every process and thread started meanwhile, so the
    workers never see SIGINT; this process takes the one that waited here when the block
    ends, and tears them down (``run_atlas``).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def dask_setup(worker: object) -> None:
    """
    Start-up of each local worker (Dask's preload hook): Ctrl-C is ignored for good.

    The SIGINT mask the worker inherits (``_sigint_blocked``) keeps Ctrl-C out while it
    starts, but does not last (the started worker's main thread was seen with SIGINT
    unblocked), and asyncio's runner would turn one into a KeyboardInterrupt traceback.
    Ignoring it is process-wide and lasting; the preload runs in the worker's main thread,
    where handlers may be set.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def dask_client(workers: Optional[int], scheduler: Optional[str]):
    """Return a Dask client of the running cluster at ``scheduler`` or of a new LocalCluster."""
    from distributed import Client, LocalCluster
    if scheduler is not None:
        client = Client(scheduler, timeout='30s')
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        return client, None
    count = workers if workers is not None else (os.cpu_count() or 1)
    if count < 1:
        raise ValueError(f'workers must be at least 1, got {count}')
    cluster = None
    try:
        with _sigint_blocked():
            # its WARNINGs (a task cancelled, a busy worker killed at close after Ctrl-C) are
            # the cluster's business, not the command's: only its errors are printed
            cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                   dashboard_address=None, memory_limit='2GiB',
                                   silence_logs=logging.ERROR, preload=[__name__])
        return Client(cluster), cluster
    except KeyboardInterrupt:  # the Ctrl-C that waited for the cluster: tear it down
        if cluster is not None:
            cluster.close()
        raise


def run_atlas(spec: AtlasSpec, out: Path, chunk_size: Optional[int] = None,
              workers: Optional[int] = None, scheduler: Optional[str] = None,
              progress: bool = True, client=None) -> dict:
    """
    Compute the missing chunks of the atlas ``spec`` into the Zarr store ``out``.

    The chunks run on ``client`` (a distributed.Client, left open) if given, else on the
    cluster at ``scheduler``, else on a new LocalCluster of ``workers`` processes. Return a
    summary: chunks total / already done / computed, samples computed, wall time (including
    starting a cluster), samples per second, and the number of workers used.
    """
    chunk_size = chunk_size if chunk_size is not None else spec.grid ** 2
    bounds = chunk_bounds(spec.size, chunk_size)
    done = open_or_create(out, spec, chunk_size)
    missing = [index for index, finished in enumerate(done) if not finished]
    summary = {'chunks': len(bounds), 'already_done': len(bounds) - len(missing),
               'computed_chunks': 0, 'computed_samples': 0, 'wall_time_s': 0.0,
               'samples_per_s': math.nan, 'workers': 0}
    if not missing:
        return summary
    from distributed import as_completed
    from tqdm import tqdm
    started = time.perf_counter()
    owned = client is None
    cluster = None
    if owned:
        client, cluster = dask_client(workers, scheduler)
    try:
        count = max(1, len(client.scheduler_info(n_workers=-1)['workers']))
        summary['workers'] = count
        pending = iter(missing)
        window = as_completed()
        index_of = {}

        def submit() -> None:
            index = next(pending, None)
            if index is not None:
                start, stop = bounds[index]
                future = client.submit(solve_chunk, spec, start, stop, pure=False,
                                       key=f'atlas-chunk-{index}-{time.time_ns()}')
                index_of[future.key] = index
                window.add(future)

        for _ in range(IN_FLIGHT_PER_WORKER * count):
            submit()
        bar = tqdm(total=sum(bounds[i][1] - bounds[i][0] for i in missing), unit='sample',
                   disable=not progress, file=sys.stderr, desc='atlas')
        for future in window:
            index = index_of.pop(future.key)
            results = future.result()
            future.release()
            start, stop = bounds[index]
            # a Ctrl-C inside the write would abandon Zarr's asynchronous tasks halfway
            # (their complaints printed at exit): the chunk is written, then it is honoured
            with deferred_sigint() as interrupt:
                write_chunk(out, index, start, stop, results)
            if interrupt.requested:
                raise KeyboardInterrupt
            summary['computed_chunks'] += 1
            summary['computed_samples'] += stop - start
            bar.update(stop - start)
            submit()
        bar.close()
    finally:
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()
    elapsed = time.perf_counter() - started
    summary['wall_time_s'] = elapsed
    summary['samples_per_s'] = summary['computed_samples'] / elapsed
    return summary


def load_results(out: Path) -> Tuple[AtlasSpec, Dict[str, np.ndarray]]:
    """Read an atlas store back: its spec and every variable as a numpy array."""
    import xarray as xr
    dataset = xr.open_zarr(out, consolidated=False)
    attrs = json.loads(dataset.attrs['atlas_spec'])
    spec = AtlasSpec(attrs['grid'], tuple(tuple(p) for p in attrs['payloads']),
                     tuple(attrs['params_files']), tuple(attrs['strokes']),
                     attrs['time_limit_s'], attrs.get('fidelity', 'full'),
                     attrs.get('max_position_error', 0.0), attrs.get('max_angle_error', 0.0))
    return spec, {name: dataset[name].values for name in dataset.data_vars}


def plot_atlas(out: Path) -> List[Path]:
    """
    Draw the atlas next to the store: PATH_workspace.png and PATH_stiffness.png.

    Workspace: platform positions of the first (variant, payload) block coloured by the
    stability verdict and by the parasitic rotation, with the workspace volume in the
    title. Stiffness: the smallest translational stiffness (1 / largest translational
    compliance eigenvalue) and the stiffness margin in x-z and x-y projections.
    """
    # matplotlib takes most of a second to import: only ``atlas --plot`` pays for it
    from .atlas_figures import atlas_block, save_atlas_figures
    spec, results = load_results(out)
    block = atlas_block(spec, results, workspace_volumes(spec, results)[0])
    return save_atlas_figures(block, out.with_suffix(''))


def run_cli(args: argparse.Namespace) -> int:
    """Run the ``atlas`` command, print a JSON summary (and plot); return the exit code."""
    try:
        spec = AtlasSpec.build(args.grid, args.payload or [(0.0, 0.0, 0.0)],
                               args.params or [str(DEFAULT_PARAMS_PATH)], args.time_limit,
                               args.fidelity, args.max_position_error, args.max_angle_error)
        if args.chunk_size is not None and args.chunk_size < 1:
            raise ValueError(f'--chunk-size must be at least 1, got {args.chunk_size}')
        out = Path(args.out)
        reason = unwritable_reason(out, folder_ok=True)
        if reason is not None:
            raise ValueError(f'cannot write the atlas store {out}: {reason}')
        summary = run_atlas(spec, out, args.chunk_size, args.workers, args.scheduler,
                            progress=not args.no_progress)
    except (ParameterError, ValueError) as error:
        print(f'error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except (OSError, TimeoutError) as error:  # no scheduler there, or no worker in time
        print(f'error: Dask cluster {args.scheduler or "(local)"}: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    spec, results = load_results(out)
    summary['samples'] = spec.size
    summary['converged'] = int(results['converged'].sum())
    summary['stable'] = int(results['stable'].sum())
    summary['workspace_volumes'] = workspace_volumes(spec, results)
    if args.plot:
        summary['plots'] = [str(path) for path in plot_atlas(out)]
    print(json_text(summary))
    return EXIT_CONVERGED if summary['converged'] == spec.size else EXIT_NOT_CONVERGED
