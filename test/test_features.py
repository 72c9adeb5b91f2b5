"""Tests for initsel_ros.features."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.errors import GeometryError
from initsel_ros.features import (
    FEATURE_NAMES,
    Scaling,
    batch_features,
    direction_bins,
    pair_features,
    raw_features,
    scale_features,
)


def test_raw_features_match_hand_computed_values():
    p0 = np.array([[10.0, 20.0], [30.0, 40.0], [50.0, 60.0]])
    p1 = np.array([[13.0, 24.0], [30.0, 40.0], [50.0, 48.0]])  # |d| = 5, 0, 12
    f = raw_features(p0, p1)
    assert len(f) == len(FEATURE_NAMES) == 23
    assert f[0] == 3
    assert f[1] == pytest.approx(17.0 / 3)
    assert f[2] == pytest.approx(np.std([5.0, 0.0, 12.0]))  # population std
    # min/max of x0, y0, x1, y1
    assert f[3:11].tolist() == [10, 50, 20, 60, 13, 50, 24, 48]
    assert f[11:15].tolist() == [40, 40, 37, 24]
    # (3, 4): image-down y -> angle of (3, -4) = -53 deg -> bin 315 (index 7);
    # zero motion -> bin 0; (0, -12): up in the image -> 90 deg -> index 2
    assert f[15:23].tolist() == [1, 0, 1, 0, 0, 0, 0, 1]


@pytest.mark.parametrize(
    ('dx', 'dy', 'expected_bin'),
    [
        (1, 0, 0),
        (1, -1, 1),
        (0, -1, 2),
        (-1, -1, 3),
        (-1, 0, 4),
        (-1, 1, 5),
        (0, 1, 6),
        (1, 1, 7),
        (1, -0.41, 0),
        (1, -0.42, 1),
    ],
)
def test_direction_bins_use_image_y_up_and_centre_on_multiples_of_45(dx, dy, expected_bin):
    bins = direction_bins(np.zeros((1, 2)), np.array([[dx, dy]]))
    assert np.flatnonzero(bins).tolist() == [expected_bin]


def test_paper_scaling_divides_by_the_authors_constants_and_bin_norm():
    rng = np.random.default_rng(1)
    p0 = rng.uniform(0, 640, (150, 2))
    p1 = p0 + rng.normal(0, 20, (150, 2))
    raw = raw_features(p0, p1)
    f = scale_features(raw, scaling=Scaling.PAPER)
    assert f[0] == pytest.approx(150 / 300)
    assert f[1] == pytest.approx(raw[1] / 800)
    assert f[3] == pytest.approx(raw[3] / 640)
    assert f[5] == pytest.approx(raw[5] / 480)
    assert np.linalg.norm(f[15:23]) == pytest.approx(1.0)


def test_scalings_agree_at_640x480_and_resolution_free_is_size_invariant():
    rng = np.random.default_rng(2)
    p0 = rng.uniform(0, 480, (100, 2))
    p1 = p0 + rng.normal(0, 10, (100, 2))
    paper = pair_features(p0, p1, 640, 480, Scaling.PAPER)
    free = pair_features(p0, p1, 640, 480, Scaling.RESOLUTION_FREE)
    np.testing.assert_allclose(paper, free)
    # The same scene at twice the resolution gives the same resolution-free features.
    double = pair_features(2 * p0, 2 * p1, 1280, 960, Scaling.RESOLUTION_FREE)
    np.testing.assert_allclose(double, free)
    assert not np.allclose(pair_features(2 * p0, 2 * p1, 1280, 960, Scaling.PAPER), paper)


def test_empty_set_gives_zeros_and_bad_shapes_raise():
    assert not pair_features(np.zeros((0, 2)), np.zeros((0, 2))).any()
    with pytest.raises(GeometryError, match='differ in shape'):
        raw_features(np.zeros((3, 2)), np.zeros((4, 2)))
    with pytest.raises(GeometryError, match=r'\(N, 2\)'):
        raw_features(np.zeros((3, 3)), np.zeros((3, 3)))


def test_batch_features_equal_per_pair_features():
    rng = np.random.default_rng(3)
    pairs = [(a := rng.uniform(0, 400, (n, 2)), a + rng.normal(0, 5, (n, 2))) for n in (5, 50, 9)]
    batch = batch_features(pairs, 640, 480)
    assert batch.shape == (3, 23)
    for row, (p0, p1) in zip(batch, pairs, strict=True):
        np.testing.assert_allclose(row, pair_features(p0, p1, 640, 480))


# ------------------------------------------------------------------ extra features (issue 10)
def _tracks(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    p0 = (rng.uniform(0, 1, (n, 2)) * [640, 480]).astype(np.float32)
    p1 = (p0 + rng.normal(0, 4, p0.shape) + [6, -3]).astype(np.float32)
    return p0, p1


def test_the_pair_table_stores_the_live_extra_features():
    from geometry_fixtures import K, two_view

    from initsel_ros.features import EXTRA_FEATURE_NAMES, extra_features
    from initsel_ros.learn.correspondences import Pair, Source
    from initsel_ros.learn.labels import label_pair
    from initsel_ros.learn.pairs import DatasetConfig, pair_row

    p0, p1, R, t, _ = two_view(planar=False, n=120)
    T_cur = np.eye(4)
    T_cur[:3, :3], T_cur[:3, 3] = R.T, -R.T @ t  # camera-to-world of the moved camera
    labels = label_pair(p0, p1, K, None, np.eye(4), T_cur)
    config = DatasetConfig(orbslam_iterations=0, vins_ransac=False)
    row = pair_row(
        's', 0, Pair(0, 1, p0, p1), (0.0, 0.1), (640, 480), K, labels, Source.KLT, config
    )
    live = extra_features(p0, p1, 640, 480)
    assert live.shape == (len(EXTRA_FEATURE_NAMES),) and np.all(np.isfinite(live))
    np.testing.assert_array_equal([row[name] for name in EXTRA_FEATURE_NAMES], live)


def test_extra_features_are_computed_for_the_names_asked_in_their_order():
    from initsel_ros.features import EXTRA_FEATURE_NAMES, extra_features

    p0, p1 = _tracks(np.random.default_rng(1), 200)
    full = dict(zip(EXTRA_FEATURE_NAMES, extra_features(p0, p1, 640, 480), strict=True))
    names = ('x_homography_residual', 'x_disp_p10', 'x_grid_entropy')
    assert extra_features(p0, p1, 640, 480, names).tolist() == [full[n] for n in names]
    with pytest.raises(GeometryError, match='unknown extra features'):
        extra_features(p0, p1, 640, 480, ('x_magic',))


def test_homography_and_affine_residuals_vanish_on_their_own_motions():
    from initsel_ros.features import extra_features

    p0, _ = _tracks(np.random.default_rng(2), 100)
    H = np.array([[1.02, 0.01, 5.0], [-0.01, 0.99, -3.0], [1e-5, 2e-5, 1.0]])
    q = np.c_[p0, np.ones(len(p0))] @ H.T
    planar = (q[:, :2] / q[:, 2:]).astype(np.float64)
    affine = p0 @ np.array([[1.01, 0.02], [-0.02, 0.98]]).T + [4.0, 2.0]
    names = ('x_affine_residual', 'x_homography_residual')
    assert extra_features(p0, planar, 640, 480, names)[1] < 1e-5
    assert extra_features(p0, affine, 640, 480, names).max() < 1e-5
    occupancy, entropy = extra_features(
        np.full((20, 2), 10.0),
        np.full((20, 2), 12.0),
        640,
        480,
        ('x_grid_occupancy', 'x_grid_entropy'),
    )
    assert occupancy == 1 / 16 and entropy == 0.0  # every point in one cell
