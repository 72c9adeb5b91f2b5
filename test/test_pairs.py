"""Tests for initsel_ros.learn.pairs: batches, and pairs from the real 3-frame sample."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from initsel_ros.learn.build import build_table
from initsel_ros.learn.correspondences import Source
from initsel_ros.learn.pairs import DatasetConfig, batch_ranges

REAL = Path('/work/shared/data/tum_fr3_structure_texture_near')


def test_real_pairs_from_orb_matches_recover_the_true_translation_direction():
    if not REAL.is_dir():
        pytest.skip('real sample not available')
    config = DatasetConfig(batch=3, source=Source.ORB, jobs=1, nearest_tolerance=0.2)
    table = build_table([REAL], config, progress=False)
    assert len(table) == 2  # frames 1 and 2, each paired with frame 0
    assert np.all(table['gt_baseline_m'] > 0.25)  # 0.30 m and 0.62 m
    assert np.all(table['R_label'] == 0)
    assert np.all(table['E_et'] < 0.15)  # measured 0.07 with ORB + 5-point
    assert np.all(table['F_et'] < 0.8)
    assert np.all(table['E_label'] == 1)
    assert np.all(table['E_n_gt_points'] > 50)  # real depth behind the matched points
    assert all(math.isfinite(v) for v in table['orb_ratio'])
    # a static scene with real depth and ORB matches: most matches explained, some not
    # (measured 0.97 and 0.79: mismatches, and real depth at the matched pixels)
    assert np.all(table['gt_static_share'] > 0.7) and np.all(table['gt_static_share'] <= 1.0)
    # the desk's structure, 30-60 cm off to the side: depth off any one plane (measured 0.69
    # and 0.73 on the largest) and no track the rotation alone explains (measured 0)
    assert np.all(table['gt_plane_share'] > 0.4) and np.all(table['gt_plane_share'] < 0.8)
    assert np.all(table['gt_rotation_share'] < 0.1)


def test_batches_cover_the_sequence_and_drop_single_frames():
    assert batch_ranges(7, 3) == [[0, 1, 2], [3, 4, 5]]
    assert batch_ranges(8, 3)[-1] == [6, 7]
    assert batch_ranges(10, 3, stride=2) == [[0, 2, 4], [6, 8]]


def test_a_batch_whose_first_frame_has_no_pose_starts_at_its_first_frame_with_one(caplog):
    # the real fr3 sequences start before the motion capture: by default the sample's first
    # frame has no pose, and its whole batch was dropped (logged at debug level only)
    if not REAL.is_dir():
        pytest.skip('real sample not available')
    config = DatasetConfig(batch=3, source=Source.ORB, jobs=1)
    table = build_table([REAL], config, progress=False)
    assert len(table) == 1  # frame 2 against frame 1: before, no pair at all
    assert table['ref_index'].tolist() == [1] and table['cur_index'].tolist() == [2]
    assert 'batches start on frames without a ground-truth pose' in caplog.text


def test_the_dataset_reads_a_folder_with_the_intrinsics_it_is_given(static_sequence):
    from initsel_ros.camera import Intrinsics
    from initsel_ros.learn.pairs import open_cached

    camera = Intrinsics(500.0, 505.0, 321.0, 239.0, 640, 480)
    assert open_cached(str(static_sequence), DatasetConfig()).intrinsics != camera
    assert open_cached(str(static_sequence), DatasetConfig(intrinsics=camera)).intrinsics == camera


def test_two_sources_of_one_sequence_name_are_refused(static_sequence, tmp_path):
    # before: their pairs were merged under one name (eval counted one batch for two)
    import shutil

    from initsel_ros.errors import DatasetError

    copy = tmp_path / 'elsewhere' / static_sequence.name
    shutil.copytree(static_sequence, copy)
    for sources in ([static_sequence, static_sequence], [static_sequence, copy]):
        with pytest.raises(DatasetError, match=r"are both sequence '.*': the pair table"):
            build_table(sources, DatasetConfig(batch=10, jobs=1), progress=False)


def test_the_fire_path_outcome_is_the_method_the_node_publishes_and_its_best_direction():
    """A wall seen from two views is H's (E_t of the best decomposition kept); a desk with
    depth is E's or F's; a pan publishes nothing, its E_t is NaN and its rotation test's
    statistic is at the noise."""
    from geometry_fixtures import K, pan, two_view

    from initsel_ros.learn.pairs import fire_path_outcome

    p0, p1, _, t, _ = two_view(planar=True, baseline=0.3)
    wall = fire_path_outcome(p0, p1, K, t)
    assert wall.method == 'H' and wall.et < 0.1 and wall.rotation_statistic > 3.0
    p0, p1, _, t, _ = two_view(planar=False, baseline=0.3)
    desk = fire_path_outcome(p0, p1, K, t)
    assert desk.method in ('E', 'F') and desk.et < 0.1
    assert fire_path_outcome(p0, p1, K, -t).et > 1.9  # judged against the direction given
    turn = fire_path_outcome(*pan(), K, np.array([1.0, 0.0, 0.0]))
    assert turn.method == 'none' and np.isnan(turn.et) and turn.rotation_statistic < 2.0


def test_the_datasets_fire_path_tries_radial_terms_only_for_a_camera_stating_none(
    static_sequence, monkeypatch
):
    """As the node does (``initialize.radial_terms_for``): a camera that states its
    distortion has its tracks undistorted, and the rotation test tries no radial terms."""
    from dataclasses import replace

    from initsel_ros.camera import Intrinsics
    from initsel_ros.datasets import open_sequence
    from initsel_ros.geometry import ROTATION_RADIAL_TERMS
    from initsel_ros.learn import pairs

    tried = []

    def recorded(p0, p1, K, t_gt, radial_terms):
        tried.append(radial_terms)
        return pairs.FireOutcome('none')

    monkeypatch.setattr(pairs, 'fire_path_outcome', recorded)
    for distortion, want in (((), ROTATION_RADIAL_TERMS), ((0.05, -0.02, 0.0, 0.0), ())):
        camera = replace(Intrinsics.tum_fr3(), distortion=distortion)
        config = DatasetConfig(batch=6, jobs=1, fire_path=True, intrinsics=camera,
                               orbslam_iterations=0, vins_ransac=False)  # fmt: skip
        tried.clear()
        rows = pairs.label_sequence_batch(
            open_sequence(static_sequence, intrinsics=camera), 0, range(6), config
        )
        assert rows and len(tried) == len(rows)
        assert all(terms == want for terms in tried)
