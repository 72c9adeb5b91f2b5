"""Tests for initsel_ros.tracking on images warped by known motions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from initsel_ros.errors import ImageConversionError
from initsel_ros.tracking import KltTracker, TrackerConfig, detect_features


def texture(seed: int = 0, shape=(480, 640)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0, 255, (shape[0] // 8, shape[1] // 8)).astype(np.float32)
    img = cv2.resize(coarse, shape[::-1], interpolation=cv2.INTER_CUBIC)
    img += rng.normal(0, 4, shape).astype(np.float32)
    return np.clip(cv2.GaussianBlur(img, (3, 3), 0.8), 0, 255).astype(np.uint8)


def shifted(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    M = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, M, img.shape[::-1], flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REFLECT)


def test_detection_respects_the_budget_and_spreads_over_the_grid():
    cfg = TrackerConfig(max_features=120, grid_cols=4, grid_rows=3)
    pts = detect_features(texture(), cfg)
    assert 100 <= len(pts) <= 120
    cells = (pts[:, 0] // 160).astype(int) + 4 * (pts[:, 1] // 160).astype(int)
    counts = np.bincount(cells, minlength=12)
    assert counts.min() >= 5  # every cell is used
    assert counts.max() <= 10  # the cap ceil(120 / 12): a rich texture needs no spares


def test_tracks_follow_a_known_shift_through_several_frames():
    img = texture(1)
    tracker = KltTracker()
    assert tracker.reset(img) >= 250
    for k in range(1, 6):
        tracks = tracker.track(shifted(img, 3.0 * k, -2.0 * k))
    assert len(tracks) > 200
    assert tracker.frames_since_reference == 5
    d = tracks.cur - tracks.ref
    np.testing.assert_allclose(np.median(d, axis=0), [15.0, -10.0], atol=0.1)
    assert np.percentile(np.linalg.norm(d - [15.0, -10.0], axis=1), 95) < 0.5


def test_forward_backward_check_drops_tracks_on_changed_content():
    img = texture(2)
    tracker = KltTracker()
    tracker.reset(img)
    nxt = shifted(img, 2.0, 0.0)
    nxt[:, :320] = texture(3)[:, :320]  # the left half is replaced by other content
    tracks = tracker.track(nxt)
    assert len(tracks) > 50
    survivors_left = np.mean(tracks.ref[:, 0] < 300)
    assert survivors_left < 0.1


def test_tracker_rejects_frames_of_another_size_and_track_before_reset():
    tracker = KltTracker()
    with pytest.raises(RuntimeError, match='before reset'):
        tracker.track(texture())
    tracker.reset(texture())
    with pytest.raises(ImageConversionError, match='differs from the reference'):
        tracker.track(texture(shape=(240, 320)))


def test_blank_and_tiny_images_give_no_features():
    assert len(detect_features(np.zeros((480, 640), np.uint8))) == 0
    assert len(detect_features(np.zeros((1, 1), np.uint8))) == 0
