"""The per-frame path from a ``sensor_msgs/Image`` for ``initsel bench``: what one frame costs.

Image message -> numpy -> :meth:`Selector.process`, as the node's worker runs it, with its
parts (conversion, grey conversion, tracking, the debug overlay) timed on the same frames.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from initsel_ros.benchmarks.common import Timing, time_calls
from initsel_ros.names import Mode
from initsel_ros.overlay import draw_frame_overlay
from initsel_ros.policy import Reason
from initsel_ros.ros import conversions as conv
from initsel_ros.selector import Selector, SelectorConfig, to_gray
from initsel_ros.timestamps import seconds_to_ns
from initsel_ros.tracking import KltTracker, Photometric


@dataclass(frozen=True)
class FrameMessages:
    """Image messages and their stamps to replay through the per-frame path."""

    messages: list[Any]
    stamps: np.ndarray


def image_messages(seq: Any, n: int, encoding: str = 'rgb8') -> FrameMessages:
    """The first ``n`` frames as ``sensor_msgs/Image`` (rgb8 as a camera driver sends)."""
    msgs = []
    stamps = seq.stamps[:n]
    for i in range(min(n, len(seq))):
        image = seq.image(i)
        if encoding == 'rgb8':
            image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        msgs.append(
            conv.numpy_to_image(image, encoding, stamp=conv.seconds_to_stamp(float(stamps[i])))
        )
    return FrameMessages(msgs, np.asarray(stamps, dtype=np.float64))


@dataclass(frozen=True)
class FramePathResult:
    """Per-frame path timings and what the selector said.

    Attributes:
        total: every frame.
        decision_only: frames where no pose was estimated (no model fired, or a new
            reference): conversion, tracking, features, decision.
        with_pose: frames where a model fired and the pose was estimated and checked.
        floor: the same frames tracked by the selector's KltTracker with its photometric
            compensation off, from the same references, timed right after each frame (the
            frames of ``decision_only``).
        parts: conversion, grey conversion and tracking timed alone on the same frames.
        reasons: status reason -> frames.
    """

    total: Timing
    decision_only: Timing
    with_pose: Timing
    floor: Timing
    parts: list[Timing]
    reasons: dict[str, int]


def time_frame_path(
    models: Any, intrinsics: Any, frames: FrameMessages, passes: int = 2
) -> FramePathResult:
    """Image message -> numpy -> Selector.process (tracking, features, decision, pose when it
    fires), in continuous mode, over ``passes`` passes of the frames.

    The parts are timed on the same frames: conversion, conversion to grey, tracking, and the
    debug overlay (timed apart, after each decision: it is not in the per-frame figures).
    """
    pose_reasons = {
        Reason.INITIALIZED,
        Reason.POSE_FAILED,
        Reason.TOO_FEW_POINTS,
        Reason.LOW_PARALLAX,
    }
    posed = []

    selector = Selector(models, intrinsics, SelectorConfig(mode=Mode.CONTINUOUS))
    plain = KltTracker(replace(selector.config.tracker, photometric=Photometric.NONE))
    floor_samples: list[float] = []
    n = len(frames.messages)
    period = float(np.median(np.diff(frames.stamps))) if n > 1 else 1 / 30
    reasons: dict[str, int] = {}
    samples: list[float] = []
    overlay_samples: list[float] = []
    clock = time.perf_counter
    for k in range(passes * n):
        msg = frames.messages[k % n]
        if k % n == 0:
            selector.reset()  # the sequence starts over: a new reference, as after a bag loop
        stamp_ns = seconds_to_ns(float(frames.stamps[0]) + k * period)
        t0 = clock()
        image = conv.image_to_cv(msg)
        result = selector.process(image, stamp_ns)
        samples.append(clock() - t0)
        t0 = clock()  # the node draws this only while ~/debug_image has subscribers
        draw_frame_overlay(image, result)
        overlay_samples.append(clock() - t0)
        gray = to_gray(image)
        t0 = clock()  # the floor: the same frame, plain KLT from the selector's reference
        if result.new_reference or not plain.has_reference:
            plain.reset(gray)
        else:
            plain.track(gray)
        floor_samples.append(clock() - t0)
        posed.append(result.selection is not None or result.decision.reason in pose_reasons)
        reason = result.decision.reason.value
        reasons[reason] = reasons.get(reason, 0) + 1

    images = [conv.image_to_cv(m) for m in frames.messages]
    grays = [to_gray(img) for img in images]
    tracker = KltTracker(selector.config.tracker)

    def track(i: int) -> None:
        if i % 30 == 0:
            tracker.reset(grays[i % n])
        else:
            tracker.track(grays[i % n])

    parts = [
        Timing(
            '  Image -> numpy (image_to_cv)',
            time_calls(lambda i: conv.image_to_cv(frames.messages[i % n]), n),
        ),
        Timing('  BGR -> grey', time_calls(lambda i: to_gray(images[i % n]), n)),
        Timing(
            '  KLT tracking (incl. re-detection every 30 frames)', time_calls(track, n, warmup=0)
        ),
        Timing(
            '  debug overlay, drawn after the decision while ~/debug_image is subscribed',
            np.array(overlay_samples),
        ),
    ]
    times, with_pose = np.array(samples), np.array(posed, dtype=bool)
    return FramePathResult(
        Timing('per-frame path', times),
        Timing('per-frame path, no pose estimated', times[~with_pose]),
        Timing(
            'per-frame path, pose estimated (a model fired)',
            times[with_pose] if with_pose.any() else np.full(1, np.nan),
        ),
        Timing('plain KLT floor', np.array(floor_samples)[~with_pose]),
        parts,
        reasons,
    )


__all__ = ['FrameMessages', 'FramePathResult', 'image_messages', 'time_frame_path']
