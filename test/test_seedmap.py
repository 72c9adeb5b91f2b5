"""Tests for initsel_ros.learn.seedmap: the seed-map accuracy table and its baselines."""

from __future__ import annotations

import math

import numpy as np

from initsel_ros.learn.seedmap import (
    ORB2_RULE,
    RULE_SYSTEMS,
    BatchOutcome,
    evaluate_sequences,
    summarize,
    summary_markdown,
)
from initsel_ros.models import default_model_path


def test_seed_map_table_on_a_wall_and_a_desk(wall_arc_sequence, near_sequence, opened_sequences):
    outcomes = evaluate_sequences(
        [wall_arc_sequence, near_sequence], default_model_path(), length=60, step=60, jobs=1
    )
    opened = [path for path, _ in opened_sequences]
    assert opened == [wall_arc_sequence, near_sequence]  # once each, batches included
    systems = {o.system for o in outcomes}
    assert systems == {'initsel', *RULE_SYSTEMS}
    ours = [o for o in outcomes if o.system == 'initsel']
    assert len(ours) == 2 and all(o.initialized for o in ours)
    wall = next(o for o in ours if o.planar)
    assert wall.method == 'H' and wall.e_t < 0.1 and wall.rotation_deg < 1.0
    assert wall.depth_error < 0.05 and wall.chosen_ok
    # the seed map published is the one of the last verification frame (208f7d6) when that
    # frame's PnP pose agrees, so it initializes where it publishes, never before the fire
    assert wall.frames_to_publish >= wall.frames_to_init > 0
    desk = next(o for o in ours if not o.planar)
    assert desk.e_t < 0.2 and math.isfinite(desk.e_t_e)
    rows = summarize(outcomes)
    assert {r.group for r in rows} == {'planar', 'non-planar'}
    text = summary_markdown(rows)
    assert '| planar | initsel | 1 | 1 | 0 |' in text
    assert all(o.group == ('planar' if o.planar else 'non-planar') for o in outcomes)


def test_summary_counts_failures_and_skips_empty_groups():
    outcomes = [
        BatchOutcome('rotation_test', False, 'initsel', 0, False),
        BatchOutcome('rotation_test', False, ORB2_RULE, 0, True, 'F', 3, 3, 0.0, 1.2, 0.5),
    ]
    rows = summarize(outcomes)
    assert [r.group for r in rows] == ['rotation/static', 'rotation/static']
    assert rows[0].initialized == 0 and rows[1].initialized == 1
    assert math.isnan(rows[0].median_e_t)


def test_initializations_without_ground_truth_are_left_out_of_the_accuracy_shares(caplog):
    # before: a batch whose reference had no pose counted as initialized with E_t NaN, so
    # "E_t < 0.1" and "chosen method best" read 0.00 beside a median E_t of '-'
    from dataclasses import replace

    good = BatchOutcome('near', False, 'initsel', 0, True, 'E', 10, 12, 0.1, 0.02, 0.1)
    good = replace(good, chosen_ok=True)
    blind = replace(good, start=30, baseline_m=math.nan, e_t=math.nan, rotation_deg=math.nan)
    blind = replace(blind, chosen_ok=False)
    [row] = summarize([good, blind])
    assert row.initialized == 2 and abs(row.median_e_t - 0.02) < 1e-12
    assert row.share_e_t_below_0_1 == 1.0 and row.chosen_ok_share == 1.0
    assert '1 of 2 initializations have no ground-truth pose' in caplog.text
    # an initialization on a pure rotation has a baseline (0) but no E_t: still a miss
    pan = replace(good, start=60, baseline_m=0.0, e_t=math.nan, chosen_ok=False)
    [row] = summarize([good, pan])
    assert row.share_e_t_below_0_1 == 0.5 and row.chosen_ok_share == 0.5


def test_seedmap_command_refuses_bad_baselines_groups_and_a_missing_orbslam3(
    near_sequence, tmp_path, capsys
):
    from initsel_ros.cli import main

    seq = str(near_sequence)
    assert main(['seedmap', seq, '--baselines', 'rules,orbslam2']) == 2
    assert 'unknown baselines' in capsys.readouterr().err
    assert main(['seedmap', seq, '--group', f'{near_sequence.name}=wall']) == 2
    assert 'planar, non-planar, rotation/static' in capsys.readouterr().err
    nowhere = str(tmp_path / 'no-venv')
    assert main(['seedmap', seq, '--baselines', 'orbslam3', '--orbslam3-venv', nowhere]) == 2
    assert 'scripts/setup_orbslam3.sh' in capsys.readouterr().err


def test_params_file_gives_the_node_settings_and_a_bad_one_is_refused(tmp_path, capsys):
    import argparse

    from initsel_ros.cli import main, options

    good = tmp_path / 'selector.yaml'
    good.write_text(
        'selector:\n  ros__parameters:\n    min_homography_parallax_deg: 0.7\n'
        '    rotation_recheck_frames: 0\n    verify_frames: 2\n'
    )
    config = options.selector_config(argparse.Namespace(params_file=good), 'seedmap')
    assert config.policy.min_homography_parallax_deg == 0.7
    assert config.rotation_recheck_frames == 0 and config.verify.frames == 2
    assert config.policy.min_parallax_deg == 1.0  # what the file does not name: defaults
    bad = tmp_path / 'bad.yaml'
    bad.write_text('selector:\n  ros__parameters:\n    min_homography_parallax_deg: .nan\n')
    for command in ('seedmap', 'planar_arc'):
        args = [command, str(tmp_path), '--params-file', str(bad), '--out-dir', str(tmp_path)]
        assert main(args) == 2
        assert 'min_homography_parallax_deg must be a finite number' in capsys.readouterr().err


def test_batches_start_on_their_first_frame_with_a_ground_truth_pose():
    # before: a batch starting before the motion capture was never judged (the real fr3)
    from initsel_ros.learn.seedmap import batch_windows

    has_pose = np.ones(100, dtype=bool)
    assert batch_windows(has_pose, 60, 30) == ([(0, 60), (30, 60), (60, 40)], 0)
    has_pose[:40] = False
    windows, moved = batch_windows(has_pose, 60, 30)
    assert windows == [(40, 50), (60, 40)] and moved == 1  # one batch, not two, at frame 40
    has_pose[30:] = True  # the first batch moves onto the second: one batch, none moved
    assert batch_windows(has_pose, 60, 30) == ([(30, 60), (60, 40)], 0)
    has_pose[:] = False  # no ground truth at all: the batches keep their starts (unjudged)
    assert batch_windows(has_pose, 60, 30) == ([(0, 60), (30, 60), (60, 40)], 0)
    has_pose[59] = True  # the last frame of the first batch: nothing to pair it with there
    windows, _ = batch_windows(has_pose, 60, 30)
    assert (59, 1) not in windows and (59, 31) in windows  # the second batch keeps it
