"""Rendered sequences: geometry, photometry, trackability, formats and the CLI."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import open_sequence
from initsel_ros.datasets.tum import TumSequence
from initsel_ros.synth import Effects, build_scene, make_trajectory, render, render_frame
from initsel_ros.synth.textures import paper_texture


def _relative(T_w_ref: np.ndarray, T_w_cur: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) with x_cur = R x_ref + t (OpenCV convention)."""
    T = np.linalg.inv(T_w_cur) @ T_w_ref
    return T[:3, :3], T[:3, 3]


def _backproject(depth: np.ndarray, K: np.ndarray, step: int = 4):
    v, u = np.mgrid[0 : depth.shape[0] : step, 0 : depth.shape[1] : step]
    z = depth[v, u]
    ok = z > 0
    u, v, z = u[ok], v[ok], z[ok]
    X = (np.linalg.inv(K) @ np.vstack([u, v, np.ones_like(u)])) * z
    return u, v, X


def test_texture_points_move_with_depth_and_pose_onto_the_same_intensities(tmp_path):
    path = render(tmp_path / 'clean', frames=31, start=80, effects=Effects(noise=0.0)).path
    seq = TumSequence(path)
    K = seq.intrinsics.K
    i, j = 0, 30
    g_i = seq.gray(i).astype(np.float32)
    g_j = seq.gray(j).astype(np.float32)
    d_j = seq.depth(j)
    u, v, X = _backproject(seq.depth(i), K)
    R, t = _relative(seq.frames[i].pose, seq.frames[j].pose)
    Xj = R @ X + t[:, None]
    p = K @ Xj
    x, y = p[0] / p[2], p[1] / p[2]
    inside = (x > 1) & (x < g_j.shape[1] - 2) & (y > 1) & (y < g_j.shape[0] - 2)
    xi, yi = np.round(x[inside]).astype(int), np.round(y[inside]).astype(int)
    visible = np.abs(d_j[yi, xi] - Xj[2, inside]) < 0.01  # not occluded in frame j
    assert visible.sum() > 5000
    sampled = cv2.remap(
        g_j,
        x[inside][visible].astype(np.float32).reshape(-1, 1),
        y[inside][visible].astype(np.float32).reshape(-1, 1),
        cv2.INTER_LINEAR,
    ).ravel()
    residual = np.abs(sampled - g_i[v[inside][visible], u[inside][visible]])
    assert np.median(residual) < 2.0
    assert np.mean(residual < 10) > 0.9
    # the baseline is real: the points moved
    assert np.median(np.hypot(x - u, y - v)) > 10


def test_tum_files_round_trip_to_the_rendered_trajectory_and_depth(near_sequence):
    seq = open_sequence(near_sequence)
    stamps, poses = make_trajectory('near', 60, start=80)
    assert len(seq) == 60 and seq.intrinsics == Intrinsics.tum_fr3()
    assert np.allclose(seq.stamps, stamps, atol=1e-6)
    assert all(f.depth_stamp == f.stamp for f in seq.frames)
    assert np.allclose(seq.poses(), poses, atol=1e-6)
    _, depth = render_frame(build_scene(), seq.intrinsics, poses[7])
    assert np.max(np.abs(seq.depth(7) - depth)) <= 1.0 / 5000  # 16-bit PNG at TUM scale
    assert (seq.depth(7) > 0).mean() > 0.99
    for name in ('rgb.txt', 'depth.txt', 'groundtruth.txt', 'intrinsics.yaml'):
        assert (near_sequence / name).is_file()
    assert len(list((near_sequence / 'rgb').glob('*.png'))) == 60


def test_near_scene_is_seen_from_the_real_distances(near_sequence):
    seq = open_sequence(near_sequence)
    depth = seq.depth(0)
    # real fr3/structure_texture_near frames: median 1.26-1.29 m, 5-95 % 1.04-2.16 m
    assert 1.0 < np.median(depth[depth > 0]) < 1.6
    assert np.percentile(depth[depth > 0], 5) > 0.6


def test_far_sequence_is_about_twice_as_far(near_sequence, far_sequence):
    near = np.median(
        [np.median(d[d > 0]) for d in (open_sequence(near_sequence).depth(i) for i in (0, 30))]
    )
    far = np.median(
        [np.median(d[d > 0]) for d in (open_sequence(far_sequence).depth(i) for i in (0, 30))]
    )
    assert 1.6 < far / near < 2.4


@pytest.mark.parametrize('index', [0, 30, 59])
def test_near_frames_have_many_well_spread_shi_tomasi_corners(near_sequence, index):
    gray = open_sequence(near_sequence).gray(index)
    corners = cv2.goodFeaturesToTrack(gray, 300, 0.01, 8).reshape(-1, 2)
    assert len(corners) >= 150
    cells = set(map(tuple, np.floor(corners / [160, 120]).astype(int)))
    assert len(cells) >= 12  # of a 4x4 grid


def _klt_tracks(seq, first: int, last: int) -> tuple[np.ndarray, np.ndarray]:
    """Shi-Tomasi corners of ``first`` tracked frame by frame to ``last``."""
    prev = seq.gray(first)
    p0 = cv2.goodFeaturesToTrack(prev, 300, 0.01, 8).astype(np.float32)
    p = p0.copy()
    keep = np.ones(len(p0), bool)
    for k in range(first + 1, last + 1):
        cur = seq.gray(k)
        p_next, status, _ = cv2.calcOpticalFlowPyrLK(
            prev, cur, p, None, winSize=(21, 21), maxLevel=3
        )
        back, status_b, _ = cv2.calcOpticalFlowPyrLK(
            cur, prev, p_next, None, winSize=(21, 21), maxLevel=3
        )
        fb = np.linalg.norm((back - p).reshape(-1, 2), axis=1)
        keep &= (status.ravel() == 1) & (status_b.ravel() == 1) & (fb < 1.0)
        p, prev = p_next, cur
    return p0.reshape(-1, 2)[keep], p.reshape(-1, 2)[keep]


def test_klt_keeps_at_least_150_tracks_over_30_frames(near_sequence):
    p0, _ = _klt_tracks(open_sequence(near_sequence), 0, 30)
    assert len(p0) >= 150


def test_essential_matrix_recovers_the_translation_direction_of_a_20cm_pair(near_sequence):
    seq = open_sequence(near_sequence)
    centres = seq.poses()[:, :3, 3]
    j = int(np.argmin(np.abs(np.linalg.norm(centres - centres[0], axis=1) - 0.2)))
    assert abs(np.linalg.norm(centres[j] - centres[0]) - 0.2) < 0.03
    p0, p1 = _klt_tracks(seq, 0, j)
    K = seq.intrinsics.K
    E, mask = cv2.findEssentialMat(p0, p1, K, cv2.RANSAC, 0.999, 1.0)
    _, R, t, _ = cv2.recoverPose(E, p0, p1, K, mask=mask)
    R_gt, t_gt = _relative(seq.frames[0].pose, seq.frames[j].pose)
    chordal = np.linalg.norm(t_gt / np.linalg.norm(t_gt) - t.ravel() / np.linalg.norm(t))
    assert chordal < 0.1
    angle = np.degrees(np.arccos(np.clip((np.trace(R.T @ R_gt) - 1) / 2, -1, 1)))
    assert angle < 1.0


def test_pure_rotation_pair_has_no_parallax_so_its_translation_is_meaningless(rotation_sequence):
    """On a pure pan every correspondence follows the infinite homography K R K^-1 (no
    parallax); E-RANSAC still returns a unit t, but the points it triangulates have almost
    no parallax, which is what a pose check must reject."""
    seq = open_sequence(rotation_sequence)
    centres = seq.poses()[:, :3, 3]
    assert np.allclose(centres, centres[0])
    p0, p1 = _klt_tracks(seq, 0, 15)
    assert len(p0) > 100
    K = seq.intrinsics.K
    R_gt, t_gt = _relative(seq.frames[0].pose, seq.frames[15].pose)
    assert np.linalg.norm(t_gt) < 1e-9
    Hinf = K @ R_gt @ np.linalg.inv(K)
    pred = cv2.perspectiveTransform(p0.reshape(-1, 1, 2), Hinf).reshape(-1, 2)
    assert np.median(np.linalg.norm(pred - p1, axis=1)) < 1.0
    assert np.median(np.linalg.norm(p1 - p0, axis=1)) > 20  # large disparity nonetheless
    E, mask = cv2.findEssentialMat(p0, p1, K, cv2.RANSAC, 0.999, 1.0)
    E = E[:3]
    _, R, t, _, X = cv2.recoverPose(E, p0, p1, K, distanceThresh=1e3, mask=mask)
    X = (X[:3] / X[3]).T
    good = np.all(np.isfinite(X), axis=1)
    rays0 = X[good] / np.linalg.norm(X[good], axis=1, keepdims=True)
    c1 = -R.T @ t.ravel()
    rays1 = X[good] - c1
    rays1 /= np.linalg.norm(rays1, axis=1, keepdims=True)
    parallax = np.degrees(np.arccos(np.clip(np.sum(rays0 * rays1, axis=1), -1, 1)))
    assert np.median(parallax) < 0.5


def test_floor_scene_is_a_single_plane(floor_sequence):
    seq = open_sequence(floor_sequence)
    for i in (0, 59):
        _, _, X = _backproject(seq.depth(i), seq.intrinsics.K)
        T = seq.frames[i].pose
        world = T[:3, :3] @ X + T[:3, 3:4]
        assert np.max(np.abs(world[2])) < 2e-3  # z = 0 up to the PNG depth resolution


def test_wall_scene_is_a_single_plane_seen_from_an_arc(wall_arc_sequence):
    seq = open_sequence(wall_arc_sequence)
    planes = []
    for i in (0, 59):
        _, _, X = _backproject(seq.depth(i), seq.intrinsics.K)
        assert X.shape[1] > 0.95 * seq.intrinsics.width * seq.intrinsics.height / 16  # all wall
        T = seq.frames[i].pose
        world = (T[:3, :3] @ X + T[:3, 3:4]).T
        centre = world.mean(axis=0)
        normal = np.linalg.svd(world - centre, full_matrices=False)[2][-1]
        assert np.max(np.abs((world - centre) @ normal)) < 3e-3  # one plane
        planes.append((normal, centre))
    assert abs(planes[0][0] @ planes[1][0]) > 0.9999
    assert abs((planes[1][1] - planes[0][1]) @ planes[0][0]) < 3e-3  # the same plane


def test_arc_trajectory_keeps_its_distance_and_looks_at_the_target():
    stamps, poses = make_trajectory('arc', 300)
    target = build_scene('wall').target
    offsets = target - poses[:, :3, 3]
    distances = np.linalg.norm(offsets, axis=1)
    assert np.ptp(distances) < 1e-9 and distances[0] == pytest.approx(1.3)
    axes = poses[:, :3, 2]
    assert np.allclose(np.sum(axes * offsets, axis=1) / distances, 1.0)
    heading = np.degrees(np.arctan2(offsets[:, 1], offsets[:, 0]))
    assert np.ptp(heading) == pytest.approx(50.0, abs=0.5)  # +-25 degrees
    assert np.allclose(np.diff(stamps), 1 / 30)


def test_arc_parameters_set_distance_extent_and_the_rotation_that_keeps_the_plane_centred():
    from initsel_ros.errors import ConfigError
    from initsel_ros.synth.trajectories import ArcPath

    target = build_scene('wall').target
    _, arc = make_trajectory('arc', 76, arc=ArcPath(distance=3.5, extent=0.3), target=target)
    eyes = arc[:, :3, 3]
    assert np.linalg.norm(eyes - target, axis=1) == pytest.approx(3.5)  # on the circle
    assert np.linalg.norm(eyes[75] - eyes[0]) == pytest.approx(0.3, abs=0.01)  # the extent
    offsets = (target - eyes) / 3.5
    assert np.allclose(np.sum(arc[:, :3, 2] * offsets, axis=1), 1.0)  # target centred
    slide = ArcPath(distance=2.0, extent=0.2, centring=0.0, straight=True)
    _, poses = make_trajectory('arc', 76, arc=slide, target=target)
    assert np.allclose(poses[:, :3, :3], poses[0, :3, :3])  # a pure translation
    steps = poses[1:, :3, 3] - poses[0, :3, 3]
    assert np.allclose(steps[:, 2], 0.0) and np.allclose(steps @ poses[0, :3, 2], 0.0)
    half = ArcPath(distance=2.0, extent=0.2, centring=0.5, straight=True).poses(
        np.array([0.0, 2.5]), target
    )
    turned = np.degrees(
        np.arccos(np.clip((np.trace(half[1, :3, :3].T @ half[0, :3, :3]) - 1) / 2, -1, 1))
    )
    full = ArcPath(distance=2.0, extent=0.2, straight=True).poses(np.array([0.0, 2.5]), target)
    turned_full = np.degrees(
        np.arccos(np.clip((np.trace(full[1, :3, :3].T @ full[0, :3, :3]) - 1) / 2, -1, 1))
    )
    assert turned == pytest.approx(turned_full / 2, rel=0.05)
    with pytest.raises(ConfigError, match='centring'):
        ArcPath(centring=1.5)
    with pytest.raises(ConfigError, match='extent'):
        ArcPath(distance=1.0, extent=1.0)
    with pytest.raises(ConfigError, match='arc settings'):
        make_trajectory('rotation', 10, arc=ArcPath())


def test_cli_renders_an_arc_and_writes_a_focal_length_error(tmp_path):
    from initsel_ros.cli import main

    out = tmp_path / 'arc'
    args = ['synth', '--out', str(out), '--frames', '2', '--width', '160', '--no-progress']
    arc = ['--scene', 'floor', '--trajectory', 'arc', '--arc-distance', '1.5']
    assert main([*args, *arc, '--arc-elevation', '70', '--focal-error', '0.1']) == 0
    data = yaml.safe_load((out / 'intrinsics.yaml').read_text())
    true = Intrinsics.tum_fr3().scaled(160, 120)
    assert data['fx'] == pytest.approx(1.1 * true.fx) and data['fy'] == pytest.approx(
        1.1 * true.fy
    )
    poses = open_sequence(out).poses()
    target = build_scene('floor').target  # the floor scene's own target, on the floor
    view = poses[0, :3, 3] - target
    assert np.linalg.norm(view) == pytest.approx(1.5)
    assert np.degrees(np.arcsin(view[2] / 1.5)) == pytest.approx(70.0)
    assert main([*args, '--trajectory', 'rotation', '--arc-extent', '0.1']) == 2


def test_static_sequence_keeps_one_pose_and_changes_only_by_noise(static_sequence):
    seq = open_sequence(static_sequence)
    assert np.allclose(seq.poses(), seq.poses()[0])
    diff = seq.gray(0).astype(int) - seq.gray(29).astype(int)
    assert 0 < np.abs(diff).mean() < 3


def test_rendering_is_deterministic_for_a_seed(tmp_path):
    a = render(tmp_path / 'a', trajectory='random', frames=3, seed=5).path
    b = render(tmp_path / 'b', trajectory='random', frames=3, seed=5).path
    for name in sorted(p.name for p in (a / 'rgb').iterdir()):
        assert (a / 'rgb' / name).read_bytes() == (b / 'rgb' / name).read_bytes()
    assert (a / 'groundtruth.txt').read_text() == (b / 'groundtruth.txt').read_text()
    t1 = paper_texture(np.random.default_rng(1), 0.2, 0.1)
    t2 = paper_texture(np.random.default_rng(2), 0.2, 0.1)
    assert not np.array_equal(t1, t2)


def test_random_trajectories_are_smooth_and_differ_by_seed():
    _, a = make_trajectory('random', 90, seed=1)
    _, b = make_trajectory('random', 90, seed=2)
    assert not np.allclose(a, b)
    steps = np.linalg.norm(np.diff(a[:, :3, 3], axis=0), axis=1)
    assert steps.max() < 0.05  # metres per frame at 30 Hz


def test_cli_writes_distortion_and_size_into_intrinsics_yaml(tmp_path, capsys):
    from initsel_ros.cli import main

    out = tmp_path / 'small'
    code = main(
        [
            'synth',
            '--out',
            str(out),
            '--frames',
            '3',
            '--width',
            '320',
            '--height',
            '240',
            '--distortion',
            '0.1,-0.05,0,0',
            '--trajectory',
            'static',
            '--no-progress',
        ]
    )
    assert code == 0
    assert 'frames/s' in capsys.readouterr().out
    data = yaml.safe_load((out / 'intrinsics.yaml').read_text())
    assert data['width'] == 320 and data['distortion'] == [0.1, -0.05, 0.0, 0.0]
    seq = open_sequence(out)
    assert seq.image(0).shape == (240, 320, 3)
    assert seq.intrinsics.has_distortion


def test_lens_distortion_moves_points_as_the_opencv_model_says(tmp_path):
    dist = (0.15, -0.1, 0.0, 0.0)
    path = render(
        tmp_path / 'd', trajectory='static', frames=1, distortion=dist, effects=Effects(noise=0.0)
    ).path
    seq = TumSequence(path)
    K = seq.intrinsics.K
    ideal, depth = render_frame(build_scene(), Intrinsics.tum_fr3(), seq.frames[0].pose)
    u, v, X = _backproject(depth, K, step=8)
    # a point at ideal pixel (u, v) appears where cv2.projectPoints with the coefficients says
    img, _ = cv2.projectPoints(X.T.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.array(dist))
    img = img.reshape(-1, 2).astype(np.float32)
    inside = (img[:, 0] > 2) & (img[:, 0] < 637) & (img[:, 1] > 2) & (img[:, 1] < 477)
    assert np.median(np.linalg.norm(img[inside] - np.column_stack([u, v])[inside], axis=1)) > 3
    gray_ideal = cv2.cvtColor(ideal, cv2.COLOR_BGR2GRAY).astype(np.float32)
    sampled = cv2.remap(
        seq.gray(0).astype(np.float32), img[inside, :1], img[inside, 1:], cv2.INTER_LINEAR
    ).ravel()
    residual = np.abs(sampled - gray_ideal[v[inside], u[inside]])
    assert np.median(residual) < 3


def test_unknown_scene_or_bag_format_is_rejected(tmp_path):
    from initsel_ros.errors import ConfigError

    with pytest.raises(ValueError, match='nowhere'):
        render(tmp_path / 'x', scene='nowhere', frames=1)
    with pytest.raises(ConfigError, match='ros3'):
        render(tmp_path / 'x', frames=1, bags=('ros3',))


def test_near_trajectory_file_is_bundled():
    from initsel_ros.synth.trajectories import NEAR_FILE

    stamps, _ = make_trajectory('near')
    assert Path(NEAR_FILE).is_file() and len(stamps) == 1099
    assert np.all(np.diff(stamps) > 0)


def test_another_image_size_is_another_sensor_with_square_pixels(tmp_path):
    # before: 1241x376 scaled fy by the height, pixels 2.5 times as tall as wide (the
    # storeroom family's "KITTI size" saw 66 degrees vertically instead of about 29)
    import math

    fr3 = Intrinsics.tum_fr3()
    kitti = render(tmp_path / 'k', trajectory='static', frames=1, width=1241, height=376)
    cam = open_sequence(kitti.path).intrinsics
    assert (cam.width, cam.height) == (1241, 376)
    assert cam.fy / cam.fx == pytest.approx(fr3.fy / fr3.fx)
    assert cam.fx == pytest.approx(fr3.fx * 1241 / 640)  # the horizontal field of view kept
    assert cam.cy == pytest.approx(fr3.cy * 376 / 480)
    wide = render(
        tmp_path / 'w', trajectory='static', frames=1, width=1241, height=376, hfov_deg=82.0
    )
    cam = open_sequence(wide.path).intrinsics
    assert cam.fx == pytest.approx(1241 / 2 / math.tan(math.radians(41.0)))
    vertical = 2 * math.degrees(math.atan(376 / 2 / cam.fy))
    assert 25.0 < vertical < 33.0
