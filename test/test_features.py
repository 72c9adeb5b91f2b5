"""Tests for initsel_ros.features."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.errors import GeometryError
from initsel_ros.features import (
    FEATURE_NAMES,
    Scaling,
    pair_features,
    raw_features,
    scale_features,
)
from initsel_ros.geometry import ROTATION_FOCAL_SCALES


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
    bins = raw_features(np.zeros((1, 2)), np.array([[dx, dy]]))[15:23]
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
    live = extra_features(p0, p1, 640, 480, camera=(K[0, 0], K[1, 1], K[0, 2], K[1, 2]))
    assert live.shape == (len(EXTRA_FEATURE_NAMES),) and np.all(np.isfinite(live))
    np.testing.assert_array_equal([row[name] for name in EXTRA_FEATURE_NAMES], live)


def _reference_extra_features(
    p0: np.ndarray, p1: np.ndarray, width: int, height: int, K: np.ndarray | None = None
):
    """The extra features by their textbook definitions (np.percentile, a lstsq affine fit,
    cv2.findHomography's least-squares homography refined by Levenberg-Marquardt, the moments
    of the flow and points, the lstsq DLT homography and, with a camera ``K``, that
    homography's departure from a rotation, and the least of it over the rotation test's
    focal scales)."""
    import math

    import cv2

    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    n, diag = len(p0), math.hypot(width, height)
    out = np.full(18, np.nan)
    if n == 0:
        return out
    out[0:3] = np.percentile(np.hypot(*(p1 - p0).T), (10, 50, 90)) / diag
    gx = np.clip((p0[:, 0] * (4 / width)).astype(int), 0, 3)
    gy = np.clip((p0[:, 1] * (4 / height)).astype(int), 0, 3)
    counts = np.bincount(gy * 4 + gx, minlength=16)
    prob = counts[counts > 0] / n
    out[3], out[4] = np.count_nonzero(counts) / 16, -(prob * np.log(prob)).sum() / math.log(16)
    if n >= 3:
        A = np.column_stack((p0, np.ones(n)))
        sol, *_ = np.linalg.lstsq(A, p1, rcond=None)
        out[5] = math.sqrt(np.mean(np.sum((p1 - A @ sol) ** 2, axis=1))) / diag
    if n >= 4:
        H, _ = cv2.findHomography(p0.reshape(-1, 1, 2), p1.reshape(-1, 1, 2), 0)
        if H is not None and H.shape == (3, 3):
            proj = cv2.perspectiveTransform(p0.reshape(-1, 1, 2), H).reshape(-1, 2)
            out[6] = math.sqrt(np.mean(np.sum((proj - p1) ** 2, axis=1))) / diag
    if n < 3:
        return out
    # The moments: mean flow, its coherence and spread, the points' spread.
    d = p1 - p0
    out[7:9] = d.mean(axis=0) / diag
    out[9] = np.linalg.norm(d.mean(axis=0)) / np.hypot(*d.T).mean()
    out[10] = math.sqrt(np.mean(np.sum((d - d.mean(axis=0)) ** 2, axis=1))) / diag
    out[11] = math.sqrt(np.mean(np.sum((p0 - p0.mean(axis=0)) ** 2, axis=1))) / diag
    # The linear part of the least-squares affine map: (u, v) = A (x, y) + t.
    sol, *_ = np.linalg.lstsq(np.column_stack((p0, np.ones(n))), p1, rcond=None)
    (a11, a21), (a12, a22) = sol[0], sol[1]
    out[12], out[13] = (a11 + a22) / 2 - 1, (a21 - a12) / 2
    out[14] = math.hypot((a11 - a22) / 2, (a12 + a21) / 2)
    if n >= 4:  # the linear homography (h33 = 1) in centred coordinates times 2^-k ~ 1 / size
        scale = 2.0 ** -math.frexp(max(width, height))[1]
        X, Y = ((p0 - [width / 2, height / 2]) * scale).T
        u, v = ((p1 - [width / 2, height / 2]) * scale).T
        A, b = _dlt_system(X, Y, u, v)
        h, *_ = np.linalg.lstsq(A, b, rcond=None)
        out[15] = math.sqrt(np.mean((A @ h - b) ** 2) * 2) / scale / diag
        if K is not None:  # G = K^-1 H K of the pixel homography, det 1, against a rotation
            S = np.array(
                [[scale, 0, -scale * width / 2], [0, scale, -scale * height / 2], [0, 0, 1]]
            )
            H = np.linalg.inv(S) @ np.append(h, 1.0).reshape(3, 3) @ S
            G = np.linalg.inv(K) @ H @ K
            G /= np.cbrt(np.linalg.det(G))
            out[16] = np.linalg.norm(G.T @ G - np.eye(3))
            departures = []
            for f in ROTATION_FOCAL_SCALES:
                F = np.diag([f, f, 1.0])
                Gf = np.linalg.inv(F) @ G @ F
                departures.append(np.linalg.norm(Gf.T @ Gf - np.eye(3)))
            out[17] = min(departures)
    return out


def _dlt_system(
    X: np.ndarray, Y: np.ndarray, u: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The linear homography's equations A h = b (h33 = 1), two rows per point, written out
    as a textbook does."""
    zero, one = np.zeros_like(X), np.ones_like(X)
    A = np.concatenate(
        (
            np.column_stack((X, Y, one, zero, zero, zero, -u * X, -u * Y)),
            np.column_stack((zero, zero, zero, X, Y, one, -v * X, -v * Y)),
        )
    )
    return A, np.concatenate((u, v))


def _perspective_tracks(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Integer reference corners (as the tracker detects them) and a current view of a plane
    tilted away from the camera plus parallax noise, float32."""
    p0 = np.floor(rng.uniform(0, 1, (n, 2)) * [640, 480]).astype(np.float32)
    H = np.array([[1.03, 0.02, 8.0], [-0.01, 0.97, -5.0], [2e-4, -1e-4, 1.0]])
    q = np.c_[p0, np.ones(n)] @ H.T
    p1 = q[:, :2] / q[:, 2:] + rng.normal(0, 1.5, (n, 2))
    return p0, p1.astype(np.float32)


@pytest.mark.parametrize('n', [0, 1, 2, 3, 4, 5, 9, 60, 300])
def test_extra_features_equal_their_textbook_definitions(n):
    from geometry_fixtures import K

    from initsel_ros.features import EXTRA_FEATURE_NAMES, extra_features

    camera = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    for make, K_given in ((_tracks, None), (_perspective_tracks, K)):
        p0, p1 = make(np.random.default_rng(n), n)
        live = extra_features(p0, p1, 640, 480, camera=None if K_given is None else camera)
        ref = _reference_extra_features(p0, p1, 640, 480, K_given)
        assert live.shape == (len(EXTRA_FEATURE_NAMES),)
        np.testing.assert_array_equal(np.isnan(live), np.isnan(ref))
        np.testing.assert_array_equal(live[:4], ref[:4])  # percentiles, occupancy: bit-equal
        np.testing.assert_allclose(live[4:6], ref[4:6], rtol=1e-9, atol=1e-12, equal_nan=True)
        # The homography residual: one Gauss-Newton step from the DLT, against OpenCV's
        # Levenberg-Marquardt (cv2 works in float32 inside, hence the tolerance for 4 points).
        np.testing.assert_allclose(live[6], ref[6], rtol=1e-4, atol=1e-9, equal_nan=True)
        # The moments and the linear homography, from one Gram matrix (the DLT's algebraic
        # residual, a difference of sums, is exact to the precision of those sums).
        np.testing.assert_allclose(live[7:15], ref[7:15], rtol=1e-8, atol=1e-12, equal_nan=True)
        np.testing.assert_allclose(live[15], ref[15], rtol=1e-5, atol=1e-8, equal_nan=True)
        np.testing.assert_allclose(live[16:18], ref[16:18], rtol=1e-6, atol=1e-9, equal_nan=True)


def test_flow_moments_tell_a_shift_a_zoom_and_a_roll_apart():
    import math

    from initsel_ros.features import MOMENT_FEATURE_NAMES, extra_features

    p0, _ = _tracks(np.random.default_rng(3), 150)
    p0 = p0.astype(np.float64)
    centre = np.array([320.0, 240.0])
    c, s = math.cos(0.02), math.sin(0.02)
    motions = {
        'shift': p0 + np.array([6.0, -2.0]),
        'zoom': centre + (p0 - centre) * 1.04,
        'roll': centre + (p0 - centre) @ np.array([[c, -s], [s, c]]).T,
    }
    names = MOMENT_FEATURE_NAMES
    got = {
        k: dict(zip(names, extra_features(p0, p1, 640, 480, names), strict=True))
        for k, p1 in motions.items()
    }
    assert got['shift']['x_flow_coherence'] == pytest.approx(1.0)
    assert got['shift']['x_flow_mean_x'] == pytest.approx(6.0 / 800.0)
    assert got['shift']['x_flow_spread'] == pytest.approx(0.0, abs=1e-9)
    assert got['zoom']['x_affine_divergence'] == pytest.approx(0.04)
    assert got['roll']['x_affine_curl'] == pytest.approx(0.02, rel=1e-3)
    for k in ('zoom', 'roll'):
        assert got[k]['x_flow_coherence'] < 0.5 < got['shift']['x_flow_coherence']
    for motion in got.values():  # every one of them a homography
        assert motion['x_homography_dlt_residual'] < 1e-7  # 1e-4 px: the sums' rounding
        assert motion['x_affine_deformation'] < 1e-6


@pytest.mark.parametrize('motion', ['exact shift', 'noisy perspective'])
def test_linear_homography_from_the_gram_matrix_equals_least_squares(motion):
    """The bordered normal equations the Gram matrix's entries assemble are the textbook
    ones, and their solve (noisy tracks) and the plain one it falls back to when the
    homography fits exactly (the bordered system is then singular) give the DLT's h and its
    sum of squares as np.linalg.lstsq does."""
    import cv2

    from initsel_ros import features

    rng = np.random.default_rng(5)
    if motion == 'exact shift':
        p0 = np.floor(rng.uniform(0, 1, (50, 2)) * [640, 480])
        p1 = p0 + np.array([6.0, -2.0])
    else:
        p0, p1 = _perspective_tracks(rng, 50)
    plan = features.input_plan(640, 480, extra=('x_homography_dlt_residual',), directions=False)
    pair = features.MeasuredPair(p0, p1, plan)
    X, Y, _, u, v = pair.fit[0:5]
    A, b = _dlt_system(X, Y, u, v)
    Ab = np.column_stack((A, b))
    flat = pair.gram.ravel()
    bordered = (flat.take(features._DLT_FIRST) + flat.take(features._DLT_SECOND)).reshape(9, 9)
    np.testing.assert_allclose(bordered, Ab.T @ Ab, rtol=1e-12, atol=1e-12 * len(p0))
    bordered_ok, _ = cv2.solve(bordered, features._LAST_UNIT)
    assert bordered_ok == (motion != 'exact shift')  # both paths are taken
    ss, vector, factor = features._linear_homography(pair.gram)
    h, *_ = np.linalg.lstsq(A, b, rcond=None)
    np.testing.assert_allclose((vector * factor)[:, 0], h, rtol=1e-7, atol=1e-10)
    assert ss == pytest.approx(float(np.sum((A @ h - b) ** 2)), rel=1e-6, abs=1e-12)


def test_a_plan_without_direction_bins_reads_zeros_there_and_the_same_elsewhere():
    from initsel_ros.features import MOMENT_FEATURE_NAMES, input_plan, model_inputs

    p0, p1 = _perspective_tracks(np.random.default_rng(9), 200)
    full, mean = model_inputs(p0, p1, input_plan(640, 480, extra=MOMENT_FEATURE_NAMES))
    lean, lean_mean = model_inputs(
        p0, p1, input_plan(640, 480, extra=MOMENT_FEATURE_NAMES, directions=False)
    )
    assert lean[15:23] == [0.0] * 8 and sum(full[15:23]) > 0
    assert lean[:15] + lean[23:] == full[:15] + full[23:] and lean_mean == mean


def test_grid_cells_split_integer_corners_as_the_truncated_product_does():
    from initsel_ros.features import extra_features

    # x = 160 is the first pixel of column 1 at width 640; 159.99998 (float32) is still column 0
    p0 = np.array([[159.99998, 10.0], [160.0, 10.0], [320.0, 119.99999], [320.0, 120.0]])
    occupancy, entropy = extra_features(
        p0, p0 + 1, 640, 480, ('x_grid_occupancy', 'x_grid_entropy')
    )
    assert occupancy == 4 / 16  # cells (0, 0), (1, 0), (2, 0), (2, 1)
    assert entropy == pytest.approx(1.0 / 2.0)  # four equal cells: log 4 / log 16
    # At these sizes j * size / 4 times 4 / size rounds below j for some j (y = 25.75 at
    # height 103 is in row 0): every quarter pixel falls where the truncated product puts it.
    for width, height in ((107, 103), (150, 117), (1241, 376)):
        xs, ys = np.meshgrid(np.arange(-2, width + 2, 0.25), np.arange(-2, height + 2, 0.25))
        p0 = np.c_[xs.ravel(), ys.ravel()].astype(np.float64)
        names = ('x_grid_occupancy', 'x_grid_entropy')
        got = extra_features(p0, p0, width, height, names)
        ref = _reference_extra_features(p0, p0, width, height)[3:5]
        assert got[0] == ref[0] and got[1] == pytest.approx(ref[1], rel=1e-12)
        one_column = p0[p0[:, 0] == width / 4]  # a column of points on a cell edge
        got = extra_features(one_column, one_column, width, height, names)
        ref = _reference_extra_features(one_column, one_column, width, height)[3:5]
        assert got[0] == ref[0] and got[1] == pytest.approx(ref[1], rel=1e-12, abs=1e-15)


def test_raw_features_equal_the_straightforward_numpy_computation():
    rng = np.random.default_rng(7)
    for n in (1, 2, 17, 300):
        p0, p1 = _perspective_tracks(rng, n)
        q0, q1 = p0.astype(np.float64), p1.astype(np.float64)
        d = q1 - q0
        disparity = np.hypot(d[:, 0], d[:, 1])
        rows = np.c_[q0, q1].T
        expected = np.concatenate(
            (
                [n, disparity.mean(), disparity.std()],
                np.c_[rows.min(axis=1), rows.max(axis=1)].ravel(),
                rows.max(axis=1) - rows.min(axis=1),
                # 8 direction bins centred on 0, 45, ..., 315 degrees, image y up
                np.bincount(
                    np.rint(np.arctan2(-d[:, 1], d[:, 0]) / (np.pi / 4)).astype(int) % 8,
                    minlength=8,
                ),
            )
        )
        f = raw_features(p0, p1)
        np.testing.assert_array_equal(f[[0, *range(3, 23)]], expected[[0, *range(3, 23)]])
        np.testing.assert_allclose(f[1:3], expected[1:3], rtol=1e-14)


def test_model_inputs_are_the_scaled_features_then_the_extra_ones():
    from initsel_ros.features import EXTRA_FEATURE_NAMES, extra_features, input_plan, model_inputs

    p0, p1 = _perspective_tracks(np.random.default_rng(8), 120)
    names = ('x_homography_residual', 'x_grid_entropy')
    values, mean = model_inputs(p0, p1, input_plan(640, 480, Scaling.PAPER, names))
    assert len(values) == 23 + len(names)
    # (with a fit, the disparity's mean and spread come from its sums: equal to 1e-15)
    np.testing.assert_allclose(
        values[:23], pair_features(p0, p1, 640, 480, Scaling.PAPER), rtol=1e-14, atol=0
    )
    assert values[3:23] == pair_features(p0, p1, 640, 480, Scaling.PAPER).tolist()[3:]
    assert values[23:] == extra_features(p0, p1, 640, 480, names).tolist()
    assert mean == pytest.approx(raw_features(p0, p1)[1], rel=1e-14)
    with pytest.raises(GeometryError, match='unknown extra features'):
        input_plan(640, 480, Scaling.PAPER, ('x_magic',))
    assert set(EXTRA_FEATURE_NAMES) >= set(names)


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


def test_a_second_plan_from_the_same_pass_gets_what_its_own_pass_gives():
    """A referee's inputs come from the pass the file's own models made (same fit rows and
    image size); other fit rows or another size measure afresh. Either way the values are the
    ones the plan gets alone, to the bit."""
    from initsel_ros.features import EXTRA_FEATURE_NAMES, MeasuredPair, input_plan, model_inputs

    p0, p1 = _perspective_tracks(np.random.default_rng(4), 150)
    student = input_plan(640, 480, extra=('x_flow_mean_x', 'x_homography_dlt_residual'))
    teacher = input_plan(640, 480, extra=EXTRA_FEATURE_NAMES[:7], directions=True)
    moments = input_plan(640, 480, extra=('x_affine_curl',), directions=False)  # 6 fit rows
    other_size = input_plan(800, 600, extra=EXTRA_FEATURE_NAMES[:7])
    pair = MeasuredPair(p0, p1, student)
    assert pair.inputs(student) == model_inputs(p0, p1, student)
    for plan in (teacher, moments, other_size):
        alone = model_inputs(p0, p1, plan)
        assert pair.inputs(plan) == alone
        assert np.all(np.isfinite(alone[0]))
    # the pass is shared where it can be (the linear homography solved once), not elsewhere
    assert pair._dlt and pair._same_pass(teacher)
    assert not pair._same_pass(moments) and not pair._same_pass(other_size)


def _views(R: np.ndarray, t: np.ndarray, depth: np.ndarray, K: np.ndarray, rng):
    """Pixels of points at ``depth`` (N,) in a reference view and after the motion (R, t)."""
    n = len(depth)
    rays = np.c_[rng.uniform(-0.5, 0.5, (n, 2)), np.ones(n)]
    X = rays * depth[:, None]
    p0 = (X / X[:, 2:]) @ K.T
    Y = X @ R.T + t
    p1 = (Y / Y[:, 2:]) @ K.T
    return p0[:, :2], p1[:, :2]


def test_rotation_departure_is_zero_for_any_rotation_and_grows_with_a_plane_slid_along():
    """The homography of a pan is K R K^-1 whatever the depths: no departure. A wall slid
    along (the planar arc's case, a flow close to a pan's) departs by sqrt(2) |t| / d to first
    order, at any image size and focal length; without a camera the feature is NaN."""
    from initsel_ros.features import extra_features

    rng = np.random.default_rng(4)
    angle = np.radians(3.0)
    R = np.array(
        [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    )
    name = ('x_rotation_departure',)
    for f, size in ((535.0, (640, 480)), (300.0, (1241, 376)), (1070.0, (1280, 960))):
        K = np.array([[f, 0, size[0] / 2 + 7], [0, f, size[1] / 2 - 5], [0, 0, 1.0]])
        camera = (f, f, K[0, 2], K[1, 2])
        scene = rng.uniform(1.0, 8.0, 200)
        pan = extra_features(*_views(R, np.zeros(3), scene, K, rng), *size, name, camera)[0]
        assert pan < 1e-9
        wall = np.full(200, 3.5)
        slides = [
            extra_features(*_views(R, [b, 0, 0], wall, K, rng), *size, name, camera)[0]
            for b in (0.02, 0.1, 0.3)
        ]
        assert slides[0] < slides[1] < slides[2]
        assert slides[1] == pytest.approx(np.sqrt(2) * 0.1 / 3.5, rel=0.05)
        assert np.isnan(extra_features(*_views(R, np.zeros(3), scene, K, rng), *size, name)[0])


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_focal_departure_forgives_a_miscalibrated_pan_and_not_a_slide():
    """A pan seen through a focal length 10 % off is S R S^-1 to the stated camera: it
    departs from a rotation as a slide does, and under the best focal scale hardly at all.
    A slide along a wall keeps its departure (divided by at most the largest scale, 1.15)."""
    from initsel_ros.features import extra_features

    rng = np.random.default_rng(7)
    R = _yaw(np.radians(5.0))
    names = ('x_rotation_departure', 'x_rotation_departure_focal')
    f, size = 535.0, (640, 480)
    stated = (f, f, 327.0, 235.0)
    for error in (0.9, 1.1):
        true_K = np.array([[error * f, 0, 327.0], [0, error * f, 235.0], [0, 0, 1.0]])
        views = _views(R, np.zeros(3), rng.uniform(1.0, 8.0, 200), true_K, rng)
        plain, focal = extra_features(*views, *size, names, stated)
        assert plain > 0.015
        assert focal < 0.15 * plain
    K = np.array([[f, 0, 327.0], [0, f, 235.0], [0, 0, 1.0]])
    wall = np.full(200, 3.5)
    for b in (0.05, 0.2):  # a slide, and an arc turning to keep the wall centred
        for turn in (0.0, -np.arcsin(b / 3.5)):
            views = _views(_yaw(turn), [b, 0, 0], wall, K, rng)
            plain, focal = extra_features(*views, *size, names, stated)
            assert plain / 1.16 < focal <= plain
    # The limit: turning toward the side it slides to, by about as much as it slides, the
    # flow is a pan's under a focal length sqrt(1 + (b / d) / angle) times the stated one
    # (1.08 here), to first order; such a pair reads as a miscalibrated rotation.
    views = _views(R, [0.05, 0, 0], wall, K, rng)
    plain, focal = extra_features(*views, *size, names, stated)
    assert focal < 0.15 * plain
    views = _views(R, np.zeros(3), rng.uniform(1.0, 8.0, 200), K, rng)
    assert extra_features(*views, *size, names, stated)[1] < 1e-4  # (the nearest scale: 1.0003)
    assert np.isnan(extra_features(*views, *size, names)[1])


def test_a_model_set_reading_a_camera_feature_warns_without_a_camera(caplog):
    from initsel_ros.features import FEATURE_NAMES
    from initsel_ros.models import METHODS, LogisticModel, ModelSet

    names = (*FEATURE_NAMES, 'x_rotation_departure')
    k = len(names)
    models = ModelSet(
        {
            m: LogisticModel(m, np.ones(k), 0.0, 0.5, np.zeros(k), np.ones(k), features=names)
            for m in METHODS
        }
    )
    rng = np.random.default_rng(0)
    p0, p1 = _perspective_tracks(rng, 50)
    with caplog.at_level('WARNING'):
        values = models.input_values(p0, p1, 640, 480)[0]
    assert np.isnan(values[-1]) and 'no camera' in caplog.text
    values = models.input_values(p0, p1, 640, 480, (535.4, 539.2, 320.1, 247.6))[0]
    assert np.isfinite(values[-1]) and values[-1] > 0


@pytest.mark.parametrize(
    'camera',
    [(0.0, 535.0, 320.0, 240.0), (-5.0, 535.0, 320.0, 240.0), (math.nan, 535.0, 320.0, 240.0),
     (math.inf, 535.0, 320.0, 240.0), (535.0, 535.0, math.nan, 240.0), (535.0, 535.0, 320.0),
     'fx'],
)  # fmt: skip
def test_a_bad_camera_is_a_clear_error(camera):
    from initsel_ros.features import extra_features

    p0, p1 = _perspective_tracks(np.random.default_rng(0), 20)
    with pytest.raises(GeometryError, match='camera'):
        extra_features(p0, p1, 640, 480, ('x_rotation_departure',), camera)


def test_a_camera_given_as_a_list_or_array_reads_as_the_tuple():
    from initsel_ros.features import FEATURE_NAMES, extra_features
    from initsel_ros.models import METHODS, LogisticModel, ModelSet

    p0, p1 = _perspective_tracks(np.random.default_rng(0), 40)
    camera = (535.4, 539.2, 320.1, 247.6)
    name = ('x_rotation_departure',)
    want = extra_features(p0, p1, 640, 480, name, camera)
    for given in (list(camera), np.array(camera)):
        np.testing.assert_array_equal(extra_features(p0, p1, 640, 480, name, given), want)
    names = (*FEATURE_NAMES, *name)
    k = len(names)
    models = ModelSet(
        {m: LogisticModel(m, np.ones(k), 0.0, 0.5, np.zeros(k), np.ones(k), features=names)
         for m in METHODS}
    )  # fmt: skip
    for given in (camera, list(camera), np.array(camera)):
        assert models.input_values(p0, p1, 640, 480, given)[0][-1] == want[0]


def test_a_camera_whose_focal_length_keeps_changing_does_not_grow_the_plan_cache():
    from initsel_ros.models import MAX_PLANS

    models = _camera_reading_models()
    p0, p1 = _perspective_tracks(np.random.default_rng(0), 40)
    for k in range(3 * MAX_PLANS):
        models.input_values(p0, p1, 640, 480, (500.0 + k, 500.0 + k, 320.0, 240.0))
        assert len(models._plans) <= MAX_PLANS


def _camera_reading_models():
    from initsel_ros.features import FEATURE_NAMES
    from initsel_ros.models import METHODS, LogisticModel, ModelSet

    names = (*FEATURE_NAMES, 'x_rotation_departure')
    k = len(names)
    return ModelSet(
        {m: LogisticModel(m, np.ones(k), 0.0, 0.5, np.zeros(k), np.ones(k), features=names)
         for m in METHODS}
    )  # fmt: skip
