"""Tests for initsel_ros.plane."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.plane import PLANE_MIN_POINTS, depth_sigma, snap_to_plane


def _wall(n: int, seed: int, depth_noise: float = 0.03):
    """Points on a tilted wall 2 m ahead (n . X = 2), each with a relative depth error."""
    rng = np.random.default_rng(seed)
    normal = np.array([np.sin(0.35), 0.0, np.cos(0.35)])
    rays = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.4, 0.4, n), np.ones(n)])
    true = rays * (2.0 / (rays @ normal))[:, None]
    noisy = true * (1.0 + rng.normal(0.0, depth_noise, n))[:, None]
    return true, noisy


def _relative_depth_error(points: np.ndarray, true: np.ndarray) -> float:
    return float(np.median(np.abs(points[:, 2] - true[:, 2]) / true[:, 2]))


def test_the_depth_uncertainty_is_the_noise_over_the_parallax():
    # a point 2 m ahead seen from 3.5 cm aside: 1 degree of parallax
    points = np.array([[0.0, 0.0, 2.0]])
    sigma = depth_sigma(points, np.eye(3), np.array([-0.0349, 0.0, 0.0]), 0.5, 500.0)
    assert sigma[0] == pytest.approx(np.sqrt(2) * 0.5 / (500.0 * np.arctan(0.0349 / 2.0)))
    assert 0.080 < sigma[0] < 0.082  # 8 % of the depth, one sigma
    # no baseline: no depth at all
    assert np.isinf(depth_sigma(points, np.eye(3), np.zeros(3), 0.5, 500.0)[0])


def test_points_of_a_wall_move_onto_it_along_their_rays():
    true, noisy = _wall(200, seed=1)
    fit = snap_to_plane(noisy, np.full(200, 0.03))
    assert fit.on_plane.mean() > 0.95
    assert _relative_depth_error(fit.points, true) < 0.2 * _relative_depth_error(noisy, true)
    # each point moved along its own ray: its pixel is the same
    np.testing.assert_allclose(fit.points[:, :2] / fit.points[:, 2:], noisy[:, :2] / noisy[:, 2:])
    np.testing.assert_allclose(fit.points[fit.on_plane] @ fit.normal_over_distance, 1.0)


def test_points_off_the_plane_by_more_than_their_uncertainty_keep_their_depth():
    true, noisy = _wall(200, seed=2, depth_noise=0.01)
    off = np.arange(200) < 40  # boxes on the wall's floor, 10 % nearer
    noisy[off] *= 0.9
    fit = snap_to_plane(noisy, np.full(200, 0.01))
    assert not fit.on_plane[off].any()
    np.testing.assert_array_equal(fit.points[off], noisy[off])
    assert _relative_depth_error(fit.points[~off], true[~off]) < 0.003
    # with a tenth of the parallax (ten times the uncertainty) the views cannot tell them apart
    blurred = snap_to_plane(noisy, np.full(200, 0.1))
    assert blurred.on_plane[off].all()


def test_nothing_moves_without_a_plane_to_fit():
    _, noisy = _wall(PLANE_MIN_POINTS - 1, seed=3)
    assert not snap_to_plane(noisy, np.full(len(noisy), 0.03)).on_plane.any()
    _, noisy = _wall(50, seed=4)
    sigma = np.full(50, 0.03)
    noisy[0, 2] = -1.0  # a point behind the camera stays where it is
    fit = snap_to_plane(noisy, sigma)
    assert not fit.on_plane[0] and fit.on_plane[1:].any()
    noisy[1, 2] = np.nan
    assert not snap_to_plane(noisy, sigma).on_plane[:2].any()
    assert not snap_to_plane(noisy, np.full(50, np.inf)).on_plane.any()
