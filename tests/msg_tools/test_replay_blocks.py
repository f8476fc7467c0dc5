"""Replay in blocks (one solve_many per block): the same outputs as the node's per-message path."""

import math

from cdr_translator.fidelity import FidelitySolver
from cdr_translator.interface import messages
from cdr_translator.interface.batch_row import BatchRow
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import BATCHED_FIDELITIES, node_solver
from cdr_translator.interface.wrench_processing import WrenchProcessor
from cdr_translator.params.translator_params import DEFAULT_PARAMS_PATH
from mcap_ros2.reader import read_ros2_messages
from msg_tools import replay as replay_module
from msg_tools import synth
from msg_tools.replay import replay
from msg_tools.synth_poses import measure, PoseNoise
import numpy as np
import pytest

#: Diagnostic values that are measured, not computed: they differ between any two runs.
MEASURED = ('solve_time_ms', 'mean_solve_time_ms', 'max_solve_time_ms', 'estimate_time_ms',
            'mean_estimate_time_ms', 'max_estimate_time_ms')


def _plain(value):
    """Return a decoded message as nested dicts, lists and numbers."""
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    slots = getattr(value, '__slots__', None)
    if slots is not None and not isinstance(value, (str, bytes)):
        return {name: _plain(getattr(value, name)) for name in slots}
    return value


def _outputs(path):
    """(topic, message) of every record of an MCAP, measured diagnostic values left out."""
    records = []
    for item in read_ros2_messages(str(path)):
        message = _plain(item.ros_msg)
        if item.channel.topic in ('/diagnostics', '/solve_status', '/estimate_status'):
            for status in message['status']:
                status['values'] = [pair for pair in status['values']
                                    if pair['key'] not in MEASURED]
        records.append((item.channel.topic, item.log_time_ns, message))
    return records


def _assert_close(batched, single, where=''):
    """Equal structure; floats equal to 1e-9 (m, rad and SI throughout)."""
    if isinstance(single, dict):
        assert batched.keys() == single.keys(), where
        for key in single:
            _assert_close(batched[key], single[key], f'{where}.{key}')
    elif isinstance(single, list):
        assert len(batched) == len(single), where
        for index, (left, right) in enumerate(zip(batched, single)):
            _assert_close(left, right, f'{where}[{index}]')
    elif isinstance(single, float):
        assert batched == pytest.approx(single, rel=1e-7, abs=1e-9, nan_ok=True), where
    else:
        assert batched == single, where


def _recording(path, settings):
    """Write a random walk with rejected inputs and a follower load inside blocks."""
    samples = synth.generate('random-walk', count=40, force=(20.0, 0.0, 0.0),
                             moment=(0.0, 0.3, 0.0), seed=3)
    nan = samples[9]
    samples[9] = nan._replace(force=np.array([math.nan, 0.0, 0.0]))
    follower = samples[21]
    samples[21] = follower._replace(frame_id=settings.end_disk_frame)
    samples[30] = samples[30]._replace(frame_id='somewhere_else')
    synth.write_wrenches(path, samples)


def _params(tmp_path, fidelity):
    """Write the default parameters at ``fidelity``; return the file's path."""
    path = tmp_path / f'{fidelity}.yaml'
    path.write_text(DEFAULT_PARAMS_PATH.read_text().replace('fidelity: full',
                                                            f'fidelity: {fidelity}'))
    return path


def _counted_blocks_of_16(monkeypatch):
    """Replay in blocks of 16 messages; return the list each solve_many's row count joins."""
    monkeypatch.setattr(replay_module, 'BLOCK_SIZE', 16)
    runs = []
    solve_many = FidelitySolver.solve_many

    def counted(self, forces, *args, **kwargs):
        runs.append(len(forces))
        return solve_many(self, forces, *args, **kwargs)

    monkeypatch.setattr(FidelitySolver, 'solve_many', counted)
    return runs


@pytest.mark.parametrize('fidelity', BATCHED_FIDELITIES)
def test_blocks_give_the_per_message_outputs(fidelity, tmp_path, monkeypatch):
    """Block boundaries, a rejection and a follower load inside blocks: the node's outputs."""
    params = _params(tmp_path, fidelity)
    settings = TranslatorSettings.from_params_file(params)
    assert settings.fidelity == fidelity
    bag = tmp_path / 'walk.mcap'
    _recording(bag, settings)
    runs = _counted_blocks_of_16(monkeypatch)
    batched = replay(bag, tmp_path / 'blocks.mcap', params_path=params)
    # blocks 0-15, 16-31, 32-39; runs end at the rejections (9, 30) and the follower (21)
    assert runs == [9, 6, 5, 8, 1, 8]
    with monkeypatch.context() as patch:
        patch.setattr(WrenchProcessor, 'batches', property(lambda self: False))
        single = replay(bag, tmp_path / 'single.mcap', params_path=params)
    counts = (batched.messages, batched.rejected, batched.solved, batched.not_converged)
    assert counts == (single.messages, single.rejected, single.solved, single.not_converged)
    assert counts[:2] == (40, 2) and counts[2] >= 30
    got, expected = _outputs(tmp_path / 'blocks.mcap'), _outputs(tmp_path / 'single.mcap')
    assert [(topic, time) for topic, time, _ in got] == [
        (topic, time) for topic, time, _ in expected]
    topics = {topic for topic, _, _ in expected}
    assert {'/compliance', '/compliance_eigenvalues', '/solve_status', '/diagnostics'} <= topics
    for (topic, _, left), (_, _, right) in zip(got, expected):
        _assert_close(left, right, topic)


def test_measured_poses_between_the_wrenches_join_the_blocks(tmp_path, monkeypatch):
    """Each wrench followed by its pose on two topics: blocks stay whole, outputs unchanged."""
    samples = synth.generate('random-walk', count=20, seed=4)
    poses, frame_id = measure(samples, PoseNoise(2e-4, 0.1), seed=4)
    bag = tmp_path / 'walk_and_poses.mcap'
    synth.write_wrenches(bag, samples, poses=poses, pose_frame_id=frame_id)
    runs = _counted_blocks_of_16(monkeypatch)
    batched = replay(bag, tmp_path / 'blocks.mcap')
    # 60 messages in blocks of 16: 6, 5, 5 and 4 wrenches (3 messages a wrench)
    assert runs == [6, 5, 5, 4]
    with monkeypatch.context() as patch:
        patch.setattr(WrenchProcessor, 'batches', property(lambda self: False))
        single = replay(bag, tmp_path / 'single.mcap')
    assert (batched.solved, batched.poses) == (single.solved, single.poses) == (20, 40)
    got, expected = _outputs(tmp_path / 'blocks.mcap'), _outputs(tmp_path / 'single.mcap')
    # every record in the place and at the log time of the per-message path
    assert [(topic, time) for topic, time, _ in got] == [
        (topic, time) for topic, time, _ in expected]
    assert '/estimated_wrench' in {topic for topic, _, _ in expected}
    for (topic, _, left), (_, _, right) in zip(got, expected):
        _assert_close(left, right, topic)


@pytest.mark.parametrize('fidelity', BATCHED_FIDELITIES)
def test_a_batch_row_reads_as_its_single_solve(fidelity, tmp_path):
    """Every attribute the output builders read equals the single solve's result."""
    settings = TranslatorSettings.from_params_file(_params(tmp_path, fidelity))
    wrenches = np.array([[5.0, 0.0, 0.0, 0.0, 0.0, 0.0], [8.0, 1.0, 0.0, 0.0, 0.1, 0.0],
                         [12.0, 0.0, -2.0, 0.0, 0.0, 0.05]])
    batch = node_solver(settings.params, settings).solve_many(wrenches[:, :3], wrenches[:, 3:],
                                                              compliance=True)
    solver = node_solver(settings.params, settings)
    stamp = {'sec': 1, 'nanosec': 2}
    for index, wrench in enumerate(wrenches):
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
        row = BatchRow(batch, index)
        for name in ('converged', 'message', 'iterations', 'method', 'fidelity', 'stable',
                     'steps_per_segment', 'accuracy_met'):
            assert getattr(row, name) == getattr(result, name), name
        for name in ('residual_norm', 'stability_margin', 'error_estimate_m',
                     'error_estimate_deg', 'end_disk_rotation'):
            assert getattr(row, name) == pytest.approx(getattr(result, name), rel=1e-6,
                                                       abs=1e-9, nan_ok=True), name
        np.testing.assert_allclose(row.end_disk_position, result.end_disk_position, atol=1e-9)
        np.testing.assert_allclose(row.end_disk_rotation_matrix, result.frames['de'][:3, :3],
                                   atol=1e-9)
        np.testing.assert_allclose(row.compliance.eigenvalues, result.compliance.eigenvalues,
                                   rtol=1e-6)
        assert row.compliance.stable == result.compliance.stable
        assert messages.solve_level(row) == messages.solve_level(result)
        assert ([topic for topic, _, _ in messages.output_messages(row, stamp, 'base')]
                == [topic for topic, _, _ in messages.output_messages(result, stamp, 'base')])
