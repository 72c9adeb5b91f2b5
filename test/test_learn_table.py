"""Pair table round trip, threshold selection and grouped folds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.errors import DatasetError
from initsel_ros.learn.table import PairTable, read_table, schema, write_table
from initsel_ros.learn.train import choose_threshold, grouped_folds, out_of_fold_scores


def _random_rows(rng: np.random.Generator, n: int) -> list[dict]:
    rows = []
    for i in range(n):
        row = {}
        for name, kind in schema():
            if kind is float:
                row[name] = float(rng.normal())
            elif kind is int:
                row[name] = int(rng.integers(0, 100))
            else:
                row[name] = f'text {i}; with spaces'
        rows.append(row)
    rows[0]['E_et'] = math.nan
    rows[0]['E_er'] = math.inf
    rows[1]['sequence'] = 'a "quoted", comma name'
    return rows


def test_csv_round_trip_keeps_every_column_and_value(tmp_path):
    rng = np.random.default_rng(0)
    table = PairTable.from_rows(_random_rows(rng, 5))
    path = tmp_path / 'sub' / 'pairs.csv'
    write_table(table, path)
    back = read_table(path)
    assert len(back) == 5
    assert list(back.columns) == [name for name, _ in schema()]
    for name, kind in schema():
        a, b = table[name], back[name]
        if kind is float:
            np.testing.assert_array_equal(a, b)  # repr round-trips floats, nan and inf
        else:
            assert a.tolist() == b.tolist()
    assert back['sequence'][1] == 'a "quoted", comma name'
    assert [p.name for p in path.parent.iterdir()] == ['pairs.csv']  # no temp file left


def test_reading_a_foreign_csv_names_the_file_and_missing_columns(tmp_path):
    path = tmp_path / 'other.csv'
    path.write_text('a,b\n1,2\n')
    with pytest.raises(DatasetError, match=r'other\.csv.*missing columns'):
        read_table(path)
    with pytest.raises(DatasetError, match='cannot read'):
        read_table(tmp_path / 'absent.csv')


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
