"""Tests for initsel_ros.learn.seedmap: the seed-map accuracy table and its baselines."""

from __future__ import annotations

import math

from initsel_ros.learn.seedmap import (
    BatchOutcome,
    evaluate_sequences,
    summarize,
    summary_markdown,
)
from initsel_ros.models import default_model_path


def test_seed_map_table_on_a_wall_and_a_desk(wall_arc_sequence, near_sequence):
    outcomes = evaluate_sequences(
        [wall_arc_sequence, near_sequence], default_model_path(), length=60, step=60, jobs=1
    )
    systems = {o.system for o in outcomes}
    assert systems == {'initsel', 'ORB-SLAM2', 'ORB-SLAM3', 'VINS-Mono', 'Butt 2020'}
    ours = [o for o in outcomes if o.system == 'initsel']
    assert len(ours) == 2 and all(o.initialized for o in ours)
    wall = next(o for o in ours if o.planar)
    assert wall.method == 'H' and wall.e_t < 0.1 and wall.rotation_deg < 1.0
    assert wall.depth_error < 0.05 and wall.chosen_ok
    assert wall.frames_to_publish > wall.frames_to_init  # verification delays publication
    desk = next(o for o in ours if not o.planar)
    assert desk.e_t < 0.2 and math.isfinite(desk.e_t_e)
    rows = summarize(outcomes)
    assert {r.group for r in rows} == {'planar', 'non-planar'}
    text = summary_markdown(rows)
    assert '| planar | initsel | 1 | 1 |' in text


def test_summary_counts_failures_and_skips_empty_groups():
    outcomes = [
        BatchOutcome('rotation_test', False, 'initsel', 0, False),
        BatchOutcome('rotation_test', False, 'ORB-SLAM2', 0, True, 'F', 3, 3, 0.0, 1.2, 0.5),
    ]
    rows = summarize(outcomes)
    assert [r.group for r in rows] == ['rotation/static', 'rotation/static']
    assert rows[0].initialized == 0 and rows[1].initialized == 1
    assert math.isnan(rows[0].median_e_t)
