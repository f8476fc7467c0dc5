"""
Synthetic tracker measurements of the end disk under a synthetic wrench sequence.

For every wrench of a sequence that a node would solve (finite, in the base frame or with
an empty frame_id, within the node's magnitude limits), the end-disk pose is solved with a
"true" parameter set (a params file over the shipped one: another prototype than the
model's defaults), expressed in a tracker frame {t} offset from the base frame {pe}, and
perturbed by seeded Gaussian noise: the position by N(0, s_p^2) per axis, the orientation
by a rotation exp(d) applied about the fixed axes of {t}, d ~ N(0, s_a^2) per axis
(cdr_translator.calibration.pose_error gives the frame and error conventions). The covariance
diag(s_p^2 x 3, s_a^2 x 3) (m^2, rad^2; ROS order x, y, z, rx, ry, rz, row-major) goes with
each pose. A wrench whose true solve fails gets no pose.

The pose's header stamp is the wrench's, or, with a jitter J > 0, the wrench's plus a
seeded uniform offset in [-J, J] (a tracker and a force sensor are not triggered
together); its log time equals its stamp.
"""

import math
from typing import List, NamedTuple, Optional, Protocol, Sequence, Tuple

from cdr_translator.calibration.pose_error import check_frame, to_tracker
from cdr_translator.interface import messages, pose_estimation
from cdr_translator.params.translator_params import (Accuracy, DEFAULT_PARAMS_PATH,
                                                     translator_values, TranslatorParams)
from cdr_translator.solve.solver import TranslatorSolver
import numpy as np
from scipy.spatial.transform import Rotation

#: Topics and types of the measurements (translator_node's names, absolute).
MEASURED_POSE_TOPIC = '/' + pose_estimation.MEASURED_POSE_TOPIC
MEASURED_POSE_COV_TOPIC = '/' + pose_estimation.MEASURED_POSE_COV_TOPIC
POSE_COV_TYPE = messages.POSE_COV_TYPE
#: header.frame_id of measured poses in a tracker frame offset from the base.
TRACKER_FRAME = 'tracker'


class WrenchSample(Protocol):
    """A wrench of a sequence as ``measure`` reads it (msg_tools.synth.Sample is one)."""

    @property
    def stamp_ns(self) -> int:
        """Return the header stamp (ns)."""

    @property
    def force(self) -> np.ndarray:
        """Return the force in N, in the frame that ``frame_id`` names."""

    @property
    def moment(self) -> np.ndarray:
        """Return the moment in N m."""

    @property
    def frame_id(self) -> str:
        """Return the header's frame id; empty for the base frame."""


class MeasuredPose(NamedTuple):
    """One synthetic measurement: stamp, position (m), quaternion (x, y, z, w), covariance."""

    stamp_ns: int
    position: np.ndarray
    quaternion_xyzw: np.ndarray
    covariance: np.ndarray


class PoseNoise(NamedTuple):
    """Standard deviations of the measurement noise: position (m) and angle (deg)."""

    position_m: float
    angle_deg: float

    def covariance(self) -> np.ndarray:
        """Return the 6 x 6 matrix (m^2, rad^2), in ROS order."""
        return np.diag([self.position_m ** 2] * 3 + [math.radians(self.angle_deg) ** 2] * 3)


def check_noise(values: Sequence[float]) -> PoseNoise:
    """Return the noise of ``values`` (POS_M, ANG_DEG); ValueError unless two positive numbers."""
    if len(values) != 2 or not all(isinstance(value, (int, float)) and math.isfinite(value)
                                   and value > 0 for value in values):
        raise ValueError(f'--measured-pose-noise takes two positive numbers, POS_M ANG_DEG '
                         f'(a zero covariance cannot weight a fit), got {list(values)!r}')
    return PoseNoise(float(values[0]), float(values[1]))


def solvable_rows(wrenches: np.ndarray, frames: Sequence[str], values: dict) -> np.ndarray:
    """Return the mask of wrenches translator_node (with ``values``) would solve as given."""
    finite = np.all(np.isfinite(wrenches), axis=1)
    safe = np.where(finite[:, None], wrenches, 0.0)
    return (finite & np.array([frame in ('', values['base_frame']) for frame in frames])
            & (np.linalg.norm(safe[:, :3], axis=1) <= values['max_force'])
            & (np.linalg.norm(safe[:, 3:], axis=1) <= values['max_moment']))


def measure(samples: Sequence[WrenchSample], noise: PoseNoise, true_params: Optional[str] = None,
            frame: Sequence[float] = (0.0,) * 6, seed: int = 0, jitter_s: float = 0.0
            ) -> Tuple[List[Optional[MeasuredPose]], str]:
    """
    Return a measured pose per sample (None where there is none) and their header frame_id.

    ``true_params`` is a params file read over the shipped one (None: the shipped one);
    ``frame`` the tracker frame's pose in {pe} (x y z in m, rotation vector in rad). The
    frame_id is the base frame when ``frame`` is zero, else TRACKER_FRAME. ValueError names
    a bad frame or jitter, and ParameterError a bad params file.
    """
    tracker = check_frame(frame)
    if not (math.isfinite(jitter_s) and jitter_s >= 0.0):
        raise ValueError(f'the pose stamp jitter must be a finite number >= 0, got {jitter_s!r}')
    values = translator_values(true_params)
    wrenches = np.array([np.concatenate([sample.force, sample.moment]) for sample in samples],
                        dtype=float).reshape(-1, 6)
    rows = np.flatnonzero(solvable_rows(wrenches, [sample.frame_id for sample in samples],
                                        values))
    poses: List[Optional[MeasuredPose]] = [None] * len(wrenches)
    if len(rows):
        solver = TranslatorSolver(TranslatorParams.from_yaml(true_params or DEFAULT_PARAMS_PATH),
                                  accuracy=Accuracy.from_mapping(values))
        batch = solver.solve_many(wrenches[rows, :3], wrenches[rows, 3:])
        solved = batch.converged.astype(bool)
        rows, positions = rows[solved], batch.end_disk_position[solved]
        rotations = Rotation.from_quat(batch.end_disk_quaternion_xyzw[solved]).as_matrix()
        positions, rotations = to_tracker(positions, rotations.reshape(-1, 3, 3), tracker)
        generator = np.random.default_rng([seed, 1])
        positions = positions + generator.normal(0.0, noise.position_m, positions.shape)
        turns = Rotation.from_rotvec(generator.normal(
            0.0, math.radians(noise.angle_deg), (len(rows), 3)))
        quaternions = (turns * Rotation.from_matrix(rotations)).as_quat()
        offsets = generator.uniform(-jitter_s, jitter_s, len(rows)) if jitter_s else np.zeros(
            len(rows))
        covariance = noise.covariance()
        for row, position, quaternion, offset in zip(rows, positions, quaternions, offsets):
            poses[row] = MeasuredPose(samples[row].stamp_ns + int(round(offset * 1e9)),
                                      position, quaternion, covariance)
    return poses, values['base_frame'] if not tracker.any() else TRACKER_FRAME


def pose_messages(pose: MeasuredPose, frame_id: str, stamp: dict) -> Tuple[dict, dict]:
    """Return the PoseStamped and PoseWithCovarianceStamped dicts of a measured pose."""
    head = {'stamp': stamp, 'frame_id': frame_id}
    body = {'position': dict(zip('xyz', pose.position.tolist())),
            'orientation': dict(zip('xyzw', pose.quaternion_xyzw.tolist()))}
    return ({'header': head, 'pose': body},
            {'header': head, 'pose': {'pose': body,
                                      'covariance': pose.covariance.ravel().tolist()}})
