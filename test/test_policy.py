"""Tests for initsel_ros.policy."""

from __future__ import annotations

import numpy as np

from initsel_ros.geometry import Method, PoseEstimate
from initsel_ros.policy import PolicyConfig, Reason, check_pose, decide, effective_thresholds

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
    d = decide({'F': 0.95, 'E': 0.7, 'H': 0.9, 'R': 0.1}, {**T, 'H': 0.85}, 200, 40.0,
               PolicyConfig())
    assert d.candidates == (Method.F, Method.E, Method.H)
    assert d.reason is Reason.INITIALIZED


def test_nothing_fired_and_rotation_alone_are_distinguished():
    assert decide({'F': 0.1, 'E': 0.1, 'H': 0.1, 'R': 0.1}, T, 200, 1.0,
                  PolicyConfig()).reason is Reason.NO_MODEL_FIRED
    assert decide({'F': 0.1, 'E': 0.1, 'H': 0.1, 'R': 0.9}, T, 200, 1.0,
                  PolicyConfig()).reason is Reason.ROTATION


def test_threshold_overrides_replace_model_file_values():
    merged = effective_thresholds(T, PolicyConfig(thresholds={'E': 0.9}))
    assert merged == {**T, 'E': 0.9}


def _estimate(ok=True, n=100, parallax=3.0):
    return PoseEstimate(Method.E, ok, '' if ok else 'bad', np.eye(3), np.array([1.0, 0, 0]),
                        np.ones((n, 3)), np.arange(n), np.ones(n, bool), parallax)


def test_pose_check_reasons():
    cfg = PolicyConfig(min_points=50, min_parallax_deg=1.0)
    assert check_pose(_estimate(), cfg) is None
    assert check_pose(_estimate(ok=False), cfg) is Reason.POSE_FAILED
    assert check_pose(_estimate(n=20), cfg) is Reason.TOO_FEW_POINTS
    assert check_pose(_estimate(parallax=0.5), cfg) is Reason.LOW_PARALLAX
