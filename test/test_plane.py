"""Tests for initsel_ros.plane."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.plane import (
    PLANE_MIN_POINTS,
    depth_sigma,
    fit_plane,
    homography_normals,
    normal_drift_deg,
    plane_normal,
    snap_to_plane,
)


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


def _ground_flight(frames: int):
    """Pixels of 200 points of flat ground 10 m below a camera pitched 60 degrees from
    looking straight down, flying 4 cm a frame along the ground and yawing 0.05 degrees a
    frame (noise-free), and the ground's normal in the reference camera's frame."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    down = Rotation.from_euler('x', -30, degrees=True).as_matrix()  # camera -> world
    ground = np.c_[rng.uniform(-6, 6, 200), rng.uniform(4, 30, 200), np.full(200, 10.0)]
    ground = ground @ Rotation.from_euler('x', 90, degrees=True).as_matrix().T

    def project(R, C):  # world -> pixels of a camera at C with camera-to-world rotation R
        X = (ground - C) @ R
        return (X[:, :2] / X[:, 2:]) @ K[:2, :2].T + K[:2, 2], X

    poses = [
        (down @ Rotation.from_euler('y', 0.05 * k, degrees=True).as_matrix(), [0.04 * k, 0, 0])
        for k in range(frames)
    ]
    pixels = [project(R, np.asarray(C))[0] for R, C in poses]
    ref_points = project(poses[0][0], np.zeros(3))[1]
    return K, pixels, ref_points


def test_the_right_plane_stays_with_later_homographies_and_the_mirrored_one_drifts():
    """H's two decompositions fit the fire frame equally; the mirrored one's plane is that
    frame's alone, and the later frames' homographies do not decompose into it."""
    K, pixels, truth = _ground_flight(16)
    normals = homography_normals(pixels[0], pixels[3], K, 1.0)
    assert len(normals) == 4  # +-n for each of the two decompositions
    rays = np.c_[(pixels[0] - K[:2, 2]) / K[0, 0], np.ones(len(truth))]
    true_normal = fit_plane(truth)
    true_normal /= np.linalg.norm(true_normal)
    mirrored = max(normals, key=lambda n: 1 - abs(n @ true_normal))
    assert abs(mirrored @ true_normal) < 0.99  # a different plane
    mirrored_map = rays / (rays @ mirrored)[:, None]  # the same rays, on the mirrored plane
    mirrored_map *= np.sign(mirrored_map[:, 2:3])
    mirrored_plane = fit_plane(mirrored_map)
    mirrored_plane /= np.linalg.norm(mirrored_plane)
    later = [homography_normals(pixels[0], p, K, 1.0) for p in pixels[4:]]
    right = [normal_drift_deg(true_normal, normals) for normals in later]
    wrong = [normal_drift_deg(mirrored_plane, normals) for normals in later]
    assert max(right) < 0.05
    assert min(wrong) > 1.0


def test_no_plane_or_no_homography_gives_no_drift():
    assert len(homography_normals(np.zeros((5, 2)), np.zeros((5, 2)), np.eye(3), 1.0)) == 0
    assert np.isnan(normal_drift_deg(np.array([0.0, 0, 1]), np.zeros((0, 3))))
    assert plane_normal(np.zeros((3, 3)), np.eye(3), np.array([1.0, 0, 0]), 0.2, 500) is None


def test_the_plane_normal_is_as_uncertain_as_the_noise_over_the_parallax():
    """A wall of 200 points 2 m away seen from 10 cm and from 40 cm: the normal's standard
    deviation scales with the noise and falls with the baseline; fitted to points with that
    much depth noise, the normal errs by about that much."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(-1, 1, (200, 2))
    wall = np.c_[xy, 2.0 + 0.3 * xy[:, 0]]  # tilted about the y axis
    true = np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    R = np.eye(3)
    short, long = (plane_normal(wall, R, np.array([b, 0.0, 0.0]), 0.5, 500.0) for b in (0.1, 0.4))
    assert short is not None and long is not None
    assert abs(short.normal @ true) > 0.9999
    assert 3.0 < short.sigma_deg / long.sigma_deg < 5.0  # parallax grows 4 times
    doubled = plane_normal(wall, R, np.array([0.1, 0.0, 0.0]), 1.0, 500.0)
    assert doubled.sigma_deg == pytest.approx(2 * short.sigma_deg)
    # the uncertainty is what the noise does to the fit: depths off by their sigma
    sigma = depth_sigma(wall, R, np.array([0.1, 0.0, 0.0]), 0.5, 500.0)
    errors = []
    for seed in range(200):
        noisy = wall * (1 + sigma * np.random.default_rng(seed).standard_normal(200))[:, None]
        fitted = plane_normal(noisy, R, np.array([0.1, 0.0, 0.0]), 0.5, 500.0)
        errors.append(np.degrees(np.arccos(min(abs(fitted.normal @ true), 1.0))))
    assert 0.5 * short.sigma_deg < np.sqrt(np.mean(np.square(errors))) < 2 * short.sigma_deg
