"""KLT tracking from a reference frame: Shi-Tomasi corners, pyramidal Lucas-Kanade.

Tracks are carried frame to frame (previous -> current) so that they survive large total
motion, with a forward-backward check that drops a track when tracking the current point
back to the previous frame misses by more than ``fb_max_error_px``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from initsel_ros.errors import ImageConversionError


@dataclass(frozen=True)
class TrackerConfig:
    """Feature detection and tracking settings.

    Attributes:
        max_features: feature budget per reference frame.
        grid_cols: columns of the grid that spreads features over the image.
        grid_rows: rows of that grid.
        quality_level: Shi-Tomasi quality relative to the strongest corner.
        min_distance_px: minimum spacing of corners, pixels.
        block_size: corner detector block size, pixels.
        window_px: Lucas-Kanade window side, pixels.
        pyramid_levels: Lucas-Kanade pyramid levels above the base.
        fb_max_error_px: forward-backward error above which a track is dropped, pixels.
        lk_iterations: Lucas-Kanade iterations per pyramid level (at most).
        lk_epsilon_px: Lucas-Kanade stops when an update is smaller than this, pixels.
    """

    max_features: int = 300
    grid_cols: int = 8
    grid_rows: int = 6
    quality_level: float = 0.01
    min_distance_px: float = 8.0
    block_size: int = 7
    window_px: int = 17
    pyramid_levels: int = 3
    fb_max_error_px: float = 1.0
    lk_iterations: int = 10
    lk_epsilon_px: float = 0.03


@dataclass(frozen=True)
class Tracks:
    """Surviving correspondences between the reference and the current frame.

    Attributes:
        ref: (N, 2) float32 reference pixels.
        cur: (N, 2) float32 current pixels.
        ids: (N,) int64 feature ids (index in the reference detection).
    """

    ref: np.ndarray
    cur: np.ndarray
    ids: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.shape[0])


def detect_features(gray: np.ndarray, config: TrackerConfig = TrackerConfig()) -> np.ndarray:
    """Shi-Tomasi corners spread over a grid, strongest first within each cell.

    Each grid cell keeps at most ``ceil(max_features / cells)`` corners; any budget left
    goes to the strongest remaining corners anywhere.

    Args:
        gray: (H, W) uint8 image.
        config: detection settings.

    Returns:
        (N, 2) float32 pixel coordinates, N <= ``config.max_features``.
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ImageConversionError(f'expected (H, W) uint8, got {gray.shape} {gray.dtype}')
    h, w = gray.shape
    if config.max_features <= 0 or h < 2 * config.block_size or w < 2 * config.block_size:
        return np.zeros((0, 2), np.float32)
    corners = cv2.goodFeaturesToTrack(
        gray, maxCorners=2 * config.max_features, qualityLevel=config.quality_level,
        minDistance=config.min_distance_px, blockSize=config.block_size,
    )
    if corners is None:
        return np.zeros((0, 2), np.float32)
    pts = corners.reshape(-1, 2).astype(np.float32)  # strongest first
    cols, rows = max(config.grid_cols, 1), max(config.grid_rows, 1)
    cx = np.minimum((pts[:, 0] * cols / w).astype(np.int64), cols - 1)
    cy = np.minimum((pts[:, 1] * rows / h).astype(np.int64), rows - 1)
    cell = cy * cols + cx
    order = np.argsort(cell, kind='stable')  # by cell, strength order kept inside a cell
    sorted_cell = cell[order]
    rank_in_cell = np.arange(len(pts)) - np.searchsorted(sorted_cell, sorted_cell)
    rank = np.empty_like(rank_in_cell)
    rank[order] = rank_in_cell
    cap = math.ceil(config.max_features / (cols * rows))
    chosen = rank < cap
    if chosen.sum() > config.max_features:
        chosen[np.flatnonzero(chosen)[config.max_features:]] = False
    spare = config.max_features - int(chosen.sum())
    if spare > 0:
        chosen[np.flatnonzero(~chosen)[:spare]] = True
    return pts[np.flatnonzero(chosen)]


class KltTracker:
    """Tracks features from a reference frame through the following frames."""

    def __init__(self, config: TrackerConfig = TrackerConfig()) -> None:
        self.config = config
        self._criteria = (
            cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, config.lk_iterations,
            config.lk_epsilon_px,
        )
        self._prev: np.ndarray | None = None
        self._ref = np.zeros((0, 2), np.float32)
        self._cur = np.zeros((0, 2), np.float32)
        self._ids = np.zeros(0, np.int64)
        self.frames_since_reference = 0

    @property
    def has_reference(self) -> bool:
        """True once :meth:`reset` has been given a frame."""
        return self._prev is not None

    @property
    def n_tracks(self) -> int:
        """Number of tracks still alive."""
        return int(self._ids.shape[0])

    @property
    def image_shape(self) -> tuple[int, ...] | None:
        """Shape of the frames being tracked, or None before a reference."""
        return None if self._prev is None else self._prev.shape

    def clear(self) -> None:
        """Forget the reference; the next :meth:`reset` starts over."""
        self._prev = None
        self._ref = self._cur = np.zeros((0, 2), np.float32)
        self._ids = np.zeros(0, np.int64)
        self.frames_since_reference = 0

    def reset(self, gray: np.ndarray) -> int:
        """Make ``gray`` ((H, W) uint8) the reference frame; returns the features found."""
        pts = detect_features(gray, self.config)
        self._prev = gray
        self._ref = pts
        self._cur = pts.copy()
        self._ids = np.arange(len(pts), dtype=np.int64)
        self.frames_since_reference = 0
        return len(pts)

    def tracks(self) -> Tracks:
        """The current correspondences (reference, current)."""
        return Tracks(self._ref.copy(), self._cur.copy(), self._ids.copy())

    def track(self, gray: np.ndarray) -> Tracks:
        """Track into the next frame ((H, W) uint8, same size as the reference).

        Returns:
            The surviving correspondences between the reference and ``gray``.
        """
        if self._prev is None:
            raise RuntimeError('track() before reset(): no reference frame')
        if gray.shape != self._prev.shape:
            raise ImageConversionError(
                f'frame size {gray.shape} differs from the reference {self._prev.shape}'
            )
        self.frames_since_reference += 1
        if len(self._ids):
            self._step(gray)
        self._prev = gray
        return self.tracks()

    def _step(self, gray: np.ndarray) -> None:
        cfg = self.config
        lk = {
            'winSize': (cfg.window_px, cfg.window_px), 'maxLevel': cfg.pyramid_levels,
            'criteria': self._criteria,
        }
        prev_pts = self._cur.reshape(-1, 1, 2)
        nxt, status, _ = cv2.calcOpticalFlowPyrLK(self._prev, gray, prev_pts, None, **lk)
        back, status_back, _ = cv2.calcOpticalFlowPyrLK(gray, self._prev, nxt, None, **lk)
        nxt = nxt.reshape(-1, 2)
        fb = np.linalg.norm(back.reshape(-1, 2) - self._cur, axis=1)
        h, w = gray.shape
        keep = (
            (status.ravel() == 1) & (status_back.ravel() == 1) & (fb <= cfg.fb_max_error_px)
            & (nxt[:, 0] >= 0) & (nxt[:, 0] <= w - 1) & (nxt[:, 1] >= 0) & (nxt[:, 1] <= h - 1)
        )
        self._ref = self._ref[keep]
        self._cur = nxt[keep].astype(np.float32)
        self._ids = self._ids[keep]
