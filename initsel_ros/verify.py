"""Verifying a candidate seed map on the frames after it: does PnP against it hold?

A correct two-view map explains the next views too: tracking its points into a later frame
and solving PnP (``cv2.solvePnPRansac``, then Levenberg-Marquardt on the inliers) gives a pose
that reprojects the map within the tracking noise. A wrong map (the mirrored solution of a
planar pair, a pose fitted to outliers, a near-degenerate E) does not: the points drift from
their tracks as the camera moves on, the RANSAC inliers thin out and the RMS grows.

Two things grow with the camera's motion for a correct map too, and are allowed for: the
points it leaves behind (a car driving forward leaves most of its map behind in a few
frames: only the points in view count), and the reprojection error (the map's depths carry
the noise of the pair they were triangulated from, and a view twice as far from the
reference as that pair's sees those errors twice as large: the inlier threshold and the RMS
bound grow with that distance ratio, from twice the pair's distance on, which the fixed bound
already allows for). A wrong map's drift is measured against the same allowance.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from initsel_ros.errors import ConfigError

#: The inlier threshold and the RMS bound grow with a frame's distance from the reference
#: over the initializing frame's beyond this ratio (see the module docstring).
ALLOWANCE_FROM_RATIO = 2.0


@dataclass(frozen=True)
class VerifyConfig:
    """Settings of the verification.

    Attributes:
        frames: frames after the initializing frame that must confirm the map (0 = publish
            at once, no verification).
        min_fraction: share of the map's points in view (projected into the image by the
            frame's PnP pose; points the camera has left behind do not count) that must be
            tracked and PnP inliers in every verification frame.
        max_rms_px: largest RMS reprojection error of those inliers, pixels, for a frame up
            to twice as far from the reference as the initializing frame; ``k`` times as far
            (``k > 2``) allows ``k / 2`` times as much, and the inlier threshold grows alike
            (the map's depths carry the noise of the pair they were triangulated from, and a
            view that has moved on sees those errors grown in proportion; see
            :func:`check_frame`).
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
        fraction: inliers / map points in view.
        rms_px: RMS reprojection error of the inliers after refinement, pixels.
        R: (3, 3) PnP rotation, reference to this frame.
        t: (3,) PnP translation, map units.
        detail: the numbers, as text.
        max_rms_px: the RMS bound it was held to (``VerifyConfig.max_rms_px``, grown with
            the distance ratio).
    """

    ok: bool
    tracked: int
    inliers: int
    fraction: float
    rms_px: float
    R: np.ndarray
    t: np.ndarray
    detail: str
    max_rms_px: float = 0.0


def check_frame(
    points: np.ndarray,
    pixels: np.ndarray,
    tracked: np.ndarray,
    K: np.ndarray,
    config: VerifyConfig,
    size: tuple[int, int] | None = None,
    baseline: float | None = None,
    max_distance_ratio: float = 1.0,
) -> VerifyStep:
    """Check the map against one later frame.

    Args:
        points: (M, 3) map points, reference camera frame.
        pixels: (M, 2) their tracked (undistorted) pixels in this frame (rows of untracked
            points are ignored).
        tracked: (M,) bool, the point is still tracked.
        K: (3, 3) camera matrix.
        config: thresholds.
        size: (width, height) of the image: a map point the frame's PnP pose projects out
            of it (or behind the camera) has been left behind, and does not count against
            the map (a camera driving forward leaves most of its map behind within a few
            frames); None counts every point.
        baseline: distance of the initializing frame from the reference, map units: the
            inlier threshold and the RMS bound grow with this frame's distance over it, as
            the PnP pose puts it, beyond :data:`ALLOWANCE_FROM_RATIO` (None: fixed).
        max_distance_ratio: the most that ratio may be, from a measure that does not
            depend on the map under test (the selector's: the time since the reference over
            the initializing frame's, which a steady motion makes the distance ratio). A
            wrong map's PnP pose can put the camera anywhere: a spoiled test map's put it 43
            times as far, which would have let any error pass.
    """
    m = int(points.shape[0])
    n_tracked = int(np.count_nonzero(tracked))
    inf = float('inf')
    fail = VerifyStep(False, n_tracked, 0, 0.0, inf, np.eye(3), np.zeros(3), '', config.max_rms_px)
    need = 6 if size is not None else max(6, int(np.ceil(config.min_fraction * m)))
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
    scale = 1.0
    if baseline is not None and baseline > 0:  # this frame's distance over the pair's
        R = cv2.Rodrigues(rvec)[0]
        ratio = float(np.linalg.norm(R.T @ tvec.reshape(3))) / baseline
        scale = max(1.0, min(ratio, max_distance_ratio) / ALLOWANCE_FROM_RATIO)
    if scale > 1.0:  # the inliers at the threshold grown as the map's errors have
        err = _reprojection_px(obj, img, rvec, tvec, K)
        wider = np.flatnonzero(err <= config.ransac_px * scale)
        if len(wider) > len(idx):
            idx = wider
            rvec, tvec = cv2.solvePnPRefineLM(obj[idx], img[idx], K, None, rvec, tvec)
    rms = float(np.sqrt(np.mean(_reprojection_px(obj[idx], img[idx], rvec, tvec, K) ** 2)))
    R = cv2.Rodrigues(rvec)[0]
    t = tvec.reshape(3)
    n_view = m
    if size is not None:  # (a tracked point is in view, whatever the pose says)
        n_view = int(np.count_nonzero(_in_view(points, R, t, K, size) | tracked))
    fraction = len(idx) / max(n_view, 1)
    bound = config.max_rms_px * scale
    step = VerifyStep(
        fraction >= config.min_fraction and rms <= bound,
        n_tracked,
        len(idx),
        fraction,
        rms,
        R,
        t,
        '',
        bound,
    )
    return _with_detail(
        step, n_view, config, '' if n_view == m else f'{m - n_view} of {m} points out of view'
    )


def _reprojection_px(
    obj: np.ndarray, img: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, K: np.ndarray
) -> np.ndarray:
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, None)
    return np.linalg.norm(projected.reshape(-1, 2) - img.reshape(-1, 2), axis=1)


def _in_view(
    points: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, size: tuple[int, int]
) -> np.ndarray:
    """(M,) bool: the map point projects into the image of camera (R, t), in front of it."""
    cam = points @ R.T + t
    with np.errstate(divide='ignore', invalid='ignore'):
        uv = cam[:, :2] / cam[:, 2:3] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    width, height = size
    return (
        (cam[:, 2] > 0)
        & (uv[:, 0] >= 0)
        & (uv[:, 0] <= width - 1)
        & (uv[:, 1] >= 0)
        & (uv[:, 1] <= height - 1)
    )


def _with_detail(step: VerifyStep, m: int, config: VerifyConfig, note: str) -> VerifyStep:
    text = (
        f'{step.inliers} of {m} points PnP inliers ({100 * step.fraction:.0f} %, '
        f'min {100 * config.min_fraction:.0f} %), RMS {step.rms_px:.2f} px '
        f'(max {step.max_rms_px:.2f} px)'
    )
    if note:
        text = f'{note}; {text}'
    return replace(step, detail=text)
