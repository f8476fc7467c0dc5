"""
Scale of the Continuum Delta Robot atlas, and the inverse-statics timing.

Usage: python -m bench.atlas_scale [--grid N] [--chunk-size M] [--picture-grid N]

Measures the atlas throughput (samples/s, including the Zarr writes) in-process without
Dask, on a LocalCluster of 1 and of 2 worker processes, and through ``--scheduler`` with a
``dask scheduler`` and a ``dask worker --nworkers 2`` started as separate processes on
127.0.0.1 (as on a real cluster). Each cluster is warmed up first (every worker imports the
solver and loads the numba kernels), so the rates are of steady work, not of start-up.
Then the inverse statics cold / warm along a 1 mm-step path, and a picture atlas of the
default geometry under 1 kg with its workspace volume. Writes
bench/results/atlas_scale.md and bench/results/atlas_{workspace,stiffness}.png.
"""

import argparse
import json
import os
from pathlib import Path
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from typing import List

from cdr_translator.robot.atlas import plot_atlas, run_atlas
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.samples import AtlasSpec, chunk_bounds, solve_chunk, \
    workspace_volumes
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / 'bench' / 'results'
GRAVITY_1KG = (0.0, 0.0, -9.81)


def _warm(client) -> None:
    """Make every worker import the solver and solve one sample (numba kernels loaded)."""
    spec = AtlasSpec.build(2, [GRAVITY_1KG])
    client.run(solve_chunk, spec, 0, 1)


def _measure(spec: AtlasSpec, chunk_size: int, client, label: str, rows: List[dict]) -> None:
    _warm(client)
    workers = len(client.scheduler_info(n_workers=-1)['workers'])
    with tempfile.TemporaryDirectory() as folder:
        load = os.getloadavg()[0]
        summary = run_atlas(spec, Path(folder) / 'atlas.zarr', chunk_size, client=client,
                            progress=False)
    rows.append({'label': label, 'workers': workers, 'samples': summary['computed_samples'],
                 'seconds': summary['wall_time_s'], 'rate': summary['samples_per_s'],
                 'load': load})
    print(json.dumps(rows[-1]), flush=True)


def _serial(spec: AtlasSpec, chunk_size: int, rows: List[dict]) -> None:
    """In one process: the chunks of the clusters' runs, then all samples as one chunk."""
    solve_chunk(AtlasSpec.build(2, [GRAVITY_1KG]), 0, 1)
    for size, label in ((chunk_size, 'in-process, no Dask, no Zarr'),
                        (spec.size, 'in-process, no Dask, no Zarr, one chunk of all samples')):
        load = os.getloadavg()[0]
        started = time.perf_counter()
        for start, stop in chunk_bounds(spec.size, size):
            solve_chunk(spec, start, stop)
        elapsed = time.perf_counter() - started
        rows.append({'label': label, 'workers': 1, 'samples': spec.size, 'seconds': elapsed,
                     'rate': spec.size / elapsed, 'load': load})
        print(json.dumps(rows[-1]), flush=True)


def _separate_processes(spec: AtlasSpec, chunk_size: int, rows: List[dict]) -> None:
    from distributed import Client
    folder = Path(tempfile.mkdtemp())
    scheduler_file = folder / 'scheduler.json'
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS='1')
    processes = [subprocess.Popen(
        [sys.executable, '-m', 'distributed.cli.dask_scheduler', '--host', '127.0.0.1',
         '--port', '0', '--no-dashboard', '--scheduler-file', str(scheduler_file)],
        env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60.0
        while not scheduler_file.exists() or not scheduler_file.read_text().strip():
            if time.monotonic() > deadline:
                raise RuntimeError('no dask scheduler after 60 s')
            time.sleep(0.1)
        time.sleep(0.2)
        address = json.loads(scheduler_file.read_text())['address']
        processes.append(subprocess.Popen(
            [sys.executable, '-m', 'distributed.cli.dask_worker', address, '--nworkers', '2',
             '--nthreads', '1', '--no-dashboard', '--host', '127.0.0.1'],
            env=env, start_new_session=True, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL))
        with Client(address, timeout='30s') as client:
            client.wait_for_workers(2, timeout=120)
            _measure(spec, chunk_size, client, f'--scheduler {address} (separate `dask '
                                               'scheduler` + `dask worker --nworkers 2`)',
                     rows)
    finally:
        for process in reversed(processes):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
        shutil.rmtree(folder, ignore_errors=True)


def _inverse_timing() -> dict:
    """Median cold and warm (about 1 mm steps along a path) inverse-statics times, 1 kg."""
    robot, forward = DeltaRobot(), DeltaRobot()
    robot.inverse((0.0, 0.0, -0.13), GRAVITY_1KG)  # kernels loaded
    rng = np.random.default_rng(1)
    stroke = robot.geometry.slider_stroke
    cold, warm, warm_solves, errors = [], [], [], []
    for sliders in rng.uniform(-0.6 * stroke, 0.6 * stroke, size=(5, 3)):
        # reachable targets: where sliders on a path put the platform
        direction = rng.normal(size=3)
        direction *= 0.001 / np.linalg.norm(direction)
        path = [forward.solve(sliders + step * direction, GRAVITY_1KG).platform_position
                for step in range(6)]
        robot.reset()
        result = robot.inverse(path[0].tolist(), GRAVITY_1KG)
        cold.append(result.solve_time_s)
        errors.append(result.position_error)
        for target in path[1:]:
            result = robot.inverse(target.tolist(), GRAVITY_1KG)
            warm.append(result.solve_time_s)
            warm_solves.append(result.forward_solves)
            errors.append(result.position_error)
    return {'cold_median_s': statistics.median(cold), 'warm_median_s': statistics.median(warm),
            'warm_forward_solves_median': statistics.median(warm_solves),
            'max_position_error_m': max(errors), 'cold_samples': len(cold),
            'warm_samples': len(warm)}


def _picture(grid: int) -> dict:
    """Compute a picture atlas of the default geometry under 1 kg: PNGs, workspace volume."""
    spec = AtlasSpec.build(grid, [GRAVITY_1KG])
    folder = Path(tempfile.mkdtemp())
    out = folder / 'atlas.zarr'
    try:
        summary = run_atlas(spec, out, grid * grid, workers=2, progress=False)
        from cdr_translator.robot.atlas import load_results
        _, results = load_results(out)
        volume = workspace_volumes(spec, results)[0]
        paths = plot_atlas(out)
        targets = []
        for path, name in zip(paths, ('atlas_workspace.png', 'atlas_stiffness.png')):
            shutil.copy(path, RESULTS / name)
            targets.append(f'bench/results/{name}')
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return {'grid': grid, 'volume': volume, 'pictures': targets, 'summary': summary,
            'converged': int(results['converged'].sum()),
            'stable': int(results['stable'].sum()),
            'max_parasitic_deg': float(np.degrees(np.nanmax(results['parasitic_rotation'])))}


def main() -> None:
    """Run every measurement and write bench/results/atlas_scale.md."""
    parser = argparse.ArgumentParser(description='Atlas scale and inverse-statics timing.')
    parser.add_argument('--grid', type=int, default=6, help='throughput grid (N^3 samples)')
    parser.add_argument('--chunk-size', type=int, default=12)
    parser.add_argument('--picture-grid', type=int, default=8)
    args = parser.parse_args()
    from distributed import Client, LocalCluster
    spec = AtlasSpec.build(args.grid, [GRAVITY_1KG])
    rows: List[dict] = []
    _serial(spec, args.chunk_size, rows)
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            _measure(spec, args.chunk_size, client, f'LocalCluster, {workers} worker '
                     f'process{"es" if workers > 1 else ""}', rows)
    _separate_processes(spec, args.chunk_size, rows)
    inverse = _inverse_timing()
    print(json.dumps(inverse), flush=True)
    picture = _picture(args.picture_grid)
    print(json.dumps(picture, default=str), flush=True)
    one = next(row for row in rows if row['label'].startswith('LocalCluster, 1'))
    two = next(row for row in rows if row['label'].startswith('LocalCluster, 2'))
    efficiency = two['rate'] / (2.0 * one['rate'])
    core_hours = 1e6 / one['rate'] / 3600.0
    volume = picture['volume']
    lines = [
        '# Continuum Delta Robot atlas: scale and inverse-statics timing',
        '',
        f'Generated by `python -m bench.atlas_scale --grid {args.grid} --chunk-size '
        f'{args.chunk_size} --picture-grid {args.picture_grid}` on '
        f'{time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, {platform.machine()}, '
        f'{os.cpu_count()} cores, Python {platform.python_version()}.',
        '',
        f'**The machine has {os.cpu_count()} cores shared by several agents working at the '
        'same time** (the 1-minute load average when each run started is in the table; '
        'above the core count the workers were competing for CPU): the figures are lower '
        'bounds, and the parallel efficiency in particular is that of a busy machine.',
        '',
        f'## Atlas throughput ({spec.size} samples = {args.grid}^3 slider grid x 1 payload '
        f'(1 kg), chunks of {args.chunk_size}; every sample a forward solve plus its '
        'platform compliance; Zarr writes included except in the in-process rows)',
        '',
        'Each chunk starts cold (from home), its samples then warm from each other: '
        'the fewer the chunks, the fewer the cold solves. bench/results/robot_levels.md '
        'times one chunk of 4^3 samples in one process, no Dask, no Zarr (the solver, to '
        'compare the leg levels), so its full-leg rate is higher than these (the `atlas` '
        "command's path, to size a sweep with).",
        '',
        '| executor | workers | samples | wall time (s) | samples/s | load avg at start |',
        '| --- | ---: | ---: | ---: | ---: | ---: |',
    ]
    lines += [f"| {row['label']} | {row['workers']} | {row['samples']} | "
              f"{row['seconds']:.1f} | {row['rate']:.2f} | {row['load']:.1f} |" for row in rows]
    lines += [
        '',
        f'Parallel efficiency, 2 vs 1 LocalCluster worker processes: {efficiency:.0%} '
        f'({two["rate"]:.2f} vs 2 x {one["rate"]:.2f} samples/s).',
        '',
        f'Cost of a 10^6-sample atlas at the 1-worker rate: 10^6 / {one["rate"]:.2f} '
        f'samples/s = {core_hours:.0f} core-hours (one worker process is one core).',
        '',
        '## Inverse statics (1 kg payload, default geometry)',
        '',
        f'Cold (robot reset, from the sliders at home; {inverse["cold_samples"]} random '
        f'targets): median {1e3 * inverse["cold_median_s"]:.0f} ms. Warm (1 mm steps along '
        f'a path, {inverse["warm_samples"]} steps): median '
        f'{1e3 * inverse["warm_median_s"]:.0f} ms, median '
        f'{inverse["warm_forward_solves_median"]:g} forward solves (the compliance of an '
        'answer, made on first read, not timed); largest distance to the target '
        f'{inverse["max_position_error_m"]:.1e} m.',
        '',
        '## Workspace of the default geometry (config/translator.yaml, 1 kg payload)',
        '',
        f'{args.picture_grid}^3 slider grid over +-{1e3 * spec.strokes[0]:g} mm: '
        f'{picture["converged"]} converged, {picture["stable"]} stable; largest parasitic '
        f'rotation {picture["max_parasitic_deg"]:.2f} deg.',
        '',
        f'* convex hull of the platform positions of converged, stable samples '
        f'(scipy ConvexHull): **{1e6 * volume["convex_hull_m3"]:.1f} cm^3** '
        f'({1e9 * volume["convex_hull_m3"]:.3g} mm^3);',
        f'* image volume of the slider box, the integral of |det dp/dq| over it (trapezoidal '
        f'rule on the grid; no convexity assumed): **{1e6 * volume["jacobian_m3"]:.1f} cm^3**.',
        '',
        'The hull over-estimates a workspace whose boundary bulges inwards; the integral '
        'carries the quadrature error of the grid (both converge as the grid is refined).',
        '',
        f'Pictures: {", ".join(picture["pictures"])}.',
        '',
    ]
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / 'atlas_scale.md').write_text('\n'.join(lines))
    print((RESULTS / 'atlas_scale.md').read_text())


if __name__ == '__main__':
    main()
