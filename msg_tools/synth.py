"""
Synthetic WrenchStamped sequences written as ROS 2 MCAP files (replay inputs, sample bags).

Profiles (force in N, moment in N m, in the base frame {pe} unless said otherwise):

* ``ramp``: from zero to the peak wrench in equal steps;
* ``step``: zero for the first third, then the peak wrench;
* ``sinusoid``: the peak wrench times sin(2 pi f t);
* ``random-walk``: Gaussian increments (seeded) of every force (moment) component, of
  standard deviation |peak force| (|peak moment|) / sqrt(count), the magnitudes kept within
  the peak's;
* ``paper``: the paper's two cases, [12, 0, 0] N and [20, 0, 0] N (Table II);
* ``hard``: what a node meets on a bad day: large and reversing loads, pure axial
  compression, a large moment, a follower load in the end-disk frame, and inputs that must
  be rejected (NaN, Inf, an unknown frame, an absurd magnitude).

Stamps start at ``start_ns`` (default a fixed date, so files are reproducible) and advance
at ``rate_hz``; the MCAP log time of each message equals its stamp.
"""

import math
from pathlib import Path
from typing import List, NamedTuple, Optional, Sequence, Union

from cdr_translator.interface import messages
from cdr_wire.mcap_log import McapLog
from msg_tools.synth_poses import (MEASURED_POSE_COV_TOPIC, MEASURED_POSE_TOPIC, MeasuredPose,
                                   POSE_COV_TYPE, pose_messages)
import numpy as np

PROFILES = ('ramp', 'step', 'sinusoid', 'random-walk', 'paper', 'hard')
#: Default first stamp: 2024-01-01T00:00:00Z.
DEFAULT_START_NS = 1_704_067_200 * 1_000_000_000
#: Stamps must stay below this: builtin_interfaces/Time holds int32 seconds.
MAX_STAMP_NS = 2 ** 31 * 1_000_000_000


class Sample(NamedTuple):
    """One wrench of a sequence."""

    stamp_ns: int
    force: np.ndarray
    moment: np.ndarray
    frame_id: str


def _hard_cases(base_frame: str, end_disk_frame: str) -> List[tuple]:
    """Return (force, moment, frame_id) of the hard cases, in a fixed order."""
    nan, inf = math.nan, math.inf
    return [
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),
        ((40.0, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),       # large lateral load
        ((-40.0, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),      # reversed at once
        ((0.0, 0.0, -30.0), (0.0, 0.0, 0.0), base_frame),      # pure axial compression
        ((5.0, 5.0, 0.0), (0.0, 0.0, 0.5), ''),                # twist and oblique bending
        ((0.0, 0.0, 0.0), (0.6, -0.4, 0.0), base_frame),       # large end moment
        ((10.0, 0.0, 0.0), (0.0, 0.0, 0.0), end_disk_frame),   # follower load
        ((nan, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),        # rejected: NaN
        ((0.0, inf, 0.0), (0.0, 0.0, 0.0), base_frame),        # rejected: Inf
        ((12.0, 0.0, 0.0), (0.0, 0.0, 0.0), 'world'),          # rejected: unknown frame
        ((1e6, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),        # rejected: absurd magnitude
        ((20.0, 0.0, 0.0), (0.0, 0.0, 0.0), base_frame),       # and back to a paper case
    ]


def generate(profile: str, count: int = 200, rate_hz: float = 100.0,
             force: Sequence[float] = (20.0, 0.0, 0.0),
             moment: Sequence[float] = (0.0, 0.0, 0.0), frequency_hz: float = 0.5,
             seed: int = 0, frame_id: str = '', start_ns: int = DEFAULT_START_NS,
             base_frame: str = 'translator_base',
             end_disk_frame: str = 'translator_end_disk') -> List[Sample]:
    """
    Return the wrench sequence of ``profile`` (``count`` samples; 'paper' and 'hard' fixed).

    ValueError names a bad profile, count, rate, frequency or seed.
    """
    if profile not in PROFILES:
        raise ValueError(f'profile must be one of {PROFILES}, got {profile!r}')
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f'count must be a positive int, got {count!r}')
    for name, value in (('rate_hz', rate_hz), ('frequency_hz', frequency_hz)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f'{name} must be positive and finite, got {value!r}')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f'seed must be an int >= 0, got {seed!r}')
    peak = np.concatenate([np.asarray(force, dtype=float), np.asarray(moment, dtype=float)])
    if peak.shape != (6,) or not np.all(np.isfinite(peak)):
        raise ValueError(f'force and moment must be 3 finite numbers each, got {force!r}, '
                         f'{moment!r}')
    times = np.arange(count) / rate_hz
    frames = [frame_id] * count
    if profile == 'ramp':
        wrenches = np.outer(np.linspace(0.0, 1.0, count), peak)
    elif profile == 'step':
        wrenches = np.outer(np.arange(count) >= count // 3, peak).astype(float)
    elif profile == 'sinusoid':
        with np.errstate(invalid='ignore', over='ignore'):   # checked next, by name
            wrenches = np.outer(np.sin(2.0 * math.pi * frequency_hz * times), peak)
        if not np.all(np.isfinite(wrenches)):
            raise ValueError(f'frequency_hz = {frequency_hz!r} gives non-finite wrenches at '
                             f'rate_hz = {rate_hz!r}')
    elif profile == 'random-walk':
        scale = np.repeat([np.linalg.norm(peak[:3]), np.linalg.norm(peak[3:])], 3)
        steps = np.random.default_rng(seed).normal(size=(count, 6)) * scale / math.sqrt(count)
        wrenches = np.cumsum(steps, axis=0)
        for part, limit in ((slice(0, 3), np.linalg.norm(peak[:3])),
                            (slice(3, 6), np.linalg.norm(peak[3:]))):
            norms = np.linalg.norm(wrenches[:, part], axis=1)
            over = norms > limit
            wrenches[over, part] *= (limit / norms[over])[:, None]
    else:
        cases = ([((12.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame_id),
                  ((20.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame_id)] if profile == 'paper'
                 else _hard_cases(base_frame, end_disk_frame))
        wrenches = np.array([list(f) + list(m) for f, m, _ in cases])
        frames = [frame for _, _, frame in cases]
        times = np.arange(len(cases)) / rate_hz
    last_ns = start_ns + 1e9 * float(times[-1])
    if not last_ns < MAX_STAMP_NS:
        raise ValueError(f'rate_hz = {rate_hz!r} is too low for {len(times)} samples: the last '
                         f'stamp would be {float(times[-1]):.6g} s after the first, beyond '
                         'what a ROS 2 stamp holds (int32 seconds)')
    return [Sample(start_ns + int(round(t * 1e9)), w[:3].copy(), w[3:].copy(), frame)
            for t, w, frame in zip(times, wrenches, frames)]


def write_wrenches(path: Union[str, Path], samples: Sequence[Sample],
                   topic: str = '/' + messages.WRENCH_TOPIC,
                   metadata: Optional[dict] = None,
                   poses: Optional[Sequence[Optional[MeasuredPose]]] = None,
                   pose_frame_id: str = '') -> int:
    """
    Write ``samples`` as WrenchStamped (sensor-data QoS) to a new MCAP; return the count.

    ``poses`` (one per sample, None for none; msg_tools.synth_poses) are written after
    their wrench on MEASURED_POSE_TOPIC (PoseStamped) and MEASURED_POSE_COV_TOPIC
    (PoseWithCovarianceStamped), both with header frame_id ``pose_frame_id``.
    """
    with McapLog(path, flush_every_messages=0, flush_every_s=0.0,
                 if_exists='overwrite') as log:
        log.register(topic, messages.WRENCH_TYPE, qos='sensor_data')
        if poses is not None:
            log.register(MEASURED_POSE_TOPIC, messages.POSE_TYPE, qos='sensor_data')
            log.register(MEASURED_POSE_COV_TOPIC, POSE_COV_TYPE, qos='sensor_data')
        for index, sample in enumerate(samples):
            log.write(topic, messages.WRENCH_TYPE,
                      messages.wrench_message(sample.force, sample.moment, sample.frame_id,
                                              messages.stamp_from_ns(sample.stamp_ns)),
                      log_time_ns=sample.stamp_ns)
            pose = poses[index] if poses is not None else None
            if pose is not None:
                plain, covariance = pose_messages(pose, pose_frame_id,
                                                  messages.stamp_from_ns(pose.stamp_ns))
                log.write(MEASURED_POSE_TOPIC, messages.POSE_TYPE, plain,
                          log_time_ns=pose.stamp_ns)
                log.write(MEASURED_POSE_COV_TOPIC, POSE_COV_TYPE, covariance,
                          log_time_ns=pose.stamp_ns)
        if metadata:
            log.add_metadata('msg_tools.synth', metadata)
    return len(samples)
