"""Tests for initsel_ros.policy."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from initsel_ros.geometry import Method, PoseEstimate
from initsel_ros.policy import (
    PolicyConfig,
    Reason,
    check_pose,
    check_pose_batch,
    decide,
    decide_batch,
    effective_thresholds,
)

T = {'F': 0.5, 'E': 0.5, 'H': 0.5, 'R': 0.5}


def test_too_few_tracks_wins_over_any_probability():
    d = decide({'F': 1, 'E': 1, 'H': 1, 'R': 0}, T, 10, 40.0, PolicyConfig(min_tracks=50))
    assert d.reason is Reason.TOO_FEW_TRACKS and not d.positive


def test_rotation_vetoes_the_configured_models_only():
    probs = {'F': 0.9, 'E': 0.8, 'H': 0.7, 'R': 0.9}
    d = decide(probs, T, 200, 40.0, PolicyConfig(r_veto=frozenset({'F', 'E'})))
    assert d.vetoed == ('E', 'F')
    assert d.candidates == (Method.H,)
    d = decide(probs, T, 200, 40.0, PolicyConfig(r_veto=frozenset({'F', 'E', 'H'})))
    assert d.reason is Reason.ROTATION and not d.positive


def test_candidates_are_ordered_by_margin_over_threshold():
    d = decide(
        {'F': 0.95, 'E': 0.7, 'H': 0.9, 'R': 0.1}, {**T, 'H': 0.85}, 200, 40.0, PolicyConfig()
    )
    assert d.candidates == (Method.F, Method.E, Method.H)
    assert d.reason is Reason.INITIALIZED


def test_nothing_fired_and_rotation_alone_are_distinguished():
    assert (
        decide({'F': 0.1, 'E': 0.1, 'H': 0.1, 'R': 0.1}, T, 200, 1.0, PolicyConfig()).reason
        is Reason.NO_MODEL_FIRED
    )
    assert (
        decide({'F': 0.1, 'E': 0.1, 'H': 0.1, 'R': 0.9}, T, 200, 1.0, PolicyConfig()).reason
        is Reason.ROTATION
    )


def test_threshold_overrides_replace_model_file_values():
    merged = effective_thresholds(T, PolicyConfig(thresholds={'E': 0.9}))
    assert merged == {**T, 'E': 0.9}


def _estimate(ok=True, n=100, parallax=3.0, method=Method.E, n_tracks=None):
    tracks = np.zeros(n if n_tracks is None else n_tracks, bool)
    tracks[:n] = True
    return PoseEstimate(
        method,
        ok,
        '' if ok else 'bad',
        np.eye(3),
        np.array([1.0, 0, 0]),
        np.ones((n, 3)),
        np.arange(n),
        tracks,
        parallax,
    )


def test_pose_check_reasons():
    cfg = PolicyConfig(min_points=50, min_parallax_deg=1.0)
    assert check_pose(_estimate(), cfg) is None
    assert check_pose(_estimate(ok=False), cfg) is Reason.POSE_FAILED
    assert check_pose(_estimate(n=20), cfg) is Reason.TOO_FEW_POINTS
    assert check_pose(_estimate(parallax=0.5), cfg) is Reason.LOW_PARALLAX


def test_h_has_its_own_parallax_floor_in_both_pose_checks():
    cfg = PolicyConfig(min_parallax_deg=1.0, min_homography_parallax_deg=0.5)
    assert check_pose(_estimate(parallax=0.7, method=Method.H), cfg) is None
    assert check_pose(_estimate(parallax=0.7, method=Method.E), cfg) is Reason.LOW_PARALLAX
    assert check_pose(_estimate(parallax=0.4, method=Method.H), cfg) is Reason.LOW_PARALLAX
    ok, n, parallax = np.ones(2, bool), np.array([100, 100]), np.array([0.7, 0.4])
    assert list(check_pose_batch(ok, n, parallax, cfg, 'H')) == [None, Reason.LOW_PARALLAX]
    assert list(check_pose_batch(ok, n, parallax, cfg, 'E')) == [Reason.LOW_PARALLAX] * 2


def test_h_floor_holds_only_where_the_plane_is_the_scene():
    """An H on 100 of 200 tracks leaves half the scene off its plane: E's floor binds it."""
    cfg = PolicyConfig(
        min_parallax_deg=1.0, min_homography_parallax_deg=0.5, min_homography_plane_share=0.8
    )
    plane = _estimate(parallax=0.7, method=Method.H, n_tracks=110)
    part = _estimate(parallax=0.7, method=Method.H, n_tracks=200)
    assert check_pose(plane, cfg) is None
    assert check_pose(part, cfg) is Reason.LOW_PARALLAX
    assert check_pose(replace(part, parallax_deg=1.1), cfg) is None
    ok, n, parallax = np.ones(3, bool), np.array([100, 100, 100]), np.array([0.7, 0.7, 1.1])
    got = check_pose_batch(ok, n, parallax, cfg, 'H', np.array([110, 200, 200]))
    assert list(got) == [None, Reason.LOW_PARALLAX, None]
    # A floor above E's still binds an H on part of the scene.
    high = replace(cfg, min_homography_parallax_deg=2.0)
    assert check_pose(replace(part, parallax_deg=1.5), high) is Reason.LOW_PARALLAX


def _agree(probs: dict, thresholds: dict, n_tracks: np.ndarray, config: PolicyConfig) -> None:
    batch = decide_batch(probs, thresholds, n_tracks, config)
    first = batch.first_method()
    for i in range(len(n_tracks)):
        row = {m: float(np.asarray(v)[i]) for m, v in probs.items()}
        one = decide(row, thresholds, int(n_tracks[i]), 0.0, config)
        assert batch.reason[i] is one.reason, (i, row)
        assert batch.candidates(i) == one.candidates, (i, row)
        assert first[i] == (one.candidates[0].value if one.candidates else '')
        names = ('E', 'H', 'F')
        assert tuple(m for j, m in enumerate(names) if batch.vetoed[i, j]) == one.vetoed


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(*[st.floats(0, 1)] * 4, st.integers(0, 400)), min_size=1, max_size=20),
    st.tuples(*[st.sampled_from([0.0, 0.3, 0.5, 0.5, 0.9, 1.0])] * 4),
    st.sets(st.sampled_from(['F', 'E', 'H'])),
)
def test_vectorized_policy_agrees_with_the_live_one(rows, thresholds, veto):
    probs = {m: np.array([r[j] for r in rows]) for j, m in enumerate('FEHR')}
    n_tracks = np.array([r[4] for r in rows])
    config = PolicyConfig(r_veto=frozenset(veto))
    _agree(probs, dict(zip('FEHR', thresholds, strict=True)), n_tracks, config)


def test_vectorized_policy_agrees_on_a_real_pair_table(near_pair_table):
    """Every pair of a labelled table, with the shipped models' probabilities."""
    from initsel_ros.learn.table import input_columns, read_table
    from initsel_ros.models import ModelSet, default_model_path

    table = read_table(near_pair_table)
    models = ModelSet.load(default_model_path())
    probs = models.predict_proba_batch(
        table.matrix(input_columns(models.input_names, models.scaling))
    )
    config = PolicyConfig()
    thresholds = effective_thresholds(models.thresholds, config)
    _agree(probs, thresholds, np.asarray(table['n_tracks']), config)
    # and the evaluation's rule is that policy
    from initsel_ros.learn.evaluate import decision_rule

    rule = decision_rule(
        'm', probs, thresholds, veto=tuple(config.r_veto), n_tracks=np.asarray(table['n_tracks'])
    )
    batch = decide_batch(probs, thresholds, np.asarray(table['n_tracks']), config)
    assert np.array_equal(rule.method, batch.first_method())


def test_vectorized_pose_check_agrees_with_the_live_one():
    ok = np.array([True, True, True, False, True, True])
    points = np.array([80, 20, 80, 80, 50, 80])
    parallax = np.array([2.0, 2.0, 0.5, 2.0, 1.0, np.nan])
    batch = check_pose_batch(ok, points, parallax, PolicyConfig())
    for i in range(len(ok)):
        est = _estimate(bool(ok[i]), int(points[i]), float(parallax[i]))
        assert batch[i] is check_pose(est, PolicyConfig())
