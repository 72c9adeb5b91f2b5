"""Labelled pairs of one batch: the paper's batch protocol, one table row per pair.

A sequence is cut into batches of ``batch`` frames (:func:`batch_ranges`); every frame of a
batch is paired with the batch's first frame (:mod:`initsel_ros.learn.correspondences`). A
batch is tracked once (:func:`track_sequence_batch`: decoding, tracking, ground-truth points)
and its pairs are labelled independently (:func:`label_inputs`), so the two stages spread over
workers (:mod:`initsel_ros.learn.build`). Each pair becomes one row of the pair table
(:mod:`initsel_ros.learn.table`): features, ground-truth labels
(:mod:`initsel_ros.learn.labels`) and the correspondence-based baselines.

With lens distortion the correspondences are undistorted first (as the node does), and depth
is read at the distorted pixel. Sequences without depth (EuRoC, KITTI) are labelled from E_t
and the rotation error (``scale_rule`` ``no_depth``, see :mod:`initsel_ros.learn.labels`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import DatasetError
from initsel_ros.features import Scaling, extra_features, pair_features
from initsel_ros.geometry import ROTATION_RADIAL_TERMS
from initsel_ros.initialize import FireConfig, initialize_pair, radial_terms_for
from initsel_ros.learn import baselines
from initsel_ros.learn.correspondences import Pair, Source, klt_pairs, orb_pairs
from initsel_ros.learn.labels import (
    POSE_METHODS,
    LabelConfig,
    PairLabels,
    ground_truth_points,
    label_pair_points,
)
from initsel_ros.learn.table import (
    EXTRA_NAMES,
    free_feature_columns,
    paper_feature_columns,
)
from initsel_ros.metrics import translation_chordal_error
from initsel_ros.policy import Reason
from initsel_ros.tracking import TrackerConfig

LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class DatasetConfig:
    """Options of :func:`build_table`.

    Attributes:
        batch: (int)
            Frames per batch (the paper: 90 for training, 30 for testing).
        source: (Source)
            KLT tracks or ORB matches.
        jobs: (int)
            Worker processes (1 = in this process).
        min_tracks: (int)
            Pairs with fewer correspondences are skipped.
        tracker: (TrackerConfig)
            KLT settings.
        orb_features: (int)
            ORB keypoints per frame (ORB source).
        orb_ratio: (float)
            Lowe ratio test (ORB source).
        label: (LabelConfig)
            Label thresholds and scale rule.
        orbslam_iterations: (int)
            RANSAC iterations of the ORB-SLAM baseline (0 = skip it, columns NaN).
        vins_ransac: (bool)
            Run VINS-Mono's F-RANSAC stage when its cheap rule fires.
        stride: (int)
            Use every ``stride``-th frame (1 = all).
        nearest_tolerance: (float or None)
            Passed to the TUM, EuRoC and bag readers: frames outside the ground-truth trajectory
            take the nearest pose within this many seconds (None = the reader's default).
        sequence: (str or None)
            KITTI sequence ('NN') for sources that are a KITTI odometry root.
        camera: (str or None)
            The camera of EuRoC and KITTI sources (``open_sequence``'s ``camera``; None = the
            reader's default).
        image_topic: (str or None)
            Image topic of bag sources (None = the reader's default).
        intrinsics: (Intrinsics or None)
            The camera of TUM and bag sources, replacing ``intrinsics.yaml`` or CameraInfo
            (None = the source's own).
        chunk: (int)
            Pairs per labelling task: a tracked batch is labelled in slices of this many pairs,
            in parallel (0 = the whole batch in one task).
        executor: (str)
            ``'processes'`` (a local pool of ``jobs`` processes) or ``'dask'`` (a
            dask.distributed cluster, see ``scheduler``).
        scheduler: (str or None)
            Dask scheduler address (e.g. ``tcp://host:8786``); None starts a LocalCluster of
            ``jobs`` single-threaded worker processes on this machine.
        fire_path: (bool)
            Also run the node's whole fire path on each pair (:func:`fire_path_outcome`: the
            ``fire_*`` columns; about 20 ms a pair more). Off: they read '' and NaN.
    """

    batch: int = 90
    source: Source = Source.KLT
    jobs: int = 2
    min_tracks: int = 8
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    orb_features: int = 1500
    orb_ratio: float = 0.8
    label: LabelConfig = field(default_factory=LabelConfig)
    orbslam_iterations: int = 200
    vins_ransac: bool = True
    stride: int = 1
    nearest_tolerance: float | None = None
    sequence: str | None = None
    camera: str | None = None
    image_topic: str | None = None
    intrinsics: Intrinsics | None = None
    chunk: int = 10
    executor: str = 'processes'
    scheduler: str | None = None
    fire_path: bool = False


def batch_ranges(n_frames: int, batch: int, stride: int = 1) -> list[list[int]]:
    """Frame indices of each batch: consecutive runs of ``batch`` (strided) frames.

    The last, shorter batch is kept when it holds at least two frames.
    """
    if batch < 2:
        raise DatasetError(f'batch must be at least 2 frames, got {batch}')
    frames = list(range(0, n_frames, max(1, stride)))
    out = [frames[i : i + batch] for i in range(0, len(frames), batch)]
    return [b for b in out if len(b) >= 2]


def labelled_batches(
    sequence: Any, config: DatasetConfig, warn: bool = True
) -> list[tuple[int, list[int]]]:
    """(batch index, frames) of the batches of ``sequence`` that can be labelled
    (:func:`batch_ranges`): a batch whose first frames have no ground-truth pose starts at its
    first frame that has one, since every pair is measured against the batch's first frame
    (the real fr3 sequences start before their motion capture); one with fewer than 2 frames
    from there is left out. ``warn``: log how many batches were moved or left out."""
    has_pose = sequence.has_pose
    out, moved, skipped = [], 0, 0
    for b, frames in enumerate(batch_ranges(len(sequence), config.batch, config.stride)):
        first = next((k for k, i in enumerate(frames) if has_pose[i]), len(frames))
        if len(frames) - first < 2:
            skipped += 1
            continue
        moved += first > 0
        out.append((b, frames[first:]))
    if warn and (moved or skipped):
        LOG.warning(
            '%s: %d batches start on frames without a ground-truth pose: their reference is '
            'their first frame with one; %d batches have fewer than 2 such frames and are left '
            'out',
            sequence.name,
            moved,
            skipped,
        )
    return out


def feature_columns(
    p0: np.ndarray, p1: np.ndarray, width: int, height: int, K: np.ndarray
) -> dict[str, float]:
    """The table's feature columns of one correspondence set: the 23 features in both
    scalings and every extra feature (those that need the camera from ``K``)."""
    paper = pair_features(p0, p1, width, height, scaling=Scaling.PAPER)
    free = pair_features(p0, p1, width, height, scaling=Scaling.RESOLUTION_FREE)
    camera = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    extra = extra_features(p0, p1, width, height, EXTRA_NAMES, camera=camera)
    columns = dict(zip(paper_feature_columns(), map(float, paper), strict=True))
    columns.update(zip(free_feature_columns(), map(float, free), strict=True))
    columns.update(zip(EXTRA_NAMES, map(float, extra), strict=True))
    return columns


def pair_row(
    sequence_name: str,
    batch: int,
    pair: Pair,
    stamps: tuple[float, float],
    size: tuple[int, int],
    K: np.ndarray,
    labels: PairLabels,
    source: Source,
    config: DatasetConfig,
    *,
    states_distortion: bool = False,
) -> dict[str, Any]:
    """One table row (every schema column) for a labelled pair; ``states_distortion``: the
    camera states its lens distortion (the pair is undistorted; see
    :func:`fire_path_outcome`)."""
    width, height = size
    p0, p1 = pair.p0, pair.p1
    row: dict[str, Any] = {
        'sequence': sequence_name,
        'batch': batch,
        'ref_index': pair.ref_index,
        'cur_index': pair.cur_index,
        'ref_stamp': stamps[0],
        'cur_stamp': stamps[1],
        'source': source.value,
        'width': width,
        'height': height,
        'n_tracks': len(p0),
        'gt_baseline_m': labels.baseline_m,
        'gt_rotation_deg': labels.rotation_deg,
        'gt_parallax_deg': labels.parallax_deg,
        'gt_static_share': labels.static_share,
        'gt_plane_share': labels.plane_share,
        'gt_rotation_share': labels.rotation_share,
        'R_label': labels.r_label,
        'scale_rule': labels.scale_rule,
    }
    row.update(feature_columns(p0, p1, width, height, K))
    disp = np.hypot(*(np.asarray(p1, float) - np.asarray(p0, float)).T)
    row['disp_mean_px'] = float(disp.mean())
    row['disp_median_px'] = float(np.median(disp))
    row['disp_std_px'] = float(disp.std())
    if config.orbslam_iterations > 0:
        rng = np.random.default_rng([batch, pair.ref_index, pair.cur_index])
        scores = baselines.orbslam_scores(p0, p1, iterations=config.orbslam_iterations, rng=rng)
        row.update(orb_s_h=scores.s_h, orb_s_f=scores.s_f, orb_ratio=scores.ratio)
    else:
        row.update(orb_s_h=math.nan, orb_s_f=math.nan, orb_ratio=math.nan)
    if config.vins_ransac:  # RANSAC only where the cheap rule fires, as VINS-Mono does
        vins = baselines.vins_relative_pose(p0, p1, K, run_ransac=False)
        t_gt = labels.t_gt
        norm = float(np.linalg.norm(t_gt))
        row.update(vins_parallax_px=vins.parallax_px, vins_inliers=vins.inliers)
        row['vins_et'] = (
            float(np.linalg.norm(t_gt / norm - vins.t))
            if vins.inliers > 0 and norm > 1e-9
            else math.nan
        )
    else:
        row.update(vins_parallax_px=baselines.vins_parallax(p0, p1, K), vins_inliers=-1)
        row['vins_et'] = math.nan
    fire = FireOutcome()
    if config.fire_path:
        fire = fire_path_outcome(p0, p1, K, labels.t_gt, radial_terms_for(states_distortion))
    row.update(
        fire_method=fire.method, fire_et=fire.et, fire_rotation_statistic=fire.rotation_statistic
    )
    for m in POSE_METHODS:
        o = labels.outcomes[m]
        row.update(
            {
                f'{m}_ok': int(o.ok),
                f'{m}_reason': o.reason.replace(',', ';').replace('\n', ' '),
                f'{m}_et': o.et,
                f'{m}_er': o.er(labels.config.scale_rule),
                f'{m}_er_first_two': o.er_first_two,
                f'{m}_er_median': o.er_median,
                f'{m}_n_points': o.n_points,
                f'{m}_n_gt_points': o.n_gt_points,
                f'{m}_parallax_deg': o.parallax_deg,
                f'{m}_rot_err_deg': o.rotation_error_deg,  # stored once table.py has the column
                f'{m}_label': labels.label(m),
            }
        )
    return row


@dataclass(frozen=True)
class FireOutcome:
    """What the node's fire path makes of one pair (:func:`fire_path_outcome`).

    Attributes:
        method: the method it publishes, or ``'none'``.
        et: the lowest E_t against the ground truth of its seed map and the rival
            decompositions it keeps for the verification frames (NaN when it publishes
            nothing).
        rotation_statistic: its rotation test's statistic, the flow a rotation leaves over
            the tracking noise (NaN when the test had too few tracks).
    """

    method: str = ''
    et: float = math.nan
    rotation_statistic: float = math.nan


def fire_path_outcome(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    t_gt: np.ndarray,
    radial_terms: tuple[float, ...] = ROTATION_RADIAL_TERMS,
) -> FireOutcome:
    """The node's fire path on one pair given E, F and H to try, with its default settings
    (the rotation test, GRIC's selection, the checks and the refinement; no verification
    frames) and the rotation test's ``radial_terms`` as the node picks them for the camera
    (:func:`~initsel_ros.initialize.radial_terms_for`)."""
    config = FireConfig(radial_terms=radial_terms)
    fire = initialize_pair(p0, p1, K, POSE_METHODS, config)
    statistic = fire.rotation.statistic if fire.rotation is not None else math.nan
    if fire.reason is not Reason.INITIALIZED or fire.seed is None:
        return FireOutcome('none', math.nan, statistic)
    seeds = (fire.seed, *fire.alternatives)
    errors = [translation_chordal_error(t_gt, seed.t) for seed in seeds]
    et = min((e for e in errors if e == e), default=math.nan)
    return FireOutcome(fire.seed.method.value, et, statistic)


# ----------------------------------------------------------------------------- batch workers
def open_cached(path: str, config: DatasetConfig) -> Any:
    """The sequence at ``path`` with the reader options of ``config``, opened once per process
    (:func:`initsel_ros.datasets.cache.open_cached`)."""
    from initsel_ros.datasets import reader_options
    from initsel_ros.datasets.cache import open_cached as open_once

    options = reader_options(
        path,
        nearest_tolerance=config.nearest_tolerance,
        image_topic=config.image_topic,
        intrinsics=config.intrinsics,
        camera=config.camera,
        sequence=config.sequence,
    )
    return open_once(path, **options)


@dataclass(frozen=True)
class BatchTask:
    """One batch of one sequence, as sent to a worker."""

    path: str
    batch: int
    frames: tuple[int, ...]
    config: DatasetConfig


@dataclass(frozen=True)
class PairInput:
    """Everything the labelling of one pair needs, without the images (small to send).

    Attributes:
        pair: (Pair)
            Correspondences (undistorted when the camera has lens distortion).
        gt_points, gt_valid: ((N, 3) float64, (N,) bool)
            Ground-truth points of ``pair.p0`` from the reference depth
            (:func:`initsel_ros.learn.labels.ground_truth_points`).
        T_ref, T_cur: ((4, 4) float64)
            Ground-truth camera-to-world poses.
        stamps: ((float, float))
            Reference and current image times.
    """

    pair: Pair
    gt_points: np.ndarray
    gt_valid: np.ndarray
    T_ref: np.ndarray
    T_cur: np.ndarray
    stamps: tuple[float, float]


@dataclass(frozen=True)
class TrackedBatch:
    """A batch after the sequential stage (decoding, tracking, ground-truth points).

    ``inputs`` holds the pairs that will be labelled, in frame order; pairs without a pose or
    with fewer than ``min_tracks`` correspondences are already dropped. Its slices are labelled
    independently (:func:`label_inputs`), in a pool or on a cluster.
    """

    sequence_name: str
    batch: int
    size: tuple[int, int]
    K: np.ndarray
    has_depth: bool
    inputs: tuple[PairInput, ...]
    config: DatasetConfig
    states_distortion: bool = False  # (the camera's: the fire path's radial terms follow it)


def track_sequence_batch(
    sequence: Any, batch: int, frames: Sequence[int], config: DatasetConfig
) -> TrackedBatch:
    """The sequential part of one batch: correspondences and ground-truth points per pair."""
    frames = list(frames)
    ref = frames[0]
    intr = sequence.intrinsics
    K = intr.K
    size = (intr.width, intr.height)
    T_ref = sequence.frames[ref].pose
    if T_ref is None:
        LOG.warning(
            '%s batch %d: reference frame %d has no pose: no pairs', sequence.name, batch, ref
        )
        return TrackedBatch(sequence.name, batch, size, K, sequence.has_depth, (), config)
    depth = sequence.depth(ref)  # None: labels from E_t and the rotation error only
    if config.source is Source.KLT:
        pairs: Iterator[Pair] = klt_pairs(sequence, frames, config.tracker)
    else:
        pairs = orb_pairs(sequence, frames, config.orb_features, config.orb_ratio)
    inputs = []
    ref_stamp = float(sequence.frames[ref].stamp)
    for pair in pairs:
        T_cur = sequence.frames[pair.cur_index].pose
        if T_cur is None or len(pair.p0) < config.min_tracks:
            continue
        depth_pixels = None
        if intr.has_distortion:
            depth_pixels = pair.p0
            pair = Pair(
                pair.ref_index,
                pair.cur_index,
                intr.undistort_pixels(pair.p0),
                intr.undistort_pixels(pair.p1),
            )
        gt_points, gt_valid = ground_truth_points(pair.p0, K, depth, depth_pixels)
        stamps = (ref_stamp, float(sequence.frames[pair.cur_index].stamp))
        inputs.append(PairInput(pair, gt_points, gt_valid, T_ref, T_cur, stamps))
    return TrackedBatch(
        sequence.name,
        batch,
        size,
        K,
        depth is not None,
        tuple(inputs),
        config,
        intr.has_distortion,
    )


def label_inputs(
    tracked: TrackedBatch, start: int = 0, stop: int | None = None
) -> list[dict[str, Any]]:
    """Rows of the pairs ``tracked.inputs[start:stop]`` (independent of the other pairs)."""
    config = tracked.config
    rows = []
    for item in tracked.inputs[start:stop]:
        pair = item.pair
        labels = label_pair_points(
            pair.p0,
            pair.p1,
            tracked.K,
            item.gt_points,
            item.gt_valid,
            item.T_ref,
            item.T_cur,
            config.label,
            has_depth=tracked.has_depth,
        )
        rows.append(
            pair_row(
                tracked.sequence_name,
                tracked.batch,
                pair,
                item.stamps,
                tracked.size,
                tracked.K,
                labels,
                config.source,
                config,
                states_distortion=tracked.states_distortion,
            )
        )
    return rows


def label_sequence_batch(
    sequence: Any, batch: int, frames: Sequence[int], config: DatasetConfig
) -> list[dict[str, Any]]:
    """Rows of one batch of an open sequence (pairs without ground truth are skipped)."""
    return label_inputs(track_sequence_batch(sequence, batch, frames, config))


def chunk_bounds(n_pairs: int, chunk: int) -> list[tuple[int, int]]:
    """(start, stop) slices of ``n_pairs`` pairs, ``chunk`` at a time (0 = one slice)."""
    if n_pairs <= 0:
        return []
    step = n_pairs if chunk <= 0 else chunk
    return [(i, min(i + step, n_pairs)) for i in range(0, n_pairs, step)]


def track_task(task: BatchTask) -> TrackedBatch:
    """Worker entry: the sequential stage of one batch (the sequence opened once per process)."""
    c = task.config
    sequence = open_cached(task.path, c)
    return track_sequence_batch(sequence, task.batch, task.frames, c)


__all__ = [
    'BatchTask',
    'DatasetConfig',
    'FireOutcome',
    'PairInput',
    'TrackedBatch',
    'batch_ranges',
    'chunk_bounds',
    'fire_path_outcome',
    'label_inputs',
    'label_sequence_batch',
    'labelled_batches',
    'open_cached',
    'pair_row',
    'track_sequence_batch',
    'track_task',
]
