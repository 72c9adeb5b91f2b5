"""COLMAP's two-view geometry as a seed-map baseline (row ``COLMAP (real)``).

On each frame of a batch, pycolmap's calibrated two-view estimator (the one COLMAP's geometric
verification runs: E, F and H RANSAC, then a configuration: CALIBRATED, PLANAR, PANORAMIC,
DEGENERATE...) runs on the selector's KLT tracks from the batch's first frame. It fires on the
first pair classified CALIBRATED or PLANAR with at least :data:`MIN_INLIERS` inliers and a
median triangulation angle of at least :data:`MIN_TRI_ANGLE_DEG`; its relative pose
(``cam2_from_cam1``) is judged, and its inliers, triangulated with that pose, are the map.
COLMAP's options are its defaults, except that the relative pose is computed and the RANSAC
seed is fixed (runs repeat exactly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.geometry import triangulate_pair

#: Acceptance of COLMAP's pair: inliers, and median triangulation angle (degrees).
MIN_INLIERS = 50
MIN_TRI_ANGLE_DEG = 1.0
#: Configurations that fire (COLMAP's names).
FIRING = ('CALIBRATED', 'PLANAR')
#: Reprojection cut-off of the triangulated inliers kept as the map, pixels.
MAX_REPROJECTION_PX = 4.0


@dataclass(frozen=True)
class ColmapPair:
    """COLMAP's verdict on one pair.

    Attributes:
        config: the configuration's name ('CALIBRATED', 'PLANAR', 'DEGENERATE'...).
        n_inliers: inlier matches of that configuration.
        tri_angle_deg: median triangulation angle (NaN without a pose).
        R: (3, 3) rotation, ``x_cur = R x_ref + t`` (None without a pose).
        t: (3,) unit translation (None without a pose).
        inliers: indices of the inlier correspondences.
    """

    config: str
    n_inliers: int
    tri_angle_deg: float
    R: np.ndarray | None
    t: np.ndarray | None
    inliers: np.ndarray

    @property
    def fires(self) -> bool:
        """CALIBRATED or PLANAR, enough inliers, enough triangulation angle."""
        return (
            self.config in FIRING
            and self.R is not None
            and self.n_inliers >= MIN_INLIERS
            and self.tri_angle_deg >= MIN_TRI_ANGLE_DEG
        )


def _camera(intrinsics: Intrinsics):
    import pycolmap

    return pycolmap.Camera(
        model='PINHOLE',
        width=intrinsics.width,
        height=intrinsics.height,
        params=[intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy],
    )


def two_view_geometry(p0: np.ndarray, p1: np.ndarray, intrinsics: Intrinsics) -> ColmapPair:
    """COLMAP's calibrated two-view geometry of undistorted correspondences.

    Raises:
        ImportError: pycolmap is not installed (``pip install -e .[test]``).
    """
    import pycolmap

    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 2)
    options = pycolmap.TwoViewGeometryOptions()
    options.compute_relative_pose = True
    options.ransac.random_seed = 0
    camera = _camera(intrinsics)
    matches = np.repeat(np.arange(len(p0), dtype=np.uint32)[:, None], 2, axis=1)
    if len(p0) < 8:
        return ColmapPair('DEGENERATE', 0, math.nan, None, None, np.zeros(0, int))
    geometry = pycolmap.estimate_calibrated_two_view_geometry(
        camera, p0, camera, p1, matches, options
    )
    config = pycolmap.TwoViewGeometryConfiguration(geometry.config).name
    inliers = np.asarray(geometry.inlier_matches, dtype=np.int64).reshape(-1, 2)[:, 0]
    pose = geometry.cam2_from_cam1 if config in (*FIRING, 'PANORAMIC') else None
    if pose is None:
        return ColmapPair(config, len(inliers), math.nan, None, None, inliers)
    R = np.asarray(pose.rotation.matrix(), dtype=np.float64)
    t = np.asarray(pose.translation, dtype=np.float64).reshape(3)
    norm = float(np.linalg.norm(t))
    t = t / norm if norm > 0 else t
    return ColmapPair(config, len(inliers), math.degrees(geometry.tri_angle), R, t, inliers)


def colmap_attempt(p0: np.ndarray, p1: np.ndarray, intrinsics: Intrinsics):
    """The seed-map hit ``(config, R, t, points, pixels_ref)`` of one pair, or None."""
    pair = two_view_geometry(p0, p1, intrinsics)
    if not pair.fires:
        return None
    a, b = p0[pair.inliers], p1[pair.inliers]
    tri = triangulate_pair(pair.R, pair.t, intrinsics.K, a, b)
    good = tri.in_front & (tri.reprojection_px <= MAX_REPROJECTION_PX)
    return pair.config, pair.R, pair.t, tri.points[good], a[good]


__all__ = [
    'FIRING',
    'MIN_INLIERS',
    'MIN_TRI_ANGLE_DEG',
    'ColmapPair',
    'colmap_attempt',
    'two_view_geometry',
]
