"""Tests for initsel_ros.metrics: the measures of an estimate against ground truth."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from initsel_ros.errors import GeometryError
from initsel_ros.metrics import (
    depth_error,
    reconstruction_error,
    relative_pose,
    rotation_error_deg,
    translation_chordal_error,
)


def rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    return cv2.Rodrigues(np.array([rx, ry, rz], dtype=np.float64))[0]


def test_chordal_error_values():
    assert translation_chordal_error([1, 0, 0], [2, 0, 0]) == pytest.approx(0.0)
    assert translation_chordal_error([1, 0, 0], [-1, 0, 0]) == pytest.approx(2.0)
    assert translation_chordal_error([1, 0, 0], [0, 3, 0]) == pytest.approx(np.sqrt(2))
    assert np.isnan(translation_chordal_error([0, 0, 0], [1, 0, 0]))


def test_reconstruction_error_removes_scale_with_both_rules():
    rng = np.random.default_rng(14)
    g = rng.uniform(1, 3, (30, 3))
    assert reconstruction_error(g, g / 7.0, 'first_two') == pytest.approx(0.0, abs=1e-12)
    assert reconstruction_error(g, g / 7.0, 'median') == pytest.approx(0.0, abs=1e-12)
    e = g / 7.0
    e[0] = e[1] + 1e-3  # a bad first pair ruins the paper's scale, not the median one
    assert reconstruction_error(g, e, 'first_two') > 1.0
    assert reconstruction_error(g, e, 'median') < 0.01
    assert np.isnan(reconstruction_error(g[:1], e[:1]))
    with pytest.raises(GeometryError, match='scale must be'):
        reconstruction_error(g, e, 'mean')


def test_relative_pose_of_camera_to_world_poses():
    A = np.eye(4)
    A[:3, :3] = rotation(0.1, 0.2, 0.3)
    A[:3, 3] = [1.0, 2.0, 3.0]
    B = np.eye(4)
    B[:3, :3] = rotation(-0.2, 0.1, 0.0)
    B[:3, 3] = [1.5, 2.0, 2.5]
    R, t = relative_pose(A, B)
    x_ref = np.array([0.3, -0.2, 2.0])
    x_world = A[:3, :3] @ x_ref + A[:3, 3]
    x_cur = B[:3, :3].T @ (x_world - B[:3, 3])
    np.testing.assert_allclose(R @ x_ref + t, x_cur)
    assert np.linalg.norm(t) == pytest.approx(np.linalg.norm(A[:3, 3] - B[:3, 3]))


def test_rotation_error_is_the_angle_between_truth_and_estimate():
    R = rotation(0.1, -0.2, 0.3)
    off = rotation(0.0, np.radians(2.0), 0.0)
    assert rotation_error_deg(R, R) == pytest.approx(0.0, abs=1e-5)
    assert rotation_error_deg(R, R @ off) == pytest.approx(2.0)
    assert rotation_error_deg(R @ off, R) == pytest.approx(2.0)


def test_depth_error_is_scale_free_and_measures_relative_error():
    true = np.array([2.0, 2.0, 4.0, 4.0])
    exact = np.column_stack((np.zeros((4, 2)), true)) * 0.37
    assert depth_error(exact, true) == pytest.approx(0.0)
    off = exact.copy()
    off[2:, 2] *= 1.1  # the far points 10 % too far
    assert 0.0 < depth_error(off, true) <= 0.1
    assert math.isnan(depth_error(exact, np.full(4, np.nan)))
    assert math.isnan(depth_error(exact, np.zeros(4)))
    assert math.isnan(depth_error(exact, true[:3]))  # not one depth per point
