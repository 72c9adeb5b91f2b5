"""Random two-view pairs: the distillation pairs of `initsel twoview`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from table_fixtures import synthetic_table

from initsel_ros.cli import main
from initsel_ros.errors import DatasetError
from initsel_ros.learn.table import (
    EXTRA_NAMES,
    PairTable,
    free_feature_columns,
    read_table,
    write_table,
)
from initsel_ros.learn.twoview import (
    TWOVIEW_SOURCE,
    check_labelled,
    random_two_view,
    twoview_table,
)


def test_pairs_are_two_views_of_one_rigid_scene_within_the_drawn_noise():
    """Each pair is a projection of 3D points into two cameras: a fundamental matrix fitted
    to it leaves most points within the noise (at most 1 px drawn, 6 % outliers)."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        view = random_two_view(rng)
        p0, p1 = view.p0, view.p1
        assert len(p0) == len(p1) >= 30
        assert np.all((p0 >= 0) & (p0 < [640, 480])) and np.all((p1 >= 0) & (p1 < [640, 480]))
        F, inliers = cv2.findFundamentalMat(
            p0.reshape(-1, 1, 2), p1.reshape(-1, 1, 2), cv2.FM_LMEDS
        )
        if F is None:  # a still camera: no epipolar geometry to fit
            assert np.median(np.hypot(*(p1 - p0).T)) < 3.0
            continue
        assert inliers.mean() > 0.8


def test_a_table_is_reproducible_and_holds_no_labels(tmp_path):
    table = twoview_table(25, seed=4)
    again = twoview_table(25, seed=4)
    other = twoview_table(25, seed=5)
    column = free_feature_columns()[1]  # the mean disparity
    assert np.array_equal(table[column], again[column])
    assert not np.array_equal(table[column], other[column])
    assert set(table['source']) == {TWOVIEW_SOURCE} and set(table['sequence']) == {'twoview_s4'}
    for m in 'FEH':
        assert not table[f'{m}_label'].any() and not table[f'{m}_ok'].any()
    assert np.all(np.isfinite(table.matrix(free_feature_columns())))
    assert np.isfinite(table['x_homography_dlt_residual']).all()
    assert set(EXTRA_NAMES) <= set(table.columns)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    assert np.array_equal(read_table(path)[column], table[column])
    with pytest.raises(DatasetError, match='at least one pair'):
        twoview_table(0, seed=1)


def test_training_from_labels_and_evaluation_refuse_two_view_pairs(tmp_path, capsys):
    labelled = synthetic_table(60, seed=1)
    check_labelled(labelled, 'training')  # labelled pairs pass
    mixed = PairTable.concat([labelled, twoview_table(10, seed=2)])
    with pytest.raises(DatasetError, match='10 pairs of the tables are random two-view'):
        check_labelled(mixed, 'training from labels')
    pairs = tmp_path / 'twoview.csv'
    assert main(['twoview', '--pairs', '12', '--seed', '1', '2', '--out', str(pairs)]) == 0
    assert '24 random two-view pairs' in capsys.readouterr().out
    assert len(read_table(pairs)) == 24
    assert main(['train', str(pairs), '--out', str(tmp_path / 'm.json')]) != 0
    assert 'training from labels needs labelled pairs' in capsys.readouterr().err
    assert not (tmp_path / 'm.json').exists()


def test_students_distil_on_two_view_pairs_too(tmp_path, capsys):
    labelled = tmp_path / 'pairs.csv'
    write_table(synthetic_table(180, seed=2), labelled)
    teacher = tmp_path / 'teacher.json'
    assert main(['train', str(labelled), '--out', str(teacher), '--trees', '10']) == 0
    pairs = tmp_path / 'twoview.csv'
    assert main(['twoview', '--pairs', '60', '--seed', '3', '--out', str(pairs)]) == 0
    student = tmp_path / 'student.json'
    argv = ['train', str(labelled), str(pairs), '--distill', str(teacher), '--out', str(student)]
    argv += ['--trees', '10', '--extra-features', 'x_homography_dlt_residual']
    assert main(argv) == 0
    assert 'distilled from' in capsys.readouterr().out
    assert '"train_pairs": 240' in student.read_text()  # the labelled 180 and 60 two-view
    assert main(['eval', str(pairs), '--models', str(student)]) != 0
    assert 'evaluation needs labelled pairs' in capsys.readouterr().err
