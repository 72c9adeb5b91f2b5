"""Pair tables of random two-view geometries: distillation pairs without images or labels.

A distilled student learns its teacher's logits, not labels (:mod:`learn.distill`), so any
correspondence set serves as distillation data. Rendered sequences show only the motions of
their trajectories, and where a test sequence moves otherwise, trees fitted to other inputs
extrapolate otherwise than the teacher (docs/learning.md, section 5). These pairs spread the
geometry a tracker can meet over the whole space instead, each drawn independently:

* a pinhole camera, focal length 0.6-1.25 image widths (a horizontal field of view of 44-80
  degrees), principal point near the centre;
* 60-360 reference points over the whole image, in a window of 25-100 % of each side, or in
  1-6 blobs (texture rarely covers a frame evenly);
* depths from a cloud (log-depth spread 0.02-1.2), one plane tilted up to 70 degrees, or two;
* a motion: general (translation over median depth log-uniform 0.002-0.35 in any direction,
  rotation up to 10 degrees), an arc that turns to keep the scene centred, a rotation of
  0.2-10 degrees with at most 2 % of that translation, or a still camera;
* tracking noise of 0.05-1 px (log-uniform), up to 6 % outliers of 15 px, points leaving the
  image or passing behind the camera dropped (pairs left with under 30 are drawn again).

Rows hold the features of :func:`learn.pairs.feature_columns` and no labels: their label
columns are 0, their ``source`` is :data:`TWOVIEW_SOURCE`, and training from labels or
evaluating refuses them (:func:`check_labelled`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from initsel_ros.errors import DatasetError
from initsel_ros.learn.pairs import feature_columns
from initsel_ros.learn.table import BINARY_SUFFIXES, PairTable, schema

#: The ``source`` of a random two-view pair (a rendered pair's is ``klt`` or ``orb``).
TWOVIEW_SOURCE = 'twoview'
#: Pairs per ``batch`` value (the unit of batch-grouped folds).
PAIRS_PER_BATCH = 30
MIN_POINTS = 30
_MARGIN = 8.0  # px: detections keep off the image border


@dataclass(frozen=True)
class TwoView:
    """One drawn pair: (N, 2) reference and current pixels, the 3x3 intrinsics."""

    p0: np.ndarray
    p1: np.ndarray
    K: np.ndarray


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about the unit ``axis`` by ``angle`` radians."""
    return cv2.Rodrigues((np.asarray(axis, np.float64) * angle).reshape(3, 1))[0]


def _direction(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return math.exp(rng.uniform(math.log(low), math.log(high)))


def _reference_points(rng: np.random.Generator, n: int, width: int, height: int) -> np.ndarray:
    """(n, 2) detections: over the whole image, in a window, or in blobs."""
    m = _MARGIN
    cover = rng.choice(['full', 'window', 'blobs'], p=[0.3, 0.4, 0.3])
    if cover == 'full':
        return np.column_stack((rng.uniform(m, width - m, n), rng.uniform(m, height - m, n)))
    if cover == 'window':
        w = rng.uniform(0.25, 1) * (width - 2 * m)
        h = rng.uniform(0.25, 1) * (height - 2 * m)
        x0 = m + rng.uniform(0, width - 2 * m - w)
        y0 = m + rng.uniform(0, height - 2 * m - h)
        return np.column_stack((x0 + rng.uniform(0, w, n), y0 + rng.uniform(0, h, n)))
    k = int(rng.integers(1, 7))
    centres = np.column_stack((rng.uniform(m, width - m, k), rng.uniform(m, height - m, k)))
    which = rng.integers(0, k, n)
    offsets = rng.normal(0, 1, (n, 2))
    points = centres[which] + offsets * rng.uniform(20, 140, k)[which, None]
    return np.clip(points, m, [width - m, height - m])


def _depths(rng: np.random.Generator, rays: np.ndarray) -> np.ndarray:
    """Depths (z) of the points along ``rays`` (N, 3, z = 1), median about 1."""
    n = len(rays)
    scene = rng.choice(['cloud', 'plane', 'two_planes'], p=[0.5, 0.3, 0.2])
    if scene == 'cloud':
        spread = _log_uniform(rng, 0.02, 1.2)
        return np.exp(rng.uniform(-spread, spread, n))

    def plane() -> np.ndarray:  # through (0, 0, 1), normal tilted up to 70 degrees
        normal = _rotation(_direction(rng), rng.uniform(0, math.radians(70))) @ [0.0, 0.0, 1.0]
        return normal[2] / np.maximum(rays @ normal, 1e-3)

    z = plane()
    if scene == 'two_planes':
        other = plane() * rng.uniform(0.5, 2.0)
        side = rays[:, 0] * rng.choice([-1, 1]) > rng.uniform(-0.3, 0.3)
        z = np.where(side, z, other)
    return np.clip(z, 0.1, 20.0)


def _motion(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) taking reference-camera coordinates to the current camera's: x_c = R x + t."""
    kind = rng.choice(['general', 'arc', 'rotation', 'static'], p=[0.5, 0.3, 0.15, 0.05])
    baseline = _log_uniform(rng, 0.002, 0.35)  # over the median depth, 1
    if kind == 'general':
        t = _direction(rng) * baseline
        R = _rotation(_direction(rng), math.radians(rng.uniform(0, 10)))
    elif kind == 'arc':  # sideways, turning to keep the point (0, 0, 1) in view
        way = np.array([*_direction(rng)[:2], 0.0])
        way /= np.linalg.norm(way)
        centre = np.array([0.0, 0.0, 1.0])
        R = _rotation(np.cross(way, centre), -baseline * rng.uniform(0.6, 1.2))
        t = centre - R @ centre + way * baseline * rng.uniform(0.0, 0.3)
        t = t + rng.normal(0, 0.1 * baseline, 3)
    elif kind == 'rotation':
        t = _direction(rng) * baseline * rng.uniform(0, 0.02)
        R = _rotation(_direction(rng), math.radians(rng.uniform(0.2, 10)))
    else:
        t = _direction(rng) * rng.uniform(0, 1e-4)
        R = np.eye(3)
    return R, t


def random_two_view(rng: np.random.Generator, width: int = 640, height: int = 480) -> TwoView:
    """One random pair (see the module docstring); draws again until 30 points remain."""
    while True:
        focal = rng.uniform(0.59375, 1.25) * width
        cx, cy = width / 2 + rng.normal(0, 5), height / 2 + rng.normal(0, 5)
        K = np.array([[focal, 0.0, cx], [0.0, focal, cy], [0.0, 0.0, 1.0]])
        n = int(rng.integers(60, 360))
        uv = _reference_points(rng, n, width, height)
        rays = np.linalg.solve(K, np.column_stack((uv, np.ones(n))).T).T
        points = rays * _depths(rng, rays)[:, None]
        R, t = _motion(rng)
        moved = points @ R.T + t
        ahead = moved[:, 2] > 0.05
        projected = moved @ K.T
        uv1 = projected[:, :2] / projected[:, 2:3]
        uv1 = uv1 + rng.normal(0, _log_uniform(rng, 0.05, 1.0), uv1.shape)
        uv0 = uv + rng.normal(0, 0.05, uv.shape)
        outlier = rng.random(n) < rng.uniform(0, 0.06)
        uv1[outlier] += rng.normal(0, 15, (int(outlier.sum()), 2))
        keep = ahead & (uv1[:, 0] >= 0) & (uv1[:, 0] < width)
        keep &= (uv1[:, 1] >= 0) & (uv1[:, 1] < height)
        if keep.sum() >= MIN_POINTS:
            return TwoView(uv0[keep], uv1[keep], K)


def _empty_row() -> dict[str, Any]:
    row: dict[str, Any] = {}
    for name, kind in schema():
        row[name] = '' if kind is str else (0 if kind is int else math.nan)
        if name.endswith(BINARY_SUFFIXES):
            row[name] = 0
    return row


def twoview_table(n_pairs: int, seed: int, width: int = 640, height: int = 480) -> PairTable:
    """``n_pairs`` random pairs of ``seed`` as a pair table (sequence ``twoview_s<seed>``)."""
    if n_pairs < 1:
        raise DatasetError(f'a two-view table needs at least one pair, got {n_pairs}')
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_pairs):
        view = random_two_view(rng, width, height)
        p0, p1, K = view.p0, view.p1, view.K
        row = _empty_row()
        row.update(
            sequence=f'twoview_s{seed}',
            batch=i // PAIRS_PER_BATCH,
            ref_index=0,
            cur_index=i,
            source=TWOVIEW_SOURCE,
            width=width,
            height=height,
            n_tracks=len(p0),
        )
        row.update(feature_columns(p0, p1, width, height, K))
        rows.append(row)
    return PairTable.from_rows(rows)


def check_labelled(table: PairTable, purpose: str) -> None:
    """Raises DatasetError when ``table`` holds two-view pairs, which have no labels."""
    if not len(table):
        return
    n = int(np.count_nonzero(np.asarray(table['source']).astype(str) == TWOVIEW_SOURCE))
    if n:
        raise DatasetError(
            f'{n} pairs of the tables are random two-view pairs (`initsel twoview`), which have '
            f'no labels: {purpose} needs labelled pairs (they serve `initsel train --distill`)'
        )
