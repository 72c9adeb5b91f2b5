"""Rotations, quaternions and pose matrices, on ``scipy.spatial.transform.Rotation``.

Conventions: quaternions are ``(x, y, z, w)`` (TUM's ``groundtruth.txt``, ROS messages and
scipy all use this order); poses are (4, 4) matrices, positions in metres. Every function
takes one item or a stack (leading axis N) and returns the same.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from initsel_ros.errors import GeometryError


def _rotations_from_quaternions(q: np.ndarray) -> Rotation:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (4,) or q.ndim > 2:
        raise GeometryError(f'quaternions must have shape (4,) or (N, 4), got {q.shape}')
    norm = np.linalg.norm(q, axis=-1)
    if np.any(~np.isfinite(norm)):
        raise GeometryError('quaternion with a non-finite component')
    if np.any(norm < 1e-12):
        raise GeometryError('quaternion with zero norm')
    return Rotation.from_quat(q)  # normalizes


def normalize_quaternions(q: np.ndarray) -> np.ndarray:
    """Unit quaternions: (4,) or (N, 4) in, float64 out (GeometryError on a zero norm)."""
    q = np.asarray(q, dtype=np.float64)
    _rotations_from_quaternions(q)  # the checks
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """(4,) or (N, 4) quaternions xyzw (any norm > 0) -> (3, 3) or (N, 3, 3) rotations."""
    return _rotations_from_quaternions(q).as_matrix()


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(3, 3) or (N, 3, 3) rotation matrices -> unit quaternions xyzw with ``w >= 0``."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3) or R.ndim > 3:
        raise GeometryError(
            f'rotation matrices must have shape (3, 3) or (N, 3, 3), got {R.shape}'
        )
    return Rotation.from_matrix(R).as_quat(canonical=True)


def pose_matrix(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(4, 4) pose from a position (3,) and a quaternion (4,) xyzw; (N, 3), (N, 4) -> (N, 4, 4)."""
    t = np.asarray(t, dtype=np.float64)
    R = quaternion_to_matrix(q)
    T = np.zeros((*R.shape[:-2], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def matrix_to_pose(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`pose_matrix`: ``(t (..., 3), q (..., 4) xyzw, w >= 0)``."""
    T = np.asarray(T, dtype=np.float64)
    return T[..., :3, 3].copy(), matrix_to_quaternion(T[..., :3, :3])


def slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation between pairs of rotations, along the shorter arc.

    Args:
        q0: (N, 4) quaternions xyzw at ``alpha = 0``.
        q1: (N, 4) quaternions xyzw at ``alpha = 1``.
        alpha: (N,) fractions in [0, 1].

    Returns:
        (N, 4) unit quaternions xyzw with ``w >= 0``.
    """
    r0 = _rotations_from_quaternions(np.atleast_2d(q0))
    r1 = _rotations_from_quaternions(np.atleast_2d(q1))
    alpha = np.asarray(alpha, dtype=np.float64).reshape(-1, 1)
    step = (r0.inv() * r1).as_rotvec()  # the shorter arc: angle at most pi
    return (r0 * Rotation.from_rotvec(alpha * step)).as_quat(canonical=True)


__all__ = [
    'matrix_to_pose',
    'matrix_to_quaternion',
    'normalize_quaternions',
    'pose_matrix',
    'quaternion_to_matrix',
    'slerp',
]
