"""Tests for initsel_ros.verify: PnP checks of a seed map on later frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, two_view

from initsel_ros.errors import ConfigError
from initsel_ros.verify import VerifyConfig, check_frame


def _later_view(X: np.ndarray, noise_px: float = 0.3, seed: int = 0) -> np.ndarray:
    """Pixels of X in a third camera, further along the motion."""
    R = cv2.Rodrigues(np.array([0.02, -0.12, 0.01]))[0]
    t = np.array([-0.3, 0.02, 0.04]) * np.linalg.norm(X, axis=1).mean() / 2.5
    proj = (X @ R.T + t) @ K.T
    rng = np.random.default_rng(seed)
    return proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, (len(X), 2))


def test_a_correct_map_is_confirmed_by_a_later_frame():
    _, _, _, _, X = two_view(planar=False)
    pixels = _later_view(X)
    step = check_frame(X, pixels, np.ones(len(X), bool), K, VerifyConfig())
    assert step.ok, step.detail
    assert step.fraction > 0.95 and step.rms_px < 0.6


def test_a_wrong_map_is_rejected_with_the_numbers():
    _, _, _, _, X = two_view(planar=False)
    pixels = _later_view(X)
    wrong = X.copy()
    wrong[:, 2] = wrong[:, 2].mean() * 2 - wrong[:, 2]  # depths mirrored about their mean
    step = check_frame(wrong, pixels, np.ones(len(X), bool), K, VerifyConfig())
    assert not step.ok
    assert 'PnP inliers' in step.detail and 'RMS' in step.detail


def test_losing_most_tracks_fails_verification():
    _, _, _, _, X = two_view(planar=False)
    tracked = np.zeros(len(X), bool)
    tracked[:40] = True
    step = check_frame(X, _later_view(X), tracked, K, VerifyConfig(min_fraction=0.5))
    assert not step.ok and 'still tracked' in step.detail


@pytest.mark.parametrize(
    'bad',
    [dict(frames=-1), dict(min_fraction=0.0), dict(max_rms_px=float('nan')), dict(ransac_px=0.0)],
)
def test_verify_config_rejects_out_of_range_values(bad):
    with pytest.raises(ConfigError):
        VerifyConfig(**bad)


def _scene(n: int = 300, seed: int = 3) -> np.ndarray:
    """Points 2-6 m ahead of the reference camera, spread over its image."""
    rng = np.random.default_rng(seed)
    uv1 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n), np.ones(n)])
    return (uv1 @ np.linalg.inv(K).T) * rng.uniform(2.0, 6.0, (n, 1))


def _seen_from(X: np.ndarray, centre: np.ndarray, noise_px: float, seed: int = 4):
    """Pixels of X in a camera at ``centre`` (reference orientation), and which are in view."""
    proj = (X - centre) @ K.T
    rng = np.random.default_rng(seed)
    pixels = proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, (len(X), 2))
    inside = (pixels[:, 0] >= 0) & (pixels[:, 0] < 640) & (pixels[:, 1] >= 0)
    return pixels, inside & (pixels[:, 1] < 480)


def test_points_the_camera_has_left_behind_do_not_count_against_the_map():
    # before: a car driving forward lost most of its map out of the image within a few
    # frames, and its correct map failed for it (KITTI-like, never initialized)
    X = _scene()
    pixels, inside = _seen_from(X, np.array([1.5, 0.0, 1.0]), 0.3)
    assert inside.mean() < 0.5  # most points have left the image
    kept = check_frame(X, pixels, inside, K, VerifyConfig(), size=(640, 480))
    assert kept.ok, kept.detail
    assert 'points out of view' in kept.detail
    assert not check_frame(X, pixels, inside, K, VerifyConfig()).ok  # counted: fails
    wrong = X.copy()
    wrong[:, 2] = wrong[:, 2].mean() * 2 - wrong[:, 2]  # the same tracks, a wrong map
    assert not check_frame(wrong, pixels, inside, K, VerifyConfig(), size=(640, 480)).ok


def test_the_rms_bound_grows_with_the_distance_from_the_reference():
    # a map triangulated from a 10 cm pair: depths off by its noise, about 2 %
    X = _scene()
    rng = np.random.default_rng(5)
    noisy = X * (1.0 + rng.normal(0.0, 0.025, (len(X), 1)))
    near, _ = _seen_from(X, np.array([0.12, 0.0, 0.0]), 0.2)
    far, _ = _seen_from(X, np.array([0.45, 0.0, 0.0]), 0.2)
    tracked = np.ones(len(X), bool)
    frames = {'baseline': 0.1, 'max_distance_ratio': 4.5}  # at a steady speed: 4.5 x as far
    assert check_frame(noisy, near, tracked, K, VerifyConfig(), **frames).ok
    fixed = check_frame(noisy, far, tracked, K, VerifyConfig())
    grown = check_frame(noisy, far, tracked, K, VerifyConfig(), **frames)
    assert not fixed.ok and fixed.rms_px > 1.0  # the old fixed 1 px refuses a correct map
    assert grown.ok and grown.max_rms_px == pytest.approx(4.5 / 2, rel=0.05), grown.detail
    # the allowance is the smaller of the two ratios: a frame count that says the camera
    # stood still keeps the fixed bound, whatever the pose says
    still = check_frame(noisy, far, tracked, K, VerifyConfig(), baseline=0.1, max_distance_ratio=1)
    assert still.max_rms_px == 1.0 and not still.ok
    wrong = X.copy()
    wrong[:, 2] = wrong[:, 2].mean() * 2 - wrong[:, 2]
    assert not check_frame(wrong, far, tracked, K, VerifyConfig(), **frames).ok
