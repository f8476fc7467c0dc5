"""geometry's joint bending: the compiled frame-to-frame version against the matrix formula."""

import math
import warnings

from cdr_translator import geometry
import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def _frame(rotation: np.ndarray, origin=(0.01, -0.02, 0.15)) -> np.ndarray:
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = rotation, origin
    return frame


def test_bending_between_frames_equals_the_relative_rotation_formula():
    """On 500 random frame pairs, bending_between(a, b) is the bending of R_a^T R_b."""
    rotations = Rotation.random(1000, random_state=7).as_matrix()
    for rotation_a, rotation_b in zip(rotations[:500], rotations[500:]):
        a, b = _frame(rotation_a), _frame(rotation_b)
        expected = geometry.bending_angle_and_direction(rotation_a.T @ rotation_b)
        np.testing.assert_allclose(geometry.bending_between(a, b), expected, atol=1e-12)
        np.testing.assert_allclose(geometry.bending_between(rotation_a, rotation_b), expected,
                                   atol=1e-12)


@pytest.mark.parametrize('theta, delta', [(0.3, 0.0), (0.5, 2.0), (1.2, -2.5), (0.0, 0.0)])
def test_a_joint_bent_by_theta_in_plane_delta_gives_them_back(theta, delta):
    """R = Rz(delta) Ry(theta) Rz(-delta) after any base frame: (theta, delta); straight: 0."""
    base = Rotation.from_rotvec([0.4, -0.3, 1.1]).as_matrix()
    joint = Rotation.from_euler('ZYZ', [delta, theta, -delta]).as_matrix()
    found = geometry.bending_between(_frame(base), _frame(base @ joint))
    assert found[0] == pytest.approx(theta, abs=1e-12)
    assert math.remainder(found[1] - delta, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_the_frame_of_a_failed_solve_has_a_nan_quaternion_and_no_warning():
    """A non-finite matrix is no rotation: NaN (not assessed), without numpy's det warning."""
    for bad in (np.full((3, 3), math.nan), np.diag([1.0, math.inf, 1.0])):
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            quaternion = geometry.quaternion_xyzw(bad)
        assert quaternion.shape == (4,) and np.all(np.isnan(quaternion))
