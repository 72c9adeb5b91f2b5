"""Correspondences of a batch: KLT tracks from its first frame, or ORB descriptor matches.

Every frame of a batch is paired with the batch's first frame (the reference). KLT tracks are
carried through the batch (:class:`initsel_ros.tracking.KltTracker`, as the node tracks);
ORB matching with a ratio test serves sparse or distant frames, such as the real 3-frame
sample.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

import cv2
import numpy as np

from initsel_ros.tracking import KltTracker, TrackerConfig


class Source(str, Enum):
    """Where the correspondences of a pair come from."""

    KLT = 'klt'
    ORB = 'orb'


@dataclass(frozen=True)
class Pair:
    """Correspondences between a batch's reference frame and one later frame.

    Attributes:
        ref_index, cur_index: (int)
            Frame indices in the sequence.
        p0, p1: ((N, 2) float32)
            Reference and current pixels.
    """

    ref_index: int
    cur_index: int
    p0: np.ndarray
    p1: np.ndarray


def klt_pairs(sequence: Any, frames: Sequence[int], config: TrackerConfig) -> Iterator[Pair]:
    """Pair every frame of ``frames`` with ``frames[0]`` through KLT tracks."""
    tracker = KltTracker(config, sequence.intrinsics.field_mask())
    tracker.reset(sequence.gray(frames[0]))
    for index in frames[1:]:
        tracks = tracker.track(sequence.gray(index))
        yield Pair(frames[0], index, np.asarray(tracks.ref), np.asarray(tracks.cur))


def orb_matches(
    des0: np.ndarray | None,
    kp0: Sequence[Any],
    des1: np.ndarray | None,
    kp1: Sequence[Any],
    ratio: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Ratio-test ORB matches -> (N, 2) float32 reference and current pixels."""
    empty = np.zeros((0, 2), np.float32)
    if des0 is None or des1 is None or len(des0) < 2 or len(des1) < 2:
        return empty, empty
    knn = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(des0, des1, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < ratio * m[1].distance]
    # one-to-one: keep the best match per current keypoint
    best: dict[int, Any] = {}
    for m in good:
        if m.trainIdx not in best or m.distance < best[m.trainIdx].distance:
            best[m.trainIdx] = m
    matches = sorted(best.values(), key=lambda m: m.queryIdx)
    if not matches:
        return empty, empty
    p0 = np.array([kp0[m.queryIdx].pt for m in matches], np.float32)
    p1 = np.array([kp1[m.trainIdx].pt for m in matches], np.float32)
    return p0, p1


def orb_pairs(
    sequence: Any, frames: Sequence[int], n_features: int = 1500, ratio: float = 0.8
) -> Iterator[Pair]:
    """Pair every frame of ``frames`` with ``frames[0]`` through ORB descriptor matches."""
    orb = cv2.ORB_create(n_features)
    kp0, des0 = orb.detectAndCompute(sequence.gray(frames[0]), None)
    for index in frames[1:]:
        kp1, des1 = orb.detectAndCompute(sequence.gray(index), None)
        p0, p1 = orb_matches(des0, kp0, des1, kp1, ratio)
        yield Pair(frames[0], index, p0, p1)


__all__ = [
    'Pair',
    'Source',
    'klt_pairs',
    'orb_matches',
    'orb_pairs',
]
