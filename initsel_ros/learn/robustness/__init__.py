"""Robustness studies: the tracker under brightness changes, model files under camera effects.

:mod:`.tracker` compares the tracker's photometric modes against the rendered truth;
:mod:`.models` scores model files and the baselines on the same labelled pairs per effect and
chooses the file to ship; :mod:`.report` writes that comparison as Markdown, CSV and plots.
Run them with ``initsel robustness tracker|models``.
"""

from __future__ import annotations

from initsel_ros.learn.robustness.models import (
    BASELINES,
    COLUMNS,
    LEVELS,
    MODEL_ROWS,
    MODEL_SYSTEM,
    ROTATION_SEQUENCE,
    TEST_SEQUENCE,
    choose_model,
    compare_models,
    f1_score,
    format_number,
    is_model_row,
    label_sequence,
    slug,
)
from initsel_ros.learn.robustness.report import (
    CSV_COLUMNS,
    comparison_markdown,
    plot_comparison,
    write_comparison_csv,
)
from initsel_ros.learn.robustness.tracker import (
    ESTIMATES_ONLY,
    EXTRA_CONDITIONS,
    MIN_BASELINE_M,
    NOISE_SEEDS,
    RAMPS,
    TRACKER_SEQUENCES,
    PairResult,
    compare_trackers,
    track_sequence,
    tracker_markdown,
    true_positions,
)

__all__ = [
    'BASELINES',
    'COLUMNS',
    'CSV_COLUMNS',
    'ESTIMATES_ONLY',
    'EXTRA_CONDITIONS',
    'LEVELS',
    'MIN_BASELINE_M',
    'MODEL_ROWS',
    'MODEL_SYSTEM',
    'NOISE_SEEDS',
    'RAMPS',
    'ROTATION_SEQUENCE',
    'TEST_SEQUENCE',
    'TRACKER_SEQUENCES',
    'PairResult',
    'choose_model',
    'compare_models',
    'compare_trackers',
    'comparison_markdown',
    'f1_score',
    'format_number',
    'is_model_row',
    'label_sequence',
    'plot_comparison',
    'slug',
    'track_sequence',
    'tracker_markdown',
    'true_positions',
    'write_comparison_csv',
]
