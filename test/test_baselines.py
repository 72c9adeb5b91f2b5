"""Baselines on synthetic correspondences with known geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.learn import baselines

K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


def _rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _project(X: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    Y = X @ R.T + t
    x = Y @ K.T
    return x[:, :2] / x[:, 2:3]


def _scene(rng: np.random.Generator, n: int, planar: bool) -> np.ndarray:
    z = np.full(n, 3.0) if planar else rng.uniform(2.0, 6.0, n)
    return np.column_stack((rng.uniform(-1, 1, n) * z / 3, rng.uniform(-0.7, 0.7, n) * z / 3, z))


def _pair(rng, planar, R, t, noise=0.3, n=250):
    X = _scene(rng, n, planar)
    p0 = _project(X, np.eye(3), np.zeros(3)) + rng.normal(0, noise, (n, 2))
    p1 = _project(X, R, t) + rng.normal(0, noise, (n, 2))
    return p0, p1


def test_butt_fires_h_on_pure_rotation_with_large_disparity():
    rng = np.random.default_rng(0)
    p0, p1 = _pair(rng, False, _rot_y(0.15), np.zeros(3))
    d = np.hypot(*(p1 - p0).T)
    assert d.mean() > 50  # a pan of 8.6 degrees moves every point ~80 px
    h, f = baselines.butt_rule(np.array([d.mean()]), np.array([d.std()]))
    assert h[0]  # the disparity rule is fooled by rotation: no baseline at all
    assert not f[0]  # rotation flow is uniform: small spread


def test_butt_f_needs_both_disparity_and_spread():
    h, f = baselines.butt_rule(np.array([60.0, 60.0, 40.0]), np.array([20.0, 10.0, 30.0]))
    assert h.tolist() == [True, True, False]
    assert f.tolist() == [True, False, False]


def test_orbslam_picks_h_on_a_plane_and_f_on_a_3d_scene():
    rng = np.random.default_rng(1)
    R, t = _rot_y(0.05), np.array([-0.3, 0.02, 0.05])
    plane = baselines.orbslam_scores(*_pair(rng, True, R, t), rng=np.random.default_rng(2))
    depth = baselines.orbslam_scores(*_pair(rng, False, R, t), rng=np.random.default_rng(2))
    assert plane.ratio > 0.40
    assert baselines.orbslam_choice(np.array([plane.ratio]))[0] == 'H'  # ORB-SLAM2
    orb3 = baselines.orbslam_choice(np.array([plane.ratio]), baselines.OrbSlamVersion.ORB3)
    assert orb3[0] == ('H' if plane.ratio > 0.5 else 'F')
    assert depth.ratio < 0.40
    assert baselines.orbslam_choice(np.array([depth.ratio]))[0] == 'F'
    # the best homography of the plane explains almost every correspondence
    assert plane.inliers_h.mean() > 0.9
    assert depth.inliers_f.mean() > 0.8 > depth.inliers_h.mean()


def test_orbslam_scores_are_reproducible_and_need_eight_points():
    rng = np.random.default_rng(3)
    p0, p1 = _pair(rng, False, _rot_y(0.05), np.array([-0.3, 0.0, 0.0]))
    a = baselines.orbslam_scores(p0, p1, rng=np.random.default_rng(7))
    b = baselines.orbslam_scores(p0, p1, rng=np.random.default_rng(7))
    assert a.s_h == b.s_h and a.s_f == b.s_f
    few = baselines.orbslam_scores(p0[:7], p1[:7])
    assert math.isnan(few.ratio)
    assert baselines.orbslam_choice(np.array([few.ratio]))[0] == ''


def test_vins_rule_and_relative_pose_recover_translation_direction():
    rng = np.random.default_rng(4)
    t = np.array([-0.6, 0.05, 0.1])
    p0, p1 = _pair(rng, False, _rot_y(0.02), t, noise=0.2)
    result = baselines.vins_relative_pose(p0, p1, K)
    assert result.rule and result.accepted
    assert result.inliers > 12
    assert np.linalg.norm(result.t - t / np.linalg.norm(t)) < 0.1
    # tiny motion: the cheap rule refuses before any RANSAC
    q0, q1 = _pair(rng, False, np.eye(3), np.array([-0.01, 0.0, 0.0]), noise=0.0)
    small = baselines.vins_relative_pose(q0, q1, K, run_ransac=False)
    assert not small.rule and small.inliers == -1 and not small.accepted
    assert small.parallax_px == pytest.approx(baselines.vins_parallax(q0, q1, K))


def test_vins_parallax_uses_the_virtual_focal_length():
    p0 = np.array([[320.1, 247.6]])
    p1 = p0 + np.array([[535.4 * 0.1, 0.0]])  # 0.1 in normalized coordinates
    assert baselines.vins_parallax(p0, p1, K) == pytest.approx(46.0)
    rule = baselines.vins_rule(np.array([25, 25, 10]), np.array([31.0, 29.0, 40.0]))
    assert rule.tolist() == [True, False, False]


def test_orbslam_scores_take_exactly_eight_points():
    # Low-texture frames can leave exactly 8 tracks; a dataset build once died on them.
    rng = np.random.default_rng(4)
    p0, p1 = _pair(rng, False, _rot_y(0.05), np.array([-0.3, 0.0, 0.0]), noise=0.0, n=8)
    eight = baselines.orbslam_scores(p0, p1)
    assert np.isfinite(eight.s_f) and eight.s_f > 0
