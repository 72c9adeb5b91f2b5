"""The points of a homography's seed map that lie on its plane, placed on it.

An H initialization says the tracks are a plane, yet its two-view triangulation places each
point on its own: along the ray, a point's depth is as uncertain as the tracking noise over
its parallax (a few per cent at one degree). Fitting one plane to the points and moving those
that agree with it to within the noise onto it is the estimate of their depth that the plane
model implies; points off the plane by more than the noise keep their own depth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A point whose depth differs from the plane's by more than this many robust standard
#: deviations of all the points' differences is off the plane and keeps its own depth.
PLANE_MAX_SIGMA = 3.0
#: Fewer points than this are left as they are (no plane worth fitting).
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
        depth_sigma: robust standard deviation of all the points' relative depth differences
            from the first plane fitted to them (NaN when no plane was fitted).
    """

    points: np.ndarray
    on_plane: np.ndarray
    normal_over_distance: np.ndarray
    depth_sigma: float


def snap_to_plane(points: np.ndarray, max_sigma: float = PLANE_MAX_SIGMA) -> PlaneFit:
    """Fit one plane to ``points`` (M, 3; camera frame, in front) and move the points that
    agree with it onto it.

    The plane ``X . p = 1`` is fitted by least squares, for which ``X_i . p - 1`` is the
    relative difference between a point's depth and the plane's along its ray; points within
    ``max_sigma`` robust standard deviations (1.4826 x the median absolute deviation) of the
    median difference are kept and the plane refitted on them, twice; the points kept after
    the last fit move onto it. Points behind the camera, a plane through the
    camera centre or too few points leave everything as it was.
    """
    points = np.asarray(points, dtype=np.float64)
    unchanged = PlaneFit(points, np.zeros(len(points), bool), np.full(3, np.nan), float('nan'))
    if len(points) < PLANE_MIN_POINTS or not np.all(points[:, 2] > 0):
        return unchanged
    keep = np.ones(len(points), bool)
    sigma = float('nan')
    for fit in range(_REFITS + 1):
        if keep.sum() < PLANE_MIN_POINTS:
            return unchanged
        p = np.linalg.lstsq(points[keep], np.ones(int(keep.sum())), rcond=None)[0]
        difference = points @ p - 1.0
        centre = float(np.median(difference[keep]))
        spread = 1.4826 * float(np.median(np.abs(difference[keep] - centre)))
        if fit == 0:
            sigma = spread  # the spread of all the points, before any is left out
        keep = np.abs(difference - centre) <= max_sigma * max(spread, 1e-12)
    rays = points / points[:, 2:3]
    inverse_depth = rays @ p
    keep &= inverse_depth > 0
    if keep.sum() < PLANE_MIN_POINTS or not np.all(np.isfinite(p)):
        return unchanged
    snapped = points.copy()
    snapped[keep] = rays[keep] / inverse_depth[keep, None]
    return PlaneFit(snapped, keep, p, sigma)


__all__ = ['PLANE_MAX_SIGMA', 'PLANE_MIN_POINTS', 'PlaneFit', 'snap_to_plane']
