"""The points of a homography's seed map that lie on its plane, placed on it.

An H initialization says the tracks are a plane, yet its two-view triangulation places each
point on its own: along the ray, a point's depth is as uncertain as the tracking noise over
its parallax (a few per cent at one degree). Fitting one plane to the points and moving those
that the two views cannot tell from it onto it is the estimate of their depth that the plane
model implies; points off the plane by more than their own uncertainty keep their depth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
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


def _weighable(points: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """(M,) bool: the points in front, finite, with a finite positive depth uncertainty."""
    usable = np.isfinite(sigma) & (sigma > 0) & np.all(np.isfinite(points), axis=1)
    return usable & (points[:, 2] > 0)


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
    usable = _weighable(points, sigma)
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


def fit_plane(points: np.ndarray, min_points: int = PLANE_MIN_POINTS) -> np.ndarray | None:
    """``p`` of the plane ``X . p = 1`` through ``points`` (M, 3) by least squares, or None
    (fewer than ``min_points`` finite points in front, or a singular fit)."""
    usable = np.all(np.isfinite(points), axis=1) & (points[:, 2] > 0)
    if np.count_nonzero(usable) < min_points:
        return None
    X = points[usable]
    p, _, rank, _ = np.linalg.lstsq(X, np.ones(len(X)), rcond=None)
    return p if rank == 3 and np.all(np.isfinite(p)) else None


def homography_normals(
    ref_px: np.ndarray, cur_px: np.ndarray, K: np.ndarray, threshold_px: float
) -> np.ndarray:
    """(k, 3) unit plane normals, in the reference camera's frame, of the decompositions of
    the homography fitted (RANSAC) to the pixel pairs ``ref_px -> cur_px`` (N, 2); (0, 3)
    when fewer than :data:`PLANE_MIN_POINTS` pairs or no homography."""
    if len(ref_px) < PLANE_MIN_POINTS:
        return np.zeros((0, 3))
    homography, _ = cv2.findHomography(
        np.asarray(ref_px, np.float32).reshape(-1, 1, 2),
        np.asarray(cur_px, np.float32).reshape(-1, 1, 2),
        cv2.RANSAC,
        threshold_px,
    )
    if homography is None or not np.all(np.isfinite(homography)):
        return np.zeros((0, 3))
    _, _, _, normals = cv2.decomposeHomographyMat(homography, np.asarray(K, np.float64))
    return np.array([np.ravel(n) for n in normals], np.float64).reshape(-1, 3)


@dataclass(frozen=True)
class PlaneNormal:
    """The plane of a map's points and how well two views fix it.

    Attributes:
        normal: (3,) unit normal, in the points' frame.
        sigma_deg: first-order standard deviation of its direction along its least certain
            axis, degrees, from the points' depth uncertainty (:func:`depth_sigma`).
    """

    normal: np.ndarray
    sigma_deg: float


def plane_normal(
    points: np.ndarray, R: np.ndarray, t: np.ndarray, noise_px: float, focal_px: float
) -> PlaneNormal | None:
    """The plane ``X . p = 1`` through ``points`` (M, 3), each weighted by its depth
    uncertainty as two views with pose ``R, t`` (reference to current) and this tracking noise
    measure it, and the uncertainty of its normal's direction: ``Cov(p) = (sum X X^T /
    sigma^2)^-1``, projected across the normal, over ``|p|``. None with fewer than
    :data:`PLANE_MIN_POINTS` usable points or a singular fit."""
    points = np.asarray(points, np.float64)
    sigma = depth_sigma(points, R, t, noise_px, focal_px)
    usable = _weighable(points, sigma)
    if np.count_nonzero(usable) < PLANE_MIN_POINTS:
        return None
    weighted = points[usable] / sigma[usable, None]
    information = weighted.T @ weighted
    try:
        covariance = np.linalg.inv(information)
    except np.linalg.LinAlgError:
        return None
    p = covariance @ (weighted.T @ (1.0 / sigma[usable]))
    size = float(np.linalg.norm(p))
    if not np.all(np.isfinite(covariance)) or not math.isfinite(size) or size == 0.0:
        return None
    normal = p / size
    across = np.eye(3) - np.outer(normal, normal)
    largest = float(np.linalg.eigvalsh(across @ covariance @ across).max())
    return PlaneNormal(normal, math.degrees(math.sqrt(max(largest, 0.0)) / size))


def normal_drift_deg(normal: np.ndarray, normals: np.ndarray) -> float:
    """Angle, degrees, between the unit ``normal`` of a map's plane and the nearest of
    ``normals`` (k, 3; :func:`homography_normals`); NaN without one.

    A seed map of a plane and a later frame's homography describe the same plane when the
    map is right. H's mirrored decomposition fits the fire frame's flow as well, but its
    plane is that frame's alone: the later frames' homographies decompose into the true plane
    and mirrored planes of their own (flying over flat ground, the mirrored map's angle to
    them grew 0.2 -> 1.7 degrees over 15 frames, the right one's stayed under 0.3)."""
    if not len(normals):
        return math.nan
    cosine = float(np.abs(normals @ normal).max())
    return math.degrees(math.acos(min(cosine, 1.0)))


__all__ = [
    'PLANE_MAX_SIGMA',
    'PLANE_MIN_POINTS',
    'PlaneFit',
    'PlaneNormal',
    'depth_sigma',
    'fit_plane',
    'homography_normals',
    'normal_drift_deg',
    'plane_normal',
    'snap_to_plane',
]
