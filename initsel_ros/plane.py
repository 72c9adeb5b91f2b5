"""The points of a homography's seed map that lie on its plane, placed on it.

An H initialization says the tracks are a plane, yet its two-view triangulation places each
point on its own: along the ray, a point's depth is as uncertain as the tracking noise over
its parallax (a few per cent at one degree). Fitting one plane to the points and moving those
that the two views cannot tell from it onto it is the estimate of their depth that the plane
model implies; points off the plane by more than their own uncertainty keep their depth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from initsel_ros.geometry import ray_parallax_rad

#: A point whose depth differs from the plane's by more than this many of its own standard
#: deviations is off the plane and keeps its own depth.
PLANE_MAX_SIGMA = 3.0
#: Fewer points than this on the plane leave everything as it was (no plane worth fitting).
PLANE_MIN_POINTS = 10
#: Refits of the plane on the points that agree with it.
_REFITS = 2


@dataclass(frozen=True)
class PlaneFit:
    """Result of :func:`snap_to_plane`.

    Attributes:
        points: (M, 3) the points, those on the plane moved onto it along their rays.
        on_plane: (M,) bool, the points moved.
        normal_over_distance: (3,) ``n / d`` of the plane ``n . X = d`` in the points' frame
            (NaN when no plane was fitted).
    """

    points: np.ndarray
    on_plane: np.ndarray
    normal_over_distance: np.ndarray


def depth_sigma(
    points: np.ndarray, R: np.ndarray, t: np.ndarray, noise_px: float, focal_px: float
) -> np.ndarray:
    """(M,) first-order relative standard deviation of each point's two-view depth:
    ``sqrt(2) noise / (focal x parallax)``, the tracking noise of both images over the angle
    between the two rays (radians). ``R, t``: reference to current camera."""
    parallax = ray_parallax_rad(points, R, t)
    with np.errstate(divide='ignore'):
        return np.sqrt(2.0) * noise_px / (focal_px * parallax)


def snap_to_plane(
    points: np.ndarray, sigma: np.ndarray, max_sigma: float = PLANE_MAX_SIGMA
) -> PlaneFit:
    """Fit one plane to ``points`` (M, 3; camera frame, in front) and move the points that
    agree with it, within ``max_sigma`` of their own relative depth uncertainty ``sigma``
    (M,; :func:`depth_sigma`), onto it along their rays.

    The plane ``X . p = 1`` is fitted by least squares weighted by ``1 / sigma``, for which
    ``X_i . p - 1`` is the relative difference between a point's depth and the plane's along
    its ray; the points within ``max_sigma`` of it refit it, twice. Points behind the camera,
    a non-finite uncertainty, a plane through the camera centre or too few points on the plane
    leave everything as it was.
    """
    points = np.asarray(points, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    unchanged = PlaneFit(points, np.zeros(len(points), bool), np.full(3, np.nan))
    usable = np.isfinite(sigma) & (sigma > 0) & np.all(np.isfinite(points), axis=1)
    usable &= points[:, 2] > 0
    keep = usable.copy()
    p = np.full(3, np.nan)
    for _ in range(_REFITS + 1):
        if keep.sum() < PLANE_MIN_POINTS:
            return unchanged
        w = 1.0 / sigma[keep]
        p = np.linalg.lstsq(points[keep] * w[:, None], w, rcond=None)[0]
        with np.errstate(invalid='ignore'):
            keep = usable & (np.abs(points @ p - 1.0) <= max_sigma * sigma)
    rays = points / np.where(points[:, 2:3] > 0, points[:, 2:3], 1.0)
    inverse_depth = rays @ p
    keep &= inverse_depth > 0
    if keep.sum() < PLANE_MIN_POINTS or not np.all(np.isfinite(p)):
        return unchanged
    snapped = points.copy()
    snapped[keep] = rays[keep] / inverse_depth[keep, None]
    return PlaneFit(snapped, keep, p)


__all__ = ['PLANE_MAX_SIGMA', 'PLANE_MIN_POINTS', 'PlaneFit', 'depth_sigma', 'snap_to_plane']
