"""
Measured against predicted end-disk poses: tracker frames, pose errors, whitening.

A tracker (motion capture, camera) measures the end disk in its own frame {t}. The pose
of {t} in the base frame {pe} is a translation ``t`` (m) and a rotation vector ``r`` (rad,
axis times angle): a point p_t in {t} is ``R(r) p_t + t`` in {pe}. Six numbers
``[tx, ty, tz, rx, ry, rz]`` hold it, in that order.

The error of a predicted pose against a measured one is the 6-vector ``[dp; dtheta]`` in
{t}: ``dp`` = predicted - measured position (m), ``dtheta`` the rotation vector of
``R_predicted R_measured^T`` (rad), a rotation about the fixed axes of {t}. That is the
order and the orientation convention of a ``geometry_msgs/PoseWithCovariance`` covariance
(x, y, z, then rotations about the fixed X, Y, Z axes), so the covariance of a measurement
whitens its error directly.
"""

from typing import Tuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

__all__ = ['FRAME_NAMES', 'check_frame', 'from_tracker', 'pose_errors', 'register',
           'rotations_from_quaternions', 'to_tracker', 'whitening']

#: Names of the six numbers of a tracker frame (translation in m, rotation vector in rad).
FRAME_NAMES = ('frame_x', 'frame_y', 'frame_z', 'frame_rx', 'frame_ry', 'frame_rz')


def check_frame(frame: ArrayLike) -> np.ndarray:
    """Return the tracker frame as 6 finite floats; ValueError saying what is wrong."""
    array = np.asarray(frame, dtype=float)
    if array.shape != (6,) or not np.all(np.isfinite(array)):
        raise ValueError(f'a tracker frame is 6 finite numbers (x y z in m, rotation vector '
                         f'rx ry rz in rad), got {frame!r}')
    return array


def rotations_from_quaternions(quaternions_xyzw: ArrayLike) -> np.ndarray:
    """
    Return the rotation matrices (N, 3, 3) of unit quaternions (N, 4) in ROS order x, y, z, w.

    ValueError names the first row that is not finite or whose norm is off 1 by more than
    1e-3 (a quaternion a tracker sends is normalized; a larger error is a wrong field).
    """
    array = np.asarray(quaternions_xyzw, dtype=float).reshape(-1, 4)
    norms = np.linalg.norm(array, axis=1)
    bad = ~np.isfinite(norms) | (np.abs(norms - 1.0) > 1e-3)
    if bad.any():
        row = int(np.argmax(bad))
        raise ValueError(f'quaternion row {row} is not a unit quaternion (x, y, z, w): '
                         f'{array[row].tolist()}')
    return Rotation.from_quat(array / norms[:, None]).as_matrix().reshape(-1, 3, 3)


def to_tracker(positions: np.ndarray, rotations: np.ndarray, frame: ArrayLike
               ) -> Tuple[np.ndarray, np.ndarray]:
    """Express poses given in {pe} (positions (N, 3), rotations (N, 3, 3)) in the tracker {t}."""
    frame = check_frame(frame)
    inverse = Rotation.from_rotvec(frame[3:]).as_matrix().T
    return (positions - frame[:3]) @ inverse.T, np.einsum('ij,njk->nik', inverse, rotations)


def from_tracker(positions: np.ndarray, rotations: np.ndarray, frame: ArrayLike
                 ) -> Tuple[np.ndarray, np.ndarray]:
    """Express poses given in the tracker {t} in {pe}: the inverse of ``to_tracker``."""
    frame = check_frame(frame)
    rotation = Rotation.from_rotvec(frame[3:]).as_matrix()
    return positions @ rotation.T + frame[:3], np.einsum('ij,njk->nik', rotation, rotations)


def register(base_positions: np.ndarray, base_rotations: np.ndarray,
             tracker_positions: np.ndarray, tracker_rotations: np.ndarray) -> np.ndarray:
    """
    Return the tracker frame (6 numbers) that best maps poses in {t} onto the same in {pe}.

    Closed form: the rotation is the chordal mean of ``R_pe R_t^T`` over the samples (the
    orthogonal polar factor of their sum), the translation the mean of ``p_pe - R p_t``.
    The start of a frame fit, from the poses predicted at the starting parameters.
    """
    total = np.einsum('nij,nkj->ik', base_rotations, tracker_rotations)
    left, _, right = np.linalg.svd(total)
    sign = np.sign(np.linalg.det(left @ right))
    rotation = left @ np.diag([1.0, 1.0, sign]) @ right
    translation = np.mean(base_positions - tracker_positions @ rotation.T, axis=0)
    return np.concatenate([translation, Rotation.from_matrix(rotation).as_rotvec()])


def pose_errors(predicted_positions: np.ndarray, predicted_rotations: np.ndarray,
                measured_positions: np.ndarray, measured_rotations: np.ndarray) -> np.ndarray:
    """Return the errors (N, 6): predicted - measured position, then rotation vector (rad)."""
    relative = np.einsum('nij,nkj->nik', predicted_rotations, measured_rotations)
    return np.concatenate([predicted_positions - measured_positions,
                           Rotation.from_matrix(relative).as_rotvec().reshape(-1, 3)], axis=1)


def whitening(covariances: ArrayLike) -> np.ndarray:
    """
    Return W (N, 6, 6) with ``W @ error`` of unit covariance: the inverse Cholesky factor.

    ValueError names the first covariance that is not finite, symmetric and positive
    definite (a tracker that sends zeros for an unknown covariance gives such a row).
    """
    array = np.asarray(covariances, dtype=float).reshape(-1, 6, 6)
    result = np.empty_like(array)
    for row, covariance in enumerate(array):
        scale = float(np.abs(covariance).max()) if np.all(np.isfinite(covariance)) else 0.0
        if not scale or np.abs(covariance - covariance.T).max() > 1e-9 * scale:
            raise ValueError(f'covariance of sample {row} is not finite and symmetric')
        try:
            factor = np.linalg.cholesky(covariance)
        except np.linalg.LinAlgError:
            raise ValueError(f'covariance of sample {row} is not positive definite: '
                             f'diagonal {np.diag(covariance).tolist()}') from None
        result[row] = np.linalg.inv(factor)
    return result
