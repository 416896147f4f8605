"""Rotations: matrices, rotation vectors (axis x angle, radians) and unit quaternions."""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray


def rodrigues(r: FloatArray) -> FloatArray:
    """Rotation matrices (N, 3, 3) of rotation vectors ``r`` (N, 3)."""
    theta = np.linalg.norm(r, axis=-1)[:, None, None]
    k = np.zeros((len(r), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    k = k - k.transpose(0, 2, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(theta > 1e-12, np.sin(theta) / theta, 1.0)
        b = np.where(theta > 1e-12, (1 - np.cos(theta)) / theta**2, 0.5)
    return np.eye(3) + a * k + b * (k @ k)


def quaternion(R: FloatArray) -> FloatArray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (3, 3), w >= 0."""
    w = np.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)  # type: ignore[no-any-return]


def rotation_of(q: tuple[float, float, float, float]) -> FloatArray:
    """Rotation matrix (3, 3) of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotation_matrix(r: FloatArray) -> FloatArray:
    """Rotation matrix (3, 3) of one rotation vector ``r`` (3,)."""
    out: FloatArray = rodrigues(np.asarray(r, dtype=np.float64).reshape(1, 3))[0]
    return out


def rotation_vector(R: FloatArray) -> FloatArray:
    """Rotation vector (3,) of a rotation matrix (3, 3)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(c))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-9:
        return w / 2.0
    return w * (theta / (2.0 * np.sin(theta)))  # type: ignore[no-any-return]
