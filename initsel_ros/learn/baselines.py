"""Initialization rules of other systems, as baselines for the learned models.

Three families (numpy/OpenCV only):

- Butt et al. 2020: H is good when the disparity (mean or median) exceeds 50 px; F is good when,
  in addition, the disparity's standard deviation exceeds 15 px. Works on table columns.
- VINS-Mono: more than 20 correspondences with an average parallax above 30 px at a virtual
  focal length of 460 px (the cheap rule), then F-RANSAC on normalized points and
  ``recoverPose``, accepting more than 12 inliers (:func:`vins_relative_pose`).
- ORB-SLAM2/3: H and F RANSAC on the same 200 random 8-point sets, symmetric transfer scores with
  chi-square cut-offs 5.991 (H) / 3.841 (F), H chosen when ``S_H / (S_H + S_F)`` exceeds 0.40
  (ORB-SLAM2) or 0.50 (ORB-SLAM3) (:func:`initsel_ros.orb_slam.orbslam_scores`, re-exported
  here, and :func:`orbslam_choice`).

The correspondence-based baselines run at dataset time (``initsel dataset``) and are stored as
table columns, so evaluation is a matter of thresholds on columns.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import cv2
import numpy as np

# ORB-SLAM's H/F scoring is core code (the selector reports its ratio); re-exported here.
from initsel_ros.orb_slam import CHI2_F, CHI2_H, OrbSlamScores, orbslam_scores

#: VINS-Mono's virtual focal length (pixels).
VINS_FOCAL = 460.0
#: ORB-SLAM's acceptance of a reconstruction: triangulated points, and parallax (degrees).
ORB_MIN_POINTS = 50
ORB_MIN_PARALLAX_DEG = 1.0


class OrbSlamVersion(int, Enum):
    """ORB-SLAM version, for the H-vs-F ratio cut-off."""

    ORB2 = 2
    ORB3 = 3

    @property
    def ratio_threshold(self) -> float:
        """Choose H when ``S_H / (S_H + S_F)`` exceeds this value."""
        return 0.40 if self is OrbSlamVersion.ORB2 else 0.50


# ---------------------------------------------------------------------------------- Butt 2020
def butt_rule(
    disparity_px: np.ndarray,
    std_px: np.ndarray,
    h_threshold_px: float = 50.0,
    f_std_threshold_px: float = 15.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Butt et al. 2020: (H good, F good) per pair.

    Args:
        disparity_px: (N,) mean (the authors' code) or median (the paper's text) disparity,
            pixels.
        std_px: (N,) population standard deviation of the disparity, pixels.

    Returns:
        (N,) bool, (N,) bool: H fires when disparity > ``h_threshold_px``; F fires when, in
        addition, std > ``f_std_threshold_px``.
    """
    disparity_px = np.asarray(disparity_px, dtype=float)
    std_px = np.asarray(std_px, dtype=float)
    h = disparity_px > h_threshold_px
    return h, h & (std_px > f_std_threshold_px)


# ---------------------------------------------------------------------------------- VINS-Mono
@dataclass(frozen=True)
class VinsResult:
    """VINS-Mono's initialization check on one correspondence set.

    Attributes:
        n: number of correspondences.
        parallax_px: average parallax at the virtual focal length of 460 px.
        rule: the cheap rule: ``n > min_correspondences`` and
            ``parallax_px > min_parallax_px``.
        inliers: inliers that pass ``recoverPose``'s chirality check (-1 when not run).
        accepted: ``rule`` and ``inliers > min_inliers``.
        R: (3, 3) float64 rotation (x_cur = R x_ref + t); identity when not run.
        t: (3,) float64 unit translation direction; zeros when not run.
    """

    n: int
    parallax_px: float
    rule: bool
    inliers: int
    accepted: bool
    R: np.ndarray
    t: np.ndarray


def normalized_points(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    """(N, 2) pixels -> (N, 2) float64 normalized image coordinates (undistorted input)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    return np.column_stack(
        ((points[:, 0] - K[0, 2]) / K[0, 0], (points[:, 1] - K[1, 2]) / K[1, 1])
    )


def vins_parallax(p0: np.ndarray, p1: np.ndarray, K: np.ndarray) -> float:
    """Average parallax (pixels) at VINS-Mono's virtual focal length of 460 px."""
    if len(p0) == 0:
        return 0.0
    d = normalized_points(p1, K) - normalized_points(p0, K)
    return float(np.mean(np.hypot(d[:, 0], d[:, 1])) * VINS_FOCAL)


def vins_relative_pose(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    *,
    min_correspondences: int = 20,
    min_parallax_px: float = 30.0,
    min_inliers: int = 12,
    run_ransac: bool = True,
) -> VinsResult:
    """VINS-Mono's ``relativePose`` check (rule, then F-RANSAC + recoverPose).

    Args:
        p0: (N, 2) reference pixels (undistorted).
        p1: (N, 2) current pixels (undistorted).
        K: (3, 3) camera matrix.
        run_ransac: run the RANSAC stage even when the cheap rule fails (to record inliers
            for analysis).
    """
    p0 = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    n = len(p0)
    parallax = vins_parallax(p0, p1, K)
    rule = bool(n > min_correspondences and parallax > min_parallax_px)
    R, t, inliers = np.eye(3), np.zeros(3), -1
    if (rule or run_ransac) and n >= 15:
        ll = normalized_points(p0, K)
        rr = normalized_points(p1, K)
        E, mask = cv2.findFundamentalMat(
            ll.reshape(-1, 1, 2),
            rr.reshape(-1, 1, 2),
            cv2.FM_RANSAC,
            0.3 / VINS_FOCAL,
            0.99,
            1000,
        )
        if E is not None and E.shape == (3, 3):
            inliers, Rc, tc, _ = cv2.recoverPose(
                E, ll.reshape(-1, 1, 2), rr.reshape(-1, 1, 2), np.eye(3), mask=mask
            )
            inliers = int(inliers)
            R, t = np.asarray(Rc, dtype=float), np.asarray(tc, dtype=float).reshape(3)
        else:
            inliers = 0
    accepted = bool(rule and inliers > min_inliers)
    return VinsResult(n, parallax, rule, inliers, accepted, R, t)


def vins_rule(
    n: np.ndarray,
    parallax_px: np.ndarray,
    min_correspondences: int = 20,
    min_parallax_px: float = 30.0,
) -> np.ndarray:
    """Vectorized cheap VINS rule on table columns: (N,) bool."""
    return (np.asarray(n) > min_correspondences) & (np.asarray(parallax_px) > min_parallax_px)


# ---------------------------------------------------------------------------------- ORB-SLAM
def orbslam_choice(ratio: np.ndarray, version: OrbSlamVersion = OrbSlamVersion.ORB2) -> np.ndarray:
    """Vectorized model choice: (N,) array of 'H' / 'F' ('' where the ratio is NaN)."""
    ratio = np.asarray(ratio, dtype=float)
    out = np.where(ratio > version.ratio_threshold, 'H', 'F').astype(object)
    out[~np.isfinite(ratio)] = ''
    return out


__all__ = [
    'CHI2_F',
    'CHI2_H',
    'ORB_MIN_PARALLAX_DEG',
    'ORB_MIN_POINTS',
    'VINS_FOCAL',
    'OrbSlamScores',
    'OrbSlamVersion',
    'VinsResult',
    'butt_rule',
    'normalized_points',
    'orbslam_choice',
    'orbslam_scores',
    'vins_parallax',
    'vins_relative_pose',
    'vins_rule',
]
