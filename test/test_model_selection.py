"""Tests for initsel_ros.model_selection: Sampson errors, GRIC and the choice among F/E/H."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, two_view

from initsel_ros.geometry import Method, estimate_pose, skew
from initsel_ros.model_selection import (
    fundamental_from_essential,
    gric,
    sampson_fundamental,
    sampson_homography,
    select_method,
)


def test_sampson_errors_vanish_on_exact_data_and_grow_with_the_offset():
    p0, p1, R, t, _ = two_view(planar=True, noise_px=0.0)
    H, _ = cv2.findHomography(p0, p1, 0)
    assert np.max(sampson_homography(H, p0, p1)) < 1e-6
    shifted = p1 + np.array([0.0, 2.0])  # 2 px off: the first-order error is close to the true one
    err = np.sqrt(sampson_homography(H, p0, shifted))
    assert np.median(err) == pytest.approx(2.0 / math.sqrt(2), rel=0.1)  # split over 2 views
    F = fundamental_from_essential(skew(t) @ R, K)
    assert np.max(sampson_fundamental(F, p0, p1)) < 1e-6
    assert np.median(sampson_fundamental(F * 7.0, p0, shifted)) > 0.1  # scale-free, non-zero


def test_gric_penalizes_dimension_and_parameters_as_torr_defines_it():
    n = 100
    zero = np.zeros(n)
    assert gric(zero, 'H') == pytest.approx(math.log(4) * 2 * n + math.log(4 * n) * 8)
    assert gric(zero, 'F') - gric(zero, 'E') == pytest.approx(2 * math.log(4 * n))
    assert gric(np.full(n, 1e9), 'F') == pytest.approx(gric(zero, 'F') + 2.0 * n)  # capped
    assert gric(np.zeros(0), 'E') == math.inf


def _select(p0, p1):
    estimates = [estimate_pose(m, p0, p1, K) for m in ('F', 'E', 'H')]
    return select_method(estimates, ['' if e.ok else e.reason for e in estimates], p0, p1, K)


def test_a_plane_selects_h_and_a_scene_with_depth_selects_e():
    planar = _select(*two_view(planar=True)[:2])
    assert planar.winner is Method.H
    assert planar.orb_ratio > 0.40  # ORB-SLAM2 would agree (its threshold)
    deep = _select(*two_view(planar=False)[:2])
    assert deep.winner is Method.E
    assert deep.orb_ratio < 0.45
    text = deep.summary()
    assert 'E*' in text and 'GRIC' in text
    assert deep.to_dict()['winner'] == 'E' and len(deep.to_dict()['candidates']) == 3


def test_a_wrong_camera_matrix_hands_the_choice_from_e_to_f():
    p0, p1, *_ = two_view(planar=False, noise_px=0.2)
    wrong = K.copy()
    wrong[0, 0] = wrong[1, 1] = 0.6 * K[0, 0]  # 40 % focal length error
    estimates = [estimate_pose(m, p0, p1, wrong) for m in ('F', 'E')]
    selection = select_method(estimates, ['', ''], p0, p1, wrong)
    assert selection.winner is Method.F


def test_no_candidate_passing_the_pose_check_selects_nothing():
    p0, p1, *_ = two_view(planar=False)
    estimates = [estimate_pose(m, p0, p1, K) for m in ('E', 'H')]
    selection = select_method(estimates, ['too few points', 'low parallax'], p0, p1, K)
    assert selection.winner is None and 'no candidate' in selection.why
    assert 'E failed (too few points)' in selection.summary()
