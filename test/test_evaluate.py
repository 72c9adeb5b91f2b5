"""Tests for initsel_ros.learn.evaluate: pair scores, precision at recall, the report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.learn.evaluate import (
    binary_scores,
    precision_at_recall,
    report_markdown,
    results_csv_rows,
    verdict,
)
from initsel_ros.learn.table import input_columns
from initsel_ros.models import METHODS


def test_binary_scores_on_a_hand_counted_case():
    y = np.array([1, 1, 0, 0, 1], bool)
    pred = np.array([1, 0, 1, 0, 0], bool)
    s = binary_scores(y, pred)
    assert (s.predicted, s.positives, s.n) == (2, 3, 5)
    assert s.accuracy == pytest.approx(0.4)
    assert s.precision == pytest.approx(0.5)
    assert s.recall == pytest.approx(1 / 3)
    assert s.f1 == pytest.approx(0.4)


def test_binary_scores_without_predictions_or_positives_are_zero_not_nan():
    none = binary_scores(np.array([1, 0, 1], bool), np.zeros(3, bool))
    assert (none.precision, none.recall, none.f1) == (0.0, 0.0, 0.0)
    no_pos = binary_scores(np.zeros(3, bool), np.array([1, 0, 0], bool))
    assert (no_pos.precision, no_pos.recall) == (0.0, 0.0)
    assert no_pos.accuracy == pytest.approx(2 / 3)
    assert math.isnan(binary_scores(np.zeros(0, bool), np.zeros(0, bool)).accuracy)
    # ... but a table shows them as undefined (before: 0.0000 for R with 0 yes, 0 positives)
    shown = [np.isnan(v) for v in none.shown()]
    assert shown == [True, False, True]  # precision without a yes; recall 0 of 2 is a 0
    assert [np.isnan(v) for v in no_pos.shown()] == [False, True, True]


def test_precision_at_recall_takes_the_best_threshold_reaching_the_recall():
    y = np.array([1, 0, 1, 0], bool)
    scores = np.array([0.9, 0.8, 0.7, 0.1])
    assert precision_at_recall(y, scores, 0.5) == pytest.approx(1.0)  # top pair only
    assert precision_at_recall(y, scores, 1.0) == pytest.approx(2 / 3)  # down to 0.7
    assert math.isnan(precision_at_recall(np.zeros(4, bool), scores, 0.5))


def test_model_rows_score_the_shipped_thresholds_on_every_pair(near_evaluation):
    table, models, report = near_evaluation
    assert report.n_pairs == len(table) > 0
    assert sum(report.sequences.values()) == len(table)
    probs = models.predict_proba_batch(
        table.matrix(input_columns(models.input_names, models.scaling))
    )
    rows = {r.name: r for r in report.rows}
    for m in METHODS:
        y = np.asarray(table[f'{m}_label']).astype(bool)
        fired = probs[m] >= models.thresholds[m]
        np.testing.assert_allclose(report.probabilities[m], probs[m])
        assert rows[f'Model {m}'].scores == binary_scores(y, fired)
    r_fired = probs['R'] >= models.thresholds['R']
    e_fired = probs['E'] >= models.thresholds['E']
    assert rows['Model E after R veto'].scores == binary_scores(
        np.asarray(table['E_label']).astype(bool), e_fired & ~r_fired
    )
    assert {r.group for r in report.rows} == {'model', 'veto', 'baseline'}
    assert report.decision_us > 0 and report.inference_ms_all_pairs >= 0


def test_report_markdown_and_csv_rows_carry_every_row(near_evaluation):
    _, _, report = near_evaluation
    text = report_markdown(report)
    assert text.startswith(f'# Evaluation on {report.n_pairs} pairs')
    for row in report.rows:
        assert row.name in text
    for system in report.systems:
        assert system.name in text
    csv_rows = results_csv_rows(report)
    names = [r['classifier'] for r in csv_rows]
    assert names[: len(report.rows)] == [r.name for r in report.rows]
    assert names[len(report.rows) :] == [f'sequence level: {s.name}' for s in report.systems]
    assert 'No candidate families' in verdict(report)  # evaluated without --train


def test_h_by_the_fire_path_is_a_row_where_the_table_holds_the_fire_paths_outcome(
    near_evaluation,
):
    """Without the fire path's outcome in the table there is no such row; with it, the row
    counts the pairs a model's yes hands to the fire path and on which it publishes H."""
    from initsel_ros.learn.evaluate import evaluate, fire_path_h, fire_path_h_scores
    from initsel_ros.learn.table import PairTable

    table, models, report = near_evaluation
    assert 'H by the fire path' not in {r.name for r in report.rows}
    cols = dict(table.columns)
    rng = np.random.default_rng(0)
    cols['fire_method'] = rng.choice(np.array(['E', 'H', 'none'], dtype=object), len(table))
    cols['fire_et'] = rng.uniform(0.0, 0.4, len(table))
    held = PairTable(cols)
    rows = {r.name: r for r in evaluate(held, models, et_max=0.2).rows}
    probs = models.predict_proba_batch(
        held.matrix(input_columns(models.input_names, models.scaling))
    )
    published, good = fire_path_h(held, probs, models.thresholds, et_max=0.2)
    y = np.asarray(held['H_label']).astype(bool)
    scores = rows['H by the fire path'].scores
    assert scores == fire_path_h_scores(y, published, good)
    assert 0 < good.sum() < published.sum() == scores.predicted
    assert scores.precision == pytest.approx(good.sum() / published.sum())
    assert scores.recall == pytest.approx((published & y).sum() / y.sum())
    assert math.isnan(scores.accuracy)
