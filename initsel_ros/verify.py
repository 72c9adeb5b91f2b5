"""Verifying a candidate seed map on the frames after it: does PnP against it hold?

A correct two-view map explains the next views too: tracking its points into a later frame
and solving PnP (``cv2.solvePnPRansac``, then Levenberg-Marquardt on the inliers) gives a pose
that reprojects the map within the tracking noise. A wrong map (the mirrored solution of a
planar pair, a pose fitted to outliers, a near-degenerate E) does not: the points drift from
their tracks as the camera moves on, the RANSAC inliers thin out and the RMS grows.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from initsel_ros.errors import ConfigError


@dataclass(frozen=True)
class VerifyConfig:
    """Settings of the verification.

    Attributes:
        frames: frames after the initializing frame that must confirm the map (0 = publish
            at once, no verification).
        min_fraction: share of the map's points that must be tracked and PnP inliers in
            every verification frame.
        max_rms_px: largest RMS reprojection error of those inliers, pixels.
        ransac_px: PnP RANSAC inlier threshold, pixels.
    """

    frames: int = 5
    min_fraction: float = 0.5
    max_rms_px: float = 1.0
    ransac_px: float = 2.0

    def __post_init__(self) -> None:
        if not 0 <= self.frames <= 100:
            raise ConfigError(f'verify frames must be in [0, 100], got {self.frames}')
        if not 0.0 < self.min_fraction <= 1.0:
            raise ConfigError(f'verify min_fraction must be in (0, 1], got {self.min_fraction}')
        if not 0.0 < self.max_rms_px < 1e3:
            raise ConfigError(f'verify max_rms_px must be in (0, 1000), got {self.max_rms_px}')
        if not 0.0 < self.ransac_px < 1e3:
            raise ConfigError(f'verify ransac_px must be in (0, 1000), got {self.ransac_px}')


@dataclass(frozen=True)
class VerifyStep:
    """One frame's check of the map.

    Attributes:
        ok: the frame confirms the map.
        tracked: map points still tracked in this frame.
        inliers: of those, PnP RANSAC inliers.
        fraction: inliers / map points.
        rms_px: RMS reprojection error of the inliers after refinement, pixels.
        R: (3, 3) PnP rotation, reference to this frame.
        t: (3,) PnP translation, map units.
        detail: the numbers, as text.
    """

    ok: bool
    tracked: int
    inliers: int
    fraction: float
    rms_px: float
    R: np.ndarray
    t: np.ndarray
    detail: str


def check_frame(
    points: np.ndarray,
    pixels: np.ndarray,
    tracked: np.ndarray,
    K: np.ndarray,
    config: VerifyConfig,
) -> VerifyStep:
    """Check the map against one later frame.

    Args:
        points: (M, 3) map points, reference camera frame.
        pixels: (M, 2) their tracked (undistorted) pixels in this frame (rows of untracked
            points are ignored).
        tracked: (M,) bool, the point is still tracked.
        K: (3, 3) camera matrix.
        config: thresholds.
    """
    m = int(points.shape[0])
    n_tracked = int(np.count_nonzero(tracked))
    fail = VerifyStep(False, n_tracked, 0, 0.0, float('inf'), np.eye(3), np.zeros(3), '')
    need = max(6, int(np.ceil(config.min_fraction * m)))
    if n_tracked < need:
        return _with_detail(fail, m, config, f'only {n_tracked} of {m} points still tracked')
    obj = np.ascontiguousarray(points[tracked], dtype=np.float64).reshape(-1, 1, 3)
    img = np.ascontiguousarray(pixels[tracked], dtype=np.float64).reshape(-1, 1, 2)
    ok, rvec, tvec, inliers = cv2.solvePnPRansac(
        obj,
        img,
        K,
        None,
        iterationsCount=100,
        reprojectionError=config.ransac_px,
        confidence=0.999,
        flags=cv2.SOLVEPNP_EPNP,
    )
    if not ok or inliers is None or len(inliers) < 6:
        return _with_detail(fail, m, config, 'PnP found no pose')
    idx = inliers.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(obj[idx], img[idx], K, None, rvec, tvec)
    projected, _ = cv2.projectPoints(obj[idx], rvec, tvec, K, None)
    err = np.linalg.norm(projected.reshape(-1, 2) - img[idx].reshape(-1, 2), axis=1)
    rms = float(np.sqrt(np.mean(err**2)))
    fraction = len(idx) / m
    R = cv2.Rodrigues(rvec)[0]
    step = VerifyStep(
        fraction >= config.min_fraction and rms <= config.max_rms_px,
        n_tracked,
        len(idx),
        fraction,
        rms,
        R,
        tvec.reshape(3),
        '',
    )
    return _with_detail(step, m, config, '')


def _with_detail(step: VerifyStep, m: int, config: VerifyConfig, note: str) -> VerifyStep:
    text = (
        f'{step.inliers} of {m} points PnP inliers ({100 * step.fraction:.0f} %, '
        f'min {100 * config.min_fraction:.0f} %), RMS {step.rms_px:.2f} px '
        f'(max {config.max_rms_px:.2f} px)'
    )
    if note:
        text = f'{note}; {text}'
    return VerifyStep(
        step.ok, step.tracked, step.inliers, step.fraction, step.rms_px, step.R, step.t, text
    )
