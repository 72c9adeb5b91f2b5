"""`initsel train` families: per-model kinds and features, CLI parsing, and metadata."""

from __future__ import annotations

import numpy as np
import pytest
from test_learn_faults import synthetic_table

from initsel_ros.cli import main
from initsel_ros.errors import ConfigError
from initsel_ros.features import EXTRA_FEATURE_NAMES, FEATURE_NAMES
from initsel_ros.learn.table import write_table
from initsel_ros.learn.train import Family, TrainConfig, TreeConfig, train_models
from initsel_ros.models import ModelSet


def test_each_model_gets_its_family_and_declares_its_features():
    config = TrainConfig(family=Family.LOGISTIC, families={'F': Family.TREES_EXTRA,
                                                            'R': Family.TREES},
                         extra=('x_homography_residual', 'x_disp_p50'),
                         trees=TreeConfig(20, 2, 0.2))
    report = train_models(synthetic_table(), config)
    ms = report.models
    assert ms.kinds == {'F': 'trees', 'E': 'logistic', 'H': 'logistic', 'R': 'trees'}
    # extras in the canonical order, whatever order they were asked in
    assert ms.models['F'].features == (*FEATURE_NAMES, 'x_disp_p50', 'x_homography_residual')
    assert ms.models['E'].features == FEATURE_NAMES
    assert ms.extra_names == ('x_disp_p50', 'x_homography_residual')
    training = ms.metadata['training']
    assert training['families'] == {'F': 'trees+extra', 'E': 'logistic', 'H': 'logistic',
                                    'R': 'trees'}
    assert training['trees']['n_trees'] == 20
    assert ms.models['F'].metrics['family'] == 'trees+extra'
    assert len(ms.models['F'].trees) == 20
    # the synthetic labels follow free__disparity_mean: the trees learn it
    x = np.zeros(len(ms.input_names))
    lo, hi = x.copy(), x.copy()
    lo[1], hi[1] = -2.0, 2.0
    assert ms.predict_proba(hi)['F'] > ms.predict_proba(lo)['F']


def test_training_is_reproducible_for_tree_families():
    a = train_models(synthetic_table(seed=4), TrainConfig()).models.to_dict()['models']
    b = train_models(synthetic_table(seed=4), TrainConfig()).models.to_dict()['models']
    assert a == b


def test_bad_family_options_are_one_line(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    write_table(synthetic_table(), path)
    for spec in ('forest', 'X=trees', 'F=forest'):
        assert main(['train', str(path), '--out', str(tmp_path / 'm.json'), '--family',
                     spec]) == 1
        err = capsys.readouterr().err
        assert '--family' in err and len(err.strip().splitlines()) == 1
    with pytest.raises(ConfigError, match='unknown extra features'):
        TrainConfig(extra=('x_magic',))
    with pytest.raises(ConfigError, match='tree depth'):
        TreeConfig(depth=40)


def test_cli_family_options_reach_the_model_file(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    write_table(synthetic_table(), path)
    out = tmp_path / 'models.json'
    assert main(['train', str(path), '--out', str(out), '--family', 'logistic+extra',
                 '--family', 'H=trees', '--extra-features', 'x_grid_entropy',
                 '--trees', '12', '--tree-depth', '2']) == 0
    assert '| H | trees |' in capsys.readouterr().out
    ms = ModelSet.load(out)
    assert ms.kinds == {'F': 'logistic', 'E': 'logistic', 'H': 'trees', 'R': 'logistic'}
    assert ms.extra_names == ('x_grid_entropy',)
    assert len(ms.models['H'].trees) == 12 and ms.models['H'].depth <= 2
    assert set(ms.metadata['training']['extra_features']) <= set(EXTRA_FEATURE_NAMES)
