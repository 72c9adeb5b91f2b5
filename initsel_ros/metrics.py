"""Evaluation metrics against ground truth: translation direction, rotation, reconstruction.

The labels (``learn/labels.py``), the seed-map judge (``learn/seedmap.py``), the robustness
studies and the demo measure estimates with these; the live pipeline never does (it has no
ground truth). Poses follow OpenCV: ``x_cur = R @ x_ref + t``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import rotation_angle_deg

_EPS = 1e-12


def translation_chordal_error(t_gt: np.ndarray, t_est: np.ndarray) -> float:
    """Normalized translational chordal distance ``|t_g/|t_g| - t_e/|t_e||``, in [0, 2].

    Returns NaN when either translation is (numerically) zero: its direction is undefined,
    as for a pure rotation.
    """
    g = np.asarray(t_gt, dtype=np.float64).reshape(3)
    e = np.asarray(t_est, dtype=np.float64).reshape(3)
    ng, ne = np.linalg.norm(g), np.linalg.norm(e)
    if ng < 1e-9 or ne < 1e-9 or not (np.isfinite(ng) and np.isfinite(ne)):
        return float('nan')
    return float(np.linalg.norm(g / ng - e / ne))


def reconstruction_error(
    points_gt: np.ndarray, points_est: np.ndarray, scale: str = 'first_two'
) -> float:
    """Median scaled reconstruction error ``median_i |P_g,i - s P_e,i|``.

    Args:
        points_gt: (M, 3) ground-truth points, reference camera frame, metres.
        points_est: (M, 3) estimated points, same order and frame, arbitrary scale.
        scale: ``'first_two'`` (the paper: ``s = |P_g,0 - P_g,1| / |P_e,0 - P_e,1|``) or
            ``'median'`` (robust: median over points of ``|P_g,i| / |P_e,i|``, distances
            from the reference camera centre).

    Returns:
        The error in the ground truth's unit (metres); NaN when it is undefined (fewer
        than two points, or a zero scale denominator).
    """
    g = np.asarray(points_gt, dtype=np.float64).reshape(-1, 3)
    e = np.asarray(points_est, dtype=np.float64).reshape(-1, 3)
    if g.shape != e.shape:
        raise GeometryError(f'point sets differ in shape: {g.shape} vs {e.shape}')
    if g.shape[0] < 2:
        return float('nan')
    if scale == 'first_two':
        den = np.linalg.norm(e[0] - e[1])
        if den < _EPS:
            return float('nan')
        s = np.linalg.norm(g[0] - g[1]) / den
    elif scale == 'median':
        ne = np.linalg.norm(e, axis=1)
        ok = ne > _EPS
        if not ok.any():
            return float('nan')
        s = float(np.median(np.linalg.norm(g[ok], axis=1) / ne[ok]))
    else:
        raise GeometryError(f"scale must be 'first_two' or 'median', got {scale!r}")
    return float(np.median(np.linalg.norm(g - s * e, axis=1)))


def relative_pose(T_w_ref: np.ndarray, T_w_cur: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative pose between two camera-to-world poses, in OpenCV's convention.

    Args:
        T_w_ref: (4, 4) reference camera to world.
        T_w_cur: (4, 4) current camera to world.

    Returns:
        ``(R, t)`` with ``x_cur = R @ x_ref + t``; ``|t|`` is the baseline in world units.
    """
    A = np.asarray(T_w_ref, dtype=np.float64)
    B = np.asarray(T_w_cur, dtype=np.float64)
    if A.shape != (4, 4) or B.shape != (4, 4):
        raise GeometryError('poses must be (4, 4) matrices')
    R = B[:3, :3].T @ A[:3, :3]
    t = B[:3, :3].T @ (A[:3, 3] - B[:3, 3])
    return R, t


def rotation_error_deg(R_gt: np.ndarray, R_est: np.ndarray) -> float:
    """Angle of ``R_gt^T R_est``: how far an estimated rotation is from the truth, degrees."""
    return rotation_angle_deg(np.asarray(R_gt, dtype=np.float64).T @ np.asarray(R_est))


def finite_median(values: Iterable[float]) -> float:
    """Median of the finite values; NaN when there is none."""
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def depth_error(points: np.ndarray, true_depth: np.ndarray) -> float:
    """Median relative depth error of map points after one scale.

    Args:
        points: (M, 3) map points, reference camera frame (any scale).
        true_depth: (M,) their true depths, metres (NaN or <= 0 = unknown; see
            ``learn.labels.true_depths`` for reading them off a depth map).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    z_gt = np.asarray(true_depth, dtype=np.float64).reshape(-1)
    if len(points) == 0 or len(z_gt) != len(points):
        return math.nan
    z = points[:, 2]
    with np.errstate(invalid='ignore'):
        ok = np.isfinite(z_gt) & (z_gt > 0) & (z > 0)
    if ok.sum() < 3:
        return math.nan
    s = float(np.median(z_gt[ok] / z[ok]))
    return float(np.median(np.abs(s * z[ok] - z_gt[ok]) / z_gt[ok]))


__all__ = [
    'depth_error',
    'finite_median',
    'reconstruction_error',
    'relative_pose',
    'rotation_error_deg',
    'translation_chordal_error',
]
