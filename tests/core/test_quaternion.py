"""geometry.quaternion_xyzw and rotation_of_quaternion against scipy's Rotation."""

from cdr_translator.geometry import quaternion_xyzw, rotation_of_quaternion, rotation_of_vector
import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def _scipy(matrix: np.ndarray) -> np.ndarray:
    """Return scipy's quaternion with w >= 0 (the old implementation)."""
    quaternion = Rotation.from_matrix(matrix).as_quat()
    return -quaternion if quaternion[3] < 0.0 else quaternion


def test_matches_scipy_on_random_and_special_rotations():
    """Equal to 1e-15 on random rotations, half turns about each axis and the identity."""
    matrices = list(Rotation.random(2000, random_state=3).as_matrix())
    matrices += [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
                 np.diag([-1.0, -1.0, 1.0]),
                 Rotation.from_rotvec([0.0, 0.0, np.pi - 1e-9]).as_matrix()]
    for matrix in matrices:
        ours = quaternion_xyzw(matrix)
        np.testing.assert_allclose(ours, _scipy(matrix), rtol=0.0, atol=1e-15)
        assert ours[3] >= 0.0


@pytest.mark.parametrize('offset', [1e-11, 1e-6, 1e-2])
def test_non_orthonormal_matrix_is_projected_like_scipy(offset):
    """Off by 1e-11 (a solved frame), 1e-6 or 1e-2 (scipy's path): scipy's nearest rotation."""
    matrix = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_matrix() + offset
    np.testing.assert_allclose(quaternion_xyzw(matrix), _scipy(matrix), atol=1e-15)


def test_a_solved_frame_does_not_need_scipy(monkeypatch):
    """A solved end-disk frame (orthonormal to ~1e-11 only) is projected without scipy."""
    solved = Rotation.from_rotvec([0.2, 0.4, -0.1]).as_matrix() * (1.0 + 7e-12)
    solved[0, 1] += 3e-12
    expected = _scipy(solved)

    def refuse(*_):
        raise AssertionError('scipy was called')

    monkeypatch.setattr(Rotation, 'from_matrix', refuse)
    np.testing.assert_allclose(quaternion_xyzw(solved), expected, rtol=0.0, atol=1e-15)


def test_improper_matrix_is_refused():
    """A reflection is not a rotation: scipy's ValueError."""
    with pytest.raises(ValueError):
        quaternion_xyzw(np.diag([1.0, 1.0, -1.0]))


def test_rotation_of_quaternion_is_scipys_and_inverts_quaternion_xyzw():
    """The matrix of a unit quaternion equals scipy's, and quaternion_xyzw gives it back."""
    for seed in range(20):
        quaternion = Rotation.random(random_state=seed).as_quat()
        matrix = rotation_of_quaternion(quaternion)
        assert np.allclose(matrix, Rotation.from_quat(quaternion).as_matrix(), atol=1e-15)
        back = quaternion_xyzw(matrix)
        assert np.allclose(back, quaternion if quaternion[3] >= 0 else -quaternion,
                           atol=1e-14)


@pytest.mark.parametrize('scale', [0.0, 1e-12, 1e-9, 1e-6, 0.3, 3.0])
def test_rotation_of_vector_is_scipys(scale):
    """The matrix of a rotation vector equals scipy's, small angles included."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        vector = scale * rng.normal(size=3)
        assert np.allclose(rotation_of_vector(vector), Rotation.from_rotvec(vector).as_matrix(),
                           rtol=0.0, atol=1e-15)
