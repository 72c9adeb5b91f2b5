"""The live pipeline, free of ROS: frames in, decisions and (once) an initialization out.

One :class:`Selector` serves one camera stream. For each frame it tracks against the
reference frame, computes the 23 features, scores the four models, applies the policy and,
when a model fires, recovers the pose with that method and checks it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.corners import EDGE_ISOTROPY, structure_isotropy
from initsel_ros.errors import ConfigError, ImageConversionError
from initsel_ros.features import Camera
from initsel_ros.geometry import Method, RotationTest, rotation_angle_deg
from initsel_ros.image import BitDepth, to_gray  # to_gray re-exported: selector.to_gray
from initsel_ros.initialize import (
    FireConfig,
    FireResult,
    SeedMap,
    fire_methods,
    initialize_pair,
    radial_terms_for,
    usable_seed,
)
from initsel_ros.model_selection import Selection
from initsel_ros.models import ModelSet
from initsel_ros.names import Mode
from initsel_ros.plane import (
    PlaneNormal,
    depth_sigma,
    homography_normals,
    normal_drift_deg,
    plane_normal,
    snap_to_plane,
)
from initsel_ros.policy import (
    Decision,
    PolicyConfig,
    Reason,
    decide,
    effective_thresholds,
)
from initsel_ros.recheck import cadence_frames, evidence_gap, frames_to_recheck
from initsel_ros.refine import Refinement
from initsel_ros.tracking import KltTracker, TrackerConfig, Tracks
from initsel_ros.verify import VerifyConfig, VerifyStep, check_frame

log = logging.getLogger(__name__)

#: The last verification frame's own seed map replaces the verified one when its pose is
#: within these of that frame's PnP pose against the verified map (degrees; chordal distance
#: of the translation directions, as E_t).
LAST_FRAME_MAX_ROTATION_DEG = 1.0
LAST_FRAME_MAX_E_T = 0.1
#: ...or within this, where its direction of motion is the more certain of the two (the
#: bundle adjustment's ``translation_sigma_deg``): the PnP pose against the verified map
#: inherits that map's direction, so where the verified map is the less certain one, a
#: better direction from the longer baseline disagrees with it (a poster seen from an arc:
#: refit E_t 0.005, verified map 0.124, 0.127 apart). Far enough to keep out the other
#: decomposition of a plane, which lies near the plane's normal.
LAST_FRAME_MORE_CERTAIN_MAX_E_T = 0.3
#: When an H's two decompositions both held on every verification frame, the rival replaces
#: the fire path's choice (the one with more points in front of both cameras and reprojecting
#: well) only when its RMS reprojection error is under this share of the choice's, both on
#: average over those frames and on the last one. Two poses of one plane fit the same points
#: about equally well (on the seed-map planes the RMS of one was 0.92-1.07 times the other's),
#: and a few percent less by chance chose the wrong one. The wrong map's misfit grows with the
#: baseline, so it shows on the last frame, the longest baseline; the noise's difference
#: changes sides from frame to frame (straight motion toward a wall: 11-13 % less on
#: average, on the last frame from 1 % less to 12 % more).
RIVAL_MAX_RMS_RATIO = 0.9
#: Where a rival decomposition still holds after the verification frames, the verification
#: goes on to this many times its frames (it publishes sooner if only one is left holding),
#: and the choice by :data:`RIVAL_MAX_RMS_RATIO` is made then (where neither fits clearly
#: better, the fire path's). Flying straight over flat ground, both decompositions of the
#: ground plane held on 5 frames and the fire path's choice was the wrong one on 4 of 7
#: flights (E_t 1.44, 3.5-4.1 degrees). The wrong map's misfit grows with the square of the
#: baseline, so it shows once the baseline has grown a few times: on 5 frames the right one
#: fitted 17 % worse by the maps' own noise, on 15 the wrong one's RMS had grown 0.09 -> 0.43
#: px, the right one's stayed at 0.14-0.20.
AMBIGUOUS_VERIFY_FACTOR = 3
#: Where rival decompositions hold, the one whose plane stays with the later frames'
#: homographies is chosen as soon as the verification frames show it (from
#: ``VerifyConfig.frames`` on). On each frame, each map's plane is compared with the nearest
#: plane of the homography from the reference to that frame (:func:`plane.normal_drift_deg`),
#: in units of the two planes' uncertainty (the map's from its points' depth uncertainty at
#: the fire frame's baseline, the homography's as that of the same points at this frame's:
#: :func:`plane.plane_normal`, with the fire path's noise estimate). The mirrored map's plane
#: is the fire frame's alone and drifts as the baseline grows (flying over flat ground with
#: yaw and noise: 0.2 -> 1.7 degrees over 15 frames, 1.6 -> 15.5 times the uncertainty; the
#: right map's 0.1-0.3 degrees, 0.7-1.7 times), while its RMS can grow just like the right
#: one's. Over the last
#: ``VerifyConfig.frames`` frames, the candidate chosen must lie within this many
#: uncertainties on average, and nearer than every rival on each frame.
RIVAL_STEADY_Z = 3.0
#: ... and every rival at least this many on average (at 5, four slow flights at 50 m whose
#: mirrored plane drifted 4.5 uncertainties on average were published mirrored; in no window
#: of 125 verifications with rivals did a wrong map lie within 3 while the right one
#: drifted, so the bar only sets how soon).
RIVAL_DRIFT_Z = 4.0
#: ... and the two maps' planes at least this far apart, degrees. The mirrored plane's normal
#: lies near the direction of motion, so moving toward the plane the two stay close and the
#: mirror barely drifts: straight toward the README's wall (8 batches, planes 33-37 degrees
#: apart) the right map lay 2-3 uncertainties off the homographies and the mirrored one
#: nearer, which chose the mirrored map on 3 of them.
RIVAL_MIN_PLANE_ANGLE_DEG = 45.0
#: What the fire path tries when the rotation test re-checks model R's veto: E (the general
#: model of a calibrated camera) and H (a plane), GRIC choosing.
RECHECK_METHODS = (Method.E, Method.H)


@dataclass(frozen=True)
class _FireSchedule:
    """When the fire path runs next for want of baseline (frames since the reference).

    Attributes:
        set_at: the frame of the run that set it (0: none since the reference).
        due: the frame of the next run (a re-check of R's veto, or a model's yes).
        rotation: the rotation test that stopped that run (the main one, or the background
            test of the tracks the winner left out), else None; a model's yes before ``due``
            is held without running the fire path while it is set.
        stopped_by: what ``rotation`` measured, for the log of a held frame.
    """

    set_at: int
    due: int
    rotation: RotationTest | None = None
    stopped_by: str = ''

    def next_run(self, every: int) -> int:
        """The frame of the next run: ``due``, or before any run since the reference the
        cadence's first frame (``every``: the setting may have changed since)."""
        return self.due if self.set_at > 0 else every


@dataclass(frozen=True)
class SelectorConfig:
    """Settings of the live pipeline.

    Attributes:
        tracker: feature detection and tracking.
        policy: thresholds, R veto and pose checks.
        mode: :class:`~initsel_ros.names.Mode` (the strings 'once' and 'continuous' are
            converted): ONCE stops after the first initialization until
            :meth:`Selector.reset`; CONTINUOUS re-anchors on the initializing frame and keeps
            going.
        max_frames_since_reference: a frame this many frames after the reference becomes the
            new reference when nothing initialized (the paper's batch length at 30 Hz) ...
        min_seconds_since_reference: ... and at least this many seconds after it, by the
            stamps (where they rise): a 60 Hz camera keeps the 3 s window of 90 frames at 30
            Hz, not half of it (slower cameras are unchanged). 0 = frames only.
        ransac_threshold_px: RANSAC inlier threshold of the pose estimators, pixels.
        refine: bundle-adjust the chosen pose and points before publishing (refine.py).
        snap_to_plane: publish the points of an H initialization that agree with one plane
            to within their own depth uncertainty (the refinement's reprojection RMS over
            their parallax) on that plane (plane.py; needs ``refine``); the verification uses
            the map as triangulated.
        verify: hold the candidate back and confirm it on the next frames (verify.py).
        rotation_recheck_frames: while model R's yes is what holds every other model back
            (the reason is ``rotation`` from the models), the fire path runs with E and H
            every this many frames after the reference: its rotation test, which measures
            the flow a rotation leaves against the tracking noise, either confirms R (cheap:
            it stops at the first good rotation) or finds the parallax of a plane seen from
            a sideways arc, which the models' summary features do not see. Each fire-path
            run that found the baseline too short schedules the next for the frame its gate
            is predicted to pass (``recheck.py``), never later than this cadence; where the
            rotation test stopped it, a model's yes on the frames before is held without
            running the fire path. 0 = never (and every yes runs the fire path).
        bit_depth: significant bits of 16-bit frames (8-16); 0 = automatic, per stream
            (:class:`~initsel_ros.image.BitDepth`; :meth:`Selector.reset` forgets it).
        rotation_rereference_share: when a fire-path run finds a rotation at the noise level
            (the rotation test's statistic at most half ``policy.min_rotation_residual_sigma``)
            and at most this share of the reference's tracks is left, this frame becomes the
            reference. A rotation keeps the camera centre, so no baseline is lost, and the new
            reference holds the whole current view: on a pan the background leaves the image
            while objects moving on their own can stay in it, until one rotation no longer
            explains the third of the tracks the rotation test needs. 0 = never.
    """

    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    mode: Mode = Mode.ONCE
    max_frames_since_reference: int = 90
    min_seconds_since_reference: float = 3.0
    ransac_threshold_px: float = 1.0
    refine: bool = True
    snap_to_plane: bool = True
    verify: VerifyConfig = field(default_factory=VerifyConfig)
    rotation_recheck_frames: int = 3
    bit_depth: int = 0
    rotation_rereference_share: float = 0.7

    def __post_init__(self) -> None:
        if self.mode not in tuple(Mode):
            accepted = ' or '.join(repr(m.value) for m in Mode)
            raise ConfigError(f'mode must be {accepted}, got {self.mode!r}')
        object.__setattr__(self, 'mode', Mode(self.mode))  # 'once' -> Mode.ONCE
        if self.max_frames_since_reference < 1:
            raise ConfigError('max_frames_since_reference must be at least 1')
        if not 0.0 <= self.min_seconds_since_reference < math.inf:
            raise ConfigError(
                'min_seconds_since_reference must be a finite number of seconds, 0 or more, '
                f'got {self.min_seconds_since_reference!r}'
            )
        if self.rotation_recheck_frames < 0:
            raise ConfigError('rotation_recheck_frames must be 0 (never) or more')
        if isinstance(self.bit_depth, bool) or self.bit_depth not in (0, *range(8, 17)):
            raise ConfigError(f'bit_depth must be 0 or 8 to 16, got {self.bit_depth!r}')
        if not 0.0 <= self.rotation_rereference_share <= 1.0:
            raise ConfigError(
                'rotation_rereference_share must be within 0 (never) and 1, got '
                f'{self.rotation_rereference_share!r}'
            )


@dataclass(frozen=True)
class Initialization:
    """A map initialization: the method, the pose and the first map points.

    Scale: monocular scale is arbitrary; it is fixed so that the median depth of the points
    in the reference camera is 1, and ``t`` is scaled by the same factor.

    Attributes:
        method: the method that produced it.
        R: (3, 3) rotation, reference to current camera (``x_cur = R x_ref + t``).
        t: (3,) translation, reference to current camera, map units.
        points: (M, 3) float64 points in the reference camera frame, map units.
        pixels_ref: (M, 2) float32 pixels of the points in the reference image.
        pixels_cur: (M, 2) float32 pixels of the points in the current image.
        reference_stamp_ns: time of the reference frame, integer nanoseconds.
        stamp_ns: time of the current frame, integer nanoseconds.
        frames_since_reference: frames between reference and current.
        probabilities: model name -> probability for this pair.
        parallax_deg: median parallax of the points, degrees.
        selection: the candidates tried at fire time, their scores and why this one won.
        refinement: the bundle adjustment's result (None when refinement is off).
        verification: the checks of the frames after it (empty when verification is off).
        points_on_plane: of ``points``, those placed on the plane of an H map
            (``SelectorConfig.snap_to_plane``; 0 otherwise).
    """

    method: Method
    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    pixels_ref: np.ndarray
    pixels_cur: np.ndarray
    reference_stamp_ns: int
    stamp_ns: int
    frames_since_reference: int
    probabilities: dict[str, float]
    parallax_deg: float
    selection: Selection | None = None
    refinement: Refinement | None = None
    verification: tuple[VerifyStep, ...] = ()
    points_on_plane: int = 0


@dataclass(frozen=True)
class _Candidate:
    """An initialization held back until the next frames confirm it.

    ``rivals`` are the other poses of the same pair that fit it as well (H's two-fold planar
    ambiguity): each is checked on the same frames, those that fail drop out, and of the
    ones left at the end the first leads unless another reprojects clearly better
    (:func:`_verified_choice`).
    """

    initialization: Initialization
    track_ids: np.ndarray  # (M,) sorted tracker ids of the map points
    steps: tuple[VerifyStep, ...] = ()
    rivals: tuple[_Candidate, ...] = ()
    methods: tuple[Method, ...] = ()  # what the fire path tried (the last frame tries again)
    #: the plane of the map's points and the noise that measured it (while rivals hold)
    plane: PlaneNormal | None = None
    noise_px: float = math.nan
    #: per checked frame while rivals hold: the plane's angle to that frame's homography's,
    #: degrees, and the same in units of the two planes' uncertainty
    drift_deg: tuple[float, ...] = ()
    drift_z: tuple[float, ...] = ()

    def mean_rms_px(self) -> float:
        """Mean RMS reprojection error over the frames checked so far, pixels."""
        return float(np.mean([s.rms_px for s in self.steps])) if self.steps else np.inf


def _unit_depth_scale(points: np.ndarray) -> float:
    """The factor that brings the points' median depth to 1 (the published scale; 1 when
    there is no positive depth)."""
    depth = float(np.median(points[:, 2])) if len(points) else 0.0
    return 1.0 / depth if depth > 0 else 1.0


#: Mean disparity, pixels, under which the camera has not moved for any method: the parallax
#: floors (min_parallax_deg, 1 degree: 9 px of flow at the TUM focal length, 4 px at 320x240)
#: are out of reach, so no fire-path run is made (on a still camera a model's yes ran it on
#: every third frame, and the frames said 'rotation').
STILL_DISPARITY_PX = 1.0


#: A view has turned away from its reference (:meth:`Selector._rotated_away`) only when its
#: mean flow is at least this share of the image's shorter side. A slide along repeated
#: tiles loses 30 % of its tracks in place (the forward-backward check) within 3 frames,
#: at 11 px of flow, while its 1-3 cm of baseline still passes for a rotation: it took a new
#: reference every 3 frames and initialized at frame 48 instead of 14. A noisy pan with
#: moving boards (the planar-arc stress set's seed 18) had moved 36 px when it lost as many.
#: A still camera whose boards move and lose their tracks moves less, but has no baseline to
#: lose: it renews its reference as before (without that, still seed 31 of the stress set
#: initialized H on a board at frame 41).
TURNED_AWAY_MIN_FLOW = 0.05

#: Stamps a millisecond short of ``min_seconds_since_reference`` count as reaching it (90
#: frames of a 30 Hz stream whose stamps are rounded to the nanosecond are 3.0 s less 30 ns).
_STAMP_SLACK_S = 1e-3


def _elapsed_ratio(since_ns: int, fired_after_ns: int, frames: float) -> float:
    """This frame's time since the reference over the initializing frame's; ``frames`` (the
    same ratio of frame counts) where the stamps cannot say (not increasing)."""
    if fired_after_ns > 0 and since_ns >= fired_after_ns:
        return since_ns / fired_after_ns
    return frames


def _noted(result: FrameResult, note: str) -> FrameResult:
    """``result`` with ``note`` after its decision's detail (the note alone where there is
    none)."""
    decision = result.decision
    detail = f'{decision.detail}; {note}' if decision.detail else note
    return replace(result, decision=replace(decision, detail=detail))


def _rotation_said(decision: Decision, thresholds: Mapping[str, float]) -> Decision:
    """A rotation by model R, with the detail saying so (the policy decides, the selector
    explains: the decision's own cost stays the models')."""
    vetoed = f', vetoing {", ".join(decision.vetoed)}' if decision.vetoed else ''
    p_r, t_r = decision.probabilities.get('R', 0.0), thresholds.get('R', 0.5)
    said = 'only rotated'
    if decision.mean_disparity < STILL_DISPARITY_PX:  # (R's class is 'no baseline')
        said = 'has hardly moved'
    return replace(
        decision,
        detail=f'model R says the camera {said} (p {p_r:.2f} >= {t_r:.2f}{vetoed}; mean '
        f'disparity {decision.mean_disparity:.1f} px)',
    )


def _still(decision: Decision) -> Decision:
    """A model's yes on a camera that has not moved: low parallax, nothing to try."""
    fired = ', '.join(decision.fired)
    return replace(
        decision,
        reason=Reason.LOW_PARALLAX,
        candidates=(),
        detail=f'{fired} fired, but the camera has hardly moved: mean disparity '
        f'{decision.mean_disparity:.2f} px < {STILL_DISPARITY_PX:g} px',
    )


def _fits_better(one: _Candidate, other: _Candidate) -> bool:
    """``one``'s RMS is under :data:`RIVAL_MAX_RMS_RATIO` of ``other``'s, on average over the
    verification frames and on the last one."""
    ratio = RIVAL_MAX_RMS_RATIO
    return (
        one.mean_rms_px() < ratio * other.mean_rms_px()
        and one.steps[-1].rms_px < ratio * other.steps[-1].rms_px
    )


def _verified_choice(chosen: _Candidate, rivals: Sequence[_Candidate]) -> _Candidate | None:
    """Of poses that all held on every verification frame, the one whose RMS is under
    :data:`RIVAL_MAX_RMS_RATIO` of every other's, on average and on the last frame: ``chosen``
    (the fire path's) or the rival with the lowest mean RMS; ``chosen`` when there is no
    rival, and None when neither fits better by that margin."""
    rival = min(rivals, key=_Candidate.mean_rms_px, default=None)
    if rival is None or not rival.steps or not chosen.steps:
        return chosen
    if _fits_better(rival, chosen):
        return rival
    if all(_fits_better(chosen, other) for other in rivals):
        return chosen
    return None


def _tracked(candidate: _Candidate, tracks: Tracks) -> tuple[np.ndarray, np.ndarray]:
    """Where the candidate's map tracks are in ``tracks`` (index, clipped) and which of them
    are there."""
    ids = candidate.track_ids
    pos = np.minimum(np.searchsorted(tracks.ids, ids), max(len(tracks.ids) - 1, 0))
    tracked = (tracks.ids[pos] == ids) if len(tracks.ids) else np.zeros(len(ids), bool)
    return pos, tracked


def _steady_plane(candidates: Sequence[_Candidate], frames: int) -> tuple[_Candidate, str] | None:
    """The candidate whose plane stays with the last ``frames`` frames' homographies while
    every other's drifts away (:data:`RIVAL_STEADY_Z`, :data:`RIVAL_DRIFT_Z`,
    :data:`RIVAL_MIN_PLANE_ANGLE_DEG`), and a sentence saying so; None when none does so
    clearly, or another fits clearly better by RMS (:func:`_fits_better`)."""
    if frames < 1 or any(len(c.drift_z) < frames or c.plane is None for c in candidates):
        return None
    z = np.array([c.drift_z[-frames:] for c in candidates])
    angle = np.array([c.drift_deg[-frames:] for c in candidates])
    if not np.all(np.isfinite(z)):
        return None
    steady = int(np.argmin(z.mean(axis=1)))
    chosen = candidates[steady]
    others = [c for i, c in enumerate(candidates) if i != steady]
    apart = min(normal_drift_deg(c.plane.normal, chosen.plane.normal[None]) for c in others)
    own, theirs = z[steady].mean(), np.delete(z, steady, axis=0).mean(axis=1).min()
    if (
        apart >= RIVAL_MIN_PLANE_ANGLE_DEG
        and own <= RIVAL_STEADY_Z
        and theirs >= RIVAL_DRIFT_Z
        and np.all(np.delete(angle, steady, axis=0) > angle[steady])
        and not any(_fits_better(c, chosen) for c in others)
    ):
        why = (
            f"its plane stayed with the later frames' homographies ({own:.1f} x its "
            f'uncertainty on average over the last {frames}, {angle[steady].mean():.2f} '
            f"degrees), the rival's drifted ({theirs:.1f} x)"
        )
        return chosen, why
    return None


@dataclass(frozen=True)
class FrameResult:
    """What the selector did with one frame.

    Attributes:
        frame_index: running count of processed frames, from 0.
        stamp_ns: this frame's time, integer nanoseconds.
        reference_stamp_ns: the reference frame's time, integer nanoseconds (None before
            one exists).
        decision: the decision and its reason.
        initialization: set on the frame that initializes, else None.
        new_reference: True when this frame became the reference frame.
        frames_since_reference: frames between the reference and this frame.
        selection: on frames where a model fired, the candidates tried and their scores.
        verification: while a candidate is verified, this frame's check.
        tracks_ref: (N, 2) float32 reference pixels of this frame's tracks, as tracked (not
            undistorted: what an overlay draws on the image); None on skipped frames.
        tracks_cur: (N, 2) float32 their pixels in this frame.
        thresholds: the per-model thresholds the decision used.
        rotation: on frames where a model fired, the rotation test (residual, noise, ratio).
        background: on frames where a winner was chosen and left many tracks out, the
            rotation test of those tracks (``initialize.background_test``).
        fire_path_due_in: frames from this one until the fire path next runs on a model's
            yes or a re-check of R's veto (0: on the next frame that asks; ``recheck.py``);
            None when nothing is scheduled (the re-check off, a candidate under
            verification, initialized in mode ONCE).
    """

    frame_index: int
    stamp_ns: int
    reference_stamp_ns: int | None
    decision: Decision
    initialization: Initialization | None = None
    new_reference: bool = False
    frames_since_reference: int = 0
    selection: Selection | None = None
    verification: VerifyStep | None = None
    tracks_ref: np.ndarray | None = field(default=None, repr=False, compare=False)
    tracks_cur: np.ndarray | None = field(default=None, repr=False, compare=False)
    thresholds: Mapping[str, float] = field(default_factory=dict, compare=False)
    rotation: RotationTest | None = None
    background: RotationTest | None = None
    fire_path_due_in: int | None = None


def decide_pair(
    models: ModelSet,
    thresholds: dict[str, float],
    policy: PolicyConfig,
    ref: np.ndarray,
    cur: np.ndarray,
    width: int,
    height: int,
    camera: Camera | None = None,
) -> Decision:
    """The per-frame decision: model inputs, four model probabilities, policy.

    The inputs are the 23 paper features, plus the extra features (homography residual,
    grid occupancy, ...) only when a model of ``models`` reads them; a model file's referee
    decides for a model near its threshold (:meth:`ModelSet.predict_points`).

    Args:
        models: the four models.
        thresholds: per-model thresholds (see :func:`effective_thresholds`).
        policy: the policy settings.
        ref: (N, 2) reference pixels.
        cur: (N, 2) current pixels.
        width: image width, pixels.
        height: image height, pixels.
        camera: (fx, fy, cx, cy), pixels, for the features that need it (see
            :meth:`ModelSet.input_plan`).
    """
    probs, mean_disparity, referred = models.predict_points(
        ref, cur, width, height, thresholds, camera
    )
    return decide(probs, thresholds, len(ref), mean_disparity, policy, referred)


def _lost_at_once(before: int) -> str:
    """The detail's note when a frame lost most of the tracks the one before it had."""
    return (
        f'; {before} tracks on the frame before, lost at once: the view was blocked or changed, '
        'the image went dark or saturated, or the camera moved too fast to track'
    )


def _fits_better_than_h(selection: Selection | None) -> str:
    """'E better than H (GRIC a against b)' when E or F has a lower GRIC than H among a fire path's
    candidates, whether or not they passed the pose check (the tracks are then no plane);
    '' when H fits best or was not scored."""
    if selection is None:
        return ''
    gric = {s.method: s.gric for s in selection.scores if math.isfinite(s.gric)}
    if Method.H not in gric or len(gric) < 2:
        return ''
    best = min(gric, key=gric.__getitem__)
    if best is Method.H:
        return ''
    return f'{best.value} better than H (GRIC {gric[best]:.0f} against {gric[Method.H]:.0f})'


def _chordal_degrees(apart: float) -> float:
    """The angle between two unit vectors ``apart`` (chordal distance, as E_t), degrees."""
    return float(np.degrees(2 * np.arcsin(min(apart / 2, 1.0))))


def _direction_sigma_deg(refinement: Refinement | None) -> float:
    """How uncertain a seed map's direction of motion is, degrees (inf when unknown)."""
    if refinement is None or not math.isfinite(refinement.translation_sigma_deg):
        return math.inf
    return refinement.translation_sigma_deg


class Selector:
    """Live initialization selector for one camera stream."""

    def __init__(
        self,
        models: ModelSet,
        intrinsics: Intrinsics,
        config: SelectorConfig | None = None,
    ) -> None:
        self.models = models
        self.config = config or SelectorConfig()
        self.intrinsics = intrinsics
        self.thresholds = effective_thresholds(models.thresholds, self.config.policy)
        self.tracker = KltTracker(self.config.tracker, intrinsics.field_mask())
        #: How 16-bit frames become 8-bit on this stream.
        self.bit_depth = BitDepth(self.config.bit_depth)
        self.initialized = False
        self._frame_index = 0
        self._reference_stamp_ns: int | None = None
        self._candidate: _Candidate | None = None
        self._dropped = ''  # why a candidate under verification was dropped, for the next frame
        self._reference_dropped = ''  # why the reference was dropped, for the next frame
        self._frame_tracks: Tracks | None = None
        # when the fire path runs next for want of baseline: see _recheck_rotation
        self._schedule = _FireSchedule(0, self.config.rotation_recheck_frames)

    def set_intrinsics(self, intrinsics: Intrinsics) -> bool:
        """Use new intrinsics from the next frame on (e.g. from CameraInfo).

        Returns:
            True when they describe another camera (size, K or distortion) than the current
            ones: the reference is then dropped and the next frame becomes the new one
            (``initialized`` stays as it is).
        """
        changed = not intrinsics.same_camera(self.intrinsics)
        self.intrinsics = intrinsics
        if changed:
            self._drop_reference('the intrinsics changed')
            self.tracker.region = intrinsics.field_mask()
        return changed

    def update_config(self, config: SelectorConfig) -> None:
        """Use new settings from the next frame on (live parameter changes).

        The thresholds are recomputed; the tracker is rebuilt (dropping the reference) only
        when its own settings changed. Switching to mode continuous once initialized in mode
        once starts over (:meth:`reset`'s reference and state, the bit depth kept): the old
        reference has been tracked past, and its initialization already published. A
        candidate under verification was fired under the old thresholds and policy: when
        those change it is dropped (the next frames fire, or not, under the new ones).
        """
        old = self.config
        if self.initialized and config.mode is not Mode.ONCE:
            self._drop_reference('mode continuous starts over')
            self.initialized = False
        if config.policy != old.policy:
            self._drop_candidate('the thresholds or the decision policy changed')
        self.config = config
        self.thresholds = effective_thresholds(self.models.thresholds, config.policy)
        if config.tracker != old.tracker:
            self._drop_reference('the tracker settings changed')
            self.tracker = KltTracker(config.tracker, self.intrinsics.field_mask())
        if config.bit_depth != self.bit_depth.fixed:
            self.bit_depth = BitDepth(config.bit_depth)

    def reset(self) -> None:
        """Start over: the next frame becomes the reference; the automatic bit depth is reset."""
        self._drop_reference('~/reset')
        self.bit_depth.reset()
        self.initialized = False

    def restart(self) -> None:
        """The stream started over (time jumped back): the next frame becomes the reference.

        Unlike :meth:`reset`, an initialization in mode ONCE is kept (frames stay
        ``already initialized`` until :meth:`reset`), and so is the bit depth.
        """
        self._drop_reference('the stream restarted')

    def _drop_reference(self, why: str) -> None:
        """The next frame becomes the reference (and a candidate is dropped); that frame's
        detail says why."""
        if self.tracker.has_reference:
            self._reference_dropped = why
        self.tracker.clear()
        self._reference_stamp_ns = None
        self._drop_candidate(why)

    def _drop_candidate(self, why: str) -> None:
        """Forget the candidate under verification, if any; the next frame's detail says why."""
        if self._candidate is not None:
            self._candidate = None
            self._dropped = why

    def _new_reference(
        self,
        gray: np.ndarray,
        stamp_ns: int,
        reason: Reason,
        index: int,
        decision: Decision | None = None,
    ) -> FrameResult:
        found = self.tracker.reset(gray)
        self._reference_stamp_ns = stamp_ns
        self._candidate = None
        if decision is None:
            decision = Decision(reason, n_tracks=found, detail=f'{found} features detected')
        return FrameResult(index, stamp_ns, stamp_ns, decision, None, True, 0)

    def process(self, image: np.ndarray, stamp_ns: int) -> FrameResult:
        """Handle one frame (see :meth:`_process`); the result carries its tracks too."""
        self._frame_tracks = None
        result = self._process(image, stamp_ns)
        note = ''
        if self._dropped:
            note = f'the candidate being verified was dropped: {self._dropped}'
        elif self._reference_dropped and result.decision.reason is Reason.NEW_REFERENCE:
            note = f'new reference: {self._reference_dropped}'
        if note:
            result = _noted(result, note)
        self._dropped = self._reference_dropped = ''
        # The tracks this frame was decided on; a new reference's fresh detections otherwise.
        # (``is None``: an empty Tracks is falsy.) ``thresholds`` is replaced, never mutated,
        # by update_config, so the result can share it.
        tracks = self.tracker.tracks() if self._frame_tracks is None else self._frame_tracks
        return replace(
            result, tracks_ref=tracks.ref, tracks_cur=tracks.cur, thresholds=self.thresholds
        )

    def _process(self, image: np.ndarray, stamp_ns: int) -> FrameResult:
        """Handle one frame.

        Args:
            image: (H, W) or (H, W, 3|4) grey, BGR or BGR(A), uint8 or uint16 (16-bit frames
                scaled by :attr:`bit_depth`); its size must match the intrinsics.
            stamp_ns: capture time, integer nanoseconds (any int: negative and repeated
                stamps are carried through unchanged; the node decides what they mean).

        Returns:
            The :class:`FrameResult`; its ``initialization`` is set on the initializing frame.

        Raises:
            ImageConversionError: unusable image (the selector's state is unchanged).
        """
        gray = to_gray(self.bit_depth.scale(np.asarray(image)))
        h, w = gray.shape
        if (w, h) != (self.intrinsics.width, self.intrinsics.height):
            raise ImageConversionError(
                f'image is {w}x{h} but the intrinsics are for '
                f'{self.intrinsics.width}x{self.intrinsics.height}'
            )
        stamp_ns = int(stamp_ns)
        index = self._frame_index
        self._frame_index += 1
        if self.initialized and self.config.mode is Mode.ONCE:
            return FrameResult(index, stamp_ns, self._reference_stamp_ns, Decision(Reason.DONE))
        if not self.tracker.has_reference or self.tracker.image_shape != gray.shape:
            return self._new_reference(gray, stamp_ns, Reason.NEW_REFERENCE, index)

        before = self.tracker.n_tracks
        tracks = self.tracker.track(gray)
        self._frame_tracks = tracks
        since = self.tracker.frames_since_reference
        ref = self.intrinsics.undistort_pixels(tracks.ref)
        cur = self.intrinsics.undistort_pixels(tracks.cur)
        camera = self.intrinsics.pinhole
        decision = decide_pair(
            self.models, self.thresholds, self.config.policy, ref, cur, w, h, camera
        )
        if decision.positive and decision.mean_disparity < STILL_DISPARITY_PX:
            decision = _still(decision)
        elif decision.reason is Reason.ROTATION:
            decision = _rotation_said(decision, self.thresholds)
        if decision.reason is Reason.TOO_FEW_TRACKS:
            if before >= 2 * self.config.policy.min_tracks:
                decision = replace(decision, detail=decision.detail + _lost_at_once(before))
            if self._candidate is not None:
                decision = replace(
                    decision,
                    detail=decision.detail + '; the candidate being verified lost its tracks',
                )
            result = self._new_reference(gray, stamp_ns, Reason.TOO_FEW_TRACKS, index, decision)
            return replace(result, reference_stamp_ns=stamp_ns)

        recheck = self._recheck_rotation(decision, since)
        held = decision.positive and self._rotation_holds(since)
        if self._candidate is not None or (decision.positive and not held) or recheck:
            # geometry is estimated on this frame: from each point measured against the
            # reference, not carried frame to frame (tracking.py)
            tracks = self.tracker.anchored()
            self._frame_tracks = tracks
            cur = self.intrinsics.undistort_pixels(tracks.cur)
        if self._candidate is not None:
            result = self._verify(tracks, ref, cur, decision, index, stamp_ns, since)
        else:
            result = FrameResult(
                index, stamp_ns, self._reference_stamp_ns, decision, None, False, since
            )
            if held:
                result = self._held(result, since)
            elif decision.positive:
                result = self._fire(result, ref, cur, tracks.ids, stamp_ns, since)
            elif recheck:
                result = self._fire(result, ref, cur, tracks.ids, stamp_ns, since, RECHECK_METHODS)
        if result.initialization is not None:
            self.initialized = self.config.mode is Mode.ONCE
            if self.config.mode is Mode.CONTINUOUS:  # re-anchor on the initializing frame
                result = self._reanchor(result, gray, stamp_ns)
        elif self._candidate is None and (aged := self._aged(since, stamp_ns)):
            result = _noted(result, f'{aged}: this frame is the new reference')
            result = self._reanchor(result, gray, stamp_ns)
        elif self._candidate is None and self._rotated_away(result):
            statistic = result.rotation.statistic if result.rotation is not None else math.nan
            result = _noted(
                result,
                f"{self.tracker.n_tracks} of the reference's {self.tracker.reference_tracks} "
                f'tracks are left, the view has moved {result.decision.mean_disparity:.0f} px '
                f'and the camera only rotated as far as the tracks tell (the rotation test '
                f'{statistic:.1f} x the noise): this frame is the new reference (no baseline '
                'lost)',
            )
            result = self._reanchor(result, gray, stamp_ns)
        elif self._candidate is None and self.config.rotation_recheck_frames > 0:
            due = self._schedule.next_run(self.config.rotation_recheck_frames)
            result = replace(result, fire_path_due_in=max(due - since, 0))
        return result

    def _aged(self, since: int, stamp_ns: int) -> str:
        """Why the reference is too old to keep ('' while it is not): at least
        ``max_frames_since_reference`` frames and ``min_seconds_since_reference`` seconds
        (by the stamps; frames alone where they do not rise)."""
        config = self.config
        if since < config.max_frames_since_reference:
            return ''
        reference_ns = self._reference_stamp_ns
        elapsed_s = 0.0 if reference_ns is None else (stamp_ns - reference_ns) * 1e-9
        if elapsed_s > 0.0 and elapsed_s < config.min_seconds_since_reference - _STAMP_SLACK_S:
            return ''
        when = f' ({elapsed_s:.1f} s)' if elapsed_s > 0.0 else ''
        return f'{since} frames{when} since the reference (max_frames_since_reference)'

    def _reanchor(self, result: FrameResult, gray: np.ndarray, stamp_ns: int) -> FrameResult:
        """Make this frame, already decided on, the reference; ``result`` says so."""
        self.tracker.reset(gray)
        self._reference_stamp_ns = stamp_ns
        return replace(result, new_reference=True)

    def _rotated_away(self, result: FrameResult) -> bool:
        """This frame's fire-path run found a rotation at the noise level, and the view has
        turned away from the reference: at most ``rotation_rereference_share`` of its tracks
        are left (see :class:`SelectorConfig`), and the view has moved
        (:data:`TURNED_AWAY_MIN_FLOW`) or the camera has not (:meth:`_camera_still`): tracks
        lost in place (repeated texture, blur) while a short baseline still passes for a
        rotation are not a view turned away."""
        share = self.config.rotation_rereference_share
        test = result.rotation
        shorter_side = min(self.intrinsics.width, self.intrinsics.height)
        return (
            share > 0.0
            and result.decision.reason is Reason.ROTATION
            and test is not None
            and test.statistic <= 0.5 * self.config.policy.min_rotation_residual_sigma
            and self.tracker.n_tracks <= share * self.tracker.reference_tracks
            and (
                result.decision.mean_disparity >= TURNED_AWAY_MIN_FLOW * shorter_side
                or self._camera_still()
            )
        )

    def _camera_still(self) -> bool:
        """Most of this frame's tracks have not moved (under :data:`STILL_DISPARITY_PX`): a
        still camera, whatever objects move in front of it, has no baseline to lose."""
        tracks = self._frame_tracks
        if tracks is None or not len(tracks.ref):
            return False
        flow = np.linalg.norm(tracks.cur - tracks.ref, axis=1)
        return float(np.median(flow)) < STILL_DISPARITY_PX

    def _recheck_rotation(self, decision: Decision, since: int) -> bool:
        """Is this a frame on which the rotation test re-checks model R's veto?

        The first re-check comes ``rotation_recheck_frames`` frames after the reference;
        each fire-path run schedules the next (:func:`recheck.frames_to_recheck`: when the
        gate that stopped it is predicted to pass, at most that many frames on). Called on
        every tracked frame: a frame count not above the schedule's own means a new
        reference, which starts the cadence over.
        """
        every = self.config.rotation_recheck_frames
        if since <= self._schedule.set_at:  # (also while off: it may be switched on later)
            self._schedule = _FireSchedule(0, every)
        if every <= 0:
            return False
        return decision.reason is Reason.ROTATION and since >= self._schedule.next_run(every)

    def _rotation_holds(self, since: int) -> bool:
        """Does the last fire-path run's rotation test still stand for a model that fired on
        this frame? It does until the frame it scheduled (the flow a rotation leaves grows
        with the baseline, and the frames before that frame are predicted to fall short too):
        the fire path, and its points re-measured against the reference, are skipped."""
        schedule = self._schedule
        return (
            self.config.rotation_recheck_frames > 0
            and self._candidate is None
            and schedule.rotation is not None
            and schedule.set_at < since < schedule.due
        )

    def _held(self, result: FrameResult, since: int) -> FrameResult:
        """A model fired on a frame before the one the last rotation test scheduled."""
        schedule = self._schedule
        statistic = math.nan if schedule.rotation is None else schedule.rotation.statistic
        decision = result.decision
        fired = '/'.join(m.value for m in decision.candidates)
        detail = (
            f'{fired} fired, but the rotation test {since - schedule.set_at} frame(s) ago found '
            f'{schedule.stopped_by} {statistic:.1f} x the noise; the fire path runs '
            f'again in {schedule.due - since} frame(s)'
        )
        return replace(result, decision=replace(decision, reason=Reason.ROTATION, detail=detail))

    def _fire(
        self,
        result: FrameResult,
        ref: np.ndarray,
        cur: np.ndarray,
        ids: np.ndarray,
        stamp_ns: int,
        since: int,
        methods: tuple[Method, ...] | None = None,
    ) -> FrameResult:
        """A model fired (or R's veto is re-checked with ``methods``): run the fire path
        (initialize.py); hold the seed map for verification."""
        decision = result.decision
        recheck = methods is not None
        if methods is None:
            methods = fire_methods(decision, self.thresholds, self.config.policy)
        fire = initialize_pair(ref, cur, self.intrinsics.K, methods, self._fire_config())
        result = replace(result, rotation=fire.rotation, background=fire.background)
        schedule = self._schedule_next(fire, since, recheck, Method.H in methods)
        if fire.reason is Reason.ROTATION:  # (after a re-check: R stands)
            fired = '/'.join(m.value for m in decision.candidates)
            why = f'{fired} fired, but '
            if recheck:
                why = 'R fired; the rotation test re-checked it: '
            return replace(
                result,
                decision=replace(
                    decision, reason=Reason.ROTATION, detail=why + fire.detail + schedule
                ),
            )
        context = ''
        if recheck:  # the test found parallax: the pair goes on as if E and H had fired
            statistic = fire.rotation.statistic if fire.rotation is not None else math.nan
            context = (
                f'R fired, but the flow a rotation leaves is {statistic:.1f} x the noise, so '
                + '/'.join(e.method.value for e in fire.estimates)
                + (' was' if len(fire.estimates) == 1 else ' were')
                + ' tried; '
            )
        result = replace(result, selection=fire.selection)
        if fire.reason is not Reason.INITIALIZED or fire.seed is None:
            return replace(
                result,
                decision=replace(
                    decision, reason=fire.reason, detail=context + fire.detail + schedule
                ),
            )
        on_edges = self._on_edges(fire.seed)
        if on_edges:
            return replace(
                result,
                decision=replace(decision, reason=Reason.POSE_FAILED, detail=context + on_edges),
            )
        init = self._initialization(fire.seed, ref, cur, decision, stamp_ns, since, fire.selection)
        detail = f'{context}{init.method.value}: {fire.detail}'
        if self.config.verify.frames > 0:
            noise = fire.rotation.noise_px if fire.rotation is not None else math.nan
            rivals = tuple(
                self._held_candidate(
                    self._initialization(
                        seed, ref, cur, decision, stamp_ns, since, fire.selection
                    ),
                    np.asarray(ids)[seed.indices],
                    methods,
                    rivalled=True,
                    tracking_noise_px=noise,
                )
                for seed in fire.alternatives
            )
            self._candidate = replace(
                self._held_candidate(
                    init,
                    np.asarray(ids)[fire.seed.indices],
                    methods,
                    rivalled=bool(fire.alternatives),
                    tracking_noise_px=noise,
                ),
                rivals=rivals,
            )
            return replace(
                result,
                decision=replace(
                    decision,
                    reason=Reason.VERIFYING,
                    detail=f'{detail}; verifying on the next {self.config.verify.frames} frames',
                ),
            )
        return replace(
            result,
            initialization=self._published(init),
            decision=replace(decision, reason=Reason.INITIALIZED, detail=detail),
        )

    def _on_edges(self, seed: SeedMap) -> str:
        """Why ``seed`` is refused for resting on points along straight edges of the
        reference frame (``PolicyConfig.max_edge_point_share``; module ``corners``), or ''."""
        limit = self.config.policy.max_edge_point_share
        image = self.tracker.reference_image
        tracks = self._frame_tracks
        if limit >= 1.0 or image is None or tracks is None or not len(seed.indices):
            return ''
        isotropy = structure_isotropy(
            image, tracks.ref[seed.indices], self.config.tracker.block_size
        )
        on_edges = int(np.count_nonzero(isotropy < EDGE_ISOTROPY))
        if on_edges <= limit * len(isotropy):
            return ''
        return (
            f'{seed.method.value} failed ({on_edges} of its {len(isotropy)} points lie on '
            f'straight edges of the reference frame, more than {limit:.0%} '
            '(max_edge_point_share): a track there slides along its edge, and the map would '
            'rest on such tracks; too little texture)'
        )

    def _held_candidate(
        self,
        init: Initialization,
        track_ids: np.ndarray,
        methods: tuple[Method, ...],
        *,
        rivalled: bool,
        tracking_noise_px: float = math.nan,
    ) -> _Candidate:
        """A candidate for verification; where rival decompositions come with it
        (``rivalled``), with its map's plane, to follow against the later frames'
        homographies. The plane's uncertainty follows ``tracking_noise_px`` (the rotation
        test's measure of the same tracks), else the noise GRIC used, which is ORB-SLAM's
        1 px when only H was estimated."""
        if not rivalled:
            return _Candidate(init, track_ids, methods=methods)
        noise = tracking_noise_px
        if not (math.isfinite(noise) and noise > 0.0) and init.selection is not None:
            noise = init.selection.sigma_px
        plane = plane_normal(init.points, init.R, init.t, noise, self.intrinsics.fx)
        return _Candidate(init, track_ids, methods=methods, plane=plane, noise_px=noise)

    def _schedule_next(self, fire: FireResult, since: int, recheck: bool, h_tried: bool) -> str:
        """Schedule the next fire-path run for want of baseline after this one (a re-check
        of R's veto, or a model's yes that the rotation test stopped); the log's words for it
        ('' when there is nothing to say). ``h_tried``: H was among the run's methods."""
        every = self.config.rotation_recheck_frames
        if every <= 0 or fire.reason is Reason.INITIALIZED:
            return ''
        if not recheck and fire.reason is not Reason.ROTATION:
            # a model's yes that got past the rotation test: the next frame tries again
            self._schedule = replace(self._schedule, rotation=None)
            return ''
        gap = evidence_gap(fire, self.config.policy, h_tried)
        frames = frames_to_recheck(since, every, gap)
        if fire.reason is not Reason.ROTATION:
            self._schedule = _FireSchedule(since, since + frames)
        elif fire.background is not None:  # the winner's left-out tracks were a rotation's
            self._schedule = _FireSchedule(
                since, since + frames, fire.background, 'the tracks the winner left out at'
            )
        else:
            self._schedule = _FireSchedule(
                since, since + frames, fire.rotation, 'the flow a rotation leaves'
            )
        # (sooner than the cadence because of the prediction, not the cadence's own frame)
        predicted = gap.gate and frames < cadence_frames(since, every)
        when = f', when {gap.gate} should pass' if predicted else ''
        return f'; the fire path runs again in {frames} frame(s){when}'

    def _published(self, init: Initialization) -> Initialization:
        """The initialization as published: an H map's points on their plane
        (``config.snap_to_plane``), at a median depth of 1."""
        refinement = init.refinement
        if not self.config.snap_to_plane or init.method is not Method.H or refinement is None:
            return init  # (without the bundle adjustment there is no noise to judge by)
        K = self.intrinsics.K
        sigma = depth_sigma(
            init.points, init.R, init.t, refinement.rms_after_px, 0.5 * (K[0, 0] + K[1, 1])
        )
        fit = snap_to_plane(init.points, sigma)
        scale = _unit_depth_scale(fit.points)  # the median depth stays 1
        return replace(
            init,
            points=fit.points * scale,
            t=init.t * scale,
            points_on_plane=int(fit.on_plane.sum()),
        )

    def _fire_config(self) -> FireConfig:
        return FireConfig(
            policy=self.config.policy,
            ransac_threshold_px=self.config.ransac_threshold_px,
            refine=self.config.refine,
            radial_terms=radial_terms_for(self.intrinsics.has_distortion),
        )

    def _verify(
        self,
        tracks: Tracks,
        ref: np.ndarray,
        cur: np.ndarray,
        decision: Decision,
        index: int,
        stamp_ns: int,
        since: int,
    ) -> FrameResult:
        """Check the held-back candidate on this frame; publish it once enough frames agree."""
        assert self._candidate is not None
        # Every rival pose of the pair is checked on this frame; the first that holds leads.
        everyone = (self._candidate, *self._candidate.rivals)
        normals = (
            self._homography_normals(self._candidate, tracks, cur) if len(everyone) > 1 else None
        )
        checked = [
            (c, step, self._drifted(c, step, normals))
            for c in everyone
            for step in [self._check(c, tracks, cur, stamp_ns)]
        ]
        holding = [(c, s, d) for c, s, d in checked if s.ok]
        candidate, step, drift = holding[0] if holding else checked[0]
        rivals = tuple(replace(d, steps=(*c.steps, s), rivals=()) for c, s, d in holding[1:])
        candidate = replace(drift, rivals=rivals)
        init = candidate.initialization
        base = FrameResult(
            index,
            stamp_ns,
            self._reference_stamp_ns,
            decision,
            None,
            False,
            since,
            verification=step,
        )
        done = len(candidate.steps) + 1
        wanted = self.config.verify.frames
        if not step.ok:
            self._candidate = None
            return replace(
                base,
                decision=replace(
                    decision,
                    reason=Reason.VERIFICATION_FAILED,
                    detail=f'{init.method.value} candidate of frame {init.frames_since_reference} '
                    f'failed on frame {done} of {wanted}: {step.detail}',
                ),
            )
        steps = (*candidate.steps, step)
        best = replace(candidate, steps=steps)
        most = wanted * AMBIGUOUS_VERIFY_FACTOR
        settled, steady = None, None
        if done >= wanted and rivals:
            steady = _steady_plane((best, *rivals), wanted)
        if steady is not None:
            settled = steady[0]
        elif done >= (most if rivals else wanted):
            settled = _verified_choice(best, rivals)
        if settled is None and done < most:
            self._candidate = best
            if done < wanted:
                note = f'frame {done} of {wanted} ok'
                tail = f'; {len(rivals)} rival decomposition(s) hold too' if rivals else ''
            else:
                note = f'frame {done} ok'
                tail = (
                    f'; {len(rivals)} rival decomposition(s) hold too: verifying on to frame '
                    f'{most}, where the longer baseline tells them apart'
                )
            return replace(
                base,
                decision=replace(
                    decision,
                    reason=Reason.VERIFYING,
                    detail=f'{init.method.value} candidate: {note}, {step.detail}{tail}',
                ),
            )
        self._candidate = None
        undecided = settled is None
        best = best if settled is None else settled
        init, steps = best.initialization, best.steps
        again, contradiction = self._on_last_frame(
            best, ref, cur, decision, stamp_ns, since, steps[-1]
        )
        if contradiction:
            return replace(
                base,
                decision=replace(
                    decision,
                    reason=Reason.VERIFICATION_FAILED,
                    detail=f'{init.method.value} candidate of frame '
                    f'{init.frames_since_reference} held on {done} frames, but {contradiction}',
                ),
            )
        detail = f'{init.method.value} verified on {len(steps)} frames (last: {step.detail})'
        if steady is not None:
            detail += f'; {len(rivals)} rival decomposition(s) held as well, this one chosen: '
            detail += steady[1]
        if undecided:
            detail += (
                f'; {len(rivals)} rival decomposition(s) held as well, none fitting '
                f"{1 - RIVAL_MAX_RMS_RATIO:.0%} better: the fire path's choice"
            )
        if again is not None and again.method is not init.method:
            detail += (
                f'; published as {again.method.value} from this frame: its '
                f'{again.method.value} seed map, from the longer baseline, agrees with the '
                f'verified {init.method.value} map'
            )
        init = again or init
        verified = self._published(replace(init, verification=steps))
        return replace(
            base,
            initialization=verified,
            decision=replace(
                decision,
                reason=Reason.INITIALIZED,
                probabilities=dict(init.probabilities),
                detail=detail,
            ),
        )

    def _on_last_frame(
        self,
        candidate: _Candidate,
        ref: np.ndarray,
        cur: np.ndarray,
        decision: Decision,
        stamp_ns: int,
        since: int,
        step: VerifyStep,
    ) -> tuple[Initialization | None, str]:
        """The verified map again, from the last verification frame's longer baseline; and
        why the candidate must be refused after all ('' when it stands).

        The fire path runs once more on the reference and this frame, with the methods it
        tried at fire time (every method for an H candidate: see below). A seed map of the
        same method whose pose agrees with this frame's PnP pose against the verified map
        (rotation within
        :data:`LAST_FRAME_MAX_ROTATION_DEG`, translation direction within
        :data:`LAST_FRAME_MAX_E_T`) replaces the candidate: the same geometry, confirmed,
        seen with a few frames more baseline. Within :data:`LAST_FRAME_MORE_CERTAIN_MAX_E_T`
        where its direction of motion is the more certain. An H the fire path refused only as
        ambiguous (its two decompositions too close to call) is judged the same way, at the
        strict bounds: agreeing with the verified map's PnP pose tells which decomposition it
        is. None when there is none.

        An E or F candidate whose last frame's own E or F seed map is the more certain and
        lies further than :data:`LAST_FRAME_MORE_CERTAIN_MAX_E_T` from the PnP pose is
        refused: the two cannot both be the motion, and the map from the longer baseline is
        the better evidence (a desk with two moving boards: F verified 16 degrees off from 3
        frames of baseline, E from 8 frames 0.3 degrees off and 18 degrees from the PnP pose).

        An H candidate is checked against E and F too. At a baseline of a centimetre or
        two every track of a scene with depth fits some homography, and that H's
        decomposition says nothing about the motion; PnP against its map stays consistent
        for a few frames. So when this frame's rotation test reaches E and F's floor and the
        fire path chooses E or F: one whose direction lies more than
        :data:`LAST_FRAME_MORE_CERTAIN_MAX_E_T` from the PnP pose refuses the candidate (a
        desk 1.5 cm into a forward motion: H 48 degrees off, verified on 5 frames; E from
        the last frame's 4.4 cm: 4 degrees), and one that agrees with it by the bounds above
        replaces it, as a seed map of H's own would (a camera-effects desk: H 25 degrees
        off at 2.3 cm, F from 5.2 cm 3 degrees).
        """
        init = candidate.initialization
        config = self._fire_config()
        h_candidate = init.method is Method.H
        methods = tuple(Method) if h_candidate else candidate.methods
        fire = initialize_pair(ref, cur, self.intrinsics.K, methods, config)
        t_pnp = step.t / max(float(np.linalg.norm(step.t)), 1e-12)
        threshold = self.config.policy.min_rotation_residual_sigma
        if h_candidate and fire.rotation is not None and fire.rotation.statistic >= threshold:
            on_frame = (
                f'on frame {len(candidate.steps)} the rotation test reads '
                f'{fire.rotation.statistic:.1f} x the noise and '
            )
            if fire.seed is not None and fire.seed.method is not Method.H:
                apart = float(np.linalg.norm(fire.seed.t - t_pnp))
                if apart > LAST_FRAME_MORE_CERTAIN_MAX_E_T:
                    return None, (
                        f'{on_frame}{fire.seed.method.value} moves '
                        f'{_chordal_degrees(apart):.0f} degrees from '
                        'its direction: the H fitted a scene with depth'
                    )
            elif fire.seed is None and (deeper := _fits_better_than_h(fire.selection)):
                return None, (
                    f"{on_frame}the tracks fit {deeper}: not a plane, so the H's "
                    'decomposition says nothing about the motion'
                )
        verified_sigma = _direction_sigma_deg(init.refinement)
        if fire.reason is Reason.INITIALIZED and fire.seed is not None:
            best = fire.seed  # an E or F candidate: E or F, more certain and far away, refuses it
            if (
                not h_candidate
                and best.method is not Method.H
                and _direction_sigma_deg(best.refinement) < verified_sigma
                and (apart := float(np.linalg.norm(best.t - t_pnp)))
                > LAST_FRAME_MORE_CERTAIN_MAX_E_T
            ):
                return None, (
                    f'on frame {len(candidate.steps)} {best.method.value}, from the longer '
                    f'baseline and the more certain, moves {_chordal_degrees(apart):.0f} '
                    'degrees from its direction: the two cannot both be the motion'
                )
            seeds = [(seed, False) for seed in (best, *fire.alternatives)]
        else:  # an H refused only as ambiguous: the verified map tells its decomposition
            seeds = [
                (seed, True)
                for estimate in fire.estimates
                if estimate.ambiguous and estimate.method is init.method
                for seed in [usable_seed(estimate, ref, cur, self.intrinsics.K, config)]
                if seed is not None
            ]
        for seed, ambiguous in seeds:
            looser = not ambiguous and _direction_sigma_deg(seed.refinement) < verified_sigma
            agrees = (
                (seed.method is init.method or h_candidate)
                and rotation_angle_deg(seed.R.T @ step.R) <= LAST_FRAME_MAX_ROTATION_DEG
                and float(np.linalg.norm(seed.t - t_pnp))
                <= (LAST_FRAME_MORE_CERTAIN_MAX_E_T if looser else LAST_FRAME_MAX_E_T)
            )
            if agrees:
                again = self._initialization(
                    seed, ref, cur, decision, stamp_ns, since, fire.selection
                )
                return again, ''
        return None, ''

    def _drifted(
        self, candidate: _Candidate, step: VerifyStep, normals: np.ndarray | None
    ) -> _Candidate:
        """The candidate with this frame's angle between its map's plane and the nearest of
        this frame's homography's, in degrees and in units of their uncertainty (NaN
        without them); unchanged when there are no rivals (``normals`` None)."""
        if normals is None:
            return candidate
        plane, angle, z = candidate.plane, math.nan, math.nan
        if plane is not None and step.ok:
            angle = normal_drift_deg(plane.normal, normals)
            init = candidate.initialization
            here = plane_normal(
                init.points, step.R, step.t, candidate.noise_px, self.intrinsics.fx
            )
            if here is not None:
                z = angle / math.hypot(plane.sigma_deg, here.sigma_deg)
        return replace(
            candidate,
            drift_deg=(*candidate.drift_deg, angle),
            drift_z=(*candidate.drift_z, z),
        )

    def _homography_normals(
        self, candidate: _Candidate, tracks: Tracks, cur: np.ndarray
    ) -> np.ndarray:
        """The plane normals of the homography from the reference to this frame, fitted to
        the candidate's map tracks (:func:`plane.homography_normals`)."""
        pos, tracked = _tracked(candidate, tracks)
        return homography_normals(
            np.asarray(candidate.initialization.pixels_ref, np.float64)[tracked],
            np.asarray(cur)[pos[tracked]],
            self.intrinsics.K,
            self.config.ransac_threshold_px,
        )

    def _check(
        self, candidate: _Candidate, tracks: Tracks, cur: np.ndarray, stamp_ns: int
    ) -> VerifyStep:
        """PnP of one candidate's map points against their tracks in this frame."""
        ids = candidate.track_ids
        pos, tracked = _tracked(candidate, tracks)
        pixels = np.zeros((len(ids), 2))
        pixels[tracked] = cur[pos[tracked]]
        init = candidate.initialization
        return check_frame(
            init.points,
            pixels,
            tracked,
            self.intrinsics.K,
            self.config.verify,
            (self.intrinsics.width, self.intrinsics.height),
            float(np.linalg.norm(init.t)),
            # at a steady speed, the distance ratio is the elapsed times' (never what a wrong
            # map's pose makes of it; frames dropped before the fire would inflate a count)
            _elapsed_ratio(
                stamp_ns - init.reference_stamp_ns,
                init.stamp_ns - init.reference_stamp_ns,
                self.tracker.frames_since_reference / max(init.frames_since_reference, 1),
            ),
        )

    def _initialization(
        self,
        seed: SeedMap,
        ref: np.ndarray,
        cur: np.ndarray,
        decision: Decision,
        stamp_ns: int,
        since: int,
        selection: Selection | None,
    ) -> Initialization:
        """The published record of a seed map, scaled to a median point depth of 1."""
        scale = _unit_depth_scale(seed.points)
        return Initialization(
            method=seed.method,
            R=seed.R,
            t=seed.t * scale,
            points=seed.points * scale,
            pixels_ref=np.asarray(ref, np.float32)[seed.indices],
            pixels_cur=np.asarray(cur, np.float32)[seed.indices],
            reference_stamp_ns=self._reference_stamp_ns,
            stamp_ns=int(stamp_ns),
            frames_since_reference=since,
            probabilities=dict(decision.probabilities),
            parallax_deg=seed.parallax_deg,
            selection=selection,
            refinement=seed.refinement,
        )
