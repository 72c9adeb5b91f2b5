"""Tests for initsel_ros.initialize: the fire path as one pure function."""

from __future__ import annotations

import re
from dataclasses import replace

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, least_quantile_rotation_px, pan, two_view

from initsel_ros import geometry
from initsel_ros.geometry import Method, estimate_pose
from initsel_ros.initialize import (
    BACKGROUND_MIN_TRACKS,
    FireConfig,
    fire_methods,
    initialize_pair,
    off_plane_support,
)
from initsel_ros.metrics import translation_chordal_error
from initsel_ros.policy import Decision, PolicyConfig, Reason


def test_a_rotation_stops_the_path_before_any_estimate():
    p0, p1 = pan()
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


def _arc_on_a_wall(
    baseline: float = 0.2, distance: float = 3.5, noise_px: float = 0.2, n: int = 300
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A wall ``distance`` m ahead, seen 30 degrees from its normal (a phone held up and
    looking down at it), the camera slid sideways by ``baseline`` and turned back toward the
    wall's centre (issue 20's sideways arc). Returns p0, p1 and the unit translation."""
    rng = np.random.default_rng(11)
    p0 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    rays = np.column_stack([p0, np.ones(n)]) @ np.linalg.inv(K).T
    normal = np.array([0.0, np.sin(np.radians(30.0)), -np.cos(np.radians(30.0))])
    X = rays * (-distance / (rays @ normal))[:, None]
    centre = np.array([baseline, 0.0, 0.0])  # camera centre in the reference frame
    R = cv2.Rodrigues(np.array([0.0, -np.arctan2(baseline, distance), 0.0]))[0]
    t = -R @ centre
    proj = (X @ R.T + t) @ K.T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, (n, 2))
    return p0 + rng.normal(0, noise_px, (n, 2)), p1, t / np.linalg.norm(t)


def test_a_plane_from_a_sideways_arc_is_parallax_against_the_noise_and_initializes_with_h():
    p0, p1, t = _arc_on_a_wall()
    # The old fixed guard is wrong here: the arc's perspective change is under 3 px ...
    assert least_quantile_rotation_px(p0, p1, K) < 3.0
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H))
    # ... but several times the tracking noise, measured on the same tracks.
    assert fire.rotation is not None
    assert fire.rotation.noise_px == pytest.approx(0.2, rel=0.5)
    assert fire.rotation.statistic > 1.5 * PolicyConfig().min_rotation_residual_sigma
    assert fire.reason is Reason.INITIALIZED
    assert fire.seed is not None and fire.seed.method is Method.H
    assert translation_chordal_error(t, fire.seed.t) < 0.1


def test_a_noisy_miscalibrated_pan_is_a_rotation_at_the_noise_level():
    # 2 px of tracking noise and a focal length 10 % off: a rotation leaves more than 3 px
    # under the nominal K (the old fixed guard would let it through to the estimators) ...
    rng = np.random.default_rng(5)
    n = 300
    K_true = K.copy()
    K_true[:2, :2] *= 1.1
    p0 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    R = cv2.Rodrigues(np.array([0.02, np.radians(8.0), 0.0]))[0]
    proj = (np.column_stack([p0, np.ones(n)]) @ np.linalg.inv(K_true).T) @ (K_true @ R).T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, 2.0, (n, 2))
    p0 = p0 + rng.normal(0, 2.0, (n, 2))
    assert least_quantile_rotation_px(p0, p1, K) >= 3.0
    fire = initialize_pair(p0, p1, K, (Method.E, Method.F, Method.H))
    # ... yet it is the noise level once the focal scale is free and the noise measured.
    assert fire.reason is Reason.ROTATION and fire.seed is None
    assert fire.rotation is not None and fire.rotation.statistic < 1.5
    assert fire.rotation.noise_px == pytest.approx(2.0, rel=0.3)
    assert 'x the noise' in fire.detail


def test_a_pan_through_a_lens_whose_distortion_was_left_out_is_a_rotation_unless_it_was_stated():
    from model_fixtures import constant_models
    from test_geometry import _through_a_lens

    from initsel_ros.camera import Intrinsics
    from initsel_ros.selector import Selector

    wide = np.array([[420.0, 0.0, 319.5], [0.0, 420.0, 239.5], [0.0, 0.0, 1.0]])
    rng = np.random.default_rng(4)
    X = np.column_stack([rng.uniform(-0.6, 0.6, (300, 2)), np.ones(300)])
    X *= rng.uniform(1.0, 4.0, (300, 1))
    p0, p1 = _through_a_lens(X, (0.01, 0.12, 0.0), (0.0, 0.0, 0.0), wide, 0.2)
    methods = (Method.E, Method.F, Method.H)
    # the fire path tries radial terms by default: a rotation, said with its term
    fire = initialize_pair(p0, p1, wide, methods)
    assert fire.reason is Reason.ROTATION and fire.rotation.radial_term < 0
    # without them (a camera that states its distortion: its pixels arrive undistorted) the
    # bending is parallax, and an estimate goes ahead on a zero baseline
    bare = initialize_pair(p0, p1, wide, methods, FireConfig(radial_terms=()))
    assert bare.reason is not Reason.ROTATION and bare.estimates
    # the selector passes them exactly when its camera states no distortion
    camera = Intrinsics(420.0, 420.0, 319.5, 239.5, 640, 480)
    plain = Selector(constant_models(), camera)
    stated = Selector(constant_models(), replace(camera, distortion=(-0.25, 0.05, 0.0, 0.0)))
    assert plain._fire_config().radial_terms and not stated._fire_config().radial_terms


def test_close_homography_decompositions_are_both_kept_and_a_later_view_tells_them_apart():
    from geometry_fixtures import TOWARD_A_WALL_TURN, toward_a_wall, view_of

    from initsel_ros.verify import VerifyConfig, check_frame

    baseline = 0.1
    p0, p1, _, t, X = toward_a_wall(baseline)
    # Moving toward a wall, both decompositions keep the whole wall in front of both cameras;
    # the mirrored one has fewer points with parallax, which a laxer pose check keeps.
    # (the rotation test, and the directions' uncertainty, are not what this is about)
    policy = PolicyConfig(
        min_points=30, min_homography_parallax_deg=0.2, max_translation_sigma_deg=0.0
    )
    config = FireConfig(policy=policy, rotation_test=False)
    fire = initialize_pair(p0, p1, K, (Method.H,), config)
    assert fire.reason is Reason.INITIALIZED and fire.seed is not None
    assert 'the next frames choose' in fire.detail
    assert len(fire.alternatives) == 1
    seeds = (fire.seed, *fire.alternatives)
    errors = [translation_chordal_error(t, s.t) for s in seeds]
    assert min(errors) < 0.1 and max(errors) > 0.5  # one is the mirrored plane
    # The camera goes on, twice as far, bending right and down.
    bend = np.array([0.6, 0.3, 1.0]) / np.linalg.norm([0.6, 0.3, 1.0])
    p2 = view_of(X * baseline, 2 * TOWARD_A_WALL_TURN, 2 * baseline * bend)
    p2 = p2 + np.random.default_rng(2).normal(0, 0.3, p2.shape)
    steps = [
        check_frame(s.points, p2[s.indices], np.ones(s.n_points, bool), K, VerifyConfig())
        for s in seeds
    ]
    # Both maps may hold on a plane (PnP on a plane has the same two-fold ambiguity), but
    # the right one reprojects better and keeps more inliers (the selector lets the rival
    # replace its first choice only when it reprojects clearly better).
    right = int(np.argmin(errors))
    assert steps[right].ok
    assert int(np.argmin([st.rms_px for st in steps])) == right
    assert steps[right].fraction > steps[1 - right].fraction


def test_an_ambiguous_h_waits_while_its_runner_up_has_no_seed_map_to_follow(monkeypatch):
    # The pair of the test above: both decompositions pass the pose check and go on to the
    # verification together. When the runner-up's seed map is not usable yet (here: made
    # so), the winner alone would pass the verification whichever it is: the pair waits.
    from geometry_fixtures import toward_a_wall

    import initsel_ros.initialize as fire_path

    p0, p1, *_ = toward_a_wall(0.1)
    policy = PolicyConfig(
        min_points=30, min_homography_parallax_deg=0.2, max_translation_sigma_deg=0.0
    )
    config = FireConfig(policy=policy, rotation_test=False)
    both = initialize_pair(p0, p1, K, (Method.H,), config)
    assert both.reason is Reason.INITIALIZED and len(both.alternatives) == 1
    monkeypatch.setattr(fire_path, 'usable_seed', lambda *args, **kwargs: None)
    waits = initialize_pair(p0, p1, K, (Method.H,), config)
    assert waits.reason is Reason.LOW_PARALLAX and not waits.alternatives, waits.detail
    assert 'its two decompositions are close, and the runner-up has no usable seed' in (
        waits.detail
    )


def test_a_pan_is_a_rotation_when_boards_moving_on_their_own_hold_more_than_half_the_tracks():
    # Textured boards attract many corners: here 55 % of the tracks move with them.
    p0, p1 = pan(n=300)
    board = np.arange(300) < 165
    rng = np.random.default_rng(8)
    p1[board] = p0[board] + np.array([9.0, -4.0]) + 0.02 * (p0[board] - 320) @ [[0, 1], [-1, 0]]
    p1[board] += rng.normal(0, 0.2, (board.sum(), 2))
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H))
    assert fire.reason is Reason.ROTATION
    assert fire.rotation is not None and fire.rotation.statistic < 1.5


def _board_in_front_of(p0: np.ndarray, background: np.ndarray, share: float, seed: int):
    """Tracks of a planar board, moving on its own, that holds ``share`` of them: the first
    ``share`` of the rows move by the board's homography (it slides and turns toward the
    camera), the others as ``background`` says (the camera's own motion)."""
    rng = np.random.default_rng(seed)
    n = len(p0)
    board = np.arange(n) < int(share * n)
    # the board: 1.2 m away, tilted, brought 15 cm closer while it turns 8 degrees (a plane,
    # so a homography, and one no rotation of the camera explains)
    R = cv2.Rodrigues(np.radians(8.0) * np.array([0.6, 0.8, 0.0]))[0]
    t, depth = np.array([0.1, 0.05, -0.15]), 1.2
    normal = np.array([0.0, np.sin(np.radians(20.0)), np.cos(np.radians(20.0))])
    H = K @ (R + np.outer(t, normal) / depth) @ np.linalg.inv(K)
    q = np.column_stack([p0[board], np.ones(board.sum())]) @ H.T
    p1 = background.copy()
    p1[board] = q[:, :2] / q[:, 2:3] + rng.normal(0, 0.2, (board.sum(), 2))
    return p1, board


def _board_scene(camera: str, n: int, share: float, seed: int):
    """``n`` tracks of a still or panning camera (noise 0.2 px), ``share`` of them on a board
    moving on its own (:func:`_board_in_front_of`, seeded ``seed + 1``): p0, p1, board."""
    rng = np.random.default_rng(seed)
    p0 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    if camera == 'still':
        background = p0 + rng.normal(0, 0.2, (n, 2))
    else:
        p0, background = pan(n=n, seed=seed)
    p1, board = _board_in_front_of(p0, background, share, seed=seed + 1)
    return p0, p1, board


@pytest.mark.parametrize('camera', ['still', 'panning'])
def test_a_board_moving_on_its_own_with_most_of_the_tracks_is_no_baseline(camera):
    # A person holds a textured board in front of a still or panning camera, and its corners
    # are 70 % of the tracks: the first rotation test's least-quantile fit follows the board,
    # a winner fits the board's motion, and only the tracks it leaves out tell the camera
    # did not move.
    p0, p1, _ = _board_scene(camera, 300, 0.7, seed=21)
    without = initialize_pair(p0, p1, K, (Method.E, Method.H), FireConfig(refine=False))
    assert without.rotation is not None and without.rotation.statistic > 3.0
    assert without.selection is not None and without.selection.winner is not None
    assert without.reason is Reason.ROTATION, without.detail
    assert without.background is not None and without.background.statistic < 3.0
    assert 'moving on its own' in without.detail and without.seed is None


@pytest.mark.parametrize('camera', ['still', 'panning'])
def test_two_boards_moving_their_own_ways_with_three_fifths_of_the_tracks_are_no_baseline(camera):
    # Two boards, each with 31 % of the tracks, move differently in front of a still or
    # panning camera (the planar-arc tuning set's still camera at 2 grey levels: its boards
    # held 62 %). A winner can fit one board and the background as one rigid scene, leaving
    # the other board out, whose motion no rotation explains: only the rotation test can tell,
    # and a rotation must explain a third of the tracks for it to (40 % let F publish there).
    p0, p1, first = _board_scene(camera, 300, 0.31, seed=41)
    rest = ~first
    second = rest & (np.cumsum(rest) <= int(0.31 * 300))
    # the second board, facing the camera, slides down-left and turns about the view axis
    turn = (p0[second] - [320.0, 240.0]) @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    p1[second] = p0[second] + [-12.0, 6.0] + 0.03 * turn
    p1[second] += np.random.default_rng(43).normal(0, 0.2, (second.sum(), 2))
    assert first.sum() + second.sum() == 186  # 62 % of 300
    fire = initialize_pair(p0, p1, K, (Method.E, Method.F, Method.H), FireConfig(refine=False))
    assert fire.reason is Reason.ROTATION, fire.detail
    assert fire.rotation is not None and fire.rotation.statistic < 2.0 and fire.seed is None


@pytest.mark.parametrize('camera', ['still', 'panning'])
def test_a_board_with_most_of_few_tracks_is_no_baseline_either(camera):
    # Late in a pan the background has lost most of its tracks: 75 are left, 57 on the board
    # and 18 on the background, which a rotation explains to within the noise.
    p0, p1, board = _board_scene(camera, 75, 0.76, seed=31)
    assert (~board).sum() == 18
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H), FireConfig(refine=False))
    assert fire.reason is Reason.ROTATION, fire.detail
    assert fire.background is not None and fire.background.statistic < 3.0
    assert 'moving on its own' in fire.detail and fire.seed is None


def test_the_background_test_passes_a_wall_and_objects_with_parallax():
    # A translating camera before a wall (70 % of the tracks) and objects 1-4 m away, and the
    # models fired H alone: H fits the wall and leaves the objects out, whose parallax no
    # rotation explains, so the test lets the pair through.
    wall = two_view(planar=True, seed=4)
    objects = two_view(planar=False, seed=5)
    p0 = np.vstack((wall[0][:175], objects[0][:75]))
    p1 = np.vstack((wall[1][:175], objects[1][:75]))
    fire = initialize_pair(p0, p1, K, (Method.H,))
    assert fire.reason is Reason.INITIALIZED, fire.detail
    assert fire.background is not None  # it ran: H left the objects out
    assert fire.background.statistic > 2 * PolicyConfig().min_rotation_residual_sigma
    off = initialize_pair(p0, p1, K, (Method.H,), FireConfig(background_test=False))
    assert off.background is None and off.reason is Reason.INITIALIZED


def _poster_over_a_table(baseline: float, seed: int = 7, noise_px: float = 0.1):
    """A poster 0.6 m away (170 tracks, the upper image) over a table 0.8 m below the camera
    (130 tracks, 2-8 m away), the camera slid ``baseline`` m sideways and turned back toward
    the poster: p0, p1 and the unit translation."""
    rng = np.random.default_rng(seed)
    p0 = np.vstack(
        (rng.uniform([40, 20], [600, 260], (170, 2)), rng.uniform([40, 300], [600, 460], (130, 2)))
    )
    rays = np.c_[p0, np.ones(len(p0))] @ np.linalg.inv(K).T
    normal = np.array([0.0, -np.sin(np.radians(25)), np.cos(np.radians(25))])
    depth = np.concatenate((0.6 / (rays[:170] @ normal), 0.8 / rays[170:, 1]))
    R = cv2.Rodrigues(np.array([0.0, -np.arctan2(baseline, 1.1), 0.0]))[0]
    t = -R @ np.array([baseline, 0.0, 0.0])
    proj = (rays * depth[:, None] @ R.T + t) @ K.T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, p0.shape)
    return p0 + rng.normal(0, noise_px, p0.shape), p1, t / np.linalg.norm(t)


@pytest.mark.parametrize('seed', [7, 8])
def test_the_tracks_h_left_out_that_move_with_its_motion_are_no_moving_object(seed):
    # A probe's view synthesized from a real TUM frame: H fits a poster, and the table below
    # it, far away, shows parallax at 2-3 times the noise only. The background test took the
    # table for the background of a pan and the poster for an object moving on its own, for
    # 20 frames of a slide. The table's flow beyond H's rotation lies on H's epipolar lines,
    # in front of both cameras: it moves with H's motion, so it is a static scene.
    p0, p1, t = _poster_over_a_table(0.02, seed)
    fire = initialize_pair(p0, p1, K, (Method.H,), FireConfig(refine=False))
    assert fire.background is not None
    assert 2.0 < fire.background.statistic < PolicyConfig().min_rotation_residual_sigma
    assert fire.reason is Reason.INITIALIZED, fire.detail
    assert translation_chordal_error(t, fire.seed.t) < 0.05


def test_h_alone_on_a_single_plane_stays_alone():
    p0, p1, _, t, _ = two_view(planar=True, seed=4)
    fire = initialize_pair(p0, p1, K, (Method.H,))
    assert fire.reason is Reason.INITIALIZED, fire.detail
    assert [e.method for e in fire.estimates] == [Method.H]
    assert translation_chordal_error(t, fire.seed.t) < 0.05


def test_the_background_test_leaves_a_static_scene_with_depth_alone():
    # E fits the wall and the objects alike: few tracks are left out, nothing to test.
    wall = two_view(planar=True, seed=4)
    objects = two_view(planar=False, seed=5)
    p0 = np.vstack((wall[0][:175], objects[0][:75]))
    p1 = np.vstack((wall[1][:175], objects[1][:75]))
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H))
    assert fire.reason is Reason.INITIALIZED, fire.detail
    assert fire.selection.winner is Method.E


def test_a_direction_of_motion_known_worse_than_the_bound_waits_for_more_baseline():
    # 6 cm of baseline at 1 px of noise fixes the direction to about 1 degree; a bound of
    # 0.5 degrees makes that pair wait, and the same scene from 30 cm passes it
    p0, p1, _, _, _ = two_view(planar=False, baseline=0.06, noise_px=1.0, seed=3)
    strict = FireConfig(rotation_test=False, policy=PolicyConfig(max_translation_sigma_deg=0.5))
    fire = initialize_pair(p0, p1, K, (Method.E,), strict)
    assert fire.reason is Reason.LOW_PARALLAX, fire.detail
    assert fire.seed.translation_sigma_deg > 0.5
    assert 'fixes the direction of motion only to' in fire.detail
    off = replace(strict, policy=PolicyConfig(max_translation_sigma_deg=0.0))
    assert initialize_pair(p0, p1, K, (Method.E,), off).reason is Reason.INITIALIZED
    # the bound is measured by the refinement: without it there is nothing to hold against it
    unrefined = initialize_pair(p0, p1, K, (Method.E,), replace(strict, refine=False))
    assert unrefined.reason is Reason.INITIALIZED
    assert np.isnan(unrefined.seed.translation_sigma_deg)
    longer = two_view(planar=False, baseline=0.3, noise_px=1.0, seed=3)
    wide = initialize_pair(longer[0], longer[1], K, (Method.E,), strict)
    assert wide.reason is Reason.INITIALIZED, wide.detail
    assert wide.seed.translation_sigma_deg < 0.5


def test_an_e_winner_waits_when_the_tracks_are_a_plane_and_h_is_not_ready():
    # A wall: H fits as well as E with fewer dimensions (lower GRIC), but keeps fewer points
    # than this policy asks, so it fails its pose check; E, degenerate on a plane, would win
    # alone. The pair waits for H instead.
    # (OpenCV's USAC keeps 65-83 of a plane's 300 tracks for E on most seeds, and E fails
    # its own check there; on this seed it keeps 250.)
    p0, p1, _, _, _ = two_view(planar=True, baseline=0.15, noise_px=0.3, seed=2)
    picky = FireConfig(policy=PolicyConfig(min_points=240))
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H), picky)
    h, e = fire.estimate('H'), fire.estimate('E')
    assert h.n_points < 240 <= e.n_points  # (the premise)
    assert fire.reason is Reason.TOO_FEW_POINTS and fire.seed is None, fire.detail
    assert 'the tracks are a plane' in fire.detail
    # with depth H scores worse than E, and E wins as before
    q0, q1, _, _, _ = two_view(planar=False, baseline=0.15, noise_px=0.3, seed=1)
    deep = initialize_pair(q0, q1, K, (Method.E, Method.H), FireConfig())
    gric = {score.method: score.gric for score in deep.selection.scores}
    assert gric[Method.H] > gric[Method.E]
    assert deep.reason is Reason.INITIALIZED and deep.seed.method is Method.E, deep.detail


def _wall_and_poster(n_wall: int, seed: int):
    """A wall 3 m away (``n_wall`` tracks around the poster) and a poster 1 m away (the rest
    of 300, the image's centre), the camera slid 15 cm sideways, 0.1 px of noise: p0, p1 and
    the unit translation."""
    rng = np.random.default_rng(seed)
    wall = rng.uniform([20, 20], [620, 460], (4 * n_wall, 2))
    inside = (np.abs(wall[:, 0] - 320) < 120) & (np.abs(wall[:, 1] - 240) < 100)
    poster = rng.uniform([200, 140], [440, 340], (300 - n_wall, 2))
    p0 = np.vstack((wall[~inside][:n_wall], poster))
    rays = np.c_[p0, np.ones(len(p0))] @ np.linalg.inv(K).T
    depth = np.r_[np.full(n_wall, 3.0), np.full(300 - n_wall, 1.0)]
    R = cv2.Rodrigues(np.array([0.0, -0.02, 0.0]))[0]
    t = np.array([-0.15, 0.0, 0.0])
    proj = (rays * depth[:, None] @ R.T + t) @ K.T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, 0.1, p0.shape)
    return p0 + rng.normal(0, 0.1, p0.shape), p1, t / np.linalg.norm(t)


@pytest.mark.parametrize(('seed', 'n_wall', 'waits_seed'), [(32, 230, 1), (32, 234, 7)])
def test_an_e_winner_stands_when_a_fifth_of_the_tracks_it_fits_lie_off_the_plane(
    seed, n_wall, waits_seed
):
    # A probe's poster 1 m before a wall 3 m away: GRIC caps what a track off the wall costs
    # H, so with the wall holding 77-78 % of the tracks H can score lower than E (with USAC's
    # E on these seeds; on most, E's fit scores lower). H fails its pose check (this policy
    # asks 10 points more than the wall has), and the better-model test took the tracks for a
    # plane and made E wait, for 40 frames live, though the poster's 66-70 tracks lie tens of
    # pixels off the wall's plane on E's epipolar lines: depth that makes E well-posed.
    p0, p1, t = _wall_and_poster(n_wall, seed)
    picky = FireConfig(policy=PolicyConfig(min_points=n_wall + 10))
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H, Method.F), picky)
    gric = {score.method: score.gric for score in fire.selection.scores}
    assert gric[Method.H] < gric[Method.E] and fire.estimate('H').n_points < n_wall + 10
    assert fire.reason is Reason.INITIALIZED and fire.seed.method is Method.E, fire.detail
    assert translation_chordal_error(t, fire.seed.t) < 0.01
    # a sixth off the plane is not the share that makes H's plane less than the scene: E waits
    p0, p1, _ = _wall_and_poster(250, waits_seed)
    fire = initialize_pair(
        p0,
        p1,
        K,
        (Method.E, Method.H, Method.F),
        replace(picky, policy=PolicyConfig(min_points=260)),
    )
    assert fire.reason is Reason.TOO_FEW_POINTS and fire.seed is None, fire.detail
    off = re.search(r'; (\d+) of 300 tracks lie off its plane, triangulated by E\)', fire.detail)
    assert 'the tracks are a plane' in fire.detail and off and int(off[1]) <= 60, fire.detail


@pytest.mark.parametrize('seed', [1, 5])
def test_an_f_winner_stands_off_the_plane_as_e_does(seed, monkeypatch):
    # The same poster before the wall with F and H only, F from RANSAC's 8-point fit (as
    # where USAC's is not kept): F's triangulated points off H's plane carry the rule as E's
    # do (the rule's figures were measured with E winners).
    monkeypatch.setattr(geometry, 'plane_and_parallax_fundamental', lambda *args: None)
    p0, p1, t = _wall_and_poster(220, seed)
    methods = (Method.F, Method.H)
    fire = initialize_pair(p0, p1, K, methods, FireConfig(policy=PolicyConfig(min_points=230)))
    gric = {score.method: score.gric for score in fire.selection.scores}
    assert gric[Method.H] < gric[Method.F] and fire.estimate('H').n_points < 230  # (premise)
    assert fire.reason is Reason.INITIALIZED and fire.seed.method is Method.F, fire.detail
    assert translation_chordal_error(t, fire.seed.t) < 0.01
    p0, p1, _ = _wall_and_poster(250, seed)
    fire = initialize_pair(p0, p1, K, methods, FireConfig(policy=PolicyConfig(min_points=260)))
    assert fire.reason is Reason.TOO_FEW_POINTS and fire.seed is None, fire.detail
    assert 'tracks lie off its plane, triangulated by F' in fire.detail


@pytest.mark.parametrize('seed', [1, 5])
def test_usacs_f_fits_the_poster_before_the_wall_better_than_the_walls_h(seed):
    # With the poster's 70 tracks off the wall, USAC's F is kept (its points put a fifth of
    # the tracks off the plane) and fits them all: its GRIC falls below H's (RANSAC's F
    # scored above it, the case the rule above is for), and F initializes without the rule.
    p0, p1, t = _wall_and_poster(220, seed)
    fire = initialize_pair(
        p0, p1, K, (Method.F, Method.H), FireConfig(policy=PolicyConfig(min_points=230))
    )
    gric = {score.method: score.gric for score in fire.selection.scores}
    assert gric[Method.F] < gric[Method.H]
    assert fire.reason is Reason.INITIALIZED and fire.seed.method is Method.F, fire.detail
    assert translation_chordal_error(t, fire.seed.t) < 0.01


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_tracking_noise_is_no_depth_off_a_plane(seed):
    # 2 px of noise on a wall's tracks puts many of E's points 2.5 px from H's transfer: the
    # bound grows with the noise, so only depth counts
    p0, p1, _, _, _ = two_view(planar=True, n=300, baseline=1.0, noise_px=2.0, seed=seed)
    e, h = estimate_pose(Method.E, p0, p1, K), estimate_pose(Method.H, p0, p1, K)
    assert off_plane_support(e, h, p0, p1) >= BACKGROUND_MIN_TRACKS  # a fixed 2.5 px
    assert off_plane_support(e, h, p0, p1, noise_px=2.0) < BACKGROUND_MIN_TRACKS


def test_an_h_winner_waits_when_the_tracks_have_depth_and_e_is_not_ready():
    # A wall (70 % of the tracks) and objects off it: E fits all of them and scores a lower
    # GRIC than H, which fits the wall. With E's parallax floor out of reach, H would win
    # alone; it waits for E instead. (H's own floor is for a plane that is the whole scene:
    # this wall is 70 % of it, so by default H's pose check holds it to E's floor already; the
    # better-model test is seen with that share rule off.)
    wall = two_view(planar=True, seed=4)
    objects = two_view(planar=False, seed=5)
    p0 = np.vstack((wall[0][:175], objects[0][:75]))
    p1 = np.vstack((wall[1][:175], objects[1][:75]))
    far = PolicyConfig(min_parallax_deg=5.0, min_homography_parallax_deg=0.5)
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H), FireConfig(policy=far))
    assert fire.reason is Reason.LOW_PARALLAX and fire.seed is None, fire.detail
    assert 'H failed (low parallax' in fire.detail
    assert '< 5 (H triangulates 6' in fire.detail and "E's floor applies" in fire.detail, (
        fire.detail
    )
    any_share = replace(far, min_homography_plane_share=0.0)
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H), FireConfig(policy=any_share))
    assert fire.reason is Reason.LOW_PARALLAX and fire.seed is None, fire.detail
    assert 'the tracks are not a plane (GRIC E' in fire.detail
    near = PolicyConfig(min_homography_parallax_deg=0.5)
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H), FireConfig(policy=near))
    assert fire.reason is Reason.INITIALIZED and fire.seed.method is Method.E


def _decompositions_of_the_wall(wall, R, t, n_off):
    """The true motion and the mirrored one of the wall's homography, as two H estimates."""
    from initsel_ros.geometry import PoseEstimate

    # the wall's plane in the reference frame: n.X = d (two_view's wall, 2 m ahead), at the
    # scale of the unit t (two_view's baseline of 0.15 m, 0.01 m and 0.02 m)
    normal = np.array([np.sin(0.35), 0.0, -np.cos(0.35)])
    d = -2.0 / np.linalg.norm([0.15, 0.01, 0.02])
    H = K @ (R + np.outer(t, normal) / d) @ np.linalg.inv(K)
    _, rotations, translations, _ = cv2.decomposeHomographyMat(H, K)
    unit = [np.ravel(v) / np.linalg.norm(v) for v in translations]
    true = int(np.argmin([np.linalg.norm(u - t / np.linalg.norm(t)) for u in unit]))
    # the other rotation (the decomposition with -t is the same motion's epipolar geometry)
    mirror = next(
        i
        for i in range(len(unit))
        if np.degrees(
            np.arccos(np.clip((np.trace(rotations[i].T @ rotations[true]) - 1) / 2, -1, 1))
        )
        > 0.5
    )
    inliers = np.arange(len(wall[0]) + n_off) < len(wall[0])

    def estimate(i):
        return PoseEstimate(
            Method.H, True, '', rotations[i], unit[i], np.zeros((0, 3)), np.zeros(0, int),
            inliers, 2.0, H,
        )  # fmt: skip

    return estimate(true), estimate(mirror)


def test_the_tracks_off_the_plane_tell_the_two_decompositions_of_h_apart():
    from initsel_ros.initialize import _decomposition_by_the_rest

    wall = two_view(planar=True, seed=4)
    objects = two_view(planar=False, seed=5)
    R, t = wall[2], wall[3]
    right, mirrored = _decompositions_of_the_wall(wall, R, t, 75)
    assert translation_chordal_error(t, mirrored.t) > 0.3
    ref = np.vstack((wall[0], objects[0][:75]))
    cur = np.vstack((wall[1], objects[1][:75]))
    # whichever comes first, the objects' epipolar lines keep the right one alone
    for first, second in ((mirrored, right), (right, mirrored)):
        chosen = _decomposition_by_the_rest(replace(first, alternative=second), ref, cur, K)
        assert chosen.alternative is None and translation_chordal_error(t, chosen.t) < 0.05
    # a wall alone leaves nothing to tell them apart: both go on to the verification
    right, mirrored = _decompositions_of_the_wall(wall, R, t, 0)
    alone = replace(mirrored, alternative=right)
    assert _decomposition_by_the_rest(alone, wall[0], wall[1], K) is alone


def test_mistracks_off_the_plane_are_no_evidence_for_either_decomposition():
    """Tracks that fit neither motion's epipolar lines (mistracks on a plane alone) say
    nothing about which decomposition is right, even where they sit nearer one motion's lines:
    both go on to the verification. (The median rule they replaced kept the mirrored one.)"""
    from initsel_ros.geometry import fundamental_from_essential, sampson_fundamental, skew
    from initsel_ros.initialize import _decomposition_by_the_rest

    wall = two_view(planar=True, seed=4)
    R, t = wall[2], wall[3]
    right, mirrored = _decompositions_of_the_wall(wall, R, t, 20)
    rng = np.random.default_rng(7)
    ref = rng.uniform([40, 40], [600, 440], (20, 2))
    # each mistrack 2.5 px off the mirrored motion's epipolar line near where the wall puts it
    F = fundamental_from_essential(skew(mirrored.t) @ mirrored.R, K)
    guess = cv2.perspectiveTransform(ref.reshape(-1, 1, 2), right.matrix).reshape(-1, 2)
    guess += rng.normal(0, 25.0, guess.shape)
    lines = np.hstack((ref, np.ones((20, 1)))) @ F.T
    normal = lines[:, :2] / np.linalg.norm(lines[:, :2], axis=1, keepdims=True)
    offset = (np.sum(lines[:, :2] * guess, axis=1) + lines[:, 2]) / np.linalg.norm(
        lines[:, :2], axis=1
    )
    cur = guess - (offset - 2.5)[:, None] * normal
    errors = [
        np.median(sampson_fundamental(fundamental_from_essential(skew(e.t) @ e.R, K), ref, cur))
        for e in (right, mirrored)
    ]
    assert errors[0] > 3 * errors[1] and errors[1] > 1.0  # nearer the mirrored motion's lines
    both = replace(right, alternative=mirrored)
    chosen = _decomposition_by_the_rest(
        both, np.vstack((wall[0], ref)), np.vstack((wall[1], cur)), K
    )
    assert chosen is both


def test_a_motion_missed_by_a_tracking_error_is_not_contradicted():
    """Tracks a few pixels off the plane, on the mirrored motion's epipolar lines and about a
    pixel off the right one's: a tracking error, not a static point, can do that. Both go on
    to the verification; the right motion is rejected only when it misses them clearly."""
    from initsel_ros.geometry import fundamental_from_essential, sampson_fundamental, skew
    from initsel_ros.initialize import _decomposition_by_the_rest

    wall = two_view(planar=True, seed=4)
    R, t = wall[2], wall[3]
    right, mirrored = _decompositions_of_the_wall(wall, R, t, 12)
    rng = np.random.default_rng(3)
    F = [fundamental_from_essential(skew(e.t) @ e.R, K) for e in (right, mirrored)]

    def along_mirrored_lines(miss_px2):
        ref = rng.uniform([60, 60], [580, 420], (40, 2))
        on_plane = cv2.perspectiveTransform(ref.reshape(-1, 1, 2), right.matrix).reshape(-1, 2)
        lines = np.hstack((ref, np.ones((len(ref), 1)))) @ F[1].T
        direction = np.column_stack((lines[:, 1], -lines[:, 0]))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        unit = sampson_fundamental(F[0], ref, on_plane + direction)  # right's miss at 1 px
        step = np.sqrt(miss_px2 / unit)
        keep = (step > 3.0) & (step < 30.0)
        return ref[keep][:12], (on_plane + step[:, None] * direction)[keep][:12]

    both = replace(right, alternative=mirrored)
    for miss_px2, expected in ((1.5, 'both'), (12.0, 'mirrored')):
        ref, cur = along_mirrored_lines(miss_px2)
        assert len(ref) == 12
        errors = [np.median(sampson_fundamental(f, ref, cur)) for f in F]
        assert errors[1] < 0.1 and errors[0] > 3 * errors[1]
        chosen = _decomposition_by_the_rest(
            both, np.vstack((wall[0], ref)), np.vstack((wall[1], cur)), K
        )
        if expected == 'both':
            assert chosen is both
        else:
            assert chosen.alternative is None and chosen.t is mirrored.t


def test_the_runner_up_of_an_ambiguous_h_is_judged_with_the_winners_plane_share():
    """The mirrored decomposition puts fewer of the plane's points in front of both cameras;
    the plane is no smaller for it, so H's own parallax floor applies to both."""
    from initsel_ros.geometry import PoseEstimate
    from initsel_ros.initialize import _resolve_ambiguity

    tracks = np.ones(200, bool)

    def decomposition(n_points):
        return PoseEstimate(
            Method.H, True, '', np.eye(3), np.array([1.0, 0, 0]), np.ones((n_points, 3)),
            np.arange(n_points), tracks, 0.7,
        )  # fmt: skip

    policy = PolicyConfig(
        min_parallax_deg=1.0, min_homography_parallax_deg=0.5, min_homography_plane_share=0.8
    )
    winner = replace(decomposition(190), alternative=decomposition(100))
    kept = _resolve_ambiguity(winner, policy)
    assert kept.ok and kept.alternative is not None and not kept.ambiguous
    # a winner that is only part of the scene holds its runner-up to E's floor as well
    part = replace(decomposition(120), alternative=decomposition(100))
    refused = _resolve_ambiguity(part, policy)
    assert not refused.ok and 'runner-up fails the pose check (low parallax)' in refused.reason
    assert refused.ambiguous and refused.alternative is None  # (a later frame may tell)


def test_f_is_judged_by_the_parallax_e_measures_with_the_camera_matrix(monkeypatch):
    """An F may reconstruct a projectively distorted scene whose points show more parallax
    than the motion gives; where the calibrated E says the parallax is too low, F waits too."""
    import initsel_ros.initialize as fire_path
    from initsel_ros.geometry import PoseEstimate

    n = 120
    parallax = {Method.E: 0.9, Method.F: 1.3}

    def estimate(method, ref, cur, K, config):
        method = Method(method)
        return PoseEstimate(
            method, True, '', np.eye(3), np.array([1.0, 0, 0]), np.ones((n, 3)), np.arange(n),
            np.ones(n, bool), parallax[method],
        )  # fmt: skip

    monkeypatch.setattr(fire_path, '_estimate', estimate)
    ref = cur = np.zeros((n, 2))
    policy = PolicyConfig(min_parallax_deg=1.0)
    config = FireConfig(policy=policy, rotation_test=False, select=False, refine=False)
    both = fire_path.initialize_pair(ref, cur, K, (Method.E, Method.F), config)
    assert both.checks == (Reason.LOW_PARALLAX, Reason.LOW_PARALLAX)
    assert both.reason is Reason.LOW_PARALLAX
    selected = fire_path.initialize_pair(
        ref, cur, K, (Method.E, Method.F), replace(config, select=True)
    )
    assert selected.reason is Reason.LOW_PARALLAX and selected.seed is None
    assert "E, with the camera matrix, measures parallax 0.90 deg < 1 (F's own 1.30" in (
        selected.detail
    )
    # without E's measurement, or with E above the floor, F stands on its own
    alone = fire_path.initialize_pair(ref, cur, K, (Method.F,), config)
    assert alone.checks == (None,) and alone.reason is Reason.INITIALIZED
    parallax[Method.E] = 1.1
    passed = fire_path.initialize_pair(ref, cur, K, (Method.E, Method.F), config)
    assert passed.checks == (None, None)


def test_between_the_plane_and_the_rotation_floor_h_alone_goes_on(monkeypatch):
    import initsel_ros.initialize as fire_path
    from initsel_ros.geometry import PoseEstimate, RotationTest

    tried = []
    plane = {'points': 0}  # H's triangulated points of the 60 tracks (0: no pose)

    def estimate(method, ref, cur, K, config):
        tried.append(Method(method))
        n = plane['points']
        return PoseEstimate(
            Method(method), n > 0, '' if n else 'no pose', np.eye(3), np.array([1.0, 0, 0]),
            np.ones((n, 3)), np.arange(n), np.ones(60, bool), 0.6,
        )  # fmt: skip

    monkeypatch.setattr(fire_path, '_estimate', estimate)
    ref = cur = np.zeros((60, 2))

    def fire(statistic, methods, **policy):
        tried.clear()
        monkeypatch.setattr(
            fire_path,
            'rotation_test',
            lambda *a, **k: RotationTest(0.1 * statistic, 0.1, statistic, 1.0),
        )
        config = FireConfig(policy=PolicyConfig(**policy), refine=False)
        return fire_path.initialize_pair(ref, cur, K, methods, config)

    between = fire(2.5, (Method.E, Method.H))
    assert tried == [Method.H] and between.reason is Reason.POSE_FAILED
    assert 'measured 2.5 x the noise: parallax for H, not yet for E and F' in between.detail
    assert fire(3.5, (Method.E, Method.H)).estimates and tried == [Method.E, Method.H]
    # without H to try, or under the plane's floor, or with the floor at the rotation's
    for statistic, methods, policy, floor in (
        (2.5, (Method.E, Method.F), {}, '< 3 x'),
        (1.5, (Method.E, Method.H), {}, '< 2 x'),
        (2.5, (Method.E, Method.H), {'min_plane_residual_sigma': 3.0}, '< 3 x'),
    ):
        refused = fire(statistic, methods, **policy)
        assert refused.reason is Reason.ROTATION and tried == [] and floor in refused.detail
    # an H that holds only part of the tracks is one plane of a scene with depth: E's floor
    plane['points'] = 30
    part = fire(2.5, (Method.E, Method.H))
    assert part.reason is Reason.ROTATION and tried == [Method.H]
    assert 'H holds 50% of the tracks (< 80%): the rest has depth' in part.detail


def test_an_h_fitted_to_a_desks_relief_at_a_short_baseline_is_refused(desk_start_sequence):
    # The README demo's frame 63, 1.8 cm from its reference: a homography holds 79 % of the
    # tracks within a pixel, and the rotation test measures 2.6 x the noise (the plane floor
    # is 2), but H's pose is wrong (E_t 1.4) ...
    from initsel_ros.datasets import open_sequence
    from initsel_ros.geometry import estimate_pose
    from initsel_ros.metrics import relative_pose
    from initsel_ros.tracking import KltTracker, TrackerConfig

    seq = open_sequence(desk_start_sequence)
    tracker = KltTracker(TrackerConfig())
    tracker.reset(seq.gray(0))
    for k in range(1, 64):
        tracker.track(seq.gray(k))
    tracks = tracker.anchored()
    ref, cur = (seq.intrinsics.undistort_pixels(p) for p in (tracks.ref, tracks.cur))
    K_seq = seq.intrinsics.K
    _, t_true = relative_pose(seq.frames[0].pose, seq.frames[63].pose)
    plane = estimate_pose(Method.H, ref, cur, K_seq)
    assert plane.ok and translation_chordal_error(t_true, plane.t) > 1.0
    # ... because it holds the relief of the desk, not a plane's perspective change: on its
    # own tracks it leaves as much as a rotation does, and the fire path refuses it (with the
    # share rule relaxed, which refuses it at 80 % too, so that this test is what decides)
    config = FireConfig(policy=PolicyConfig(min_homography_plane_share=0.6))
    fire = initialize_pair(ref, cur, K_seq, (Method.E, Method.F, Method.H), config)
    assert fire.rotation is not None and fire.rotation.statistic >= 2.0
    assert fire.seed is None and fire.reason is not Reason.INITIALIZED, fire.detail
    refused = fire.estimate(Method.H)
    assert refused is not None and not refused.ok, fire.detail
    assert 'H fits the relief of a scene with depth' in refused.reason


def test_a_poster_whose_mirrored_plane_would_hide_part_of_it_initializes_without_waiting():
    # H's mirrored decomposition passes the count of points in front (test_geometry), but its
    # plane leaves a fifth of the poster behind the camera: no rival for the frames to judge
    from geometry_fixtures import poster_off_centre

    p0, p1, t = poster_off_centre()
    fire = initialize_pair(p0, p1, K, (Method.E, Method.H))
    assert fire.reason is Reason.INITIALIZED, fire.detail
    assert fire.seed is not None and fire.seed.method is Method.H and not fire.alternatives
    assert translation_chordal_error(t, fire.seed.t) < 0.1


def test_the_rotation_statistic_of_a_poster_follows_the_baseline_not_the_noise_estimate(
    poster_arc_sequence,
):
    # A poster 1.2 m away from a sideways arc, re-measured KLT tracks against frame 0: the
    # perspective change grows with the baseline, and so must the statistic, up to the
    # rotation fit's own spread (one frame 12 % under the one before). With the noise from
    # F alone, which a plane leaves undetermined, the noise read 0.10 px on most frames and
    # up to twice that on others, and the statistic fell 0.77 -> 0.36 and 3.13 -> 1.70.
    from initsel_ros.datasets import open_sequence
    from initsel_ros.geometry import rotation_test
    from initsel_ros.tracking import KltTracker

    sequence = open_sequence(poster_arc_sequence)
    tracker = KltTracker()
    tracker.reset(sequence.gray(0))
    tests = []
    for k in range(1, 16):
        tracker.track(sequence.gray(k))
        tracks = tracker.anchored()
        tests.append(rotation_test(tracks.ref, tracks.cur, sequence.intrinsics.K))
    statistics = [t.statistic for t in tests]
    assert statistics[-1] > 1.5 * PolicyConfig().min_rotation_residual_sigma
    assert all(s >= 0.8 * max(statistics[:k]) for k, s in enumerate(statistics) if k), statistics
    noise = [t.noise_px for t in tests]
    assert max(noise) <= 1.2 * min(noise), noise


def _object_overtaking_a_slide(seed: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A camera sliding 15 cm past a room 2-4 m deep (170 tracks) while a board 1.4 m away
    (110 tracks, a person walking past) moves the other way relative to it. Returns the
    pixels of both views and the camera's true unit translation."""
    rng = np.random.default_rng(seed)
    R = cv2.Rodrigues(np.array([0.0, 0.004, 0.0]))[0]
    t_camera = np.array([-0.15, 0.0, 0.0])  # x1 = R x0 + t: the camera moves along +x
    t_board = np.array([0.06, 0.0, 0.0])  # the board overtakes it

    def views(n: int, depth: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u, v = rng.uniform(30, 610, n), rng.uniform(30, 450, n)
        X = (np.column_stack([u, v, np.ones(n)]) @ np.linalg.inv(K).T) * depth[:, None]
        proj = (X @ R.T + t) @ K.T
        p1 = proj[:, :2] / proj[:, 2:] + rng.normal(0, 0.2, (n, 2))
        return np.column_stack([u, v]) + rng.normal(0, 0.2, (n, 2)), p1

    room = views(170, rng.uniform(2.0, 4.0, 170), t_camera)
    board = views(110, np.full(110, 1.4), t_board)
    p0 = np.vstack([room[0], board[0]])
    p1 = np.vstack([room[1], board[1]])
    return p0, p1, t_camera / np.linalg.norm(t_camera)


def test_a_winner_whose_motion_the_rest_of_the_scene_contradicts_is_refused(monkeypatch):
    # before: a person walking past a sliding camera was published as the map (H on the
    # board, then E agreeing with it), the direction of motion reversed: E_t 2.0
    import initsel_ros.initialize as initialize

    p0, p1, t_true = _object_overtaking_a_slide()
    board = initialize_pair(p0, p1, K, (Method.H,))  # H alone: the board is its plane
    assert board.reason is Reason.POSE_FAILED and board.seed is None
    assert 'H failed (two motions: of the' in board.detail
    both = initialize_pair(p0, p1, K, (Method.E, Method.H))  # E fits the room
    assert both.reason is Reason.INITIALIZED and float(both.seed.t @ t_true) > 0.99
    monkeypatch.setattr(initialize, '_second_motion', lambda support, n: False)
    blind = initialize_pair(p0, p1, K, (Method.H,))
    assert blind.reason is Reason.INITIALIZED and float(blind.seed.t @ t_true) < -0.9


def test_a_static_scene_supports_its_motion():
    from initsel_ros.initialize import motion_support

    for planar in (False, True):
        p0, p1, R, t, _ = two_view(planar=planar, noise_px=0.3, seed=9)
        support = motion_support(
            replace(estimate_pose(Method.E, p0, p1, K), R=R, t=t), p0, p1, K, 0.3
        )
        assert support.measurable > 200 and support.contradicting <= 0.02 * support.measurable
