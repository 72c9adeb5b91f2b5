"""Tests for initsel_ros.camera: undistorting pixels."""

from __future__ import annotations

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics


def test_undistort_pixels_inverts_the_opencv_distortion_model():
    camera = Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480, (-0.15, 0.05, 5e-4, -5e-4))
    rng = np.random.default_rng(0)
    ideal = rng.uniform([40, 40], [600, 440], (100, 2))
    rays = np.hstack([ideal, np.ones((100, 1))]) @ np.linalg.inv(camera.K).T
    distorted, _ = cv2.projectPoints(
        rays, np.zeros(3), np.zeros(3), camera.K, np.array(camera.distortion)
    )
    out = camera.undistort_pixels(distorted.reshape(-1, 2))
    assert out.dtype == np.float32 and out.shape == (100, 2)
    assert np.max(np.abs(out - ideal)) < 0.05
    plain = Intrinsics.tum_fr3()
    assert np.array_equal(plain.undistort_pixels(ideal), ideal.astype(np.float32))
    assert camera.undistort_pixels(np.zeros((0, 2))).shape == (0, 2)
