"""Tests for initsel_ros.refine: two-view bundle adjustment and the E refit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, two_view

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import (
    estimate_pose,
    fundamental_from_essential,
    rotation_angle_deg,
    sampson_fundamental,
    skew,
    triangulate_pair,
)
from initsel_ros.metrics import translation_chordal_error
from initsel_ros.refine import refine_essential, refine_two_view, reprojection_errors


def _perturbed(R, t, seed=1):
    rng = np.random.default_rng(seed)
    dR = cv2.Rodrigues(rng.normal(0, 0.01, 3))[0]  # about 1 degree
    dt = t + rng.normal(0, 0.08, 3)
    return dR @ R, dt / np.linalg.norm(dt)


@pytest.mark.parametrize('planar', [False, True])
def test_bundle_adjustment_recovers_the_pose_from_a_perturbed_start(planar):
    p0, p1, R, t, _ = two_view(planar=planar, noise_px=0.3)
    R0, t0 = _perturbed(R, t)
    X0 = triangulate_pair(R0, t0, K, p0, p1).points
    before = (translation_chordal_error(t, t0), rotation_angle_deg(R0.T @ R))
    result = refine_two_view(R0, t0, X0, p0, p1, K)
    after = (translation_chordal_error(t, result.t), rotation_angle_deg(result.R.T @ R))
    assert after[0] < 0.3 * before[0] and after[0] < 0.03
    assert after[1] < 0.3 * before[1] and after[1] < 0.1
    assert np.linalg.norm(result.t) == pytest.approx(1.0)
    assert result.rms_after_px < result.rms_before_px
    assert result.rms_after_px < 0.5  # the noise level (0.3 px per coordinate)
    assert result.kept.sum() >= 0.95 * len(p0)


def test_bundle_adjustment_drops_outliers_and_resists_them():
    p0, p1, R, t, _ = two_view(planar=False, noise_px=0.2, seed=3)
    p1 = p1.copy()
    p1[:20] += np.random.default_rng(4).uniform(-15, 15, (20, 2))  # 8 % gross outliers
    estimate = estimate_pose('E', p0, p1, K)
    X = triangulate_pair(estimate.R, estimate.t, K, p0, p1).points
    result = refine_two_view(estimate.R, estimate.t, X, p0, p1, K, max_reprojection_px=2.0)
    # Two views cannot see an error along the epipolar line, and the adjustment splits an
    # error across it between both images: the outliers that must go are those off their
    # true epipolar line by more than twice the threshold.
    F = fundamental_from_essential(skew(t) @ R, K)
    off_line = np.sqrt(sampson_fundamental(F, p0[:20], p1[:20]) * 2) > 5.0
    assert off_line.sum() >= 8 and not result.kept[:20][off_line].any()
    assert result.kept[20:].mean() > 0.95
    assert translation_chordal_error(t, result.t) < 0.03
    e0, e1 = reprojection_errors(
        result.R, result.t, result.points, K, p0[result.kept], p1[result.kept]
    )
    assert np.all(e0 <= 2.0) and np.all(e1 <= 2.0)


def test_refinement_rejects_inconsistent_input():
    p0, p1, R, t, X = two_view(planar=False)
    with pytest.raises(GeometryError):
        refine_two_view(R, np.zeros(3), X, p0, p1, K)
    with pytest.raises(GeometryError):
        refine_two_view(R, t, X[:10], p0, p1, K)


def test_essential_refit_lowers_the_error_of_the_minimal_sample_solution():
    p0, p1, R, t, _ = two_view(planar=False, noise_px=0.5, seed=5)
    R0, t0 = _perturbed(R, t, seed=6)
    R1, t1 = refine_essential(R0, t0, p0, p1, K)
    assert translation_chordal_error(t, t1) < translation_chordal_error(t, t0)
    assert rotation_angle_deg(R1.T @ R) < rotation_angle_deg(R0.T @ R)
