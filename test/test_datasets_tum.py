"""The TUM folder reader on the real sample and on malformed folders."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import open_sequence
from initsel_ros.datasets.tum import (
    TumSequence,
    associate,
    read_listing,
    read_trajectory,
    write_listing,
    write_trajectory,
)
from initsel_ros.errors import DatasetError

REAL_NEAR = Path('/work/shared/data/tum_fr3_structure_texture_near')

needs_real = pytest.mark.skipif(not REAL_NEAR.is_dir(), reason='real TUM sample not available')


@needs_real
def test_real_sample_first_frame_has_no_pose_by_default_and_a_warning(caplog):
    with caplog.at_level(logging.WARNING):
        seq = open_sequence(REAL_NEAR)
    assert len(seq) == 3
    assert seq.intrinsics == Intrinsics.tum_fr3()
    assert seq.frames[0].pose is None  # 0.113 s before the first mocap sample
    assert seq.frames[1].pose is not None and seq.frames[2].pose is not None
    assert '1 of 3 frames have no ground-truth pose' in caplog.text


@needs_real
def test_real_sample_nearest_tolerance_gives_first_pose_to_first_frame():
    seq = TumSequence(REAL_NEAR, nearest_tolerance=0.15)
    stamps, positions, _ = read_trajectory(REAL_NEAR / 'groundtruth.txt')
    assert len(stamps) == 3692
    assert np.allclose(seq.frames[0].pose[:3, 3], positions[0])


@needs_real
def test_real_sample_images_and_depth_decode_with_tum_scale():
    seq = TumSequence(REAL_NEAR)
    img = seq.image(0)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert seq.gray(0).shape == (480, 640)
    depth = seq.depth(0)
    assert depth.dtype == np.float32
    valid = depth[depth > 0]
    # the near sequence sees its scene from about 0.7-1.5 m
    assert 0.7 < np.median(valid) < 1.6


@needs_real
def test_real_sample_camera_moves_about_30cm_between_first_two_frames():
    seq = TumSequence(REAL_NEAR, nearest_tolerance=0.15)
    baseline = np.linalg.norm(seq.frames[1].pose[:3, 3] - seq.frames[0].pose[:3, 3])
    assert 0.2 < baseline < 0.4


def _copy_real(tmp_path: Path) -> Path:
    dst = tmp_path / 'seq'
    shutil.copytree(REAL_NEAR, dst)
    for p in dst.rglob('*'):
        p.chmod(0o755 if p.is_dir() else 0o644)
    dst.chmod(0o755)
    return dst


@needs_real
def test_bad_groundtruth_line_names_file_line_and_format(tmp_path):
    seq = _copy_real(tmp_path)
    lines = (seq / 'groundtruth.txt').read_text().splitlines()
    lines[5] = '1341839327.5 1.0 2.0 oops'
    (seq / 'groundtruth.txt').write_text('\n'.join(lines))
    with pytest.raises(DatasetError, match=r'groundtruth.txt:6: .*tx ty tz qx qy qz qw'):
        TumSequence(seq)


@needs_real
def test_non_numeric_rgb_line_names_file_and_line(tmp_path):
    seq = _copy_real(tmp_path)
    (seq / 'rgb.txt').write_text('# c\nnot-a-time rgb/x.png\n')
    with pytest.raises(DatasetError, match=r'rgb.txt:2: .*not a number'):
        TumSequence(seq)


def test_missing_rgb_txt_names_the_file(tmp_path):
    (tmp_path / 'seq').mkdir()
    with pytest.raises(DatasetError, match=r'rgb.txt: file not found'):
        TumSequence(tmp_path / 'seq')


def test_open_sequence_rejects_unknown_paths(tmp_path):
    with pytest.raises(DatasetError, match='no such file'):
        open_sequence(tmp_path / 'nothing')
    with pytest.raises(DatasetError, match='not a TUM folder'):
        open_sequence(tmp_path)


@needs_real
def test_corrupt_and_missing_image_files_raise_dataset_error(tmp_path):
    seq_path = _copy_real(tmp_path)
    first = sorted((seq_path / 'rgb').iterdir())
    first[0].write_bytes(b'\x89PNG garbage')
    first[1].write_bytes(b'')
    first[2].unlink()
    seq = TumSequence(seq_path)
    with pytest.raises(DatasetError, match='corrupt'):
        seq.image(0)
    with pytest.raises(DatasetError, match='corrupt'):
        seq.gray(1)
    with pytest.raises(DatasetError, match='not found'):
        seq.image(2)


def test_writers_round_trip_through_the_readers(tmp_path):
    rng = np.random.default_rng(3)
    stamps = 100.0 + np.arange(5) / 30.0
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    pos = rng.normal(size=(5, 3))
    write_trajectory(tmp_path / 'gt.txt', stamps, pos, q)
    s2, p2, q2 = read_trajectory(tmp_path / 'gt.txt')
    assert np.allclose(s2, stamps, atol=1e-6) and np.allclose(p2, pos, atol=1e-8)
    assert np.allclose(q2, q, atol=1e-8)
    names = [f'rgb/{s:.6f}.png' for s in stamps]
    write_listing(tmp_path / 'rgb.txt', stamps, names, 'color images')
    s3, n3 = read_listing(tmp_path / 'rgb.txt')
    assert n3 == names and np.allclose(s3, stamps, atol=1e-6)


def test_association_is_one_to_one_and_respects_tolerance():
    rgb = np.array([0.0, 0.033, 0.066, 0.5])
    depth = np.array([0.001, 0.030, 0.040, 0.2])
    match = associate(rgb, depth, 0.02)
    assert match.tolist() == [0, 1, -1, -1]


@needs_real
def test_images_or_depth_of_another_size_than_the_intrinsics_are_refused(tmp_path):
    # before: resized images were tracked with the 640x480 K and labelled without a word (F
    # positives 26 -> 9 on a probe), half-size depth read at colour pixels, 8-bit depth taken
    # as a few millimetres
    import cv2

    seq_path = _copy_real(tmp_path)
    rgb = sorted((seq_path / 'rgb').iterdir())
    depth = sorted((seq_path / 'depth').iterdir())
    small = cv2.resize(cv2.imread(str(rgb[0])), (320, 240))
    cv2.imwrite(str(rgb[0]), small)
    raw_depth = cv2.imread(str(depth[1]), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(depth[1]), cv2.resize(raw_depth, (320, 240)))
    cv2.imwrite(str(depth[2]), (raw_depth // 256).astype(np.uint8))
    seq = TumSequence(seq_path)
    with pytest.raises(DatasetError, match='frame 0: the image is 320x240 but the intrinsics'):
        seq.gray(0)
    with pytest.raises(DatasetError, match='frame 0: the image is 320x240'):
        seq.image(0)
    with pytest.raises(DatasetError, match='frame 1: the depth map is 320x240'):
        seq.depth(1)
    with pytest.raises(DatasetError, match='depth must be a 16-bit PNG'):
        seq.depth(2)
    assert seq.image(1).shape == (480, 640, 3)  # the untouched frames still read


def test_a_listing_with_a_byte_order_mark_reads_like_one_without(tmp_path):
    from initsel_ros.datasets.tum import read_listing

    path = tmp_path / 'rgb.txt'
    path.write_bytes(b'\xef\xbb\xbf# color images\n1.0 rgb/1.png\n')  # as Notepad saves it
    assert read_listing(path) == read_listing(_bom_free(path, tmp_path))


def _bom_free(path: Path, tmp_path: Path) -> Path:
    out = tmp_path / 'plain.txt'
    out.write_bytes(path.read_bytes()[3:])
    return out


def test_a_repeated_listing_line_is_one_frame_and_a_conflicting_one_refused(tmp_path, caplog):
    from initsel_ros.datasets.tum import read_listing

    path = tmp_path / 'rgb.txt'
    path.write_text('1.0 rgb/1.png\n2.0 rgb/2.png\n1.0 rgb/1.png\n')
    stamps, names = read_listing(path)  # before: an extra frame
    assert stamps.tolist() == [1.0, 2.0] and names == ['rgb/1.png', 'rgb/2.png']
    assert 'rgb.txt: 1 repeated lines read once' in caplog.text
    path.write_text('1.0 rgb/1.png\n1.0 rgb/9.png\n')
    with pytest.raises(DatasetError, match=r'rgb.txt:2: time 1.0 is also line 1'):
        read_listing(path)
