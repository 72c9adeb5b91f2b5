"""The planar-arc table (issue 20): verdicts, grouping and one rendered arc end to end."""

from __future__ import annotations

import math

from initsel_ros.learn.planar_arc import ArcOutcome, arc_markdown, evaluate_arc


def test_verdicts_follow_issue_20s_bar():
    arc = 'wall_arc_d3.5_e0.30_n2_s0'
    assert ArcOutcome(arc, False, True, 'H', 15, 0.02, 0.1, 9).verdict == 'ok'
    assert ArcOutcome(arc, False, True, 'H', 25, 0.02, 0.1, 9).verdict == 'late'
    assert ArcOutcome(arc, False, True, 'E', 15, 0.30, 0.1, 9).verdict == 'inaccurate'
    assert ArcOutcome(arc, False, True, 'H', 15, 0.05, 1.5, 9).verdict == 'inaccurate'
    assert ArcOutcome(arc, False, False, oracle_frame=9).verdict == 'not initialized'
    assert ArcOutcome(arc, False, False).verdict == 'ok'  # no oracle frame, nothing published
    assert ArcOutcome(arc, False, True, 'F', 30, 0.5, 2.0).verdict.startswith('E_t > 0.3')
    pan = 'rotation_pan_n2_s0'
    assert ArcOutcome(pan, True, False).verdict == 'ok'
    assert ArcOutcome(pan, True, True, 'H', 30, 1.2, 1.0).verdict == 'initialized on a pan'


def test_table_groups_by_kind_and_noise_and_lists_every_sequence():
    rows = [
        ArcOutcome('wall_arc_d3.5_e0.30_n2_s0', False, True, 'H', 15, 0.02, 0.1, 9),
        ArcOutcome('wall_arc_d3.5_e0.30_n2_s1', False, True, 'H', 17, 0.04, 0.2, 8),
        ArcOutcome('rotation_pan_n2_s0', True, False),
    ]
    text = arc_markdown(rows)
    assert '| wall_arc_d3.5_e0.30 | 2 | 2 | 2 | 2 | 0.030 | 0.15 | 16.0 | 8.5 | 2/2 |' in text
    assert '| rotation_pan | 2 | 1 | 0 | 0 |' in text
    assert text.count('| wall_arc_d3.5_e0.30_n2_s') == 2


def test_a_rendered_arc_has_an_oracle_frame_and_a_pan_none(tmp_path):
    from initsel_ros.models import default_model_path
    from initsel_ros.synth import render
    from initsel_ros.synth.trajectories import ArcPath

    wall = render(
        tmp_path / 'wall_arc_n1_s0',
        'wall',
        'arc',
        30,
        0,
        arc=ArcPath(distance=2.0, extent=0.3),
        workers=1,
    ).path
    out = evaluate_arc(str(wall), str(default_model_path()), _config())
    assert not out.no_baseline and math.isfinite(out.oracle_frame) and out.oracle_frame < 20
    pan = render(tmp_path / 'rotation_pan_n1_s0', 'wall', 'rotation', 20, 0, workers=1).path
    out = evaluate_arc(str(pan), str(default_model_path()), _config())
    assert out.no_baseline and math.isnan(out.oracle_frame) and out.verdict == 'ok'


def _config():
    from initsel_ros.selector import SelectorConfig

    return SelectorConfig()
