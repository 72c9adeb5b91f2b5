"""When the fire path runs again after finding the baseline too short (recheck.py)."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from initsel_ros.geometry import Method, PoseEstimate, RotationTest
from initsel_ros.initialize import FireResult
from initsel_ros.policy import PolicyConfig, Reason
from initsel_ros.recheck import EvidenceGap, evidence_gap, frames_to_recheck

POLICY = PolicyConfig()


def _rotation(statistic: float) -> RotationTest:
    return RotationTest(statistic * 0.2, 0.2, statistic, 1.0)


def _estimate(method: Method, parallax_deg: float, n_points: int = 240) -> PoseEstimate:
    return PoseEstimate(
        method, True, '', np.eye(3), np.array([1.0, 0.0, 0.0]), np.zeros((n_points, 3)),
        np.arange(n_points), np.ones(250, dtype=bool), parallax_deg,
    )  # fmt: skip


def test_a_pan_keeps_the_fixed_cadence():
    # a pan leaves about the noise (statistic 1.0-1.3): it does not grow with time, and no
    # re-check comes sooner than rotation_recheck_frames
    for statistic in (0.9, 1.0, 1.3):
        gap = evidence_gap(FireResult(Reason.ROTATION, rotation=_rotation(statistic)), POLICY)
        for since in (3, 6, 30, 60):
            assert frames_to_recheck(since, 3, gap) == 3, (statistic, since)
    # 1.6 may be parallax on its way (it reaches 2 when the baseline has grown by 1.39):
    # from frame 3 on frame 4, from frame 6 on frame 8; from frame 9 on the prediction lies
    # past the cadence
    gap = evidence_gap(FireResult(Reason.ROTATION, rotation=_rotation(1.6)), POLICY)
    assert [frames_to_recheck(s, 3, gap) for s in (3, 6, 9, 30)] == [1, 2, 3, 3]


def test_the_rotation_statistic_is_extrapolated_in_quadrature_with_the_noise():
    # 1.9 of a bar of 2 at frame 30: s^2 - 1 must grow by 3 / 2.61, the baseline by its root
    gap = evidence_gap(FireResult(Reason.ROTATION, rotation=_rotation(1.9)), POLICY)
    assert gap.growth == pytest.approx(math.sqrt(3.0 / 2.61))
    assert gap.gate == 'rotation test 1.9 of 2 x the noise'
    assert frames_to_recheck(30, 3, gap) == 2  # 30 x 1.072 = 32.2: frame 32
    assert frames_to_recheck(60, 3, gap) == 3  # 64.3: the cadence's 63 first
    assert frames_to_recheck(12, 3, gap) == 1  # 12.9: the next frame
    # between the plane's bar and E's, after H was refused for its share: E's bar is next
    past_plane = evidence_gap(FireResult(Reason.ROTATION, rotation=_rotation(2.8)), POLICY)
    assert past_plane.growth == pytest.approx(math.sqrt(8.0 / (2.8**2 - 1.0)))


def test_a_parallax_just_short_of_its_floor_is_re_checked_on_the_next_frame():
    # the poster of the planar-arc tuning seeds: H at 0.49 degrees against 0.5 on frame 9
    h = _estimate(Method.H, 0.49)
    e = _estimate(Method.E, 0.0, n_points=0)
    fire = FireResult(
        Reason.POSE_FAILED,
        rotation=_rotation(3.8),
        estimates=(e, h),
        checks=(Reason.POSE_FAILED, Reason.LOW_PARALLAX),
    )
    gap = evidence_gap(fire, POLICY)
    assert gap.growth == pytest.approx(POLICY.min_homography_parallax_deg / 0.49)
    assert gap.gate.startswith('H parallax 0.49 of')
    assert frames_to_recheck(9, 3, gap) == 1


def test_an_uncertain_direction_shrinks_with_the_baseline():
    seed = SimpleNamespace(translation_sigma_deg=2.5)
    fire = FireResult(Reason.LOW_PARALLAX, rotation=_rotation(5.0), seed=seed)
    gap = evidence_gap(fire, POLICY)
    assert gap.growth == pytest.approx(2.5 / POLICY.max_translation_sigma_deg)
    assert frames_to_recheck(12, 3, gap) == 3  # 12 x 1.25 = 15: frame 15
    assert frames_to_recheck(6, 3, gap) == 1  # 7.5: frame 7
    assert frames_to_recheck(8, 3, gap) == 1  # 10, but the cadence's frame 9 comes first


def test_the_nearest_gate_decides_and_other_failures_keep_the_cadence():
    far = _estimate(Method.E, 0.1)
    near = _estimate(Method.H, 0.45)
    fire = FireResult(
        Reason.LOW_PARALLAX,
        rotation=_rotation(4.0),
        estimates=(far, near),
        checks=(Reason.LOW_PARALLAX, Reason.LOW_PARALLAX),
    )
    assert evidence_gap(fire, POLICY).gate.startswith('H parallax')
    failed = FireResult(
        Reason.POSE_FAILED,
        rotation=_rotation(3.2),
        estimates=(_estimate(Method.H, math.nan),),
        checks=(Reason.POSE_FAILED,),
    )
    assert evidence_gap(failed, POLICY) == EvidenceGap()
    assert frames_to_recheck(6, 3, EvidenceGap()) == 3
    # a left-out part that a rotation explains is judged by its own statistic
    background = FireResult(Reason.ROTATION, rotation=_rotation(6.0), background=_rotation(2.9))
    assert evidence_gap(background, POLICY).gate == 'left-out 2.9 of 3 x the noise'


def test_h_s_bar_is_a_gate_only_where_h_was_tried_under_e_s_bar():
    stopped = FireResult(Reason.ROTATION, rotation=_rotation(1.5))
    without_h = evidence_gap(stopped, POLICY, h_tried=False)
    assert without_h.growth == pytest.approx(math.sqrt(8.0 / 1.25))  # E's bar of 3
    assert without_h.gate == 'rotation test 1.5 of 3 x the noise'
    # a plane bar at or over E's switches H's own test off: 3.2 stops at no bar
    off = replace(POLICY, min_plane_residual_sigma=3.5)
    assert evidence_gap(replace(stopped, rotation=_rotation(3.2)), off) == EvidenceGap()


def test_frames_to_recheck_bounds():
    assert frames_to_recheck(9, 3, EvidenceGap(1.0, 'passes')) == 1
    assert frames_to_recheck(9, 3, EvidenceGap(100.0, 'far')) == 3
    assert frames_to_recheck(0, 3, EvidenceGap(1.01, 'near')) == 3
    # an early re-check (frame 10) keeps the cadence's frame 12, whatever it predicts
    assert frames_to_recheck(10, 3, EvidenceGap(100.0, 'far')) == 2
    assert frames_to_recheck(10, 3, EvidenceGap()) == 2
    assert frames_to_recheck(11, 3, EvidenceGap(1.05, 'near')) == 1
    with pytest.raises(ValueError, match='every'):
        frames_to_recheck(5, 0, EvidenceGap())
    # a finite growth too large to multiply (a direction bound near 0) keeps the cadence
    assert frames_to_recheck(2, 3, EvidenceGap(1e308, 'far')) == 1


def test_between_the_plane_bar_and_e_s_the_next_bar_is_a_gate_whatever_h_did():
    # frame 4 of a wall seen from a slide: 2.4 x the noise let H alone be tried, and its
    # homography had no decomposition yet; E's bar of 3 is the baseline-limited gate
    failed = FireResult(
        Reason.POSE_FAILED,
        rotation=_rotation(2.4),
        estimates=(_estimate(Method.H, math.nan),),
        checks=(Reason.POSE_FAILED,),
    )
    gap = evidence_gap(failed, POLICY)
    assert gap.growth == pytest.approx(math.sqrt(8.0 / (2.4**2 - 1.0)))
    assert frames_to_recheck(9, 3, gap) == 2  # 9 x 1.30 = 11.7: frame 11
    # past E's bar nothing is extrapolated from the statistic
    assert evidence_gap(replace(failed, rotation=_rotation(3.5)), POLICY) == EvidenceGap()
