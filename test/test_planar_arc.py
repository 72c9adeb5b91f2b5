"""The planar-arc table (issue 20): verdicts, grouping and one rendered arc end to end, with
the real ORB-SLAM3's column (its process replaced by a stand-in here)."""

from __future__ import annotations

import json
import math
import stat
import sys

import numpy as np

from initsel_ros.learn.planar_arc import ArcOutcome, arc_markdown, evaluate_arc
from initsel_ros.learn.real_baselines.orbslam3_runner import Orbslam3Setup
from initsel_ros.learn.seedmap import ORBSLAM3_REAL


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
    [out] = evaluate_arc(str(wall), str(default_model_path()), _config())
    assert not out.no_baseline and math.isfinite(out.oracle_frame) and out.oracle_frame < 20
    assert out.system == 'initsel'
    pan = render(tmp_path / 'rotation_pan_n1_s0', 'wall', 'rotation', 20, 0, workers=1).path
    [out] = evaluate_arc(str(pan), str(default_model_path()), _config())
    assert out.no_baseline and math.isnan(out.oracle_frame) and out.verdict == 'ok'

    # ORB-SLAM3's row, from a stand-in for its process that initializes at frame 12 with the
    # ground-truth keyframes (and one that crashes): judged by the same bar, oracle included
    from initsel_ros.datasets import open_sequence

    sequence = open_sequence(wall)
    stand_in = _orbslam3_stand_in(tmp_path / 'venv', sequence, 0, 12)
    selector, orb = evaluate_arc(str(wall), str(default_model_path()), _config(), stand_in)
    assert (orb.system, orb.initialized, orb.failed, orb.frame) == (ORBSLAM3_REAL, True, False, 12)
    assert orb.e_t < 1e-6 and orb.rotation_deg < 1e-4 and orb.oracle_frame == selector.oracle_frame
    assert orb.verdict == ('ok' if orb.frame <= orb.oracle_frame + 10 else 'late')
    crash = Orbslam3Setup(sys.executable, 'none', 60.0)  # no orbslam3 in this interpreter
    _, failed = evaluate_arc(str(wall), str(default_model_path()), _config(), crash)
    assert failed.failed and not failed.initialized and failed.verdict == 'failed'
    text = arc_markdown([selector, orb, failed])
    assert '| wall_arc | 1 | ORB-SLAM3 (real) | 2 (1 failed) | 2 | 1 |' in text
    assert f'| wall_arc_n1_s0 | ORB-SLAM3 (real) | H/F | 12 | {orb.e_t:.3f} |' in text
    assert (
        '| wall_arc_n1_s0 | ORB-SLAM3 (real) | - | - | - | - |' in text
        and 'failed: exit 1' in text
    )


def _orbslam3_stand_in(folder, sequence, reference: int, current: int) -> Orbslam3Setup:
    """An executable in ORB-SLAM3's interpreter's place that writes what its worker writes:
    an initialization at ``current`` from ``reference``, at the ground-truth poses, with
    points 3 m in front of the reference camera."""
    poses = sequence.poses()
    stamps = sequence.stamps_ns / 1e9
    ref = np.asarray(poses[reference], dtype=np.float64)
    rays = np.array([[x, y, 1.0] for x in (-0.4, 0.0, 0.4) for y in (-0.3, 0.3)]) * 3.0
    points = rays @ ref[:3, :3].T + ref[:3, 3]
    result = {
        'initialized': True,
        'keyframes': [
            [float(stamps[reference]), ref.ravel().tolist()],
            [float(stamps[current]), np.asarray(poses[current]).ravel().tolist()],
        ],
        'points': points.tolist(),
    }
    folder.mkdir(parents=True, exist_ok=True)
    script = folder / 'python'
    script.write_text(
        f'#!{sys.executable}\nimport sys\nopen(sys.argv[-1], "w").write({json.dumps(result)!r})\n'
    )
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    return Orbslam3Setup(str(script), 'none', 60.0)


def _config():
    from initsel_ros.selector import SelectorConfig

    return SelectorConfig()


def test_planar_arc_with_orbslam3_and_no_venv_is_a_clear_error(tmp_path, capsys):
    from initsel_ros.cli import main

    code = main(
        [
            'planar_arc',
            str(tmp_path / 'rotation_pan_n0_s0'),
            '--out-dir',
            str(tmp_path / 'out'),
            '--orbslam3',
            '--orbslam3-venv',
            str(tmp_path / 'no-venv'),
        ]
    )
    assert code == 2
    assert 'setup_orbslam3.sh' in capsys.readouterr().err
    assert not (tmp_path / 'out' / 'planar_arc.md').exists()
