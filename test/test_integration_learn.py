"""dataset -> train -> eval end to end through the CLI on rendered sequences and a bag."""

from __future__ import annotations

import json

import numpy as np
import pytest

from initsel_ros.cli import main
from initsel_ros.learn.build import build_table
from initsel_ros.learn.pairs import DatasetConfig
from initsel_ros.learn.table import read_table
from initsel_ros.models import ModelSet


@pytest.fixture(scope='module')
def tables(far_sequence, rotation_sequence, static_sequence, near_sequence, tmp_path_factory):
    """Train table (far + rotation + static, batches of 30) and test table (near)."""
    out = tmp_path_factory.mktemp('learn')
    train, test = out / 'train.csv', out / 'test.csv'
    assert (
        main(
            [
                'dataset',
                str(far_sequence),
                str(rotation_sequence),
                str(static_sequence),
                '--out',
                str(train),
                '--batch',
                '30',
                '--jobs',
                '2',
                '--quiet',
            ]
        )
        == 0
    )
    assert (
        main(
            [
                'dataset',
                str(near_sequence),
                '--out',
                str(test),
                '--batch',
                '30',
                '--jobs',
                '1',
                '--quiet',
            ]
        )
        == 0
    )
    return train, test


def test_dataset_labels_every_pair_of_every_batch(tables, far_sequence):
    train = read_table(tables[0])
    seqs = train['sequence'].astype(str)
    far = train.select(seqs == far_sequence.name)
    # 60 frames in batches of 30: 29 pairs per batch, each with its batch's first frame
    assert len(far) == 58
    assert set(far['ref_index'].tolist()) == {0, 30}
    assert np.all(far['cur_index'] > far['ref_index'])
    assert np.all(far['cur_index'] - far['ref_index'] < 30)
    assert np.all(np.isfinite(far['free__disparity_mean']))
    assert np.all(far['scale_rule'] == 'median')
    # pure rotation and static: zero baseline, so R says yes and no pose label is positive
    for name in ('rotation', 'static'):
        part = train.select(np.char.startswith(seqs.astype(str), name))
        assert len(part) > 0
        assert np.all(part['R_label'] == 1)
        assert np.all(part['gt_baseline_m'] < 1e-6)
        for m in ('F', 'E', 'H'):
            assert np.all(part[f'{m}_label'] == 0)
    assert far['E_label'].sum() > 0  # the far motion gives good E poses somewhere


def test_train_writes_a_valid_model_file_with_metadata(tables, tmp_path):
    out = tmp_path / 'models.json'
    assert main(['train', str(tables[0]), '--out', str(out), '--target-precision', '0.7']) == 0
    models = ModelSet.load(out)
    assert set(models.models) == {'F', 'E', 'H', 'R'}
    meta = models.metadata
    assert meta['training_data']['pairs'] == len(read_table(tables[0]))
    assert meta['training']['target_precision'] == 0.7
    assert meta['training']['class_weight'] == 'balanced'
    assert meta['sklearn_version']
    assert meta['feature_scaling'] == 'resolution_free'
    assert set(meta['training_data']['positives']) == {'F', 'E', 'H', 'R'}
    for m in models.models.values():
        assert 0.0 < m.threshold < 1.0
        assert 'validation' in m.metrics
    # reproducible: same data, same seed, same coefficients
    again = tmp_path / 'again.json'
    main(['train', str(tables[0]), '--out', str(again), '--target-precision', '0.7'])
    a, b = json.loads(out.read_text()), json.loads(again.read_text())
    assert a['models'] == b['models']


def test_eval_prints_the_tables_and_writes_files(tables, tmp_path, capsys):
    model_file = tmp_path / 'models.json'
    main(['train', str(tables[0]), '--out', str(model_file)])
    capsys.readouterr()
    out_dir = tmp_path / 'eval'
    assert (
        main(
            [
                'eval',
                str(tables[1]),
                '--models',
                str(model_file),
                '--out-dir',
                str(out_dir),
                '--train',
                str(tables[0]),
                '--candidates',
                'logistic+extra',
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    for needle in (
        'Model E after R veto',
        'Butt 2020 H (mean)',
        'VINS-Mono rule',
        'ORB-SLAM2 H',
        'ORB-SLAM3 F',
        '0.5041',
        'frames to first yes',
        'logistic+extra',
        'precision at model-file recall',
        'after R veto',
        'model file (trees+extra)',
    ):
        assert needle in text
    assert (out_dir / 'eval.md').read_text() in text + '\n'
    assert (out_dir / 'eval.csv').read_text().startswith('classifier,group,label')
    for name in ('pr_F.png', 'pr_E.png', 'pr_H.png', 'pr_R.png', 'errors_vs_baseline.png'):
        assert (out_dir / name).stat().st_size > 1000


def test_dataset_reads_a_bag_like_the_tum_folder(tables, near_bag_ros1):
    from_bag = build_table(
        [near_bag_ros1], DatasetConfig(batch=30, jobs=1, orbslam_iterations=0), progress=False
    )
    from_tum = read_table(tables[1])
    assert len(from_bag) == len(from_tum) == 58
    np.testing.assert_allclose(from_bag['gt_baseline_m'], from_tum['gt_baseline_m'], atol=1e-6)
    np.testing.assert_array_equal(from_bag['n_tracks'], from_tum['n_tracks'])
    assert from_bag['E_label'].tolist() == from_tum['E_label'].tolist()
