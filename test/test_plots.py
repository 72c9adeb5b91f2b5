"""Tests for initsel_ros.learn.plots: the evaluation figures."""

from __future__ import annotations

import logging

import pytest

from initsel_ros.learn import plots


def test_write_plots_writes_one_pr_curve_per_model_and_the_error_figure(near_evaluation, tmp_path):
    pytest.importorskip('matplotlib')
    table, models, report = near_evaluation
    out = tmp_path / 'figures'
    paths = plots.write_plots(table, models, report, out)
    assert sorted(p.name for p in paths) == sorted(
        ['pr_F.png', 'pr_E.png', 'pr_H.png', 'pr_R.png', 'errors_vs_baseline.png']
    )
    for path in paths:
        assert path.parent == out
        assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
        assert path.stat().st_size > 1000


def test_without_matplotlib_there_are_no_plots_and_a_warning(
    near_evaluation, tmp_path, monkeypatch, caplog
):
    def missing():
        raise ImportError('No module named matplotlib')

    monkeypatch.setattr(plots, '_pyplot', missing)
    table, models, report = near_evaluation
    with caplog.at_level(logging.WARNING):
        assert plots.write_plots(table, models, report, tmp_path / 'none') == []
    assert 'matplotlib not installed' in caplog.text
    assert not (tmp_path / 'none').exists()
