"""EuRoC (ASL) and KITTI odometry readers, on rendered frames written in those layouts."""

from __future__ import annotations

import argparse
import dataclasses
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import EurocSequence, KittiSequence, open_sequence
from initsel_ros.datasets.bags import write_bag
from initsel_ros.datasets.euroc import write_euroc
from initsel_ros.datasets.kitti import write_kitti
from initsel_ros.datasets.tum import TumSequence
from initsel_ros.errors import DatasetError
from initsel_ros.transforms import pose_matrix

DISTORTION = (-0.12, 0.03, 0.001, -0.0008)
FIRST_NS = 1_403_636_579_763_555_584  # a EuRoC MH_01 stamp
STEP_NS = 33_333_333


def _rot_z(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array(
        [[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]]
    )


#: A non-identity camera-in-body pose, like EuRoC's cam0 (about 90 degrees about z, offset).
T_BS = np.eye(4)
T_BS[:3, :3] = _rot_z(90.0) @ np.array(
    [[1.0, 0, 0], [0, math.cos(0.1), -math.sin(0.1)], [0, math.sin(0.1), math.cos(0.1)]]
)
T_BS[:3, 3] = (-0.0216, -0.0647, 0.0098)


@pytest.fixture(scope='module')
def distorted_sequence(tmp_path_factory) -> Path:
    """30 frames of the near trajectory rendered with radial-tangential distortion."""
    from initsel_ros.synth import render

    return render(
        tmp_path_factory.mktemp('distorted'),
        trajectory='near',
        frames=30,
        start=80,
        distortion=DISTORTION,
    ).path


def _restamped(folder: Path) -> TumSequence:
    """The folder's sequence with EuRoC-like integer-ns stamps."""
    from initsel_ros.datasets import Frame

    seq = TumSequence(folder)
    seq.frames = [
        Frame(
            f.index,
            (FIRST_NS + f.index * STEP_NS) * 1e-9,
            f.pose,
            f.depth_stamp,
            stamp_ns=FIRST_NS + f.index * STEP_NS,
        )
        for f in seq.frames
    ]
    return seq


@pytest.fixture(scope='module')
def euroc_folder(distorted_sequence, tmp_path_factory) -> Path:
    """The distorted sequence as a EuRoC folder with T_BS and 200 Hz ground truth that falls on
    no frame time but the first and the last."""
    seq = _restamped(distorted_sequence)
    last = FIRST_NS + 29 * STEP_NS
    gt_ns = np.concatenate(
        [[FIRST_NS], np.arange(FIRST_NS + 1_234_567, last, 5_000_000), [last]]
    )  # 200 Hz, bracketing every frame, exact at the two ends
    out = tmp_path_factory.mktemp('euroc') / 'MH_synth'
    write_euroc(seq, out, T_BS=T_BS, groundtruth_ns=gt_ns, rate_hz=30)
    return out


#: A 640x480 fisheye (equidistant) camera whose image corners see 60 degrees off the axis.
FISHEYE = Intrinsics(
    400.0 / math.radians(60.0),
    400.0 / math.radians(60.0),
    320.0,
    240.0,
    640,
    480,
    (0.05, -0.01, 0.004, -0.001),
    fisheye=True,
)


@pytest.fixture(scope='module')
def fisheye_sequence(tmp_path_factory) -> Path:
    """30 frames of the near trajectory rendered through the fisheye lens."""
    from initsel_ros.synth import render

    folder = tmp_path_factory.mktemp('fisheye')
    return render(folder, trajectory='near', frames=30, start=80, intrinsics=FISHEYE).path


@pytest.fixture(scope='module')
def kitti_root(near_sequence, tmp_path_factory) -> Path:
    """The near sequence's first 30 frames as KITTI odometry sequence 03."""
    seq = TumSequence(near_sequence)
    seq.frames = seq.frames[:30]
    root = tmp_path_factory.mktemp('kitti') / 'dataset'
    write_kitti(seq, root, '03')
    return root


# ------------------------------------------------------------------------------------ EuRoC
def test_euroc_reads_back_images_stamps_intrinsics_distortion_and_poses(
    distorted_sequence, euroc_folder
):
    source = _restamped(distorted_sequence)
    for path in (euroc_folder, euroc_folder / 'mav0'):  # the folder holding mav0, or mav0
        seq = open_sequence(path)
        assert isinstance(seq, EurocSequence)
        assert seq.name == 'MH_synth'
        assert len(seq) == 30
        np.testing.assert_array_equal(seq.stamps_ns, source.stamps_ns)
        assert seq.intrinsics == source.intrinsics
        assert seq.intrinsics.distortion == DISTORTION
        np.testing.assert_allclose(seq.T_BS, T_BS, atol=1e-12)
        assert seq.rate_hz == 30
        for i in (0, 29):
            assert np.array_equal(seq.gray(i), source.gray(i))
            assert seq.image(i).shape == (480, 640, 3)
            assert seq.depth(i) is None
        # body poses were sampled at other times: interpolation plus T_BS gives the camera back
        np.testing.assert_allclose(seq.poses()[:, :3, 3], source.poses()[:, :3, 3], atol=2e-4)
        R_err = [
            math.degrees(math.acos(np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1)))
            for a, b in zip(seq.poses(), source.poses(), strict=True)
        ]
        assert max(R_err) < 0.05


def _write_minimal_euroc(
    root: Path, gt_rows: list[str], t_bs: np.ndarray, distortion_model: str = 'radial-tangential'
) -> Path:
    cam = root / 'mav0' / 'cam0'
    (cam / 'data').mkdir(parents=True)
    img = np.random.default_rng(0).integers(0, 256, (48, 64), dtype=np.uint8)
    cv2.imwrite(str(cam / 'data' / '1500000000.png'), img)
    (cam / 'data.csv').write_text('#timestamp [ns],filename\n1500000000,1500000000.png\n')
    data = ', '.join(repr(float(v)) for v in t_bs.reshape(-1))
    (cam / 'sensor.yaml').write_text(
        '%YAML:1.0\nsensor_type: camera\n'
        f'T_BS:\n  cols: 4\n  rows: 4\n  data: [{data}]\n'
        'rate_hz: 20\nresolution: [64, 48]\ncamera_model: pinhole\n'
        'intrinsics: [50.0, 51.0, 32.0, 24.0] #fu, fv, cu, cv\n'
        f'distortion_model: {distortion_model}\n'
        'distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]\n'
    )
    gt = root / 'mav0' / 'state_groundtruth_estimate0'
    gt.mkdir()
    (gt / 'data.csv').write_text(
        '#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], '
        'q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n' + '\n'.join(gt_rows) + '\n'
    )
    return root


def test_euroc_camera_pose_is_interpolated_body_pose_times_t_bs(tmp_path):
    """Body at x = 0 m yawed 0 deg at t = 1.45 s and x = 1 m yawed 90 deg at 1.55 s; the frame
    at 1.5 s: body at x = 0.5 m yawed 45 deg (slerp), camera = T_WB @ T_BS."""
    q90 = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))  # w x y z
    rows = [
        '1450000000,0,0,0,1,0,0,0,0,0,0,0,0,0,0,0,0',
        f'1550000000,1,0,0,{q90[0]!r},0,0,{q90[3]!r},0,0,0,0,0,0,0,0,0',
    ]
    t_bs = np.eye(4)
    t_bs[:3, :3] = _rot_z(-90.0)
    t_bs[:3, 3] = (0.1, 0.0, 0.0)
    seq = open_sequence(_write_minimal_euroc(tmp_path, rows, t_bs))
    T_WB = pose_matrix(
        np.array([0.5, 0.0, 0.0]),
        np.array([0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)]),
    )
    np.testing.assert_allclose(seq.frames[0].pose, T_WB @ t_bs, atol=1e-12)
    # the camera sits 0.1 m along the body's x axis, which is yawed 45 degrees
    np.testing.assert_allclose(
        seq.frames[0].pose[:3, 3], [0.5 + 0.1 / math.sqrt(2), 0.1 / math.sqrt(2), 0.0], atol=1e-12
    )
    assert seq.frames[0].stamp_ns == 1_500_000_000
    assert seq.intrinsics.distortion == (-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05)
    assert (seq.intrinsics.fx, seq.intrinsics.fy, seq.intrinsics.width) == (50.0, 51.0, 64)


@pytest.mark.parametrize(
    ('change', 'match'),
    [
        ('fov', r'sensor\.yaml: distortion_model .fov. is not supported'),
        ('no_intrinsics', r'sensor\.yaml: needs intrinsics'),
        ('bad_gt', r'data\.csv:2: expected at least 8 columns'),
        ('bad_listing', r'cam0/data\.csv:2: .abc. is not an integer timestamp'),
    ],
)
def test_broken_euroc_folders_give_one_dataset_error_naming_the_file(tmp_path, change, match):
    rows = ['1400000000,0,0,0,1,0,0,0', '1600000000,1,0,0,1,0,0,0']
    root = _write_minimal_euroc(
        tmp_path,
        rows if change != 'bad_gt' else ['1,2,3'],
        np.eye(4),
        'fov' if change == 'fov' else 'radial-tangential',
    )
    cam = root / 'mav0' / 'cam0'
    if change == 'no_intrinsics':
        text = (cam / 'sensor.yaml').read_text()
        (cam / 'sensor.yaml').write_text(text.replace('intrinsics:', 'intrinsicz:'))
    if change == 'bad_listing':
        (cam / 'data.csv').write_text('#timestamp [ns],filename\nabc,1500000000.png\n')
    with pytest.raises(DatasetError, match=match):
        open_sequence(root)


def test_euroc_distortion_under_kalibrs_key_is_read_and_a_named_model_needs_it(tmp_path):
    # before: a sensor.yaml with Kalibr's 'distortion_coeffs' was read as a lens without
    # distortion, without a word (H labels flipped on 15 of 49 pairs of a probe's folder)
    rows = ['1400000000,0,0,0,1,0,0,0', '1600000000,1,0,0,1,0,0,0']
    root = _write_minimal_euroc(tmp_path, rows, np.eye(4))
    yaml_path = root / 'mav0' / 'cam0' / 'sensor.yaml'
    text = yaml_path.read_text()
    yaml_path.write_text(text.replace('distortion_coefficients:', 'distortion_coeffs:'))
    expected = (-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05)
    assert open_sequence(root).intrinsics.distortion == expected
    both = text + 'distortion_coeffs: [0.1, 0.0, 0.0, 0.0]\n'
    yaml_path.write_text(both)
    with pytest.raises(DatasetError, match='distortion_coefficients and distortion_coeffs differ'):
        open_sequence(root)
    without = '\n'.join(ln for ln in text.splitlines() if 'distortion_coefficients' not in ln)
    yaml_path.write_text(without + '\n')
    with pytest.raises(DatasetError, match="distortion_model 'radial-tangential' without its"):
        open_sequence(root)
    yaml_path.write_text(without.replace('radial-tangential', 'none') + '\n')
    assert open_sequence(root).intrinsics.distortion == ()


# ------------------------------------------------------------------------------------ KITTI
def test_kitti_reads_back_from_the_root_or_the_sequence_folder(near_sequence, kitti_root):
    source = TumSequence(near_sequence)
    first = source.frames[0].pose
    for seq in (
        open_sequence(kitti_root, sequence='03'),
        open_sequence(kitti_root, sequence='3'),
        open_sequence(kitti_root / 'sequences' / '03'),
    ):
        assert isinstance(seq, KittiSequence)
        assert seq.name == 'kitti_03' and len(seq) == 30
        assert seq.intrinsics == source.intrinsics  # K from P0, size from the PNG
        assert seq.frames[0].stamp_ns == 0
        # times.txt keeps 7 significant digits, as KITTI's own
        np.testing.assert_allclose(seq.stamps, source.stamps[:30] - source.stamps[0], atol=1e-6)
        expected = np.linalg.inv(first) @ source.poses()[:30]  # KITTI: world = first camera
        np.testing.assert_allclose(seq.poses(), expected, atol=1e-9)
        np.testing.assert_allclose(seq.frames[0].pose, np.eye(4), atol=1e-12)
        assert np.array_equal(seq.gray(7), source.gray(7))
        assert seq.depth(7) is None


def test_kitti_root_without_a_sequence_lists_the_sequences(kitti_root):
    with pytest.raises(DatasetError, match=r'choose a sequence with --sequence NN.*\(found: 03\)'):
        open_sequence(kitti_root)
    with pytest.raises(DatasetError, match=r'no sequence .07. \(found: 03\)'):
        open_sequence(kitti_root, sequence='07')


def test_sequence_option_on_another_layout_is_refused(near_sequence):
    with pytest.raises(DatasetError, match='applies to KITTI odometry only'):
        open_sequence(near_sequence, sequence='00')


def test_kitti_calib_p0_gives_k_and_the_png_gives_the_size(tmp_path):
    folder = tmp_path / 'sequences' / '00'
    for cam in ('image_0', 'image_1'):
        (folder / cam).mkdir(parents=True)
        for i in range(2):
            cv2.imwrite(str(folder / cam / f'{i:06d}.png'), np.zeros((376, 1241), np.uint8))
    (folder / 'times.txt').write_text('0.000000e+00\n1.036205e-01\n')
    p0 = (
        '7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 '
        '0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 '
        '0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00'
    )
    p1 = p0.replace(
        '0.000000000000e+00 0.000000000000e+00 7.1',
        '-3.861448000000e+02 0.000000000000e+00 7.1',
        1,
    )
    (folder / 'calib.txt').write_text(f'P0: {p0}\nP1: {p1}\nP2: {p0}\nP3: {p0}\nTr: {p0}\n')
    seq = open_sequence(folder)
    cam = seq.intrinsics
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (718.856, 718.856, 607.1928, 185.2157)
    assert (cam.width, cam.height) == (1241, 376) and cam.distortion == ()
    assert seq.frames[1].stamp_ns == 103_620_500
    assert not seq.has_pose.any()
    (tmp_path / 'poses').mkdir()
    (tmp_path / 'poses' / '00.txt').write_text(
        '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 2\n'
    )
    seq = open_sequence(folder)
    np.testing.assert_allclose(seq.frames[1].pose[:3, 3], [0, 0, 2])
    right = KittiSequence(folder, camera=1)  # P1 = K [I | t]: the right camera 0.537 m along x
    np.testing.assert_allclose(right.frames[1].pose[:3, 3], [386.1448 / 718.856, 0, 2])


@pytest.mark.parametrize(
    ('change', 'match'),
    [
        ('times', r'times\.txt: 29 times for 30 images'),
        ('poses', r'03\.txt: 29 poses for 30 frames'),
        ('calib', r'calib\.txt: no P0: line'),
        ('pose_line', r'03\.txt:2: expected 12 numbers'),
        # before: an all-zero line read as 120 degrees of rotation, a scaled block as none
        ('pose_zero', r'03\.txt:2: the 3x3 block is not a rotation'),
        ('pose_scaled', r'03\.txt:2: the 3x3 block is not a rotation'),
    ],
)
def test_broken_kitti_sequences_give_one_dataset_error_naming_the_file(
    kitti_root, tmp_path, change, match
):
    root = tmp_path / 'copy'
    shutil.copytree(kitti_root, root)
    folder = root / 'sequences' / '03'
    if change == 'times':
        lines = (folder / 'times.txt').read_text().splitlines()
        (folder / 'times.txt').write_text('\n'.join(lines[:-1]) + '\n')
    elif change == 'poses':
        lines = (root / 'poses' / '03.txt').read_text().splitlines()
        (root / 'poses' / '03.txt').write_text('\n'.join(lines[:-1]) + '\n')
    elif change == 'calib':
        (folder / 'calib.txt').write_text('P1: 1 0 0 0 0 1 0 0 0 0 1 0\n')
    else:
        lines = (root / 'poses' / '03.txt').read_text().splitlines()
        numbers = [float(v) for v in lines[1].split()]
        lines[1] = {
            'pose_line': '1 0 0',
            'pose_zero': ' '.join(['0'] * 12),
            'pose_scaled': ' '.join(f'{2 * v:.9e}' for v in numbers),
        }[change]
        (root / 'poses' / '03.txt').write_text('\n'.join(lines) + '\n')
    with pytest.raises(DatasetError, match=match):
        open_sequence(root, sequence='03')


def test_relative_paths_find_kitti_poses_and_name_sequences(kitti_root, euroc_folder, monkeypatch):
    # before: from sequences/, '00' looked for ./../poses (its parent taken as typed), found
    # no poses and said only 'no poses/03.txt'; '.' was named 'kitti_'
    monkeypatch.chdir(kitti_root / 'sequences')
    seq = open_sequence('03')
    assert seq.name == 'kitti_03' and seq.has_pose.all()
    monkeypatch.chdir(kitti_root / 'sequences' / '03')
    seq = open_sequence('.')
    assert seq.name == 'kitti_03' and seq.has_pose.all()
    monkeypatch.chdir(euroc_folder / 'mav0')
    assert open_sequence('.').name == open_sequence(euroc_folder).name == 'MH_synth'


def test_a_colour_only_kitti_download_reads_its_colour_camera(kitti_root, tmp_path, caplog):
    # before: a download with image_2/ and no image_0/ was refused ('image_0: no PNG images')
    caplog.set_level('INFO')
    root = tmp_path / 'colour'
    shutil.copytree(kitti_root, root)
    folder = root / 'sequences' / '03'
    (folder / 'image_0').rename(folder / 'image_2')
    lines = (folder / 'calib.txt').read_text().splitlines()
    p2 = [float(v) for v in lines[0].split()[1:]]
    p2[3] = -0.06 * p2[0]  # camera 2 is 6 cm to the right of camera 0
    text = '\n'.join([*lines, 'P2: ' + ' '.join(repr(v) for v in p2)])
    (folder / 'calib.txt').write_text(text.replace('P2:', 'P9:', 1) + '\n')
    seq = open_sequence(root, sequence='03')
    reference = open_sequence(kitti_root, sequence='03')
    assert len(seq) == len(reference) and 'reading image_2/' in caplog.text
    offset = np.eye(4)
    offset[0, 3] = 0.06
    np.testing.assert_allclose(seq.poses(), reference.poses() @ offset, atol=1e-9)


def test_wrong_folders_say_what_they_probably_are(kitti_root, euroc_folder, tmp_path):
    cases = {
        euroc_folder / 'mav0' / 'cam0': f'it is inside the sequence {euroc_folder / "mav0"}',
        kitti_root / 'sequences' / '03' / 'image_0': 'it is inside the sequence',
        kitti_root / 'sequences': r'it holds sequences \(03\): give one of them',
        euroc_folder.parent: r'it holds sequences \(MH_synth\)',
    }
    for path, match in cases.items():
        with pytest.raises(DatasetError, match=match):
            open_sequence(path)
    root = tmp_path / 'copy'
    shutil.copytree(kitti_root, root)
    (root / 'sequences' / '03' / 'calib.txt').unlink()
    with pytest.raises(
        DatasetError, match=r'sequences/03: not a KITTI odometry sequence: no calib'
    ):
        open_sequence(root, sequence='03')
    with pytest.raises(DatasetError, match=r'a KITTI sequence, but no calib\.txt'):
        open_sequence(root / 'sequences' / '03')


# ------------------------------------------------------------------ labelling without depth
def _dataset(tmp_path: Path, *args: str) -> tuple[int, str]:
    from initsel_ros.cli import main

    out = tmp_path / 'pairs.csv'
    status = main(
        [
            'dataset',
            *args,
            '--out',
            str(out),
            '--batch',
            '30',
            '--jobs',
            '1',
            '--quiet',
            '--no-orbslam',
        ]
    )
    return status, str(out)


@pytest.mark.parametrize('layout', ['euroc', 'kitti'])
def test_dataset_labels_euroc_and_kitti_pairs_without_depth(request, tmp_path, capsys, layout):
    from initsel_ros.learn.table import read_table

    if layout == 'euroc':
        status, out = _dataset(tmp_path, str(request.getfixturevalue('euroc_folder')))
    else:
        status, out = _dataset(
            tmp_path, str(request.getfixturevalue('kitti_root')), '--sequence', '03'
        )
    assert status == 0
    assert '29 pairs labelled without depth' in capsys.readouterr().out
    table = read_table(Path(out))
    assert len(table) == 29
    assert np.all(table['scale_rule'] == 'no_depth')
    for m in ('F', 'E', 'H'):
        assert np.all(np.isnan(table[f'{m}_er'])) and np.all(table[f'{m}_n_gt_points'] == 0)
    # the near motion: good E poses once the baseline has grown, from E_t (and rotation) alone
    assert table['E_label'].sum() >= 20
    good = table['E_label'] == 1
    assert np.all(table['E_et'][good] < 0.8)
    assert np.all(table['R_label'][table['gt_baseline_m'] > 0.05] == 0)


def test_labels_without_depth_agree_with_the_labels_with_depth(distorted_sequence, euroc_folder):
    """The same rendered frames labelled from the TUM folder (depth: E_t and E_R) and from the
    EuRoC folder (no depth: E_t and rotation error): the same E and H labels."""
    from initsel_ros.learn.pairs import DatasetConfig, label_sequence_batch

    config = DatasetConfig(batch=30, orbslam_iterations=0, vins_ransac=False)
    with_depth = label_sequence_batch(TumSequence(distorted_sequence), 0, range(30), config)
    without = label_sequence_batch(open_sequence(euroc_folder), 0, range(30), config)
    assert {r['scale_rule'] for r in with_depth} == {'median'}
    assert {r['scale_rule'] for r in without} == {'no_depth'}
    for m in ('E', 'H'):
        a = np.array([r[f'{m}_label'] for r in with_depth])
        b = np.array([r[f'{m}_label'] for r in without])
        assert np.mean(a == b) >= 0.9, m


def test_distorted_correspondences_are_undistorted_before_labelling(distorted_sequence):
    """Undistorted (as the node does), the 5-point poses of the distorted rendering are within
    0.6 degrees of the truth (1.0 degrees median when the distortion is ignored)."""
    from initsel_ros.learn.pairs import DatasetConfig, label_sequence_batch

    config = DatasetConfig(batch=30, orbslam_iterations=0, vins_ransac=False)
    rows = label_sequence_batch(TumSequence(distorted_sequence), 0, range(30), config)
    assert np.nanmedian([r['E_rot_err_deg'] for r in rows]) < 0.6
    assert np.nanmedian([r['E_et'] for r in rows]) < 0.04


def test_a_fisheye_lens_survives_every_format_and_its_tracks_are_undistorted(
    fisheye_sequence, tmp_path
):
    """The fisheye render's lens is read back from its folder, a EuRoC folder (Kalibr's
    equidistant) and ROS 1 and 2 bags (CameraInfo equidistant), and its 5-point poses are
    close to the distorted pinhole's above; with the lens ignored they are not."""
    from initsel_ros.learn.pairs import DatasetConfig, label_sequence_batch

    folder = TumSequence(fisheye_sequence)
    assert folder.intrinsics == FISHEYE
    euroc = tmp_path / 'euroc'
    write_euroc(_restamped(fisheye_sequence), euroc, T_BS=np.eye(4), rate_hz=30)
    assert 'distortion_model: equidistant' in (euroc / 'mav0/cam0/sensor.yaml').read_text()
    assert open_sequence(euroc).intrinsics == FISHEYE
    for fmt, name in (('ros1', 'fisheye.bag'), ('ros2', 'fisheye_ros2')):
        assert open_sequence(write_bag(folder, tmp_path / name, fmt)).intrinsics == FISHEYE
    config = DatasetConfig(batch=30, orbslam_iterations=0, vins_ransac=False)
    rows = label_sequence_batch(folder, 0, range(30), config)
    assert np.nanmedian([r['E_rot_err_deg'] for r in rows]) < 0.6  # measured 0.34
    assert np.nanmedian([r['E_et'] for r in rows]) < 0.06  # 0.045
    pinhole = Intrinsics(*FISHEYE.pinhole, 640, 480)
    ignored = label_sequence_batch(
        TumSequence(fisheye_sequence, intrinsics=pinhole), 0, range(30), config
    )
    assert np.nanmedian([r['E_rot_err_deg'] for r in ignored]) > 1.5  # 2.74


def test_training_reads_a_table_mixing_depth_and_no_depth_rows(
    euroc_folder, distorted_sequence, rotation_sequence, tmp_path
):
    from initsel_ros.cli import main
    from initsel_ros.models import ModelSet

    table = tmp_path / 'mixed.csv'
    assert (
        main(
            [
                'dataset',
                str(euroc_folder),
                str(distorted_sequence),
                str(rotation_sequence),
                '--out',
                str(table),
                '--batch',
                '30',
                '--jobs',
                '1',
                '--quiet',
                '--no-orbslam',
            ]
        )
        == 0
    )
    model = tmp_path / 'models.json'
    assert main(['train', str(table), '--out', str(model), '--target-precision', '0.7']) == 0
    assert set(ModelSet.load(model).models) == {'F', 'E', 'H', 'R'}
    assert (
        main(
            [
                'train',
                str(table),
                '--out',
                str(tmp_path / 'relabelled.json'),
                '--et-max',
                '0.5',
                '--target-precision',
                '0.7',
            ]
        )
        == 0
    )


def test_kitti_times_that_do_not_rise_are_warned_about(tmp_path, caplog):
    from initsel_ros.datasets.kitti import read_times

    path = tmp_path / 'times.txt'
    path.write_text('\ufeff0.0\n0.1\n\n0.05\n0.2\n', encoding='utf-8')  # with a BOM, too
    assert read_times(path) == [0, 100_000_000, 50_000_000, 200_000_000]
    assert '1 times do not rise (first at line 4)' in caplog.text


def test_intrinsics_given_for_euroc_or_kitti_are_refused_in_one_line(euroc_folder, kitti_root):
    camera = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    for folder, options in ((euroc_folder, {}), (kitti_root, {'sequence': '03'})):
        with pytest.raises(DatasetError, match='carry their own calibration'):
            open_sequence(folder, intrinsics=camera, **options)


def _copy_with_broken_ground_truth(layout: str, request, tmp_path: Path) -> Path:
    """A copy of the ``layout`` fixture whose ground-truth file is malformed."""
    if layout == 'tum':
        source = request.getfixturevalue('near_sequence')
        folder = shutil.copytree(source, tmp_path / 'near', symlinks=True)
        (folder / 'groundtruth.txt').write_text('1.0 0 0 0 not a pose\n')
        return folder
    if layout == 'euroc':
        folder = shutil.copytree(request.getfixturevalue('euroc_folder'), tmp_path / 'mh')
        truth = folder / 'mav0' / 'state_groundtruth_estimate0' / 'data.csv'
        truth.write_text(truth.read_text().splitlines()[0] + '\n1,2,three\n')
        return folder
    if layout == 'kitti':
        root = shutil.copytree(request.getfixturevalue('kitti_root'), tmp_path / 'dataset')
        (root / 'poses' / '03.txt').write_text('1 0 0\n')
        return root / 'sequences' / '03'
    # a bag without poses of its own, its ground truth in a groundtruth.txt beside it
    sequence = TumSequence(request.getfixturevalue('near_sequence'))
    sequence.frames = [dataclasses.replace(f, pose=None) for f in sequence.frames[:30]]
    bag = write_bag(sequence, tmp_path / 'near.bag', 'ros1')
    (tmp_path / 'groundtruth.txt').write_text('1.0 0 0 0 not a pose\n')
    return bag


@pytest.mark.parametrize('layout', ['tum', 'euroc', 'kitti', 'bag'])
def test_a_reader_asked_for_no_ground_truth_opens_a_sequence_whose_ground_truth_is_broken(
    layout, request, tmp_path
):
    # a replay that does not publish the ground truth has no use for it: before, a malformed
    # groundtruth.txt made the sequence unplayable
    from initsel_ros.cli.options import options_from
    from initsel_ros.cli.replay import add_arguments
    from initsel_ros.ros.replay import ReplayOptions, open_source

    path = _copy_with_broken_ground_truth(layout, request, tmp_path)
    with pytest.raises(DatasetError):
        open_sequence(path)
    sequence = open_sequence(path, ground_truth=False)
    assert len(sequence.frames) >= 30
    assert all(frame.pose is None for frame in sequence.frames)

    parser = argparse.ArgumentParser()
    add_arguments(parser)

    def replay_source(*argv: str):
        return open_source(options_from(parser.parse_args([str(path), *argv]), ReplayOptions))

    assert len(replay_source().frames) == len(sequence.frames)
    with pytest.raises(DatasetError):  # publishing it needs it
        replay_source('--publish-groundtruth')


def test_the_camera_of_a_stereo_folder_is_chosen_by_name(kitti_root, euroc_folder, tmp_path):
    # before: no command could read KITTI's image_2/ beside image_0/, nor EuRoC's cam1
    root = shutil.copytree(kitti_root, tmp_path / 'stereo')
    folder = root / 'sequences' / '03'
    shutil.copytree(folder / 'image_0', folder / 'image_2')
    lines = (folder / 'calib.txt').read_text().splitlines()
    p2 = [float(v) for v in lines[0].split()[1:]]
    p2[3] = -0.06 * p2[0]  # camera 2 is 6 cm to the right of camera 0
    lines = [line for line in lines if not line.startswith('P2:')]
    (folder / 'calib.txt').write_text('\n'.join([*lines, 'P2: ' + ' '.join(map(repr, p2))]))
    left = open_sequence(root, sequence='03')
    offset = np.eye(4)
    offset[0, 3] = 0.06
    for name in ('2', 'image_2'):
        colour = open_sequence(root, sequence='03', camera=name)
        assert colour.image_files[0].parent.name == 'image_2'
        np.testing.assert_allclose(colour.poses(), left.poses() @ offset, atol=1e-9)
    with pytest.raises(DatasetError, match=r'a KITTI camera is 0-3 .*got .4.'):
        open_sequence(folder, camera='4')

    assert len(open_sequence(euroc_folder, camera='0')) == len(open_sequence(euroc_folder))
    with pytest.raises(DatasetError, match=r'no camera cam1 \(cameras: cam0\)'):
        open_sequence(euroc_folder, camera='cam1')
    with pytest.raises(DatasetError, match='--camera 1 applies to EuRoC and KITTI folders'):
        open_sequence(_tum_folder(euroc_folder, tmp_path), camera='1')


def _tum_folder(euroc_folder: Path, tmp_path: Path) -> Path:
    """A TUM folder: the EuRoC frames listed in an rgb.txt."""
    folder = tmp_path / 'tum'
    folder.mkdir()
    images = sorted((euroc_folder / 'mav0' / 'cam0' / 'data').glob('*.png'))
    (folder / 'rgb.txt').write_text(
        ''.join(f'{1.0 + 0.03 * k:.6f} {image}\n' for k, image in enumerate(images))
    )
    return folder


def test_the_dataset_and_replay_commands_take_a_camera(kitti_root, tmp_path):
    from initsel_ros.cli.options import options_from
    from initsel_ros.cli.replay import add_arguments
    from initsel_ros.learn.pairs import DatasetConfig, open_cached
    from initsel_ros.ros.replay import ReplayOptions, open_source

    root = shutil.copytree(kitti_root, tmp_path / 'stereo')
    folder = root / 'sequences' / '03'
    shutil.copytree(folder / 'image_0', folder / 'image_1')
    calib = (folder / 'calib.txt').read_text()
    assert 'P1:' in calib
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    replayed = open_source(
        options_from(parser.parse_args([str(folder), '--camera', '1']), ReplayOptions)
    )
    assert replayed.image_files[0].parent.name == 'image_1'
    labelled = open_cached(str(folder), DatasetConfig(camera='1'))
    assert labelled.image_files[0].parent.name == 'image_1'
    assert open_cached(str(folder), DatasetConfig()).image_files[0].parent.name == 'image_0'


def test_seedmap_takes_a_kitti_root_with_its_sequence(kitti_root, tmp_path):
    # before: seedmap had no --sequence, while the reader's message told the user to give one
    from initsel_ros.cli import main

    out = tmp_path / 'seedmap'
    argv = ['seedmap', str(kitti_root), '--sequence', '03', '--no-baselines', '--jobs', '1']
    assert main([*argv, '--length', '30', '--step', '30', '--out-dir', str(out)]) == 0
    rows = (out / 'seedmap.csv').read_text().splitlines()
    assert len(rows) >= 2 and all(row.startswith('kitti_03,') for row in rows[1:])
