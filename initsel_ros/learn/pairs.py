"""Labelled pairs from sequences with ground truth: the paper's batch protocol.

A sequence is cut into batches of ``batch`` frames; every frame of a batch is paired with the
batch's first frame (the reference). Correspondences come from KLT tracks carried through the
batch (:class:`initsel_ros.tracking.KltTracker`), or from ORB descriptor matching with a ratio
test (for sparse or distant frames, such as the real 3-frame sample). Each pair becomes one row
of the pair table (:mod:`initsel_ros.learn.table`): features, ground-truth labels
(:mod:`initsel_ros.learn.labels`) and the correspondence-based baselines.

Batches are independent, so they run in a process pool. With lens distortion the
correspondences are undistorted first (as the node does), and depth is read at the distorted
pixel. Sequences without depth (EuRoC, KITTI) are labelled from E_t and the rotation error
(``scale_rule`` ``no_depth``, see :mod:`initsel_ros.learn.labels`).
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from initsel_ros.errors import DatasetError, InitselError
from initsel_ros.features import Scaling, extra_features, pair_features
from initsel_ros.learn import baselines
from initsel_ros.learn.labels import (
    NO_DEPTH,
    POSE_METHODS,
    LabelConfig,
    PairLabels,
    ground_truth_points,
    label_pair_points,
)
from initsel_ros.learn.table import (
    EXTRA_NAMES,
    FREE_PREFIX,
    PAPER_PREFIX,
    PairTable,
    free_feature_columns,
    paper_feature_columns,
)
from initsel_ros.tracking import KltTracker, TrackerConfig

LOG = logging.getLogger(__name__)


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
        image_topic: (str or None)
            Image topic of bag sources (None = the reader's default).
        chunk: (int)
            Pairs per labelling task: a tracked batch is labelled in slices of this many pairs,
            in parallel (0 = the whole batch in one task).
        executor: (str)
            ``'processes'`` (a local pool of ``jobs`` processes) or ``'dask'`` (a
            dask.distributed cluster, see ``scheduler``).
        scheduler: (str or None)
            Dask scheduler address (e.g. ``tcp://host:8786``); None starts a LocalCluster of
            ``jobs`` single-threaded worker processes on this machine.
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
    image_topic: str | None = None
    chunk: int = 10
    executor: str = 'processes'
    scheduler: str | None = None


def batch_ranges(n_frames: int, batch: int, stride: int = 1) -> list[list[int]]:
    """Frame indices of each batch: consecutive runs of ``batch`` (strided) frames.

    The last, shorter batch is kept when it holds at least two frames.
    """
    if batch < 2:
        raise DatasetError(f'batch must be at least 2 frames, got {batch}')
    frames = list(range(0, n_frames, max(1, stride)))
    out = [frames[i : i + batch] for i in range(0, len(frames), batch)]
    return [b for b in out if len(b) >= 2]


def klt_pairs(sequence: Any, frames: Sequence[int], config: TrackerConfig) -> Iterator[Pair]:
    """Pair every frame of ``frames`` with ``frames[0]`` through KLT tracks."""
    tracker = KltTracker(config)
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
) -> dict[str, Any]:
    """One table row (every schema column) for a labelled pair."""
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
        'R_label': labels.r_label,
        'scale_rule': labels.scale_rule,
    }
    paper = pair_features(p0, p1, width, height, scaling=Scaling.PAPER)
    free = pair_features(p0, p1, width, height, scaling=Scaling.RESOLUTION_FREE)
    row.update(zip(paper_feature_columns(), map(float, paper), strict=True))
    row.update(zip(free_feature_columns(), map(float, free), strict=True))
    extra = extra_features(p0, p1, width, height, EXTRA_NAMES)
    row.update(zip(EXTRA_NAMES, map(float, extra), strict=True))
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


# ----------------------------------------------------------------------------- batch workers
_SEQUENCES: dict[str, Any] = {}


def _open(
    path: str,
    nearest_tolerance: float | None = None,
    sequence: str | None = None,
    image_topic: str | None = None,
) -> Any:
    """open_sequence with a per-process cache (bags are slow to open)."""
    key = f'{path}\0{nearest_tolerance}\0{sequence}\0{image_topic}'
    if key not in _SEQUENCES:
        from initsel_ros.datasets import open_sequence, sequence_kind

        kind = sequence_kind(Path(path))
        options: dict[str, Any] = {}
        if nearest_tolerance is not None and kind in ('tum', 'euroc', 'bag'):
            options['nearest_tolerance'] = nearest_tolerance
        if image_topic is not None and kind == 'bag':
            options['image_topic'] = image_topic
        kitti = kind in ('kitti', 'kitti_root')  # --sequence concerns KITTI sources only
        _SEQUENCES[key] = open_sequence(path, sequence=sequence if kitti else None, **options)
    return _SEQUENCES[key]


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
        LOG.debug('%s batch %d: reference frame %d has no pose', sequence.name, batch, ref)
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
    return TrackedBatch(sequence.name, batch, size, K, depth is not None, tuple(inputs), config)


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
    sequence = _open(task.path, c.nearest_tolerance, c.sequence, c.image_topic)
    return track_sequence_batch(sequence, task.batch, task.frames, c)


def _single_threaded(fn: Callable[..., Any], *args: Any) -> Any:
    """Run ``fn`` with OpenCV single-threaded (a cluster worker runs one task per core)."""
    cv2.setNumThreads(1)
    return fn(*args)


def _init_worker() -> None:
    cv2.setNumThreads(1)


@dataclass(frozen=True)
class BuildStats:
    """What :func:`build_table` did."""

    sequences: tuple[str, ...]
    batches: int
    pairs: int
    seconds: float

    @property
    def pairs_per_second(self) -> float:
        """Labelled pairs per wall-clock second."""
        return self.pairs / self.seconds if self.seconds > 0 else math.nan


class Executor(str, Enum):
    """Where the batches and chunks of :func:`build_table` run."""

    PROCESSES = 'processes'  # a local process pool (jobs = 1: this process)
    DASK = 'dask'  # a dask.distributed cluster (pip extra ``cluster``)


@dataclass
class _Plan:
    """Bookkeeping of one batch in :func:`build_table`."""

    task: BatchTask
    chunks: dict[int, list[dict[str, Any]]] = field(default_factory=dict)
    n_chunks: int = -1  # -1 until tracked (processes) or planned (dask)

    @property
    def done(self) -> bool:
        return self.n_chunks >= 0 and len(self.chunks) == self.n_chunks

    def rows(self) -> list[dict[str, Any]]:
        return [row for k in sorted(self.chunks) for row in self.chunks[k]]


def _run_in_process(plans: list[_Plan], on_done: Callable[[_Plan], None]) -> None:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # faster per pair than OpenCV's own threads on these small problems
    try:
        for plan in plans:
            plan.n_chunks = 1
            plan.chunks[0] = label_inputs(track_task(plan.task))
            on_done(plan)
    finally:
        cv2.setNumThreads(threads)


def _run_in_pool(
    plans: list[_Plan], config: DatasetConfig, on_done: Callable[[_Plan], None]
) -> None:
    """Tracking tasks (at most ``jobs`` at a time) and the label chunks of tracked batches."""
    ctx = multiprocessing.get_context('spawn')
    waiting = list(reversed(plans))
    running: dict[Future, tuple[_Plan, int]] = {}  # chunk -1 = tracking
    with ProcessPoolExecutor(config.jobs, mp_context=ctx, initializer=_init_worker) as pool:

        def top_up() -> None:
            tracking = sum(1 for _, k in running.values() if k < 0)
            while waiting and tracking < config.jobs:
                plan = waiting.pop()
                running[pool.submit(track_task, plan.task)] = (plan, -1)
                tracking += 1

        top_up()
        while running:
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                plan, k = running.pop(future)
                if k >= 0:
                    plan.chunks[k] = future.result()
                else:
                    tracked = future.result()
                    bounds = chunk_bounds(len(tracked.inputs), config.chunk)
                    plan.n_chunks = len(bounds)
                    for j, (start, stop) in enumerate(bounds):
                        # send each chunk its own pairs only, not the whole batch's arrays
                        part = replace(tracked, inputs=tracked.inputs[start:stop])
                        running[pool.submit(label_inputs, part)] = (plan, j)
                if plan.done:
                    on_done(plan)
            top_up()


def _dask_client(config: DatasetConfig) -> Any:
    """A client of ``config.scheduler``, or of a new LocalCluster of ``jobs`` processes."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as exc:
        raise DatasetError(
            '--executor dask needs dask.distributed: pip install '
            '"initsel_ros[cluster]" (or dask[distributed])'
        ) from exc
    if config.scheduler:
        try:
            return Client(config.scheduler, timeout=30)
        except (OSError, TimeoutError) as exc:
            raise DatasetError(
                f'cannot reach the dask scheduler {config.scheduler}: {exc}'
            ) from exc
    cluster = LocalCluster(
        n_workers=max(1, config.jobs),
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.WARNING,
    )
    client = Client(cluster)
    client.cluster_owned = cluster  # closed with the client below
    return client


def _run_on_dask(
    plans: list[_Plan], config: DatasetConfig, on_done: Callable[[_Plan], None]
) -> None:
    """The same per-batch and per-chunk functions as the pool, as dask tasks.

    Each batch is one tracking task; its label chunks are planned from the batch length
    (pairs dropped while tracking shorten the last slices) and depend on the tracking task's
    result, which dask keeps on the worker that made it.
    """
    client = _dask_client(config)  # DatasetError when dask is missing
    from dask.distributed import as_completed

    try:
        futures = {}
        for plan in plans:
            tracked = client.submit(_single_threaded, track_task, plan.task, pure=False)
            bounds = chunk_bounds(len(plan.task.frames) - 1, config.chunk)
            plan.n_chunks = len(bounds)
            for j, (start, stop) in enumerate(bounds):
                future = client.submit(
                    _single_threaded, label_inputs, tracked, start, stop, pure=False
                )
                futures[future] = (plan, j)
            if not bounds:
                on_done(plan)
        for future in as_completed(list(futures)):
            plan, j = futures.pop(future)
            plan.chunks[j] = future.result()
            if plan.done:
                on_done(plan)
    finally:
        cluster = getattr(client, 'cluster_owned', None)
        client.close()
        if cluster is not None:
            cluster.close()


def build_table(
    sources: Sequence[str | Path],
    config: DatasetConfig | None = None,
    *,
    progress: bool = True,
    on_stats: Callable[[BuildStats], None] | None = None,
) -> PairTable:
    """Label every pair of every batch of the given sequences.

    Each batch is tracked in one task (decoding, KLT or ORB, ground-truth points: sequential),
    and its pairs are labelled in chunks of ``config.chunk`` pairs (pose estimates, baselines,
    features: independent per pair), so that both stages spread over the workers. Rows come
    out in sequence, batch and frame order whatever the executor.

    Args:
        sources: (sequence of paths)
            TUM folders or bags (anything :func:`initsel_ros.datasets.open_sequence` reads).
        config: (DatasetConfig)
            Batch size, correspondence source, label thresholds, jobs, executor.
        progress: (bool)
            Draw a progress bar on stderr.
        on_stats: (callable)
            Receives the :class:`BuildStats` at the end (pairs/s etc.).
    """
    config = config or DatasetConfig()
    start = time.perf_counter()
    tasks: list[BatchTask] = []
    names = []
    for source in sources:
        path = str(source)
        try:
            sequence = _open(path, config.nearest_tolerance, config.sequence, config.image_topic)
        except InitselError:
            raise
        except Exception as exc:  # readers may raise anything on foreign files
            reason = str(exc).strip() or 'no message'
            raise DatasetError(
                f'{path}: cannot open sequence: {type(exc).__name__}: {reason}'
            ) from exc
        if not sequence.has_depth:
            LOG.info(
                '%s: no depth; pairs are labelled from E_t and the rotation error '
                '(scale_rule %s, E_R NaN)',
                sequence.name,
                NO_DEPTH,
            )
        names.append(sequence.name)
        for b, frames in enumerate(batch_ranges(len(sequence), config.batch, config.stride)):
            tasks.append(BatchTask(path, b, tuple(frames), config))
    # disable=None: quiet when stderr is not a terminal (logs, CI)
    bar = tqdm(total=len(tasks), unit='batch', disable=None if progress else True)
    plans = [_Plan(task) for task in tasks]
    counts = {'batches': 0, 'pairs': 0}

    def on_done(plan: _Plan) -> None:
        counts['batches'] += 1
        counts['pairs'] += sum(len(rows) for rows in plan.chunks.values())
        bar.update(1)
        bar.set_postfix(pairs=counts['pairs'], refresh=False)

    try:
        executor = Executor(config.executor)
    except ValueError:
        raise DatasetError(
            f'unknown executor {config.executor!r}: {", ".join(e.value for e in Executor)}'
        ) from None
    if config.scheduler and executor is not Executor.DASK:
        raise DatasetError('a dask scheduler address needs the dask executor (--executor dask)')
    potential_pairs = sum(len(task.frames) - 1 for task in tasks)
    if executor is Executor.DASK:
        _run_on_dask(plans, config, on_done)
    elif config.jobs <= 1 or potential_pairs <= max(config.chunk, 1):
        _run_in_process(plans, on_done)
    else:
        _run_in_pool(plans, config, on_done)
    bar.close()
    ordered = [row for plan in plans for row in plan.rows()]
    stats = BuildStats(tuple(names), len(tasks), len(ordered), time.perf_counter() - start)
    LOG.info(
        '%d pairs from %d batches of %d sequence(s) in %.1f s (%.0f pairs/s)',
        stats.pairs,
        stats.batches,
        len(names),
        stats.seconds,
        stats.pairs_per_second,
    )
    if on_stats is not None:
        on_stats(stats)
    return PairTable.from_rows(ordered)


def explain_no_pairs(sources: Sequence[str | Path], config: DatasetConfig) -> str:
    """Why :func:`build_table` labelled no pair, one clause per source (for a one-line error)."""
    reasons = []
    for source in sources:
        seq = _open(str(source), config.nearest_tolerance, config.sequence, config.image_topic)
        n_posed = int(seq.has_pose.sum())
        batches = batch_ranges(len(seq), config.batch, config.stride)
        if n_posed == 0:
            reasons.append(f'{seq.name}: none of its {len(seq)} frames has a ground-truth pose')
        elif not batches:
            reasons.append(
                f'{seq.name}: {len(seq)} frames make no batch of 2 or more '
                f'(batch {config.batch}, stride {config.stride})'
            )
        elif not any(seq.frames[b[0]].pose is not None for b in batches):
            reasons.append(
                f'{seq.name}: no batch starts on a frame with a pose '
                f'({n_posed} of {len(seq)} frames have one)'
            )
        else:
            reasons.append(
                f'{seq.name}: every pair had fewer than {config.min_tracks} '
                'correspondences or no pose'
            )
    return 'no pair could be labelled: ' + '; '.join(reasons)


__all__ = [
    'FREE_PREFIX',
    'PAPER_PREFIX',
    'BatchTask',
    'BuildStats',
    'DatasetConfig',
    'Executor',
    'Pair',
    'PairInput',
    'Source',
    'TrackedBatch',
    'batch_ranges',
    'build_table',
    'chunk_bounds',
    'explain_no_pairs',
    'klt_pairs',
    'label_inputs',
    'label_sequence_batch',
    'orb_matches',
    'orb_pairs',
    'pair_row',
    'track_sequence_batch',
    'track_task',
]
