"""The atlas: equal to direct solves, resumable after a kill, and on a separate Dask cluster."""

from contextlib import contextmanager
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Iterator
import warnings

from cdr_translator.cli import main as cli_main
from cdr_translator.robot.atlas import (load_results, open_or_create, plot_atlas, run_atlas,
                                        write_chunk)
from cdr_translator.robot.atlas_figures import atlas_block, stiffness_figure, workspace_figure
from cdr_translator.robot.delta import DeltaRobot
from cdr_translator.robot.samples import AtlasSpec, serpentine, solve_chunk, workspace_volumes
from figure_checks import assert_readable
from interrupting import interrupt
import numpy as np
import pytest
import zarr

ROOT = Path(__file__).resolve().parents[2]
GRAVITY_1KG = (0.0, 0.0, -9.81)


def main(argv) -> int:
    """Run ``python -m cdr_translator atlas ARGV`` in this process; return the exit code."""
    return cli_main(['atlas', *argv])


def _environment() -> dict:
    """Environment for subprocesses: this checkout's code wins, one BLAS thread."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')]).rstrip(
        os.pathsep)
    env['OMP_NUM_THREADS'] = '1'
    return env


def _stop(process: subprocess.Popen) -> None:
    """Kill a subprocess started in its own session, with everything it started."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGKILL)
    process.wait(timeout=30)


def test_serpentine_steps_are_neighbours():
    """Consecutive grid points differ by one step of one slider; every point once."""
    order = serpentine(4)
    assert len({tuple(point) for point in order}) == 64
    assert np.all(np.abs(np.diff(order, axis=0)).sum(axis=1) == 1)


def test_atlas_equals_direct_solves(tmp_path):
    """A 3x3x3 slider atlas under 1 kg equals cold DeltaRobot solves sample by sample."""
    spec = AtlasSpec.build(3, [GRAVITY_1KG])
    out = tmp_path / 'atlas.zarr'
    summary = run_atlas(spec, out, chunk_size=9, workers=1, progress=False)
    assert summary['computed_chunks'] == 3 and summary['computed_samples'] == 27
    _, results = load_results(out)
    assert results['sliders'].shape == (27, 3) and results['payload'].shape == (27, 3)
    assert np.all(results['chunk_done'])
    assert np.all(results['converged']) and np.all(results['stable'])
    robot = DeltaRobot()
    for sample in range(27):
        sliders = results['sliders'][sample]
        assert np.allclose(results['payload'][sample], GRAVITY_1KG)
        direct = robot.solve(sliders, GRAVITY_1KG, warm_start=False, compliance=True)
        assert direct.converged
        assert np.allclose(results['platform_position'][sample], direct.platform_position,
                           atol=1e-9)
        assert results['parasitic_rotation'][sample] == pytest.approx(
            direct.platform_rotation_angle, abs=1e-8)
        assert np.allclose(results['leg_bending'][sample], direct.leg_bending, atol=1e-8)
        assert np.allclose(results['leg_axial_force'][sample], direct.leg_axial_forces,
                           rtol=1e-6, atol=1e-7)
        translation, rotation = direct.compliance_eigenvalues
        assert np.allclose(results['compliance_eigenvalues_translation'][sample], translation,
                           rtol=1e-5)
        assert np.allclose(results['compliance_eigenvalues_rotation'][sample], rotation,
                           rtol=1e-5)
        assert bool(results['stable'][sample]) is direct.stable
    # the grid covers the whole stroke
    stroke = spec.strokes[0]
    assert set(np.round(results['sliders'].ravel() / stroke, 12)) == {-1.0, 0.0, 1.0}


def _done_chunks(out: Path) -> int:
    try:
        return int(np.sum(zarr.open_group(str(out), mode='r')['chunk_done'][:]))
    except (KeyError, FileNotFoundError, ValueError):
        return 0


def test_killed_atlas_resumes_missing_chunks_only(tmp_path, capsys):
    """Kill a run after two of nine chunks; the restart computes exactly the rest."""
    out = tmp_path / 'atlas.zarr'
    arguments = ['--grid', '3', '--payload', *map(str, GRAVITY_1KG), '--chunk-size', '3',
                 '--out', str(out)]
    process = subprocess.Popen(
        [sys.executable, '-m', 'cdr_translator', 'atlas', *arguments, '--workers', '1',
         '--no-progress'], env=_environment(), start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 240.0
        while _done_chunks(out) < 2 and process.poll() is None:
            assert time.monotonic() < deadline, 'the atlas wrote no two chunks in 240 s'
            time.sleep(0.01)   # a chunk takes about 0.1 s here: kill well before the ninth
    finally:
        _stop(process)
    done = _done_chunks(out)
    assert 2 <= done < 9, f'{done} chunks done when killed'
    assert main([*arguments, '--workers', '1', '--no-progress']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['chunks'] == 9
    assert summary['already_done'] == done
    assert summary['computed_chunks'] == 9 - done
    assert summary['converged'] == summary['samples'] == 27
    # a third run finds nothing to do
    assert main([*arguments, '--workers', '1', '--no-progress']) == 0
    assert json.loads(capsys.readouterr().out)['computed_chunks'] == 0
    # another sweep into the same store is refused, naming it
    assert main(['--grid', '2', '--out', str(out), '--no-progress']) == 2
    assert str(out) in capsys.readouterr().err


def _parsed(path: Path):
    """Return the JSON document at ``path``, or None while it is missing or incomplete."""
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


@contextmanager
def _separate_cluster(tmp_path: Path) -> Iterator[str]:
    """`dask scheduler` and one `dask worker` as processes on 127.0.0.1; yield the address."""
    scheduler_file = tmp_path / 'scheduler.json'
    environment = _environment()
    processes = []
    try:
        processes.append(subprocess.Popen(
            [sys.executable, '-m', 'distributed.cli.dask_scheduler', '--host', '127.0.0.1',
             '--port', '0', '--no-dashboard', '--scheduler-file', str(scheduler_file)],
            env=environment, start_new_session=True, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL))
        deadline = time.monotonic() + 60.0
        while (scheduler := _parsed(scheduler_file)) is None:   # complete once it parses
            assert time.monotonic() < deadline, 'no complete scheduler file in 60 s'
            assert processes[0].poll() is None, 'the scheduler exited'
            time.sleep(0.1)
        address = scheduler['address']
        assert address.startswith('tcp://127.0.0.1:')
        processes.append(subprocess.Popen(
            [sys.executable, '-m', 'distributed.cli.dask_worker', address, '--nworkers', '1',
             '--nthreads', '1', '--no-dashboard', '--host', '127.0.0.1'],
            env=environment, start_new_session=True, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL))
        yield address
    finally:
        for process in reversed(processes):
            _stop(process)


def test_scheduler_path_with_separate_processes(tmp_path, capsys):
    """`dask scheduler` and `dask worker` as processes on 127.0.0.1; the atlas uses them."""
    with _separate_cluster(tmp_path) as address:
        out = tmp_path / 'atlas.zarr'
        assert main(['--grid', '2', '--payload', '0', '0', '-9.81', '--payload', '0', '0', '0',
                     '--out', str(out), '--scheduler', address, '--no-progress']) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary['workers'] == 1
        assert summary['computed_samples'] == summary['samples'] == 16
        _, results = load_results(out)
        assert np.all(results['converged'])
        assert np.allclose(results['payload'][:8], GRAVITY_1KG)
        assert np.allclose(results['payload'][8:], 0.0)


def test_bad_atlas_input(tmp_path, capsys):
    """Bad sweeps are exit 2 with the value named."""
    assert main(['--grid', '1', '--out', str(tmp_path / 'a.zarr')]) == 2
    assert 'grid must be an integer of at least 2, got 1' in capsys.readouterr().err
    assert main(['--grid', '2', '--chunk-size', '0', '--out', str(tmp_path / 'a.zarr')]) == 2
    assert '--chunk-size must be at least 1, got 0' in capsys.readouterr().err


def test_plot_atlas_of_a_small_store(tmp_path):
    """A 2x2x2 atlas written and plotted: both pictures, each figure readable."""
    spec = AtlasSpec.build(2, [GRAVITY_1KG])
    out = tmp_path / 'atlas.zarr'
    open_or_create(out, spec, spec.size)
    write_chunk(out, 0, 0, spec.size, solve_chunk(spec, 0, spec.size))
    paths = plot_atlas(out)
    assert [path.name for path in paths] == ['atlas_workspace.png', 'atlas_stiffness.png']
    assert all(path.stat().st_size > 20_000 for path in paths)
    spec, results = load_results(out)
    block = atlas_block(spec, results, workspace_volumes(spec, results)[0])
    for figure in (workspace_figure(block), stiffness_figure(block)):
        assert_readable(figure)


def _interrupted_after_a_chunk(out: Path, arguments) -> None:
    """Run the atlas as a process, Ctrl-C it once a chunk is written: quiet, exit 130."""
    interrupt([sys.executable, '-m', 'cdr_translator', 'atlas', *arguments, '--out', str(out),
               '--no-progress'], lambda process: _done_chunks(out) >= 1,
              _environment()).assert_quiet()
    assert 1 <= _done_chunks(out) < 9


def test_ctrl_c_stops_a_local_cluster_quietly_and_the_rerun_resumes(tmp_path, capsys):
    """Ctrl-C to the whole group: one line, exit 130, no worker left; the rest resumes."""
    out = tmp_path / 'atlas.zarr'
    arguments = ['--grid', '3', '--chunk-size', '3', '--workers', '1']
    _interrupted_after_a_chunk(out, arguments)
    done = _done_chunks(out)
    assert main([*arguments, '--out', str(out), '--no-progress']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['already_done'] == done and summary['computed_chunks'] == 9 - done


def test_ctrl_c_with_a_separate_cluster_is_quiet(tmp_path):
    """With --scheduler, Ctrl-C ends the command quietly (the cluster is not its own)."""
    with _separate_cluster(tmp_path) as address:
        _interrupted_after_a_chunk(tmp_path / 'atlas.zarr', [
            '--grid', '3', '--chunk-size', '3', '--scheduler', address])


def test_a_block_with_a_non_finite_jacobian_has_no_jacobian_volume():
    """A converged sample without a finite slider Jacobian: jacobian_m3 NaN, no det warning."""
    spec = AtlasSpec.build(2, [GRAVITY_1KG], fidelity='cc')
    results = solve_chunk(spec, 0, spec.size)
    assert np.all(results['converged'])
    assert np.isfinite(workspace_volumes(spec, results)[0]['jacobian_m3'])
    results['slider_jacobian'][3] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        volume = workspace_volumes(spec, results)[0]
    assert np.isnan(volume['jacobian_m3']) and volume['convex_hull_m3'] > 0.0
