"""Tests for initsel_ros.overlay: the debug image."""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.geometry import Method
from initsel_ros.overlay import direction_colors, draw_overlay
from initsel_ros.policy import Decision, Reason
from initsel_ros.selector import FrameResult, Initialization

THRESHOLDS = {'F': 0.5, 'E': 0.6, 'H': 0.7, 'R': 0.5}


def frame(seed: int = 0, h: int = 480, w: int = 640) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(60, 200, (h, w, 3), dtype=np.uint8)


def result(reason: Reason = Reason.NO_MODEL_FIRED, **kw) -> FrameResult:
    probabilities = kw.pop('probabilities', {'F': 0.2, 'E': 0.4, 'H': 0.8, 'R': 0.1})
    decision = Decision(
        reason,
        probabilities=probabilities,
        n_tracks=kw.pop('n_tracks', 2),
        mean_disparity=12.5,
        **kw,
    )
    return FrameResult(7, 1.0, 0.5, decision, frames_since_reference=3)


def test_overlay_keeps_the_size_and_draws_something_without_touching_the_input():
    img = frame()
    before = img.copy()
    ref = np.array([[100, 200], [300, 300]], np.float32)
    out = draw_overlay(img, result(), ref, ref + np.float32([10, -5]), THRESHOLDS)
    assert out.shape == img.shape and out.dtype == np.uint8
    assert np.array_equal(img, before)
    changed = np.any(out != img, axis=2)
    assert changed.mean() > 0.05  # the panel alone covers more than 5 % of the frame


def test_opposite_directions_get_different_colours():
    ref = np.array([[400, 300], [400, 400], [200, 200], [200, 100]], np.float32)
    cur = ref + np.array([[40, 0], [-40, 0], [0, -40], [0, 40]], np.float32)  # R, L, up, down
    colours = direction_colors(ref, cur).astype(int)
    assert np.abs(colours[0] - colours[1]).sum() > 200
    assert np.abs(colours[2] - colours[3]).sum() > 200
    # and on the drawn image: sample the middle of the right- and left-going segments
    out = draw_overlay(np.zeros((480, 640, 3), np.uint8), result(), ref, cur, THRESHOLDS)
    right, left = out[300, 420].astype(int), out[400, 380].astype(int)
    assert right.sum() > 150 and left.sum() > 150
    assert np.abs(right - left).sum() > 200


def test_tracks_that_did_not_move_are_grey():
    ref = np.array([[100, 100], [500, 400]], np.float32)
    colours = direction_colors(ref, ref + 0.1)
    assert np.all(colours[:, 0] == colours[:, 1]) and np.all(colours[:, 1] == colours[:, 2])


def test_zero_tracks_nan_probabilities_and_empty_decisions_do_not_raise():
    nan = float('nan')
    empty = np.zeros((0, 2), np.float32)
    out = draw_overlay(
        frame(1),
        result(probabilities={'F': nan, 'E': nan, 'H': nan, 'R': nan}, n_tracks=0),
        empty,
        empty,
        THRESHOLDS,
    )
    assert out.shape == (480, 640, 3)
    done = FrameResult(9, 2.0, 0.5, Decision(Reason.DONE))
    out = draw_overlay(frame(1), done, empty, empty, {})
    assert out.shape == (480, 640, 3)
    nan_tracks = np.array([[nan, nan], [10, 10]], np.float32)
    draw_overlay(frame(1), result(), nan_tracks, nan_tracks + 3, THRESHOLDS)


@pytest.mark.parametrize('shape', [(480, 640), (48, 64), (720, 1280, 4), (240, 320, 1)])
def test_other_sizes_and_channel_layouts_are_drawn(shape):
    img = np.full(shape, 120, np.uint8)
    ref = np.array([[10, 10], [20, 30]], np.float32)
    out = draw_overlay(img, result(), ref, ref + 2, THRESHOLDS)
    assert out.shape == (*shape[:2], 3)
    assert np.any(out != 120)


def test_rotation_veto_is_shown_differently_from_a_plain_miss():
    probs = {'F': 0.9, 'E': 0.9, 'H': 0.1, 'R': 0.9}
    empty = np.zeros((0, 2), np.float32)
    img = np.zeros((480, 640, 3), np.uint8)
    vetoed = draw_overlay(
        img,
        result(Reason.ROTATION, probabilities=probs, fired=('E', 'F'), vetoed=('E', 'F')),
        empty,
        empty,
        THRESHOLDS,
    )
    plain = draw_overlay(img, result(probabilities=probs), empty, empty, THRESHOLDS)
    assert not np.array_equal(vetoed[:150, :300], plain[:150, :300])


def test_initialization_inliers_are_marked_in_yellow():
    pixels = np.array([[320, 300], [500, 420]], np.float32)
    init = Initialization(
        method=Method.E,
        R=np.eye(3),
        t=np.array([0.1, 0, 0]),
        points=np.ones((2, 3)),
        pixels_ref=pixels - 5,
        pixels_cur=pixels,
        reference_stamp_ns=500_000_000,
        stamp_ns=1_000_000_000,
        frames_since_reference=3,
        probabilities={'E': 0.9},
        parallax_deg=2.0,
    )
    res = result(Reason.INITIALIZED, detail='E')
    img = np.zeros((480, 640, 3), np.uint8)
    empty = np.zeros((0, 2), np.float32)
    out = draw_overlay(img, res, empty, empty, THRESHOLDS, init)
    around = out[296:305, 316:325].reshape(-1, 3).astype(int)
    yellow = (around[:, 0] < 80) & (around[:, 1] > 200) & (around[:, 2] > 200)
    assert yellow.any()
    assert not math.isnan(float(out.mean()))


def test_frame_overlay_draws_the_initializing_pairs_after_a_continuous_reset():
    from initsel_ros.overlay import draw_frame_overlay

    fresh = np.array([[100, 300], [500, 400]], np.float32)  # tracker restarted: ref == cur
    pixels = np.array([[300, 300]], np.float32)
    init = Initialization(
        method=Method.H,
        R=np.eye(3),
        t=np.array([0.1, 0, 0]),
        points=np.ones((1, 3)),
        pixels_ref=pixels - [40, 0],
        pixels_cur=pixels,
        reference_stamp_ns=500_000_000,
        stamp_ns=1_000_000_000,
        frames_since_reference=3,
        probabilities={'H': 0.9},
        parallax_deg=2.0,
    )
    res = FrameResult(
        7,
        1,
        0,
        Decision(Reason.INITIALIZED, detail='H'),
        init,
        tracks_ref=fresh,
        tracks_cur=fresh.copy(),
        thresholds=THRESHOLDS,
    )
    out = draw_frame_overlay(np.zeros((480, 640, 3), np.uint8), res)
    assert out[300, 280].sum() > 150  # the middle of the reference -> current segment


def test_a_selector_result_carries_the_tracks_and_thresholds_it_used():
    from image_fixtures import shifted, texture
    from model_fixtures import constant_models

    from initsel_ros.camera import Intrinsics
    from initsel_ros.selector import Selector

    sel = Selector(constant_models(), Intrinsics.tum_fr3())
    img = texture(3)
    first = sel.process(img, 0)
    second = sel.process(shifted(img, 2.0, 1.0), 33_000_000)
    assert first.tracks_ref.shape == first.tracks_cur.shape and len(first.tracks_ref) > 50
    assert second.thresholds == sel.thresholds
    moved = np.median(second.tracks_cur - second.tracks_ref, axis=0)
    assert np.allclose(moved, [2.0, 1.0], atol=0.1)
