"""The live pipeline, free of ROS: frames in, decisions and (once) an initialization out.

One :class:`Selector` serves one camera stream. For each frame it tracks against the
reference frame, computes the 23 features, scores the four models, applies the policy and,
when a model fires, recovers the pose with that method and checks it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Literal

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError, ImageConversionError
from initsel_ros.features import raw_features
from initsel_ros.geometry import Method, PoseEstimate, estimate_pose
from initsel_ros.models import ModelSet
from initsel_ros.policy import (
    Decision,
    PolicyConfig,
    Reason,
    check_pose,
    decide,
    effective_thresholds,
)
from initsel_ros.tracking import KltTracker, TrackerConfig

log = logging.getLogger(__name__)

Mode = Literal['once', 'continuous']


@dataclass(frozen=True)
class SelectorConfig:
    """Settings of the live pipeline.

    Attributes:
        tracker: feature detection and tracking.
        policy: thresholds, R veto and pose checks.
        mode: 'once' stops after the first initialization until :meth:`Selector.reset`;
            'continuous' re-anchors on the initializing frame and keeps going.
        max_frames_since_reference: a frame this many frames after the reference becomes the
            new reference when nothing initialized.
        ransac_threshold_px: RANSAC inlier threshold of the pose estimators, pixels.
    """

    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    mode: Mode = 'once'
    max_frames_since_reference: int = 90
    ransac_threshold_px: float = 1.0

    def __post_init__(self) -> None:
        if self.mode not in ('once', 'continuous'):
            raise ConfigError(f"mode must be 'once' or 'continuous', got {self.mode!r}")
        if self.max_frames_since_reference < 1:
            raise ConfigError('max_frames_since_reference must be at least 1')


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
    """

    frame_index: int
    stamp_ns: int
    reference_stamp_ns: int | None
    decision: Decision
    initialization: Initialization | None = None
    new_reference: bool = False
    frames_since_reference: int = 0


def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image from grey uint8/uint16 or (H, W, 3|4) BGR(A) uint8.

    Raises:
        ImageConversionError: for any other shape or type, or an empty image.
    """
    img = np.asarray(image)
    if img.size == 0 or img.ndim not in (2, 3):
        raise ImageConversionError(f'expected a non-empty 2-D or 3-D image, got {img.shape}')
    if img.ndim == 3:
        if img.dtype != np.uint8 or img.shape[2] not in (1, 3, 4):
            raise ImageConversionError(
                f'colour images must be (H, W, 3 or 4) uint8, got {img.shape} {img.dtype}'
            )
        if img.shape[2] == 1:
            img = img[:, :, 0]
        else:
            code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
            return cv2.cvtColor(img, code)
    if img.dtype == np.uint16:
        return (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise ImageConversionError(f'grey images must be uint8 or uint16, got {img.dtype}')
    return np.ascontiguousarray(img)


def decide_pair(
    models: ModelSet,
    thresholds: dict[str, float],
    policy: PolicyConfig,
    ref: np.ndarray,
    cur: np.ndarray,
    width: int,
    height: int,
) -> Decision:
    """The per-frame decision: model inputs, four model probabilities, policy.

    The inputs are the 23 paper features, plus the extra features (homography residual,
    grid occupancy, ...) only when a model of ``models`` reads them.

    Args:
        models: the four models.
        thresholds: per-model thresholds (see :func:`effective_thresholds`).
        policy: the policy settings.
        ref: (N, 2) reference pixels.
        cur: (N, 2) current pixels.
        width: image width, pixels.
        height: image height, pixels.
    """
    raw = raw_features(ref, cur)
    probabilities = models.predict_proba(models.input_vector(ref, cur, width, height, raw))
    return decide(probabilities, thresholds, len(ref), float(raw[1]), policy)


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
        self.tracker = KltTracker(self.config.tracker)
        self.initialized = False
        self._frame_index = 0
        self._reference_stamp_ns: int | None = None

    def set_intrinsics(self, intrinsics: Intrinsics) -> None:
        """Use new intrinsics from the next frame on (e.g. from CameraInfo)."""
        self.intrinsics = intrinsics

    def reset(self) -> None:
        """Start over: the next frame becomes the reference."""
        self.tracker.clear()
        self.initialized = False
        self._reference_stamp_ns = None

    def _new_reference(self, gray: np.ndarray, stamp_ns: int, reason: Reason, index: int,
                       decision: Decision | None = None) -> FrameResult:
        found = self.tracker.reset(gray)
        self._reference_stamp_ns = stamp_ns
        if decision is None:
            decision = Decision(reason, n_tracks=found, detail=f'{found} features detected')
        return FrameResult(index, stamp_ns, stamp_ns, decision, None, True, 0)

    def _undistort(self, pts: np.ndarray) -> np.ndarray:
        if not self.intrinsics.has_distortion or len(pts) == 0:
            return pts
        K = self.intrinsics.K
        out = cv2.undistortPoints(
            pts.reshape(-1, 1, 2).astype(np.float32), K,
            np.asarray(self.intrinsics.distortion, dtype=np.float64), P=K,
        )
        return out.reshape(-1, 2)

    def process(self, image: np.ndarray, stamp_ns: int) -> FrameResult:
        """Handle one frame.

        Args:
            image: (H, W) uint8/uint16 grey or (H, W, 3|4) uint8 BGR(A); its size must match
                the intrinsics.
            stamp_ns: capture time, integer nanoseconds (any int: negative and repeated
                stamps are carried through unchanged; the node decides what they mean).

        Returns:
            The :class:`FrameResult`; its ``initialization`` is set on the initializing frame.

        Raises:
            ImageConversionError: unusable image (the selector's state is unchanged).
        """
        gray = to_gray(image)
        h, w = gray.shape
        if (w, h) != (self.intrinsics.width, self.intrinsics.height):
            raise ImageConversionError(
                f'image is {w}x{h} but the intrinsics are for '
                f'{self.intrinsics.width}x{self.intrinsics.height}'
            )
        stamp_ns = int(stamp_ns)
        index = self._frame_index
        self._frame_index += 1
        if self.initialized and self.config.mode == 'once':
            return FrameResult(index, stamp_ns, self._reference_stamp_ns, Decision(Reason.DONE))
        if not self.tracker.has_reference or self.tracker.image_shape != gray.shape:
            return self._new_reference(gray, stamp_ns, Reason.NEW_REFERENCE, index)

        tracks = self.tracker.track(gray)
        since = self.tracker.frames_since_reference
        ref, cur = self._undistort(tracks.ref), self._undistort(tracks.cur)
        decision = decide_pair(
            self.models, self.thresholds, self.config.policy, ref, cur, w, h
        )
        if decision.reason is Reason.TOO_FEW_TRACKS:
            result = self._new_reference(gray, stamp_ns, Reason.TOO_FEW_TRACKS, index, decision)
            return replace(result, reference_stamp_ns=stamp_ns)

        init = None
        if decision.positive:
            decision, init = self._try_candidates(decision, ref, cur, stamp_ns, since)
        result = FrameResult(index, stamp_ns, self._reference_stamp_ns, decision, init, False,
                             since)
        if init is not None:
            self.initialized = self.config.mode == 'once'
            if self.config.mode == 'continuous':  # re-anchor on the initializing frame
                self.tracker.reset(gray)
                self._reference_stamp_ns = stamp_ns
                result = replace(result, new_reference=True)
        elif since >= self.config.max_frames_since_reference:
            self.tracker.reset(gray)
            self._reference_stamp_ns = stamp_ns
            result = replace(result, new_reference=True)
        return result

    def _try_candidates(
        self, decision: Decision, ref: np.ndarray, cur: np.ndarray, stamp_ns: int, since: int
    ) -> tuple[Decision, Initialization | None]:
        failures = []
        first_failure: Reason | None = None
        for method in decision.candidates:
            estimate = estimate_pose(
                method, ref, cur, self.intrinsics.K,
                ransac_threshold_px=self.config.ransac_threshold_px,
            )
            problem = check_pose(estimate, self.config.policy)
            if problem is None:
                init = self._initialization(estimate, ref, cur, decision, stamp_ns, since)
                return replace(decision, reason=Reason.INITIALIZED, detail=method.value), init
            first_failure = first_failure or problem
            failures.append(
                f'{method.value}: {estimate.reason or problem.value} '
                f'({estimate.n_points} points, parallax {estimate.parallax_deg:.2f} deg)'
            )
        assert first_failure is not None
        return replace(decision, reason=first_failure, detail='; '.join(failures)), None

    def _initialization(
        self, estimate: PoseEstimate, ref: np.ndarray, cur: np.ndarray,
        decision: Decision, stamp_ns: int, since: int,
    ) -> Initialization:
        depth = float(np.median(estimate.points[:, 2]))
        scale = 1.0 / depth if depth > 0 else 1.0
        return Initialization(
            method=estimate.method,
            R=estimate.R,
            t=estimate.t * scale,
            points=estimate.points * scale,
            pixels_ref=np.asarray(ref, np.float32)[estimate.indices],
            pixels_cur=np.asarray(cur, np.float32)[estimate.indices],
            reference_stamp_ns=self._reference_stamp_ns,
            stamp_ns=int(stamp_ns),
            frames_since_reference=since,
            probabilities=dict(decision.probabilities),
            parallax_deg=estimate.parallax_deg,
        )
