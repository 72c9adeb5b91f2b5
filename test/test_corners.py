"""Corners against straight edges: the structure tensor's eigenvalue ratio at given points."""

import cv2
import numpy as np
import pytest

from initsel_ros.corners import EDGE_ISOTROPY, structure_isotropy


def _square(noise: float = 0.0) -> np.ndarray:
    """A bright square on a dark ground (corners at (100, 80) and (220, 200))."""
    image = np.full((240, 320), 60.0)
    image[80:200, 100:220] = 180.0
    image += np.random.default_rng(3).normal(0.0, noise, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def test_the_ratio_is_opencvs_eigenvalues_ratio_at_every_point_inside_the_frame():
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.integers(0, 256, (120, 160)).astype(np.uint8), (5, 5), 1.5)
    points = np.column_stack([rng.integers(6, 154, 300), rng.integers(6, 114, 300)])
    eigen = cv2.cornerEigenValsAndVecs(image, 7, 3)[points[:, 1], points[:, 0], :2]
    expected = eigen.min(axis=1) / eigen.max(axis=1)
    assert structure_isotropy(image, points.astype(float)) == pytest.approx(expected, abs=1e-5)


def test_a_corner_is_isotropic_a_straight_edge_is_not_and_a_flat_patch_is_zero():
    image = _square(noise=1.0)
    corner, edge, flat = (100, 80), (160, 80), (40, 40)
    ratios = structure_isotropy(image, np.array([corner, edge, flat], dtype=float))
    assert ratios[0] > 0.3
    assert ratios[1] < EDGE_ISOTROPY
    assert structure_isotropy(_square(), np.array([flat], dtype=float))[0] == 0.0


def test_points_at_the_border_and_no_points_are_measured_without_error():
    image = _square()
    ratios = structure_isotropy(image, np.array([[0.0, 0.0], [319.4, 239.6], [-5.0, 300.0]]))
    assert ratios.shape == (3,) and np.all((ratios >= 0.0) & (ratios <= 1.0))
    assert structure_isotropy(image, np.zeros((0, 2))).shape == (0,)
