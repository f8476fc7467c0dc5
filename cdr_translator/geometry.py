"""Frames, bending angles and circular-arc fits: pure functions on numpy arrays (SI, rad)."""

import math
from typing import Tuple

import numpy as np
from scipy.spatial.transform import Rotation

from ._jit import jit

#: Below this tilt (rad) the bending direction is undefined and reported as 0.
_STRAIGHT_TILT = 1e-12

#: quaternion_xyzw projects a matrix whose m m^T is within this of the identity itself ...
PROJECTION_RANGE = 1e-3
#: ... in at most this many Newton-Schulz steps (error 1e-3 -> 1e-6 -> 1e-12 -> rounding).
PROJECTION_STEPS = 4


@jit
def _bending_of_axis(x: float, y: float, z: float) -> Tuple[float, float]:
    """Bending angle and direction of a joint whose distal z axis is (x, y, z) (rad)."""
    sideways = math.hypot(x, y)
    theta = math.atan2(sideways, z)
    delta = math.atan2(y, x) if sideways > _STRAIGHT_TILT else 0.0
    return theta, delta


def bending_angle_and_direction(rotation: np.ndarray) -> Tuple[float, float]:
    """
    Bending angle theta and bending-plane direction delta of a joint (rad).

    theta is the tilt of the distal z axis from the proximal z axis, delta the azimuth
    of that tilt about the proximal z axis, measured from x (the standard continuum-joint
    parameterization, R = Rz(delta) Ry(theta) Rz(-delta) for a joint without twist).
    """
    x, y, z = np.asarray(rotation, dtype=float)[:, 2].tolist()
    return _bending_of_axis(x, y, z)


@jit
def bending_between_frames(frame_a: np.ndarray, frame_b: np.ndarray) -> Tuple[float, float]:
    """``bending_between``'s work: the z axis of R_a^T R_b is R_a^T times b's z axis."""
    axis = [frame_a[0, row] * frame_b[0, 2] + frame_a[1, row] * frame_b[1, 2]
            + frame_a[2, row] * frame_b[2, 2] for row in range(3)]
    return _bending_of_axis(axis[0], axis[1], axis[2])


def bending_between(frame_a: np.ndarray, frame_b: np.ndarray) -> Tuple[float, float]:
    """
    Bending angle and direction of frame b relative to frame a (4x4 or 3x3; rad).

    ``bending_angle_and_direction(relative_rotation(frame_a, frame_b))`` in one compiled
    call: a SolveResult's joint angles are read once per wrench on the node's path.
    """
    return bending_between_frames(np.ascontiguousarray(frame_a, dtype=float),
                                  np.ascontiguousarray(frame_b, dtype=float))


def rotation_angle(rotation: np.ndarray) -> float:
    """Total rotation angle of a rotation matrix (rad, in [0, pi])."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = np.asarray(rotation, float).tolist()
    sine = 0.5 * math.sqrt((m21 - m12) ** 2 + (m02 - m20) ** 2 + (m10 - m01) ** 2)
    return math.atan2(sine, 0.5 * (m00 + m11 + m22 - 1.0))  # plain floats: 2 us, not 15


def relative_rotation(frame_a: np.ndarray, frame_b: np.ndarray) -> np.ndarray:
    """Rotation of 4x4 frame b relative to 4x4 frame a, R_a^T R_b."""
    return frame_a[:3, :3].T @ frame_b[:3, :3]


@jit
def _gram(m: np.ndarray) -> Tuple[float, float, float, float, float, float]:
    """Return m m^T - I of a 3x3 matrix as (xx, yy, zz, xy, xz, yz)."""
    return (m[0, 0] ** 2 + m[0, 1] ** 2 + m[0, 2] ** 2 - 1.0,
            m[1, 0] ** 2 + m[1, 1] ** 2 + m[1, 2] ** 2 - 1.0,
            m[2, 0] ** 2 + m[2, 1] ** 2 + m[2, 2] ** 2 - 1.0,
            m[0, 0] * m[1, 0] + m[0, 1] * m[1, 1] + m[0, 2] * m[1, 2],
            m[0, 0] * m[2, 0] + m[0, 1] * m[2, 1] + m[0, 2] * m[2, 2],
            m[1, 0] * m[2, 0] + m[1, 1] * m[2, 1] + m[1, 2] * m[2, 2])


@jit
def _orthonormal(m: np.ndarray) -> bool:
    """Say whether m m^T is the identity within scipy's tolerance (1e-12, 1e-5 on the diagonal)."""
    xx, yy, zz, xy, xz, yz = _gram(m)
    diagonal = 1e-12 + 1e-5
    return (abs(xx) <= diagonal and abs(yy) <= diagonal and abs(zz) <= diagonal
            and abs(xy) <= 1e-12 and abs(xz) <= 1e-12 and abs(yz) <= 1e-12)


@jit
def quaternion_of_rotation(rotation: np.ndarray, quaternion: np.ndarray) -> bool:
    """
    Write the (x, y, z, w >= 0) quaternion of ``rotation`` into ``quaternion``; say if it could.

    scipy's Rotation.from_matrix algorithm for one matrix: the largest of the diagonal and
    the trace picks the numerically safe formula. A matrix off SO(3) by up to
    PROJECTION_RANGE is first taken to its polar factor by Newton-Schulz steps,
    (3 I - m m^T) m / 2, which converge quadratically (a solved end-disk frame,
    orthonormal to about 1e-11 after the rod integration, needs one); False when it is
    further off, improper, or still off SO(3) after PROJECTION_STEPS.
    """
    m = rotation.copy()
    determinant = (m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
                   - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
                   + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]))
    if not (max([abs(value) for value in _gram(m)]) <= PROJECTION_RANGE and determinant > 0.0):
        return False
    for _ in range(PROJECTION_STEPS):
        if _orthonormal(m):
            break
        xx, yy, zz, xy, xz, yz = _gram(m)
        factor = np.array([[1.0 - 0.5 * xx, -0.5 * xy, -0.5 * xz],
                           [-0.5 * xy, 1.0 - 0.5 * yy, -0.5 * yz],
                           [-0.5 * xz, -0.5 * yz, 1.0 - 0.5 * zz]])
        m = factor @ m
    if not _orthonormal(m):
        return False
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if m[0, 0] >= max(m[1, 1], m[2, 2], trace):
        values = (1.0 - trace + 2.0 * m[0, 0], m[1, 0] + m[0, 1], m[2, 0] + m[0, 2],
                  m[2, 1] - m[1, 2])
    elif m[1, 1] >= max(m[2, 2], trace):
        values = (m[1, 0] + m[0, 1], 1.0 - trace + 2.0 * m[1, 1], m[2, 1] + m[1, 2],
                  m[0, 2] - m[2, 0])
    elif m[2, 2] >= trace:
        values = (m[2, 0] + m[0, 2], m[2, 1] + m[1, 2], 1.0 - trace + 2.0 * m[2, 2],
                  m[1, 0] - m[0, 1])
    else:
        values = (m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], 1.0 + trace)
    scale = 1.0 / math.sqrt(values[0] ** 2 + values[1] ** 2 + values[2] ** 2 + values[3] ** 2)
    if values[3] < 0.0:
        scale = -scale
    for index in range(4):
        quaternion[index] = values[index] * scale
    return True


def quaternion_xyzw(rotation: np.ndarray) -> np.ndarray:
    """
    Return the unit quaternion (x, y, z, w) of a rotation matrix, w >= 0.

    Compiled (``quaternion_of_rotation``: 1-2 us instead of 0.4-1 ms for scipy's
    Rotation; the node converts one per wrench). A matrix further from a rotation than
    PROJECTION_RANGE, or an improper one, goes to scipy itself, which projects (or
    refuses) it. A matrix with a non-finite entry (the frame of a failed solve) is no
    rotation: its quaternion is NaN, not assessed.
    """
    m = np.ascontiguousarray(rotation, dtype=float)
    if not np.all(np.isfinite(m)):
        return np.full(4, math.nan)
    quaternion = np.empty(4)
    if m.shape == (3, 3) and quaternion_of_rotation(m, quaternion):
        return quaternion
    quaternion = Rotation.from_matrix(m).as_quat()
    return -quaternion if quaternion[3] < 0.0 else quaternion


def rotation_of_quaternion(quaternion_xyzw: np.ndarray) -> np.ndarray:
    """Return the rotation matrix of a unit quaternion (x, y, z, w) (a few us, not scipy's 25)."""
    x, y, z, w = (float(value) for value in quaternion_xyzw)
    return np.array([[1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
                     [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
                     [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)]])


def rotation_of_vector(rotation_vector: np.ndarray) -> np.ndarray:
    """
    Return the rotation matrix of a rotation vector (axis times angle, rad): Rodrigues.

    I + a K + b K^2 with K the vector's cross-product matrix, a = sin(t)/t and
    b = (1 - cos(t))/t^2 (t its length; their limits 1 and 1/2 below 1e-8 rad, exact to
    rounding there); entry by entry on floats, a few microseconds (an estimate moves a
    pose by one per step).
    """
    x, y, z = (float(value) for value in rotation_vector)
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < 1e-8:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(angle) / angle, (1.0 - math.cos(angle)) / angle ** 2
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return np.array([[1.0 - b * (yy + zz), b * xy - a * z, b * xz + a * y],
                     [b * xy + a * z, 1.0 - b * (xx + zz), b * yz - a * x],
                     [b * xz - a * y, b * yz + a * x, 1.0 - b * (xx + yy)]])


#: Points whose second principal spread is below this fraction of the first are a line:
#: far above rounding (1e-15) and far below a real arc (1e-4 for a 1 mrad bend).
STRAIGHT_SPREAD_RATIO = 1e-9


def _fit_plane(points: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centroid, orthonormal axes (in-plane u, v, normal) and principal spreads of the plane."""
    centroid = points.mean(axis=0)
    _, spread, axes = np.linalg.svd(points - centroid)
    return centroid, axes[:2], axes[2], spread


def fit_circle(points: np.ndarray, iterations: int = 20) -> Tuple[np.ndarray, np.ndarray, float]:
    """
    Least-squares circle through 3-D points: (centre, unit normal, radius).

    The plane comes from an SVD, the circle in it from the algebraic (Kasa) fit refined
    by Gauss-Newton on the geometric distances. Returns radius = inf for collinear points.
    """
    centroid, in_plane, normal, spread = _fit_plane(points)
    if spread[1] <= STRAIGHT_SPREAD_RATIO * spread[0]:
        # a rank-deficient algebraic fit would return a finite, meaningless circle
        return centroid, normal, math.inf
    planar = (points - centroid) @ in_plane.T
    design = np.column_stack([2.0 * planar, np.ones(len(planar))])
    target = (planar ** 2).sum(axis=1)
    solution, *_ = np.linalg.lstsq(design, target, rcond=None)
    centre = solution[:2]
    radius_sq = solution[2] + centre @ centre
    chord = float(np.ptp(planar, axis=0).max())
    if not np.all(np.isfinite(solution)) or radius_sq <= 0.0 \
            or radius_sq > (1e6 * max(chord, 1e-300)) ** 2:
        return centroid, normal, math.inf
    radius = math.sqrt(radius_sq)
    for _ in range(iterations):
        offset = planar - centre
        distance = np.linalg.norm(offset, axis=1)
        jac = np.column_stack([-offset / distance[:, None], -np.ones(len(planar))])
        step, *_ = np.linalg.lstsq(jac, -(distance - radius), rcond=None)
        centre = centre + step[:2]
        radius += step[2]
        if np.abs(step).max() < 1e-15 * max(radius, 1.0):
            break
    return centroid + centre @ in_plane, normal, float(radius)


def circle_deviation(points: np.ndarray) -> float:
    """Largest distance of the points from their least-squares circle (or line) (m)."""
    centre, normal, radius = fit_circle(points)
    offset = points - centre
    height = offset @ normal
    if math.isinf(radius):
        _, in_plane, _, _ = _fit_plane(points)
        along = offset @ in_plane[0]
        return float(np.linalg.norm(offset - np.outer(along, in_plane[0]), axis=1).max())
    in_plane_radius = np.linalg.norm(offset - np.outer(height, normal), axis=1)
    return float(np.hypot(in_plane_radius - radius, height).max())
