"""Tests for initsel_ros.plane."""

from __future__ import annotations

import numpy as np

from initsel_ros.plane import PLANE_MIN_POINTS, snap_to_plane


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


def test_points_of_a_wall_move_onto_it_along_their_rays():
    true, noisy = _wall(200, seed=1)
    fit = snap_to_plane(noisy)
    assert fit.on_plane.mean() > 0.95
    assert _relative_depth_error(fit.points, true) < 0.2 * _relative_depth_error(noisy, true)
    assert fit.depth_sigma > 0.02  # the 3 % noise, measured
    # each point moved along its own ray: its pixel is the same
    np.testing.assert_allclose(fit.points[:, :2] / fit.points[:, 2:], noisy[:, :2] / noisy[:, 2:])
    np.testing.assert_allclose(fit.points[fit.on_plane] @ fit.normal_over_distance, 1.0)


def test_points_off_the_plane_keep_their_depth():
    true, noisy = _wall(200, seed=2, depth_noise=0.01)
    off = np.arange(200) < 40  # boxes on the wall's floor, 30 % nearer
    noisy[off] *= 0.7
    fit = snap_to_plane(noisy)
    assert not fit.on_plane[off].any()
    np.testing.assert_array_equal(fit.points[off], noisy[off])
    assert _relative_depth_error(fit.points[~off], true[~off]) < 0.003


def test_nothing_moves_without_a_plane_to_fit():
    _, noisy = _wall(PLANE_MIN_POINTS - 1, seed=3)
    assert not snap_to_plane(noisy).on_plane.any()
    _, noisy = _wall(50, seed=4)
    noisy[0, 2] = -1.0  # a point behind the camera
    assert snap_to_plane(noisy).points is not None
    assert not snap_to_plane(noisy).on_plane.any()
    noisy[0, 2] = np.nan
    fit = snap_to_plane(noisy)
    assert not fit.on_plane.any() and np.isnan(fit.depth_sigma)
