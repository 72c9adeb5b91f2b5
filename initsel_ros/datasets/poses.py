"""Quaternions, pose matrices and trajectory interpolation (numpy only).

Conventions: quaternions are ``(x, y, z, w)`` as in TUM's ``groundtruth.txt``; poses are
camera-to-world (4, 4) matrices ``T_w_c`` with positions in metres and times in seconds.
"""

from __future__ import annotations

import numpy as np

from initsel_ros.errors import GeometryError

#: Default largest gap (seconds) between the two ground-truth samples bracketing a query time.
DEFAULT_MAX_GAP = 0.1


def normalize_quaternions(q: np.ndarray) -> np.ndarray:
    """Unit quaternions; (..., 4) in, (..., 4) float64 out. Raises GeometryError on zero norm."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4:
        raise GeometryError(f'quaternions must have shape (..., 4), got {q.shape}')
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise GeometryError('quaternion with zero norm')
    return q / norm


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from quaternions.

    Args:
        q: (4,) or (N, 4) quaternions ``(x, y, z, w)``; normalized here.

    Returns:
        (3, 3) or (N, 3, 3) float64 rotation matrices.
    """
    q = normalize_quaternions(q)
    x, y, z, w = np.moveaxis(q, -1, 0)
    R = np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - z * w),
            2 * (x * z + y * w),
            2 * (x * y + z * w),
            1 - 2 * (x * x + z * z),
            2 * (y * z - x * w),
            2 * (x * z - y * w),
            2 * (y * z + x * w),
            1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return R.reshape((*q.shape[:-1], 3, 3))


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Quaternions ``(x, y, z, w)`` with ``w >= 0`` from rotation matrices.

    Args:
        R: (3, 3) or (N, 3, 3) rotation matrices.

    Returns:
        (4,) or (N, 4) float64 unit quaternions.
    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise GeometryError(f'rotation matrices must have shape (..., 3, 3), got {R.shape}')
    batch = R.reshape(-1, 3, 3)
    m = batch
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    # Four candidate formulas; pick per matrix the one with the largest pivot (stable).
    cand = np.stack(
        [
            np.stack(
                [
                    m[:, 2, 1] - m[:, 1, 2],
                    m[:, 0, 2] - m[:, 2, 0],
                    m[:, 1, 0] - m[:, 0, 1],
                    1 + trace,
                ],
                axis=-1,
            ),
            np.stack(
                [
                    1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
                    m[:, 0, 1] + m[:, 1, 0],
                    m[:, 0, 2] + m[:, 2, 0],
                    m[:, 2, 1] - m[:, 1, 2],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[:, 0, 1] + m[:, 1, 0],
                    1 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2],
                    m[:, 1, 2] + m[:, 2, 1],
                    m[:, 0, 2] - m[:, 2, 0],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[:, 0, 2] + m[:, 2, 0],
                    m[:, 1, 2] + m[:, 2, 1],
                    1 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1],
                    m[:, 1, 0] - m[:, 0, 1],
                ],
                axis=-1,
            ),
        ],
        axis=1,
    )  # (N, 4 candidates, 4)
    pivots = np.stack(
        [
            1 + trace,
            1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
            1 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2],
            1 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1],
        ],
        axis=-1,
    )
    best = np.argmax(pivots, axis=-1)
    q = cand[np.arange(len(batch)), best]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.where(q[:, 3:4] < 0, -q, q)
    return q.reshape((*R.shape[:-2], 4))


def pose_matrix(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Camera-to-world (4, 4) matrix from a position (3,) metres and a quaternion (4,) xyzw.

    Also vectorized: (N, 3) and (N, 4) give (N, 4, 4).
    """
    t = np.asarray(t, dtype=np.float64)
    R = quaternion_to_matrix(q)
    T = np.zeros((*R.shape[:-2], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def matrix_to_pose(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`pose_matrix`: ``(t (.., 3), q (.., 4) xyzw)``."""
    T = np.asarray(T, dtype=np.float64)
    return T[..., :3, 3].copy(), matrix_to_quaternion(T[..., :3, :3])


def slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation, vectorized.

    Args:
        q0, q1: (N, 4) unit quaternions xyzw.
        alpha: (N,) fractions in [0, 1].

    Returns:
        (N, 4) unit quaternions.
    """
    q0 = normalize_quaternions(q0)
    q1 = normalize_quaternions(q1)
    alpha = np.asarray(alpha, dtype=np.float64)[:, None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)  # shortest path
    dot = np.abs(dot).clip(max=1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-9
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1 - alpha, np.sin((1 - alpha) * theta) / safe)
    w1 = np.where(small, alpha, np.sin(alpha * theta) / safe)
    return normalize_quaternions(w0 * q0 + w1 * q1)


def interpolate_poses(
    query_times: np.ndarray,
    stamps: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    max_gap: float = DEFAULT_MAX_GAP,
    nearest_tolerance: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate a trajectory at query times (linear position, slerp rotation).

    Args:
        query_times: (M,) seconds.
        stamps: (N,) seconds, strictly increasing after sorting (sorted here).
        positions: (N, 3) metres.
        quaternions: (N, 4) xyzw.
        max_gap: a query is interpolated only if the two bracketing samples are at most this
            far apart (seconds).
        nearest_tolerance: a query outside the trajectory (or in a too-large gap) takes the
            nearest sample if that is within this many seconds; 0 disables it.

    Returns:
        ``(positions (M, 3), quaternions (M, 4))``; rows are NaN where no pose is available.
    """
    query = np.atleast_1d(np.asarray(query_times, dtype=np.float64))
    stamps = np.asarray(stamps, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    quaternions = normalize_quaternions(np.asarray(quaternions).reshape(-1, 4))
    if not (len(stamps) == len(positions) == len(quaternions)):
        raise GeometryError(
            f'trajectory arrays disagree: {len(stamps)} stamps, {len(positions)} positions, '
            f'{len(quaternions)} quaternions'
        )
    out_t = np.full((len(query), 3), np.nan)
    out_q = np.full((len(query), 4), np.nan)
    if len(stamps) == 0 or len(query) == 0:
        return out_t, out_q
    order = np.argsort(stamps, kind='stable')
    stamps, positions, quaternions = stamps[order], positions[order], quaternions[order]

    hi = np.searchsorted(stamps, query, side='left')
    exact = (hi < len(stamps)) & (stamps[np.minimum(hi, len(stamps) - 1)] == query)
    lo = hi - 1
    inside = (lo >= 0) & (hi < len(stamps))
    lo_c = np.clip(lo, 0, len(stamps) - 1)
    hi_c = np.clip(hi, 0, len(stamps) - 1)
    gap = stamps[hi_c] - stamps[lo_c]
    ok = inside & (gap <= max_gap) & (gap > 0)
    if np.any(ok):
        a = (query[ok] - stamps[lo_c[ok]]) / gap[ok]
        out_t[ok] = (1 - a)[:, None] * positions[lo_c[ok]] + a[:, None] * positions[hi_c[ok]]
        out_q[ok] = slerp(quaternions[lo_c[ok]], quaternions[hi_c[ok]], a)
    out_t[exact] = positions[hi_c[exact]]
    out_q[exact] = quaternions[hi_c[exact]]
    if nearest_tolerance > 0:
        missing = np.isnan(out_t[:, 0])
        if np.any(missing):
            d_lo = np.where(lo >= 0, np.abs(query - stamps[lo_c]), np.inf)
            d_hi = np.where(hi < len(stamps), np.abs(stamps[hi_c] - query), np.inf)
            nearest = np.where(d_lo <= d_hi, lo_c, hi_c)
            close = missing & (np.minimum(d_lo, d_hi) <= nearest_tolerance)
            out_t[close] = positions[nearest[close]]
            out_q[close] = quaternions[nearest[close]]
    return out_t, out_q


def interpolate_pose_matrices(
    query_times: np.ndarray,
    stamps: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    max_gap: float = DEFAULT_MAX_GAP,
    nearest_tolerance: float = 0.0,
) -> list[np.ndarray | None]:
    """Like :func:`interpolate_poses` but returns one (4, 4) camera-to-world or None per query."""
    t, q = interpolate_poses(
        query_times, stamps, positions, quaternions, max_gap, nearest_tolerance
    )
    valid = ~np.isnan(t[:, 0])
    out: list[np.ndarray | None] = [None] * len(t)
    if np.any(valid):
        mats = pose_matrix(t[valid], q[valid])
        for k, i in enumerate(np.flatnonzero(valid)):
            out[i] = mats[k]
    return out


__all__ = [
    'DEFAULT_MAX_GAP',
    'interpolate_pose_matrices',
    'interpolate_poses',
    'matrix_to_pose',
    'matrix_to_quaternion',
    'normalize_quaternions',
    'pose_matrix',
    'quaternion_to_matrix',
    'slerp',
]
