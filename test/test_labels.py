"""Labels on constructed two-view cases with exact ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.errors import ConfigError
from initsel_ros.learn.labels import LabelConfig, ScaleRule, backproject, label_pair, relabel

K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
W, H = 640, 480


def _blocky_depth(rng: np.random.Generator, block: int = 40) -> np.ndarray:
    """A non-planar scene: depth constant over 40 px blocks, 1.5 .. 4 m."""
    coarse = rng.uniform(1.5, 4.0, (H // block, W // block)).astype(np.float32)
    return np.kron(coarse, np.ones((block, block), np.float32))


def _pose(R: np.ndarray, centre: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = centre
    return T


def _rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _correspondences(rng, depth, T_w_cur, n=250, noise=0.2):
    """Reference pixels inside blocks (away from depth edges) and their exact projections."""
    bx = rng.integers(0, W // 40, n) * 40 + rng.uniform(8, 32, n)
    by = rng.integers(0, H // 40, n) * 40 + rng.uniform(8, 32, n)
    p0 = np.column_stack((bx, by))
    X, valid = backproject(p0, depth, K)
    assert valid.all()
    T_cur_w = np.linalg.inv(T_w_cur)
    Xc = X @ T_cur_w[:3, :3].T + T_cur_w[:3, 3]
    x = Xc @ K.T
    p1 = x[:, :2] / x[:, 2:3] + rng.normal(0, noise, (n, 2))
    keep = (p1[:, 0] > 0) & (p1[:, 0] < W) & (p1[:, 1] > 0) & (p1[:, 1] < H)
    return p0[keep].astype(np.float32), p1[keep].astype(np.float32)


def test_clean_translation_pair_gets_e_label_and_small_errors():
    rng = np.random.default_rng(0)
    depth = _blocky_depth(rng)
    T_cur = _pose(_rot_y(0.03), np.array([0.25, 0.02, 0.05]))
    p0, p1 = _correspondences(rng, depth, T_cur)
    labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur)
    assert labels.baseline_m == pytest.approx(np.linalg.norm([0.25, 0.02, 0.05]))
    assert labels.rotation_deg == pytest.approx(math.degrees(0.03), abs=1e-6)
    assert labels.r_label == 0
    e = labels.outcomes['E']
    assert e.ok
    assert e.et < 0.1
    assert e.er_median < 0.2 and e.er_first_two < 0.3  # metres, scene at 1.5-4 m
    assert labels.label('E') == 1
    assert e.n_gt_points == e.n_points > 50


def test_pure_rotation_gets_r_label_and_no_pose_label():
    rng = np.random.default_rng(1)
    depth = _blocky_depth(rng)
    T_cur = _pose(_rot_y(0.08), np.zeros(3))
    p0, p1 = _correspondences(rng, depth, T_cur)
    labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur)
    assert labels.baseline_m == pytest.approx(0.0, abs=1e-12)
    assert labels.r_label == 1
    for m in ('F', 'E', 'H'):
        assert labels.label(m) == 0  # no translation direction to get right
        assert math.isnan(labels.outcomes[m].et)


def test_small_baseline_just_below_the_rotation_threshold_is_r():
    labels_config = LabelConfig(rotation_baseline_m=0.05)
    rng = np.random.default_rng(2)
    depth = _blocky_depth(rng)
    T_cur = _pose(np.eye(3), np.array([0.049, 0.0, 0.0]))
    p0, p1 = _correspondences(rng, depth, T_cur)
    assert label_pair(p0, p1, K, depth, np.eye(4), T_cur, labels_config).r_label == 1
    T_cur = _pose(np.eye(3), np.array([0.051, 0.0, 0.0]))
    assert label_pair(p0, p1, K, depth, np.eye(4), T_cur, labels_config).r_label == 0


def test_backproject_skips_pixels_without_depth():
    depth = np.zeros((H, W), np.float32)
    depth[:, 320:] = 2.0
    pixels = np.array([[100.0, 100.0], [400.0, 100.0], [-5.0, 10.0], [700.0, 10.0]])
    X, valid = backproject(pixels, depth, K)
    assert valid.tolist() == [False, True, False, False]
    assert np.all(np.isnan(X[~valid]))
    assert X[1, 2] == 2.0
    assert X[1, 0] == pytest.approx((400.0 - 320.1) / 535.4 * 2.0)


def test_failed_estimate_is_label_zero_with_a_reason():
    rng = np.random.default_rng(3)
    depth = _blocky_depth(rng)
    T_cur = _pose(np.eye(3), np.array([0.2, 0.0, 0.0]))
    p0, p1 = _correspondences(rng, depth, T_cur, n=6)  # too few for F (8) and H's 8 points
    labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur)
    f = labels.outcomes['F']
    assert not f.ok and f.reason
    assert math.isnan(f.et) and labels.label('F') == 0


def test_relabel_applies_new_thresholds_to_stored_errors():
    columns = {
        'gt_baseline_m': np.array([0.01, 0.2, 0.3]),
        'scale_rule': np.array(['median'] * 3, dtype=object),
    }
    for m in ('F', 'E', 'H'):
        columns[f'{m}_ok'] = np.array([1, 1, 0])
        columns[f'{m}_et'] = np.array([0.1, 0.5, np.nan])
        columns[f'{m}_er_median'] = np.array([0.2, 0.2, np.nan])
        columns[f'{m}_er_first_two'] = np.array([2.0, 0.2, np.nan])
    strict = relabel(columns, LabelConfig(et_max=0.3))
    assert strict['E_label'].tolist() == [1, 0, 0]
    first_two = relabel(columns, LabelConfig(scale_rule=ScaleRule.FIRST_TWO))
    assert first_two['E_label'].tolist() == [0, 1, 0]
    assert first_two['scale_rule'][0] == 'first_two'
    assert relabel(columns, LabelConfig(rotation_baseline_m=0.25))['R_label'].tolist() == [
        1,
        1,
        0,
    ]
    assert columns['scale_rule'][0] == 'median'  # input untouched


def test_without_depth_labels_come_from_et_and_the_rotation_error():
    rng = np.random.default_rng(0)
    depth = _blocky_depth(rng)
    T_cur = _pose(_rot_y(0.03), np.array([0.25, 0.02, 0.05]))
    p0, p1 = _correspondences(rng, depth, T_cur)
    labels = label_pair(p0, p1, K, None, np.eye(4), T_cur)
    assert not labels.has_depth and labels.scale_rule == 'no_depth'
    e = labels.outcomes['E']
    assert e.ok and e.et < 0.1 and e.n_gt_points == 0
    assert math.isnan(e.er_median) and math.isnan(e.er_first_two)
    assert e.rotation_error_deg < 0.5
    assert labels.label('E') == 1
    strict = label_pair(
        p0,
        p1,
        K,
        None,
        np.eye(4),
        T_cur,
        LabelConfig(rotation_error_max_deg=e.rotation_error_deg / 2),
    )
    assert strict.label('E') == 0


def test_relabel_keeps_no_depth_rows_and_applies_the_rotation_threshold(caplog):
    columns = {
        'gt_baseline_m': np.array([0.2, 0.2, 0.2]),
        'scale_rule': np.array(['median', 'no_depth', 'no_depth'], dtype=object),
    }
    for m in ('F', 'E', 'H'):
        columns[f'{m}_ok'] = np.array([1, 1, 1])
        columns[f'{m}_et'] = np.array([0.1, 0.1, 0.5])
        columns[f'{m}_er_median'] = np.array([0.2, np.nan, np.nan])
        columns[f'{m}_er_first_two'] = np.array([0.2, np.nan, np.nan])
        columns[f'{m}_label'] = np.array([1, 1, 0])  # row 3: rotation error was too large
    out = relabel(columns, LabelConfig())
    assert out['E_label'].tolist() == [1, 1, 0]  # stored rotation verdict kept
    assert out['scale_rule'].tolist() == ['median', 'no_depth', 'no_depth']
    assert 'rotation-error column' in caplog.text
    assert relabel(columns, LabelConfig(et_max=0.05))['E_label'].tolist() == [0, 0, 0]
    with_rot = dict(columns, E_rot_err_deg=np.array([np.nan, 6.0, 1.0]))
    assert relabel(with_rot, LabelConfig())['E_label'].tolist() == [1, 0, 1]
    first_two = relabel(columns, LabelConfig(scale_rule=ScaleRule.FIRST_TWO))
    assert first_two['scale_rule'].tolist() == ['first_two', 'no_depth', 'no_depth']


def test_ground_truth_parallax_is_the_angle_between_the_two_rays():
    from initsel_ros.learn.labels import ground_truth_parallax_deg

    # a point 2 m ahead, the camera slid 10 cm sideways: atan(0.1 / 2)
    points = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 2.0], [np.nan, 0.0, 1.0]])
    valid = np.array([True, True, True])
    angle = ground_truth_parallax_deg(points, valid, np.eye(3), np.array([-0.1, 0.0, 0.0]))
    assert angle == pytest.approx(math.degrees(math.atan(0.1 / 2.0)))
    # a rotation about the camera centre gives none, whatever the depth
    assert ground_truth_parallax_deg(points, valid, _rot_y(0.2), np.zeros(3)) == pytest.approx(0)
    assert math.isnan(ground_truth_parallax_deg(points, ~valid, np.eye(3), np.ones(3)))


def test_the_parallax_r_label_depends_on_the_scene_depth_the_baseline_label_does_not():
    # 10 cm sideways: a baseline to the paper's rule at any depth, but at 20 m the rays to
    # the scene differ by 0.3 degrees, no usable parallax
    near, far = np.full((H, W), 2.0, np.float32), np.full((H, W), 20.0, np.float32)
    T_cur = _pose(np.eye(3), np.array([0.1, 0.0, 0.0]))
    parallax = LabelConfig(rotation_label='parallax', rotation_parallax_deg=1.0)
    for depth, expected in ((near, 0), (far, 1)):
        p0, p1 = _correspondences(np.random.default_rng(4), depth, T_cur)
        assert label_pair(p0, p1, K, depth, np.eye(4), T_cur).r_label == 0
        labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur, parallax)
        assert labels.r_label == expected, labels.parallax_deg
    without_depth = label_pair(p0, p1, K, None, np.eye(4), T_cur, parallax)
    assert math.isnan(without_depth.parallax_deg) and without_depth.r_label == 0  # baseline


def test_relabel_by_parallax_keeps_the_baseline_rule_where_there_is_none():
    columns = {
        'gt_baseline_m': np.array([0.2, 0.2, 0.01]),
        'gt_parallax_deg': np.array([3.0, 0.4, np.nan]),
        'scale_rule': np.array(['median'] * 3, dtype=object),
    }
    for m in ('F', 'E', 'H'):
        columns[f'{m}_ok'] = np.array([1, 1, 1])
        columns[f'{m}_et'] = np.array([0.1, 0.1, 0.1])
        columns[f'{m}_er_median'] = np.array([0.2, 0.2, 0.2])
        columns[f'{m}_er_first_two'] = np.array([0.2, 0.2, 0.2])
    by_parallax = relabel(columns, LabelConfig(rotation_label='parallax'))
    assert by_parallax['R_label'].tolist() == [0, 1, 1]
    assert relabel(columns, LabelConfig())['R_label'].tolist() == [0, 0, 1]
    with pytest.raises(Exception, match='rotation_label must be one of baseline, parallax'):
        LabelConfig(rotation_label='depth')


def _table_row(labels) -> dict[str, np.ndarray]:
    """The pair-table columns :func:`relabel` reads, for one labelled pair."""
    row = {
        'gt_baseline_m': np.array([labels.baseline_m]),
        'gt_plane_share': np.array([labels.plane_share]),
        'gt_rotation_share': np.array([labels.rotation_share]),
        'scale_rule': np.array(['median'], dtype=object),
    }
    for m, o in labels.outcomes.items():
        row[f'{m}_ok'] = np.array([int(o.ok)])
        row[f'{m}_et'] = np.array([o.et])
        row[f'{m}_er_median'] = np.array([o.er_median])
        row[f'{m}_er_first_two'] = np.array([o.er_first_two])
    return row


def test_the_best_method_label_keeps_only_the_methods_a_pair_should_use():
    # row 0, a plane: H at 0.01, E landing at 0.30 and F at 0.70 from degenerate fits, all
    # "good" under the paper's 0.8; row 1, a desk: E 0.02 and F 0.06 (within 0.05), H 0.40;
    # row 2: only F's pose succeeded; row 3: none good (E's 0.9 fails E_t < 0.8)
    columns = {
        'gt_baseline_m': np.full(4, 0.2),
        'scale_rule': np.array(['median'] * 4, dtype=object),
    }
    et = {
        'F': [0.70, 0.06, 0.30, np.nan],
        'E': [0.30, 0.02, np.nan, 0.9],
        'H': [0.01, 0.40, np.nan, np.nan],
    }
    for m in ('F', 'E', 'H'):
        columns[f'{m}_ok'] = np.isfinite(et[m]).astype(int)
        columns[f'{m}_et'] = np.array(et[m])
        columns[f'{m}_er_median'] = np.full(4, 0.1)
        columns[f'{m}_er_first_two'] = np.full(4, 0.1)
    paper = relabel(columns, LabelConfig())
    assert [paper[f'{m}_label'].tolist() for m in 'FEH'] == [
        [1, 1, 1, 0],
        [1, 1, 0, 0],
        [1, 1, 0, 0],
    ]
    best = relabel(columns, LabelConfig(method_label='best'))
    assert best['F_label'].tolist() == [0, 1, 1, 0]
    assert best['E_label'].tolist() == [0, 1, 0, 0]
    assert best['H_label'].tolist() == [1, 0, 0, 0]
    wide = relabel(columns, LabelConfig(method_label='best', best_margin=0.3))
    assert wide['E_label'].tolist() == [1, 1, 0, 0]
    assert best['R_label'].tolist() == paper['R_label'].tolist()  # R is not a method's pose


def test_the_best_method_label_is_the_same_pair_by_pair_and_on_tables():
    rng = np.random.default_rng(5)
    depth = _blocky_depth(rng)
    T_cur = _pose(_rot_y(0.02), np.array([0.2, 0.0, 0.03]))
    p0, p1 = _correspondences(rng, depth, T_cur)
    config = LabelConfig(method_label='best', best_margin=0.0)
    labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur, config)
    good = {m: labels.outcomes[m].label(config) for m in 'FEH'}
    assert sum(good.values()) >= 2  # (a scene with depth: F and E both good at least)
    # with no margin exactly the good method of lowest E_t keeps its label
    et = {m: labels.outcomes[m].et if good[m] else np.inf for m in 'FEH'}
    winner = min(et, key=et.get)
    assert {m: labels.label(m) for m in 'FEH'} == {m: int(m == winner) for m in 'FEH'}
    table = relabel(_table_row(labels), config)
    assert {m: int(table[f'{m}_label'][0]) for m in 'FEH'} == {m: labels.label(m) for m in 'FEH'}


def test_an_unknown_method_label_or_a_negative_margin_is_refused():
    with pytest.raises(ConfigError, match='method_label'):
        LabelConfig(method_label='chosen')
    with pytest.raises(ConfigError, match='best_margin'):
        LabelConfig(method_label='best', best_margin=-0.1)


def test_the_static_share_counts_the_tracks_the_ground_truth_explains():
    """A pan whose tracks on a moving board leave the rotation's flow: the share is that of
    the tracks on the background; a static scene's is 1 despite tracking noise, and so is a
    pan seen through a focal length 10 % off (every track moves together: not an object
    moving on its own)."""
    from initsel_ros.learn.labels import STATIC_TOLERANCE_PX, ground_truth_static_share

    rng = np.random.default_rng(7)
    depth = _blocky_depth(rng)
    T_cur = _pose(_rot_y(0.25), np.zeros(3))  # a pan of 14 degrees: no baseline
    p0, p1 = _correspondences(rng, depth, T_cur, noise=0.5)
    labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur)
    assert labels.r_label == 1 and labels.static_share == 1.0
    moved = p1.copy()
    board = np.arange(len(p1)) < len(p1) // 5  # a fifth of the tracks move with a board
    moved[board] += (3.0 * STATIC_TOLERANCE_PX, 0.0)
    labels = label_pair(p0, moved, K, depth, np.eye(4), T_cur)
    assert labels.static_share == pytest.approx(1.0 - board.mean())
    assert labels.r_label == 1  # the R label is the camera's: it did not move
    # the same pan through a lens whose focal length is 10 % longer than K says
    wrong = K.copy()
    wrong[0, 0] *= 1.1
    wrong[1, 1] *= 1.1
    H = wrong @ _rot_y(0.25).T @ np.linalg.inv(wrong)  # the camera turned by R_y(0.25)
    q = np.column_stack((p0, np.ones(len(p0)))) @ H.T
    miscalibrated = q[:, :2] / q[:, 2:3]
    X, valid = backproject(p0, depth, K)
    R_cur = _rot_y(0.25).T
    shift = np.hypot(*(miscalibrated - p1).T)
    assert np.median(shift) > 2 * STATIC_TOLERANCE_PX  # off the ground truth's flow
    assert ground_truth_static_share(miscalibrated, K, X, valid, R_cur, np.zeros(3)) == 1.0
    # too few points in front of the current camera, or no depth: NaN
    behind = ground_truth_static_share(p1, K, X, valid, np.diag([-1.0, 1.0, -1.0]), np.zeros(3))
    assert math.isnan(behind)
    assert math.isnan(label_pair(p0, p1, K, None, np.eye(4), T_cur).static_share)
    assert math.isnan(ground_truth_static_share(p1, K, X, ~valid, np.eye(3), np.zeros(3)))


def test_the_plane_share_is_the_largest_share_of_tracks_one_plane_explains():
    """A wall 3 m away slid along by 20 cm: 1; a box before it holding a third of the
    tracks: two thirds; a pure rotation before a scene with depth: 1 (no depth shows); no
    depth: NaN."""
    from initsel_ros.learn.labels import ground_truth_plane_share

    rng = np.random.default_rng(3)
    wall = np.full((H, W), 3.0, np.float32)
    slide = _pose(np.eye(3), np.array([0.2, 0.0, 0.0]))
    p0, p1 = _correspondences(rng, wall, slide)
    assert label_pair(p0, p1, K, wall, np.eye(4), slide).plane_share == 1.0
    box = wall.copy()
    box[:, : W // 3] = 1.5  # the left third of the image: 1.5 m nearer (~36 px of parallax)
    p0, p1 = _correspondences(rng, box, slide)
    on_box = p0[:, 0] < W // 3
    labels = label_pair(p0, p1, K, box, np.eye(4), slide)
    assert labels.plane_share == pytest.approx(1.0 - on_box.mean())
    pan = _pose(_rot_y(0.2), np.zeros(3))
    desk = _blocky_depth(rng)
    p0, p1 = _correspondences(rng, desk, pan)
    assert label_pair(p0, p1, K, desk, np.eye(4), pan).plane_share == 1.0
    assert math.isnan(label_pair(p0, p1, K, None, np.eye(4), pan).plane_share)
    X, valid = backproject(p0, box, K)
    assert math.isnan(ground_truth_plane_share(p0, K, X, ~valid, np.eye(3), np.zeros(3)))
    # tracks whose points the camera has passed are not seen: the share is of those ahead
    p0 = np.random.default_rng(9).uniform([40, 40], [600, 440], (300, 2))
    X, valid = backproject(p0, wall, K)
    X[:30] *= 0.5 / 3.0  # a tenth of the rays end 0.5 m away
    forward = np.array([0.0, 0.0, -1.0])  # 1 m forward: those are behind the camera
    assert ground_truth_plane_share(p0, K, X, valid, np.eye(3), forward) == 1.0


def test_the_rotation_share_and_the_flow_label_see_depth_in_pixels_not_metres():
    """5 cm is a baseline before a wall 1 m away and none before one 20 m away: the flow
    label tells them apart, the paper's baseline rule does not; a pan is a rotation."""
    from initsel_ros.learn.labels import ground_truth_rotation_share

    rng = np.random.default_rng(4)
    flow = LabelConfig(rotation_label='flow')
    slide = _pose(np.eye(3), np.array([0.05, 0.0, 0.0]))
    for distance, share in ((1.0, 0.0), (20.0, 1.0)):  # 27 px and 1.3 px of parallax
        wall = np.full((H, W), distance, np.float32)
        p0, p1 = _correspondences(rng, wall, slide)
        labels = label_pair(p0, p1, K, wall, np.eye(4), slide, flow)
        assert labels.rotation_share == share
        assert labels.r_label == int(share == 1.0)
        assert label_pair(p0, p1, K, wall, np.eye(4), slide).r_label == 1  # <= 5 cm
    pan = _pose(_rot_y(0.2), np.zeros(3))
    depth = _blocky_depth(rng)
    p0, p1 = _correspondences(rng, depth, pan)
    assert label_pair(p0, p1, K, depth, np.eye(4), pan, flow).r_label == 1
    X, valid = backproject(p0, depth, K)
    assert math.isnan(ground_truth_rotation_share(p0, K, X, ~valid, np.eye(3), np.zeros(3)))
    # on a table: the share where known, the baseline rule without depth
    columns = {
        'gt_baseline_m': np.array([0.01, 0.01, 0.5]),
        'gt_rotation_share': np.array([0.5, np.nan, 0.9]),
        'scale_rule': np.array(['median', 'no_depth', 'median'], dtype=object),
    }
    for m in ('F', 'E', 'H'):
        for column in ('ok', 'et', 'er_median', 'er_first_two', 'label'):
            columns[f'{m}_{column}'] = np.ones(3)
    assert relabel(columns, flow)['R_label'].tolist() == [0, 1, 1]
    # a scalar baseline with shares of several pairs broadcasts as the other rules do
    assert flow.rotation_labels(0.01, np.nan, np.array([0.9, 0.1, np.nan])).tolist() == [1, 0, 1]


def test_the_determined_and_flow_labels_on_an_older_table_say_they_fall_back(caplog):
    columns = {
        'gt_baseline_m': np.array([0.01, 0.5]),
        'scale_rule': np.array(['median', 'median'], dtype=object),
    }
    for m in ('F', 'E', 'H'):
        for column in ('ok', 'et', 'er_median', 'er_first_two', 'label'):
            columns[f'{m}_{column}'] = np.full(2, 0.5)
    config = LabelConfig(method_label='determined', rotation_label='flow')
    out = relabel(columns, config)
    assert out['R_label'].tolist() == [1, 0]  # the 5 cm rule
    assert out['E_label'].tolist() == [1, 1]  # the paper's
    assert '2 of the 2 rows with depth have no gt_plane_share' in caplog.text
    assert '2 of the 2 rows with depth have no gt_rotation_share' in caplog.text


def test_the_test_label_is_the_rotation_tests_verdict_and_falls_back_to_5_cm(caplog):
    """``--rotation-label test``: R is 1 where the fire path's rotation test left under its bar
    times the noise on the pair's tracks (with or without depth); a pair without the
    statistic (a table made without --fire-path) keeps the 5 cm rule, and the log says so."""
    columns = {
        'gt_baseline_m': np.array([0.5, 0.01, 0.5, 0.01]),
        'fire_rotation_statistic': np.array([1.2, 7.0, 2.99, np.nan]),
        'scale_rule': np.array(['median', 'median', 'no_depth', 'median'], dtype=object),
    }
    for m in ('F', 'E', 'H'):
        for column in ('ok', 'et', 'er_median', 'er_first_two', 'label'):
            columns[f'{m}_{column}'] = np.ones(4)
    test = LabelConfig(rotation_label='test')
    assert relabel(columns, test)['R_label'].tolist() == [1, 0, 1, 1]
    assert '1 of the 4 rows have no fire_rotation_statistic' in caplog.text
    strict = LabelConfig(rotation_label='test', rotation_test_bar=2.0)
    assert relabel(columns, strict)['R_label'].tolist() == [1, 0, 0, 1]
    assert relabel(columns, LabelConfig())['R_label'].tolist() == [0, 1, 0, 1]


def test_the_determined_label_keeps_e_and_f_off_planes_and_h_on_them():
    # row 0, a plane (share 1): every pose good; row 1, a desk (share 0.4): every pose good;
    # row 2, share 0.8 exactly (the plane holds the fire path's share); row 3, no depth
    columns = {
        'gt_baseline_m': np.full(4, 0.2),
        'gt_plane_share': np.array([1.0, 0.4, 0.8, np.nan]),
        'scale_rule': np.array(['median'] * 3 + ['no_depth'], dtype=object),
    }
    for m in ('F', 'E', 'H'):
        columns[f'{m}_ok'] = np.ones(4, dtype=int)
        columns[f'{m}_et'] = np.full(4, 0.1)
        columns[f'{m}_er_median'] = np.full(4, 0.1)
        columns[f'{m}_er_first_two'] = np.full(4, 0.1)
        columns[f'{m}_label'] = np.ones(4, dtype=int)
    determined = relabel(columns, LabelConfig(method_label='determined'))
    assert determined['E_label'].tolist() == [0, 1, 0, 1]
    assert determined['F_label'].tolist() == [0, 1, 0, 1]
    assert determined['H_label'].tolist() == [1, 0, 1, 1]
    looser = relabel(columns, LabelConfig(method_label='determined', dominant_share=0.9))
    assert looser['E_label'].tolist() == [0, 1, 1, 1]
    with pytest.raises(ConfigError, match='dominant_share'):
        LabelConfig(dominant_share=0.0)


def test_the_determined_label_is_the_same_pair_by_pair_and_on_tables():
    # a desk with depth: E, F and H as their poses say, H dropped off the plane; a wall slid
    # along 40 cm, where this seed's E lands on the right one of its two exact solutions:
    # E good by the paper's label, not determined
    config = LabelConfig(method_label='determined')
    desk = _blocky_depth(np.random.default_rng(5))
    wall = np.full((H, W), 2.0, np.float32)
    for depth, seed, slide in ((desk, 5, 0.2), (wall, 2, 0.4)):
        T_cur = _pose(_rot_y(0.02), np.array([slide, 0.0, 0.03]))
        p0, p1 = _correspondences(np.random.default_rng(seed), depth, T_cur)
        labels = label_pair(p0, p1, K, depth, np.eye(4), T_cur, config)
        good = {m: labels.outcomes[m].label(config) for m in 'FEH'}
        planar = labels.plane_share >= config.dominant_share
        assert planar == bool(np.ptp(depth) == 0)
        assert good['E'] == 1  # (premise)
        expected = {m: int(good[m] and planar == (m == 'H')) for m in 'FEH'}
        assert {m: labels.label(m) for m in 'FEH'} == expected
        assert labels.label('E') == int(not planar)
        table = relabel(_table_row(labels), config)
        assert {m: int(table[f'{m}_label'][0]) for m in 'FEH'} == expected


def test_true_depths_of_undistorted_pixels_are_read_where_the_lens_puts_them():
    from initsel_ros.camera import Intrinsics
    from initsel_ros.learn.labels import true_depths

    lens = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480, (-0.3, 0.1, 0.0, 0.0, 0.0))
    u = np.arange(640, dtype=np.float32)
    depth = np.tile(1.0 + u / 100.0, (480, 1)).astype(np.float32)  # depth grows with column
    pinhole = np.array([[600.0, 400.0], [40.0, 60.0], [320.0, 240.0]])
    rays = np.column_stack(((pinhole - [320.0, 240.0]) / 500.0, np.ones(3)))
    where = np.rint(lens.project(rays))  # the pixels on the (distorted) depth map's grid
    assert np.abs(where - pinhole).max() > 20  # a lens that moves them far
    np.testing.assert_allclose(true_depths(pinhole, lens, depth), 1.0 + where[:, 0] / 100.0)
    # without a lens the pixel itself; without depth, or outside the image, unknown
    np.testing.assert_allclose(
        true_depths(pinhole, Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480), depth),
        1.0 + pinhole[:, 0] / 100.0,
    )
    assert np.isnan(true_depths(pinhole, lens, None)).all()
    assert np.isnan(
        true_depths([[-50.0, 10.0]], lens.__class__(500.0, 500.0, 320.0, 240.0, 640, 480), depth)
    ).all()
