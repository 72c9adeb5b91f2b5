"""Tests for the real-system baselines: COLMAP's two-view geometry, the real ORB-SLAM3 run in
its own venv, and the substitute DBoW2 vocabulary ORB-SLAM3 loads."""

from __future__ import annotations

import math
import re
import stat
import sys
from pathlib import Path

import numpy as np
import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.learn.real_baselines.orbslam3_runner import (
    Orbslam3Setup,
    find_orbslam3,
    parse_result,
    run_orbslam3,
    settings_yaml,
)
from initsel_ros.learn.real_baselines.vocabulary import Vocabulary, train_vocabulary
from initsel_ros.learn.seedmap import (
    COLMAP_REAL,
    ORBSLAM3_REAL,
    RULE_SYSTEMS,
    BaselineOptions,
    add_sensor_noise,
    default_group,
    evaluate_sequences,
    summarize,
    summary_markdown,
)
from initsel_ros.models import default_model_path

INTRINSICS = Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480)


def _project(points: np.ndarray) -> np.ndarray:
    p = points @ INTRINSICS.K.T
    return p[:, :2] / p[:, 2:]


def _rot_y(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _scene(planar: bool, t: np.ndarray, deg: float = 2.0, n: int = 200):
    rng = np.random.default_rng(3)
    X = rng.uniform([-1.5, -1.0, 3.0], [1.5, 1.0, 6.0], (n, 3))
    if planar:
        X[:, 2] = 4.0
    R = _rot_y(deg)
    return _project(X), _project(X @ R.T + t), R, t / max(np.linalg.norm(t), 1e-12)


# ------------------------------------------------------------------------------------- COLMAP
def _pycolmap() -> None:
    pytest.importorskip('pycolmap', reason='pycolmap is in the test extra: pip install -e .[test]')


def test_colmap_fires_calibrated_with_the_true_pose_on_a_3d_scene():
    _pycolmap()
    from initsel_ros.learn.real_baselines.colmap import colmap_attempt, two_view_geometry

    p0, p1, R, t = _scene(planar=False, t=np.array([0.3, 0.0, 0.05]))
    pair = two_view_geometry(p0, p1, INTRINSICS)
    assert pair.config == 'CALIBRATED' and pair.fires and pair.n_inliers == len(p0)
    assert np.allclose(pair.R, R, atol=1e-6) and np.allclose(pair.t, t, atol=1e-6)
    config, _, _, points, pixels = colmap_attempt(p0, p1, INTRINSICS)
    assert config == 'CALIBRATED' and len(points) == len(p0) and pixels.shape == (len(p0), 2)


def test_colmap_classifies_a_plane_as_planar_and_a_pan_never_fires():
    _pycolmap()
    from initsel_ros.learn.real_baselines.colmap import two_view_geometry

    p0, p1, _, _ = _scene(planar=True, t=np.array([0.3, 0.0, 0.05]))
    assert two_view_geometry(p0, p1, INTRINSICS).config == 'PLANAR'
    p0, p1, _, _ = _scene(planar=False, t=np.zeros(3), deg=3.0)
    pan = two_view_geometry(p0, p1, INTRINSICS)
    assert not pan.fires  # no triangulation angle without a baseline
    few = two_view_geometry(p0[:5], p1[:5], INTRINSICS)
    assert few.config == 'DEGENERATE' and not few.fires


def test_seedmap_runs_colmap_beside_initsel_with_explicit_groups_and_noise(
    wall_arc_sequence, rotation_sequence
):
    _pycolmap()
    options = BaselineOptions(('colmap',), sensor_noise=2.0, noise_seed=1)
    groups = {wall_arc_sequence.name: 'planar', str(rotation_sequence): 'rotation/static'}
    outcomes = evaluate_sequences(
        [wall_arc_sequence, rotation_sequence],
        default_model_path(),
        length=60,
        step=60,
        jobs=1,
        baselines=options,
        groups=groups,
        noise_seeds=[1, 2],
    )
    assert {o.system for o in outcomes} == {'initsel', COLMAP_REAL}
    assert len(outcomes) == 2 * 2 * 2  # 2 sequences x 2 noise seeds x 2 systems
    assert {o.noise_seed for o in outcomes} == {1, 2}
    wall = [
        o for o in outcomes if o.system == COLMAP_REAL and o.sequence == wall_arc_sequence.name
    ]
    assert all(o.initialized and o.method in ('CALIBRATED', 'PLANAR') for o in wall)
    assert all(o.group == 'planar' and o.n_points >= 50 for o in wall)
    assert all(math.isfinite(o.e_t) and math.isfinite(o.depth_error) for o in wall)
    pan = [o for o in outcomes if o.system == COLMAP_REAL and o.group == 'rotation/static']
    assert pan and not any(o.initialized for o in pan)
    text = summary_markdown(summarize(outcomes))
    assert '| planar | COLMAP (real) | 2 | 2 | 0 |' in text


def test_explicit_groups_override_the_name_rule_and_bad_groups_are_refused(near_sequence):
    assert default_group('wall_arc_test') == 'planar'
    assert default_group('my_static_rig') == 'rotation/static'
    assert default_group('desk') == 'non-planar'
    with pytest.raises(ValueError, match='unknown groups'):
        evaluate_sequences(
            [near_sequence], default_model_path(), groups={near_sequence.name: 'wall'}
        )
    with pytest.raises(ValueError, match='unknown baselines'):
        BaselineOptions(('orbslam2',))
    with pytest.raises(ValueError, match='needs its setup'):
        BaselineOptions(('orbslam3',))


def test_sensor_noise_is_seeded_per_batch_and_sequence():
    frames = [np.full((8, 8), 100, np.uint8), np.full((8, 8, 3), 250, np.uint8)]
    a = add_sensor_noise(frames, 2.0, (1, 0, 'desk'))
    again = add_sensor_noise(frames, 2.0, (1, 0, 'desk'))
    assert all(np.array_equal(x, y) for x, y in zip(a, again, strict=True))
    b = add_sensor_noise(frames, 2.0, (2, 0, 'desk'))
    assert not np.array_equal(a[0], b[0])
    assert not np.array_equal(a[0], add_sensor_noise(frames, 2.0, (1, 30, 'desk'))[0])
    assert 1.0 < float(np.std(a[0].astype(float))) < 3.0 and a[1].max() <= 255
    with pytest.raises(ValueError, match='8-bit'):
        add_sensor_noise([np.zeros((4, 4), np.uint16)], 2.0, (0, 0, 'x'))


def test_rule_rows_are_named_as_reimplementations():
    assert all(name.endswith('rule (re-implemented)') for name in RULE_SYSTEMS)


# ------------------------------------------------------------------------------------ ORB-SLAM3
def test_settings_write_every_real_as_a_real():
    text = settings_yaml(Intrinsics(500, 500, 320, 240, 640, 480, (0.1, 0, 0, 0, 0)), fps=30.0)
    values = dict(line.split(': ', 1) for line in text.splitlines()[1:])
    integers = {
        'Camera.width',
        'Camera.height',
        'Camera.fps',
        'Camera.RGB',
        'ORBextractor.nFeatures',
        'ORBextractor.nLevels',
        'ORBextractor.iniThFAST',
        'ORBextractor.minThFAST',
    }
    for key, value in values.items():
        if key in integers:
            assert re.fullmatch(r'\d+', value), (key, value)
        elif not value.startswith('"'):
            assert re.fullmatch(r'-?\d+\.\d+(e-?\d+)?', value), (key, value)
    assert values['Camera1.fx'] == '500.0' and values['Camera1.k2'] == '0.0'
    assert values['Camera1.k1'] == '0.1' and 'Camera1.k3' not in values
    assert values['Camera.type'] == '"PinHole"' and values['Camera1.p1'] == '0.0'


def test_settings_say_which_coefficients_orbslam3_cannot_take(caplog):
    coefficients = (0.1, 0.0, 0.0, 0.0, 0.01, 0.2, 0.0, 0.0)
    rational = Intrinsics(500, 500, 320, 240, 640, 480, coefficients)
    values = dict(line.split(': ', 1) for line in settings_yaml(rational, 30.0).splitlines()[1:])
    assert values['Camera1.k3'] == '0.01'
    assert "ORB-SLAM3's PinHole model takes k1 k2 p1 p2 k3" in caplog.text
    assert '[0.2, 0.0, 0.0]' in caplog.text


def test_settings_give_orbslam3_a_fisheye_as_kannala_brandt():
    fisheye = Intrinsics(380, 380, 320, 240, 640, 480, (0.05, -0.01, 0.004, -0.001), True)
    values = dict(line.split(': ', 1) for line in settings_yaml(fisheye, 30.0).splitlines()[1:])
    assert values['Camera.type'] == '"KannalaBrandt8"'
    ks = [float(values[f'Camera1.k{i}']) for i in (1, 2, 3, 4)]
    assert ks == [0.05, -0.01, 0.004, -0.001] and 'Camera1.p1' not in values


def test_parse_result_gives_the_keyframes_relative_pose_and_reference_frame_points():
    R_wc = _rot_y(10.0)
    T_ref = np.eye(4)
    T_ref[:3, :3], T_ref[:3, 3] = R_wc, [1.0, 0.0, 0.0]
    T_cur = T_ref.copy()
    T_cur[:3, 3] += R_wc @ np.array([0.1, 0.0, 0.0])  # moved 0.1 along its own x
    stamps = np.array([0.0, 0.033, 0.066, 0.1])
    point_ref = np.array([0.0, 0.0, 2.0])
    result = {
        'initialized': True,
        'frame': 3,
        'keyframes': [[0.0331, T_ref.ravel().tolist()], [0.1, T_cur.ravel().tolist()]],
        'points': [(R_wc @ point_ref + T_ref[:3, 3]).tolist()],
    }
    init = parse_result(result, stamps)
    assert (init.status, init.reference, init.current) == ('initialized', 1, 3)
    R, t = init.pose
    assert np.allclose(R, np.eye(3)) and np.allclose(t, [-0.1, 0.0, 0.0])
    assert np.allclose(init.points, [point_ref])
    assert parse_result({'initialized': False}, stamps).status == 'not initialized'
    assert parse_result({'initialized': True, 'keyframes': []}, stamps).status == 'failed'


def test_a_crash_or_a_timeout_of_the_orbslam3_process_is_a_failure(tmp_path):
    gray = [np.zeros((48, 64), np.uint8)] * 3
    stamps = np.arange(3) * 33_000_000
    # this interpreter has no orbslam3: the worker crashes on its import
    crash = run_orbslam3(gray, stamps, INTRINSICS, Orbslam3Setup(sys.executable, 'none', 60.0))
    assert crash.status == 'failed' and 'exit 1' in crash.detail
    sleeper = tmp_path / 'python'
    sleeper.write_text('#!/bin/sh\nsleep 30\n')
    sleeper.chmod(sleeper.stat().st_mode | stat.S_IEXEC)
    slow = run_orbslam3(gray, stamps, INTRINSICS, Orbslam3Setup(str(sleeper), 'none', 0.5))
    assert slow.status == 'failed' and 'timed out' in slow.detail


def test_a_missing_venv_or_vocabulary_is_a_clear_error(tmp_path):
    with pytest.raises(ConfigError, match=r'setup_orbslam3\.sh'):
        find_orbslam3(tmp_path / 'nowhere')
    (tmp_path / 'venv' / 'bin').mkdir(parents=True)
    (tmp_path / 'venv' / 'bin' / 'python').symlink_to(sys.executable)
    with pytest.raises(ConfigError, match='vocabulary'):
        find_orbslam3(tmp_path / 'venv')
    (tmp_path / 'voc.txt').write_text('10 3 0 0')
    with pytest.raises(ConfigError, match='cannot import orbslam3'):
        find_orbslam3(tmp_path / 'venv', tmp_path / 'voc.txt')


def _orbslam3_or_skip() -> Orbslam3Setup:
    try:
        return find_orbslam3(timeout_s=240.0)
    except ConfigError as exc:
        pytest.skip(f'the ORB-SLAM3 venv is not set up here (scripts/setup_orbslam3.sh): {exc}')


def test_real_orbslam3_initializes_on_the_desk_and_is_judged(near_sequence, rotation_sequence):
    setup = _orbslam3_or_skip()
    outcomes = evaluate_sequences(
        [near_sequence, rotation_sequence],
        default_model_path(),
        length=60,
        step=60,
        jobs=1,
        baselines=BaselineOptions(('orbslam3',), setup),
    )
    real = {o.sequence: o for o in outcomes if o.system == ORBSLAM3_REAL}
    desk = real[near_sequence.name]
    assert desk.initialized and not desk.failed
    assert desk.e_t < 0.3 and desk.rotation_deg < 1.0 and desk.depth_error < 0.2
    assert desk.n_points >= 50 and desk.frames_to_init >= 1 + desk.reference_offset
    assert not real[rotation_sequence.name].failed


# ----------------------------------------------------------------------------------- vocabulary
def test_vocabulary_round_trips_in_the_dbow2_text_format(tmp_path):
    rng = np.random.default_rng(0)
    frames = [cv2_blur(rng.integers(0, 255, (240, 320), dtype=np.uint8)) for _ in range(3)]
    vocabulary = train_vocabulary(frames, k=4, levels=2)
    assert 4 < vocabulary.n_words <= 16
    path = tmp_path / 'voc.txt'
    vocabulary.save(path)
    text = path.read_text()
    lines = text.split('\n')
    assert lines[0] == '4 2 0 0' and not text.endswith('\n')
    assert all(len(line.split()) == 35 for line in lines[1:])
    loaded = Vocabulary.load(path)
    assert np.array_equal(loaded.parent, vocabulary.parent)
    assert np.array_equal(loaded.descriptor, vocabulary.descriptor)
    assert np.allclose(loaded.weight, vocabulary.weight, atol=1e-6)
    words = loaded.word_of(loaded.descriptor[loaded.leaf])
    assert np.array_equal(words, np.flatnonzero(loaded.leaf))  # a word's centre falls in it
    assert np.all(loaded.weight[loaded.leaf] >= 0) and np.all(loaded.weight[~loaded.leaf] == 0)
    with pytest.raises(ValueError, match='DBoW2 reads'):
        train_vocabulary(frames, k=1)
    bad = tmp_path / 'bad.txt'
    bad.write_text('not a vocabulary')
    with pytest.raises(ValueError, match='not a DBoW2'):
        Vocabulary.load(bad)


def cv2_blur(image: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.GaussianBlur(image, (5, 5), 1.5)


def test_orbvocab_command_writes_a_vocabulary(near_sequence, tmp_path):
    from initsel_ros.cli import main

    out = tmp_path / 'v.txt'
    assert main(['orbvocab', str(near_sequence), '--out', str(out), '--every', '20']) == 0
    assert Vocabulary.load(out).n_words > 10
    assert Path(out).read_text().startswith('10 3 0 0\n')
