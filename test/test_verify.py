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
