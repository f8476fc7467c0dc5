"""
Calibration from recordings: wrenches paired with measured end-disk poses, the fitted file.

A recording holds ``wrench`` (WrenchStamped) and the tracker's ``measured_end_disk_pose``
(PoseStamped) and/or ``measured_end_disk_pose_cov`` (PoseWithCovarianceStamped), in any
namespace. Each wrench is paired with the measured pose nearest to its header stamp, if
within the tolerance; the covariance topic is used when the file has it (its covariance
weights the fit), else the plain poses with an assumed covariance (``--sigma``). Wrenches
the node would not solve as given (non-finite, a frame_id other than the base frame or
empty) and poses that cannot weight a fit (non-unit quaternion, covariance not positive
definite) are skipped and counted. So are ambiguous pairs: wrenches that share their stamp
with another wrench of the file, poses that share theirs with another pose, and the
wrenches whose nearest pose stamp is such a shared one (which pose, or which wrench, was
measured under which load cannot be told). The fit itself is
cdr_translator.calibration.pose_fit.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

from cdr_translator.calibration.pose_error import FRAME_NAMES, rotations_from_quaternions
from cdr_translator.calibration.pose_fit import PoseSamples
from cdr_translator.interface import messages, pose_estimation
from cdr_wire.reader import Decoders, McapSource, ReadReport
import numpy as np
from scipy.spatial.transform import Rotation

#: Last name of the topics read (any namespace).
WRENCH_NAME, POSE_NAME, POSE_COV_NAME = (
    messages.WRENCH_TOPIC, pose_estimation.MEASURED_POSE_TOPIC,
    pose_estimation.MEASURED_POSE_COV_TOPIC)
#: Default largest stamp difference of a wrench and its pose (s).
DEFAULT_TOLERANCE_S = 0.002
#: Default assumed standard deviations of poses without covariance: m, deg.
DEFAULT_SIGMA = (1e-3, 0.5)
#: Reasons of the ambiguous pairs skipped (see the module text).
SHARED_WRENCH_STAMP = 'wrench sharing its stamp with another wrench (ambiguous pair)'
SHARED_POSE_STAMP = 'pose sharing its stamp with another pose (ambiguous pair)'
NEAREST_POSES_SHARED = 'wrench whose nearest pose stamp holds several poses (ambiguous pair)'


@dataclass
class Pairing:
    """The paired samples of one or more recordings and how the pairing went."""

    samples: PoseSamples
    stamps_ns: np.ndarray
    wrenches: int = 0
    poses: int = 0
    largest_gap_s: float = math.nan
    covariance_source: str = ''
    pose_frames: List[str] = field(default_factory=list)
    skipped: Dict[str, int] = field(default_factory=dict)
    reports: List[ReadReport] = field(default_factory=list)

    @property
    def matched(self) -> int:
        """Count the wrenches paired with a usable pose."""
        return len(self.stamps_ns)

    @property
    def complete(self) -> bool:
        """Tell whether every file was read intact."""
        return all(report.complete for report in self.reports)

    def skip(self, reason: str, count: int = 1) -> None:
        """Count ``count`` messages skipped for ``reason``."""
        if count:
            self.skipped[reason] = self.skipped.get(reason, 0) + count


def _topic_name(topic: str) -> str:
    """Return the last name of a topic ('/robot/wrench' -> 'wrench')."""
    return topic.rstrip('/').rsplit('/', 1)[-1]


def _read_file(path: Union[str, Path], pairing: Pairing) -> Tuple[list, list, list]:
    """Return the decoded wrenches, plain poses and covariance poses of one file."""
    wanted = {WRENCH_NAME: messages.WRENCH_TYPE, POSE_NAME: messages.POSE_TYPE,
              POSE_COV_NAME: messages.POSE_COV_TYPE}
    found: Dict[str, list] = {name: [] for name in wanted}
    source = McapSource(path)
    decoders = Decoders()
    for raw in source.messages():
        name = _topic_name(raw.topic)
        if wanted.get(name) != raw.schema_name:
            continue
        try:
            found[name].append(decoders.decode(raw))
        except ValueError:
            pairing.skip(f'undecodable {name}')
    pairing.reports.append(source.report)
    return found[WRENCH_NAME], found[POSE_NAME], found[POSE_COV_NAME]


def _pose_rows(poses: list, covariances: bool, sigma: Sequence[float]
               ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, List[str]]:
    """Return stamps, positions, quaternions, covariances and frame_ids of pose messages."""
    assumed = np.diag([sigma[0] ** 2] * 3 + [math.radians(sigma[1]) ** 2] * 3)
    stamps, positions, quaternions, matrices, frames = [], [], [], [], []
    for message in poses:
        body = message.pose.pose if covariances else message.pose
        stamps.append(messages.stamp_to_ns(message.header.stamp))
        positions.append([body.position.x, body.position.y, body.position.z])
        quaternions.append([body.orientation.x, body.orientation.y, body.orientation.z,
                            body.orientation.w])
        matrices.append(np.reshape(message.pose.covariance, (6, 6)) if covariances
                        else assumed)
        frames.append(message.header.frame_id)
    return (np.array(stamps, dtype=np.int64), np.reshape(positions, (-1, 3)),
            np.reshape(quaternions, (-1, 4)), np.reshape(matrices, (-1, 6, 6)), frames)


def _usable_poses(positions: np.ndarray, quaternions: np.ndarray,
                  covariances: np.ndarray) -> np.ndarray:
    """Return the mask of poses with a finite position, a unit quaternion and an SPD cov."""
    norms = np.linalg.norm(quaternions, axis=1)
    good = (np.all(np.isfinite(positions), axis=1) & np.isfinite(norms)
            & (np.abs(norms - 1.0) <= 1e-3) & np.all(np.isfinite(covariances), axis=(1, 2)))
    for row in np.flatnonzero(good):
        matrix = covariances[row]
        if np.abs(matrix - matrix.T).max() > 1e-9 * np.abs(matrix).max():
            good[row] = False
            continue
        try:
            np.linalg.cholesky(matrix)
        except np.linalg.LinAlgError:
            good[row] = False
    return good


def read_pairs(paths: Sequence[Union[str, Path]], tolerance_s: float = DEFAULT_TOLERANCE_S,
               base_frame: str = 'translator_base',
               sigma: Sequence[float] = DEFAULT_SIGMA) -> Pairing:
    """
    Pair the wrenches of ``paths`` with their measured poses; see the module text.

    ValueError when a file cannot be read at all, the tolerance or sigma is not positive,
    or the poses come in more than one frame.
    """
    if not (math.isfinite(tolerance_s) and tolerance_s >= 0.0):
        raise ValueError(f'the stamp tolerance must be a finite number >= 0 s, got '
                         f'{tolerance_s!r}')
    if len(sigma) != 2 or not all(math.isfinite(value) and value > 0 for value in sigma):
        raise ValueError(f'--sigma takes two positive numbers, POS_M ANG_DEG, got {sigma!r}')
    columns: Dict[str, list] = {'wrench': [], 'position': [], 'quaternion': [],
                                'covariance': [], 'stamp': []}
    pairing = Pairing(PoseSamples(np.zeros((0, 6)), np.zeros((0, 3)), np.zeros((0, 3, 3)),
                                  np.zeros((0, 6, 6))), np.zeros(0, dtype=np.int64))
    sources, gaps = set(), []
    for path in paths:
        wrenches, plain, with_cov = _read_file(path, pairing)
        pairing.wrenches += len(wrenches)
        covariances = bool(with_cov)
        poses = with_cov if covariances else plain
        pairing.poses += len(poses)
        sources.add(f'{POSE_COV_NAME} (measured covariance)' if covariances else
                    f'{POSE_NAME} (assumed: {sigma[0]:g} m, {sigma[1]:g} deg)')
        stamps, positions, quaternions, matrices, frames = _pose_rows(poses, covariances, sigma)
        usable = _usable_poses(positions, quaternions, matrices)
        pairing.skip('pose without a finite position, a unit quaternion or a positive '
                     'definite covariance', int(np.sum(~usable)))
        pairing.pose_frames = sorted(set(pairing.pose_frames) | {
            frame for frame, good in zip(frames, usable) if good})
        order = np.flatnonzero(usable)[np.argsort(stamps[usable], kind='stable')]
        sorted_stamps = stamps[order]
        shared_pose = _shared(sorted_stamps)
        pairing.skip(SHARED_POSE_STAMP, int(np.sum(shared_pose)))
        wrench_stamps = [messages.stamp_to_ns(message.header.stamp) for message in wrenches]
        shared_wrench = _shared(np.array(wrench_stamps, dtype=np.int64))
        for message, shared in zip(wrenches, shared_wrench):
            if shared:
                pairing.skip(SHARED_WRENCH_STAMP)
                continue
            force, moment, frame_id, stamp = messages.wrench_from_message(message)
            wrench = np.concatenate([force, moment])
            if frame_id not in ('', base_frame):
                pairing.skip(f'wrench in frame {frame_id!r} (not {base_frame!r} or empty)')
                continue
            if not np.all(np.isfinite(wrench)):
                pairing.skip('wrench not finite')
                continue
            stamp_ns = messages.stamp_to_ns(stamp)
            nearest = _nearest(sorted_stamps, stamp_ns)
            if nearest is None or abs(int(sorted_stamps[nearest]) - stamp_ns) > tolerance_s * 1e9:
                pairing.skip('wrench without a pose within the stamp tolerance')
                continue
            if shared_pose[nearest]:
                pairing.skip(NEAREST_POSES_SHARED)
                continue
            row = order[nearest]
            gaps.append(abs(int(stamps[row]) - stamp_ns) * 1e-9)
            columns['wrench'].append(wrench)
            columns['position'].append(positions[row])
            columns['quaternion'].append(quaternions[row])
            columns['covariance'].append(matrices[row])
            columns['stamp'].append(stamp_ns)
    if len(pairing.pose_frames) > 1:
        raise ValueError(f'the measured poses come in more than one frame '
                         f'({", ".join(map(repr, pairing.pose_frames))}): one tracker frame '
                         'per calibration')
    if columns['stamp']:
        pairing.samples = PoseSamples(
            np.array(columns['wrench']), np.array(columns['position']),
            rotations_from_quaternions(columns['quaternion']), np.array(columns['covariance']))
        pairing.stamps_ns = np.array(columns['stamp'], dtype=np.int64)
        pairing.largest_gap_s = max(gaps)
    pairing.covariance_source = '; '.join(sorted(sources))
    return pairing


def _shared(stamps: np.ndarray) -> np.ndarray:
    """Return the mask of the stamps that occur more than once in ``stamps``."""
    _, inverse, counts = np.unique(stamps, return_inverse=True, return_counts=True)
    return counts[inverse] > 1


def _nearest(sorted_stamps: np.ndarray, stamp_ns: int) -> Optional[int]:
    """Return the index of the stamp nearest ``stamp_ns`` in a sorted array (None: empty)."""
    if not len(sorted_stamps):
        return None
    index = int(np.searchsorted(sorted_stamps, stamp_ns))
    candidates = [i for i in (index - 1, index) if 0 <= i < len(sorted_stamps)]
    return min(candidates, key=lambda i: abs(int(sorted_stamps[i]) - stamp_ns))


def yaml_number(value: float) -> str:
    """Return ``value`` as a YAML float that PyYAML and rcl read as a double (a '.' in it)."""
    text = repr(float(value))
    if 'e' in text and '.' not in text.split('e')[0]:
        mantissa, exponent = text.split('e')
        text = f'{mantissa}.0e{exponent}'
    return text


def fitted_params_text(values: Dict[str, float], model_names: Sequence[str],
                       sources: Sequence[str], samples: int, base_frame: str,
                       tracker_frame: str) -> str:
    """
    Return a partial ROS 2 params file of the fitted model keys (translator_node section).

    Loaded over the shipped defaults (``--params`` of the CLI and replay,
    ``--params-file`` of the node) it changes just those keys. A fitted tracker frame is
    not a node parameter: it is written as the static transform that publishes it.
    """
    lines = [f'# Fitted by python -m msg_tools calibrate from {", ".join(map(str, sources))}'
             f' ({samples} samples).',
             '# A partial ROS 2 params file: load it on top of the shipped defaults.',
             'translator_node:', '  ros__parameters:']
    lines += [f'    {name}: {yaml_number(values[name])}' for name in model_names]
    if all(name in values for name in FRAME_NAMES):
        frame = [values[name] for name in FRAME_NAMES]
        quaternion = Rotation.from_rotvec(frame[3:]).as_quat()
        lines += ['# Fitted tracker frame (pose of the tracker frame in the base frame):',
                  '#   ros2 run tf2_ros static_transform_publisher '
                  + ' '.join(f'--{axis} {value:.9g}' for axis, value in zip(
                      ('x', 'y', 'z', 'qx', 'qy', 'qz', 'qw'), list(frame[:3]) + list(
                          quaternion)))
                  + f' --frame-id {base_frame} --child-frame-id {tracker_frame or "tracker"}']
    return '\n'.join(lines) + '\n'
