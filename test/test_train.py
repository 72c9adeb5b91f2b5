"""Tests for initsel_ros.learn.train: thresholds, grouped folds, families, degenerate labels.

Issue 11: a single-class table wrote a model that always (or never) fires and exited 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from table_fixtures import synthetic_table

from initsel_ros.cli import main
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.features import EXTRA_FEATURE_NAMES, FEATURE_NAMES
from initsel_ros.learn.table import PairTable, write_table
from initsel_ros.learn.train import (
    Family,
    TrainConfig,
    TreeConfig,
    choose_threshold,
    grouped_folds,
    out_of_fold_scores,
    train_models,
)
from initsel_ros.models import ModelSet


def test_threshold_selection_reaches_the_target_precision_with_most_recall():
    rng = np.random.default_rng(1)
    y = rng.random(2000) < 0.3
    scores = np.clip(0.35 * y + rng.normal(0.3, 0.15, 2000), 0, 1)
    for target in (0.7, 0.8, 0.9):
        choice = choose_threshold(y, scores, target)
        assert choice.reached
        pred = scores >= choice.threshold
        precision = (pred & y).sum() / pred.sum()
        assert precision >= target
        assert choice.precision == pytest.approx(precision)
        # any lower threshold breaks the target or does not add recall
        lower = np.sort(np.unique(scores[scores < choice.threshold]))[-20:]
        for t in lower:
            p = scores >= t
            assert (p & y).sum() / p.sum() < target or (p & y).sum() <= (pred & y).sum()


def test_a_threshold_prior_makes_the_threshold_independent_of_the_mix():
    # the same classifier on two mixes, 60 % and 15 % positives: precision-targeted thresholds
    # differ (the rich mix reaches 0.8 precision far lower), prior-targeted ones agree
    rng = np.random.default_rng(3)

    def mix(share: float, n: int = 4000):
        y = rng.random(n) < share
        return y, np.clip(0.3 * y + rng.normal(0.35, 0.12, n), 0, 1)

    mixes = mix(0.6), mix(0.15)
    y_rich, s_rich = mixes[0]
    plain = [choose_threshold(y, s, 0.8).threshold for y, s in mixes]
    assert plain[1] - plain[0] > 0.1
    prior = [choose_threshold(y, s, 0.8, prior=0.25) for y, s in mixes]
    assert abs(prior[0].threshold - prior[1].threshold) < 0.03
    assert 'at a 0.25 share of positives' in prior[0].rule
    # and the reported figures are those of the mix itself
    pred = s_rich >= prior[0].threshold
    assert prior[0].precision == pytest.approx((pred & y_rich).sum() / pred.sum())
    with pytest.raises(ConfigError, match='threshold_prior'):
        TrainConfig(threshold_prior=1.0)


def test_family_folds_hold_the_target_on_the_worst_family_too():
    # two families of 400 pairs: on 'easy' the scores separate the classes, on 'hard' the
    # negatives reach as high as the positives. Pooled, a low threshold reaches 0.8; with
    # the families as groups the threshold must also give 'hard' 0.8, so it rises
    rng = np.random.default_rng(5)
    y = rng.random(800) < 0.4
    hard = np.arange(800) >= 400
    scores = np.where(y, rng.uniform(0.5, 1.0, 800), rng.uniform(0.0, 0.5, 800))
    scores[hard & ~y] = rng.uniform(0.0, 0.9, int((hard & ~y).sum()))
    groups = hard.astype(int)
    pooled = choose_threshold(y, scores, 0.8)
    by_family = choose_threshold(y, scores, 0.8, groups=groups, min_group_positives=30)
    assert by_family.reached and 'worst family' in by_family.rule
    assert by_family.threshold > pooled.threshold
    for choice, worst_ok in ((pooled, False), (by_family, True)):
        pred = scores >= choice.threshold
        on_hard = (pred & y & hard).sum() / (pred & hard).sum()
        assert bool(on_hard >= 0.8) is worst_ok
    # the lowest such threshold: one step lower breaks 'hard'
    below = np.max(scores[scores < by_family.threshold])
    pred = scores >= below
    assert (pred & y & hard).sum() / (pred & hard).sum() < 0.8
    # a family with fewer positives than the bar does not count
    few = choose_threshold(y, scores, 0.8, groups=groups, min_group_positives=10_000)
    assert few.threshold == pytest.approx(pooled.threshold)


def test_family_folds_fall_back_to_the_worst_familys_best_precision_at_half_recall():
    # 'hard' cannot reach 0.8 at any threshold: the threshold keeps half of the positives
    # and, among those that do, gives 'hard' its highest precision
    rng = np.random.default_rng(6)
    y = rng.random(800) < 0.4
    hard = np.arange(800) >= 400
    scores = np.where(y, rng.uniform(0.3, 1.0, 800), rng.uniform(0.0, 0.3, 800))
    scores[hard] = rng.uniform(0.0, 1.0, int(hard.sum()))  # uninformative on 'hard'
    choice = choose_threshold(y, scores, 0.8, groups=hard.astype(int), min_group_positives=30)
    assert not choice.reached and 'recall >= 0.5' in choice.rule
    assert choice.recall >= 0.5

    def hard_precision(t):
        pred = (scores >= t) & hard
        return (pred & y).sum() / max(pred.sum(), 1)

    candidates = [t for t in np.unique(scores) if (y & (scores >= t)).sum() >= 0.5 * y.sum()]
    assert hard_precision(choice.threshold) == pytest.approx(max(map(hard_precision, candidates)))


def test_training_with_family_folds_needs_the_families_and_fits_one_fold_each(monkeypatch):
    from initsel_ros.learn import train as train_module
    from initsel_ros.learn.generalize import Families

    with pytest.raises(ConfigError, match='scene families'):
        TrainConfig(group_by='family')
    table = synthetic_table(n=240, seed=4)
    cols = dict(table.columns)
    names = ['far_a', 'far_b', 'wall_a', 'floor_a']
    cols['sequence'] = np.array([names[i % 4] for i in range(240)], dtype=object)
    families = Families({'desk': ('far_*',), 'walls': ('wall_*',), 'floor': ('floor_*',)})
    folds_seen = []
    real = train_module.out_of_fold_scores

    def spy(X, y, groups, fit, folds, seed, unit='batch'):
        folds_seen.append((folds, unit, len(np.unique(groups))))
        return real(X, y, groups, fit, folds, seed, unit)

    monkeypatch.setattr(train_module, 'out_of_fold_scores', spy)
    config = TrainConfig(group_by='family', scene_families=families, min_family_positives=5)
    report = train_models(PairTable(cols), config)
    assert folds_seen and all(f == (3, 'family', 3) for f in folds_seen)
    assert all('worst family' in c.rule for c in report.choices.values())
    training = report.models.metadata['training']
    assert 'one fold per scene family (3)' in training['validation']
    assert training['scene_families'] == {
        'desk': ['far_*'],
        'walls': ['wall_*'],
        'floor': ['floor_*'],
    }


def test_unreachable_precision_is_reported_not_hidden():
    rng = np.random.default_rng(2)
    y = rng.random(500) < 0.5
    scores = rng.random(500)  # uninformative
    choice = choose_threshold(y, scores, 0.99)
    assert not choice.reached
    assert 'unreachable' in choice.rule
    assert 0.0 < choice.threshold < 1.0


def test_grouped_folds_never_split_a_batch():
    groups = np.repeat(np.arange(12), 30)
    folds = grouped_folds(groups, 5, seed=0)
    assert sorted(np.concatenate(folds).tolist()) == list(range(len(groups)))
    for val in folds:
        inside = set(groups[val])
        outside = set(groups) - inside
        assert not inside & outside
        assert all(np.all(np.isin(np.flatnonzero(groups == g), val)) for g in inside)
    with pytest.raises(DatasetError, match='at least 2 batches'):
        grouped_folds(np.zeros(10, int), 5, seed=0)


def test_out_of_fold_scores_come_from_models_that_did_not_see_the_batch():
    groups = np.repeat(np.arange(6), 10)
    X = groups[:, None].astype(float)
    y = (groups % 2).astype(int)

    def fit(Xt, yt):
        seen = set(Xt[:, 0].tolist())
        return lambda Z: np.array([1.0 if z in seen else 0.0 for z in Z[:, 0]])

    scores = out_of_fold_scores(X, y, groups, fit, folds=3, seed=0)
    assert np.all(scores == 0.0)


def test_each_model_gets_its_family_and_declares_its_features():
    config = TrainConfig(
        family=Family.LOGISTIC,
        families={'F': Family.TREES_EXTRA, 'R': Family.TREES},
        extra=('x_homography_residual', 'x_disp_p50'),
        trees=TreeConfig(20, 2, 0.2),
    )
    report = train_models(synthetic_table(), config)
    ms = report.models
    assert ms.kinds == {'F': 'trees', 'E': 'logistic', 'H': 'logistic', 'R': 'trees'}
    # extras in the canonical order, whatever order they were asked in
    assert ms.models['F'].features == (*FEATURE_NAMES, 'x_disp_p50', 'x_homography_residual')
    assert ms.models['E'].features == FEATURE_NAMES
    assert ms.extra_names == ('x_disp_p50', 'x_homography_residual')
    training = ms.metadata['training']
    assert training['families'] == {
        'F': 'trees+extra',
        'E': 'logistic',
        'H': 'logistic',
        'R': 'trees',
    }
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
        assert main(['train', str(path), '--out', str(tmp_path / 'm.json'), '--family', spec]) == 1
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
    assert (
        main(
            [
                'train',
                str(path),
                '--out',
                str(out),
                '--family',
                'logistic+extra',
                '--family',
                'H=trees',
                '--extra-features',
                'x_grid_entropy',
                '--trees',
                '12',
                '--tree-depth',
                '2',
            ]
        )
        == 0
    )
    assert '| H | trees |' in capsys.readouterr().out
    ms = ModelSet.load(out)
    assert ms.kinds == {'F': 'logistic', 'E': 'logistic', 'H': 'trees', 'R': 'logistic'}
    assert ms.extra_names == ('x_grid_entropy',)
    assert len(ms.models['H'].trees) == 12 and ms.models['H'].depth <= 2
    assert set(ms.metadata['training']['extra_features']) <= set(EXTRA_FEATURE_NAMES)


def test_single_class_training_is_an_error_naming_the_model_and_counts(tmp_path, capsys):
    table = synthetic_table(R_label=1)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    out = tmp_path / 'models.json'
    assert main(['train', str(path), '--out', str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert 'R' in err and '120 positive' in err and '0 negative' in err
    assert '--allow-degenerate' in err
    assert not out.exists()


def test_allow_degenerate_writes_the_constant_model_with_a_warning(tmp_path, caplog):
    table = synthetic_table(R_label=1)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    out = tmp_path / 'models.json'
    assert main(['train', str(path), '--out', str(out), '--allow-degenerate']) == 0
    assert 'always fire' in caplog.text
    from initsel_ros.models import ModelSet

    models = ModelSet.load(out)
    assert models.metadata['training']['degenerate_models'] == ['R']


def test_train_models_refuses_single_class_labels_by_default():
    with pytest.raises(DatasetError, match=r'model F: .*0 positive'):
        train_models(synthetic_table(F_label=0), TrainConfig())
    report = train_models(synthetic_table(F_label=0), TrainConfig(allow_degenerate=True))
    assert report.models.models['F'].bias < -math.log(1e4)


def test_the_determined_and_flow_labels_relabel_the_training_pairs(tmp_path):
    from initsel_ros.learn.labels import LabelConfig, relabel

    table = synthetic_table()
    rng = np.random.default_rng(1)
    columns = dict(table.columns)
    columns['scale_rule'] = np.array(['median'] * len(table), dtype=object)
    columns['gt_plane_share'] = rng.uniform(0.0, 1.0, len(table))
    columns['gt_rotation_share'] = rng.uniform(0.0, 1.0, len(table))
    for m in 'FEH':
        columns[f'{m}_ok'] = np.ones(len(table), dtype=int)
        columns[f'{m}_et'] = rng.uniform(0.0, 1.0, len(table))
        columns[f'{m}_er_median'] = np.full(len(table), 0.1)
    path = tmp_path / 'pairs.csv'
    write_table(PairTable(columns), path)
    out = tmp_path / 'models.json'
    options = ['--method-label', 'determined', '--rotation-label', 'flow']
    assert main(['train', str(path), '--out', str(out), '--family', 'logistic', *options]) == 0
    meta = ModelSet.load(out).metadata
    assert meta['labels']['method_label'] == 'determined'
    assert meta['labels']['rotation_label'] == 'flow'
    assert meta['labels']['dominant_share'] == 0.8
    expected = relabel(columns, LabelConfig(method_label='determined', rotation_label='flow'))
    positives = meta['training_data']['positives']
    assert positives == {m: int(expected[f'{m}_label'].sum()) for m in 'FEHR'}
    assert positives['E'] < int((columns['E_et'] < 0.8).sum())  # the planar pairs left out


def test_the_model_file_records_the_threshold_prior_and_the_r_label_rule(tmp_path):
    path = tmp_path / 'pairs.csv'
    write_table(synthetic_table(), path)
    out = tmp_path / 'models.json'
    args = ['train', str(path), '--out', str(out), '--family', 'logistic']
    priors = ['--threshold-prior', '0.3', '--threshold-prior', 'R=0.15']
    assert main([*args, *priors, '--rotation-label', 'parallax']) == 0
    meta = ModelSet.load(out).metadata
    assert meta['training']['threshold_prior'] == {'F': 0.3, 'E': 0.3, 'H': 0.3, 'R': 0.15}
    assert meta['labels']['rotation_label'] == 'parallax'
    assert meta['labels']['rotation_parallax_deg'] == 1.0
    rules = {m: ModelSet.load(out).models[m].metrics['validation']['rule'] for m in 'FEHR'}
    assert 'at a 0.15 share of positives' in rules['R']
    assert all('at a 0.3 share of positives' in rules[m] for m in 'FEH')
    with pytest.raises(ConfigError, match="unknown model 'X'"):
        TrainConfig(threshold_priors={'X': 0.2})
    assert main([*args, '--threshold-prior', 'R=lots']) == 1


def test_r_can_leave_out_the_rotations_with_objects_moving_on_their_own(tmp_path, caplog):
    """--rotation-min-static-share: R learns without the R-positive pairs whose tracks the
    ground truth explains as a static scene for less than the share; negatives, pairs
    without depth (NaN) and the other models keep every pair."""
    import logging

    from initsel_ros.learn.table import PairTable
    from initsel_ros.learn.train import rotation_training_rows

    table = synthetic_table(n=180)
    columns = dict(table.columns)
    share = np.ones(len(table))
    share[::3] = 0.8  # a third with a board moving on its own
    share[1::9] = np.nan  # no depth
    columns['gt_static_share'] = share
    table = PairTable(columns)
    r = np.asarray(table['R_label']).astype(bool)
    config = TrainConfig(family=Family.LOGISTIC, folds=3, rotation_min_static_share=0.9)
    keep = rotation_training_rows(table, config)
    assert np.array_equal(keep, ~(r & (share < 0.9)))
    assert keep[1::9].all() and (~keep).sum() > 10
    assert rotation_training_rows(table, TrainConfig(family=Family.LOGISTIC)).all()
    with caplog.at_level(logging.INFO):
        report = train_models(table, config)
    assert report.positives['R'] == int(r.sum()) - int((~keep).sum())
    assert report.positives['E'] == int(np.asarray(table['E_label']).sum())
    training = report.models.metadata['training']
    assert training['rotation_min_static_share'] == 0.9
    assert training['rotation_pairs_left_out'] == int((~keep).sum())
    unknown = int(np.sum(r[1::9]))  # the pairs without depth are kept, and said so
    assert (
        f'model R: {unknown} of {int(r.sum())} positive pairs have no static share' in caplog.text
    )
    assert (
        'rotation_min_static_share'
        not in train_models(table, TrainConfig(family=Family.LOGISTIC, folds=3)).models.metadata[
            'training'
        ]
    )
    for bad in (0.0, 1.5, math.nan):
        with pytest.raises(ConfigError, match='rotation_min_static_share'):
            TrainConfig(rotation_min_static_share=bad)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    out = tmp_path / 'models.json'
    args = ['train', str(path), '--out', str(out), '--family', 'logistic', '--folds', '3']
    assert main([*args, '--rotation-min-static-share', '0.9']) == 0
    assert ModelSet.load(out).metadata['training']['rotation_pairs_left_out'] == (~keep).sum()
