"""Tests for initsel_ros.initialize: the fire path as one pure function."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, two_view

from initsel_ros.geometry import Method
from initsel_ros.initialize import FireConfig, fire_methods, initialize_pair
from initsel_ros.metrics import translation_chordal_error
from initsel_ros.policy import Decision, PolicyConfig, Reason


def _pan(n: int = 200, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Correspondences of a camera turning 2 degrees on the spot (any depths)."""
    rng = np.random.default_rng(seed)
    p0 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    R = cv2.Rodrigues(np.array([0.0, np.radians(2.0), 0.0]))[0]
    rays = np.column_stack([p0, np.ones(n)]) @ np.linalg.inv(K).T
    proj = rays @ (K @ R).T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, 0.2, (n, 2))
    return p0, p1


def test_a_rotation_stops_the_path_before_any_estimate():
    p0, p1 = _pan()
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H))
    assert fire.reason is Reason.ROTATION
    assert fire.estimates == () and fire.seed is None
    assert fire.rotation_residual_px < 1.0
    assert 'rotation alone explains the flow' in fire.detail


def test_depth_gives_every_estimate_and_a_refined_seed_map_of_the_winner():
    p0, p1, _, t, _ = two_view(planar=False, seed=4)
    fire = initialize_pair(p0, p1, K, (Method.E, Method.F, Method.H))
    assert fire.reason is Reason.INITIALIZED
    assert [e.method for e in fire.estimates] == [Method.E, Method.F, Method.H]
    assert len(fire.checks) == 3 and fire.estimate('F') is fire.estimates[1]
    assert fire.selection is not None and fire.selection.winner in (Method.E, Method.F)
    seed = fire.seed
    assert seed is not None and seed.method is fire.selection.winner
    assert seed.refinement is not None and seed.n_points >= 50
    assert seed.refinement.rms_after_px <= seed.refinement.rms_before_px
    assert translation_chordal_error(t, seed.t) < 0.1
    assert fire.rotation_residual_px > 3.0
    # the seed map's indices point into the input correspondences
    assert seed.indices.max() < len(p0) and len(seed.indices) == seed.n_points


def test_each_stage_can_be_switched_off():
    p0, p1, _, _, _ = two_view(planar=True, seed=5)
    only = initialize_pair(
        p0, p1, K, ('F', 'E', 'H'), FireConfig(rotation_test=False, select=False, refine=False)
    )
    assert only.selection is None and only.seed is None
    assert np.isnan(only.rotation_residual_px)
    assert only.reason is Reason.INITIALIZED  # at least one estimate passed the pose check
    plain = initialize_pair(p0, p1, K, ('H',), FireConfig(refine=False))
    assert plain.seed is not None and plain.seed.refinement is None
    np.testing.assert_array_equal(plain.seed.points, plain.estimate('H').points)


def test_no_candidate_passing_reports_the_first_failing_reason():
    p0, p1, _, _, _ = two_view(planar=False, seed=6)
    strict = FireConfig(policy=PolicyConfig(min_points=10_000))
    fire = initialize_pair(p0, p1, K, ('E', 'H'), strict)
    assert fire.reason is Reason.TOO_FEW_POINTS and fire.seed is None
    assert fire.selection is not None and fire.selection.winner is None
    assert 'failed' in fire.detail


@pytest.mark.parametrize(
    ('veto', 'p_r', 'expected'),
    [
        (frozenset({'F', 'E'}), 0.9, (Method.E, Method.H)),  # R fired, H not vetoed
        (frozenset({'F', 'E', 'H'}), 0.9, (Method.E,)),  # R fired and vetoes H
        (frozenset({'F', 'E', 'H'}), 0.1, (Method.E, Method.H)),  # R did not fire
    ],
)
def test_fire_methods_add_h_unless_r_vetoes_it(veto, p_r, expected):
    decision = Decision(Reason.INITIALIZED, {'E': 0.9, 'R': p_r}, candidates=(Method.E,))
    assert fire_methods(decision, {'R': 0.5}, PolicyConfig(r_veto=veto)) == expected
