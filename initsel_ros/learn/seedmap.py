"""How good is the seed map a SLAM front end receives? Selector and baselines, one run.

For each batch (``length`` frames starting every ``step`` frames) of each sequence, the live
:class:`~initsel_ros.selector.Selector` runs from the batch's first frame, in mode 'once',
exactly as the node runs it; its published initialization is compared with the ground truth:

- ``E_t``: translation direction error (chordal distance, 0..2);
- rotation error, degrees;
- depth error: median over the map points of ``|s z_est - z_gt| / z_gt`` after one scale
  ``s = median(z_gt / z_est)``, against the reference frame's depth;
- frames from the batch start to the initializing frame (and to publication, which
  verification delays);
- whether the chosen method is the most accurate of F/E/H on that pair, or within
  ``tolerance`` E_t of it (each method estimated and refined as the selector would).

Baselines (``baselines``, any of :data:`BASELINES`), on the same batches and ground truth:

- ``'rules'``: other systems' initialization rules, re-implemented here and run per frame on
  the same tracks (one KLT tracker per batch, the selector's settings), each initializing at
  its first accepted frame with its own method: ORB-SLAM2 and ORB-SLAM3 (parallel H/F RANSAC
  scores, H when ``R_H`` > 0.40 / 0.50, then at least 50 points with 1 degree of parallax),
  VINS-Mono (more than 20 correspondences with an average parallax above 30 px at focal 460,
  F-RANSAC + recoverPose with more than 12 inliers) and Butt et al. 2020 (H when the mean
  disparity exceeds 50 px, F when its deviation also exceeds 15 px). Their rows are named
  ``... rule (re-implemented)``.
- ``'colmap'``: COLMAP's own two-view geometry on the same tracks
  (:mod:`initsel_ros.learn.real_baselines.colmap`), row ``COLMAP (real)``.
- ``'orbslam3'``: the real ORB-SLAM3 fed the batch's frames
  (:mod:`initsel_ros.learn.real_baselines.orbslam3_runner`), row ``ORB-SLAM3 (real)``; a crash or a
  time-out is counted as ``failed``.

Sequences are grouped as planar, non-planar or rotation/static by an explicit mapping
(``groups``); a sequence it does not name is grouped by :func:`default_group`, a rule on its
folder name. ``sensor_noise`` adds Gaussian noise (grey levels, seeded by ``noise_seed``, the
batch and the sequence) to every frame before any system sees it: the real ORB-SLAM3 fixes its
RANSAC seed, so spread over runs comes from noise seeds.
"""

from __future__ import annotations

import logging
import math
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.geometry import triangulate_pair
from initsel_ros.image import to_gray
from initsel_ros.initialize import (
    ESTIMATES_ONLY,
    initialize_pair,
    plane_is_the_scene,
    seed_map,
)
from initsel_ros.learn.baselines import (
    ORB_MIN_PARALLAX_DEG,
    ORB_MIN_POINTS,
    OrbSlamVersion,
    butt_rule,
    orbslam_scores,
    vins_relative_pose,
)
from initsel_ros.learn.labels import true_depths
from initsel_ros.markdown import number
from initsel_ros.metrics import (
    depth_error,
    finite_median,
    relative_pose,
    rotation_error_deg,
    translation_chordal_error,
)
from initsel_ros.models import ModelSet
from initsel_ros.names import POSE_METHODS
from initsel_ros.selector import Selector, SelectorConfig
from initsel_ros.tracking import KltTracker

LOG = logging.getLogger(__name__)

if TYPE_CHECKING:
    from initsel_ros.learn.real_baselines.orbslam3_runner import Orbslam3Setup

#: The re-implemented rules' rows.
ORB2_RULE = 'ORB-SLAM2 rule (re-implemented)'
ORB3_RULE = 'ORB-SLAM3 rule (re-implemented)'
VINS_RULE = 'VINS-Mono rule (re-implemented)'
BUTT_RULE = 'Butt 2020 rule (re-implemented)'
RULE_SYSTEMS = (ORB2_RULE, ORB3_RULE, VINS_RULE, BUTT_RULE)
#: The selector's rows.
INITSEL = 'initsel'
#: The real systems' rows.
ORBSLAM3_REAL = 'ORB-SLAM3 (real)'
COLMAP_REAL = 'COLMAP (real)'
#: Names of the systems compared, in table order.
SYSTEMS = (INITSEL, ORBSLAM3_REAL, COLMAP_REAL, *RULE_SYSTEMS)
#: Baseline families ``evaluate_sequences`` can run.
BASELINES = ('rules', 'orbslam3', 'colmap')
#: Table groups, in table order.
GROUPS = ('planar', 'non-planar', 'rotation/static')
#: The default grouping rule: substrings of a sequence's folder name that mark it planar
#: (every visible point on one plane) ...
PLANAR_MARKERS = ('wall', 'floor', 'planar')
#: ... or without a usable baseline (no initialization expected). Anything else: non-planar.
NO_BASELINE_MARKERS = ('rotation', 'static')


def default_group(name: str) -> str:
    """The default group of a sequence from its folder name (used unless told otherwise)."""
    low = name.lower()
    if any(m in low for m in NO_BASELINE_MARKERS):
        return 'rotation/static'
    return 'planar' if any(m in low for m in PLANAR_MARKERS) else 'non-planar'


@dataclass(frozen=True)
class BaselineOptions:
    """Which baselines run, and how (picklable: it goes to the worker processes).

    Attributes:
        baselines: any of :data:`BASELINES`.
        orbslam3: the real ORB-SLAM3's setup (needed for 'orbslam3').
        sensor_noise: Gaussian noise added to every frame, grey levels (0 = none).
        noise_seed: seed of that noise (mixed with the batch start and the sequence name).
    """

    baselines: tuple[str, ...] = ('rules',)
    orbslam3: Orbslam3Setup | None = None
    sensor_noise: float = 0.0
    noise_seed: int = 0

    def __post_init__(self) -> None:
        unknown = set(self.baselines) - set(BASELINES)
        if unknown:
            raise ValueError(f'unknown baselines {sorted(unknown)}: choose from {BASELINES}')
        if 'orbslam3' in self.baselines and self.orbslam3 is None:
            raise ValueError("baseline 'orbslam3' needs its setup (find_orbslam3)")
        if not (self.sensor_noise >= 0 and math.isfinite(self.sensor_noise)):
            raise ValueError(f'sensor noise must be >= 0 grey levels, got {self.sensor_noise}')


@dataclass(frozen=True)
class BatchOutcome:
    """One system's first initialization in one batch (NaN fields when it did not).

    Attributes:
        sequence: sequence name.
        planar: the sequence is in the planar group.
        system: one of :data:`SYSTEMS`.
        start: batch start, frame index.
        initialized: the system initialized within the batch.
        method: its method ('' when none).
        frames_to_init: initializing frame - batch start.
        frames_to_publish: publishing frame - batch start (later with verification).
        baseline_m: ground-truth baseline of the initializing pair, metres.
        e_t: translation direction error.
        rotation_deg: rotation error, degrees.
        depth_error: median relative depth error after one scale.
        n_points: map points.
        best_method: the most accurate of F/E/H on that pair (selector only).
        chosen_ok: the chosen method is the best or within the tolerance (selector only).
        e_t_f: F's E_t on that pair, refined (selector only); likewise e_t_e and e_t_h.
        group: the table group (one of :data:`GROUPS`; '' = :func:`default_group`).
        reference_offset: reference frame - batch start (a system may re-reference).
        failed: the system crashed or timed out on this batch (ORB-SLAM3 (real) only).
        detail: why it failed.
        noise_seed: the sensor noise's seed (-1 without added noise).
    """

    sequence: str
    planar: bool
    system: str
    start: int
    initialized: bool
    method: str = ''
    frames_to_init: float = math.nan
    frames_to_publish: float = math.nan
    baseline_m: float = math.nan
    e_t: float = math.nan
    rotation_deg: float = math.nan
    depth_error: float = math.nan
    n_points: int = 0
    best_method: str = ''
    chosen_ok: bool = False
    e_t_f: float = math.nan
    e_t_e: float = math.nan
    e_t_h: float = math.nan
    group: str = ''
    reference_offset: float = math.nan
    failed: bool = False
    detail: str = ''
    noise_seed: int = -1

    @property
    def table_group(self) -> str:
        """The group the table counts this batch in."""
        return self.group or default_group(self.sequence)


def _pose_errors(
    T_ref: np.ndarray,
    T_cur: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
) -> tuple[float, float, float]:
    R_gt, t_gt = relative_pose(T_ref, T_cur)
    return (
        translation_chordal_error(t_gt, t),
        rotation_error_deg(R_gt, R),
        float(np.linalg.norm(t_gt)),
    )


def _estimate(method: str, p0: np.ndarray, p1: np.ndarray, K: np.ndarray):
    """One method's estimate through the core fire path (None when it failed)."""
    estimate = initialize_pair(p0, p1, K, (method,), ESTIMATES_ONLY).estimates[0]
    return estimate if estimate.ok else None


class _Batch:
    """The frames of one batch, decoded once, and its ground truth."""

    def __init__(
        self,
        sequence,
        start: int,
        length: int,
        group: str = '',
        noise: float = 0.0,
        noise_seed: int = 0,
        images: list[np.ndarray] | None = None,
    ) -> None:
        self.sequence = sequence
        self.name = sequence.name
        self.start = start
        self.stop = min(start + length, len(sequence))
        if images is None:
            images = [sequence.image(i) for i in range(start, self.stop)]
            if noise > 0:
                images = add_sensor_noise(images, noise, (noise_seed, start, self.name))
        self.images = images
        self.poses = sequence.poses()
        self.stamps_ns = sequence.stamps_ns
        self.intrinsics: Intrinsics = sequence.intrinsics
        self.group = group or default_group(self.name)
        self.planar = self.group == 'planar'

    def sub(self, start: int, stop: int) -> _Batch:
        """The frames ``start..stop - 1`` (sequence indices) of this batch, as a batch."""
        k0, k1 = start - self.start, stop - self.start
        return _Batch(self.sequence, start, stop - start, self.group, images=self.images[k0:k1])

    def missed(self, system: str, **fields) -> BatchOutcome:
        """The outcome of a system that did not initialize in this batch."""
        return BatchOutcome(
            self.name, self.planar, system, self.start, False, group=self.group, **fields
        )

    def gray(self, k: int) -> np.ndarray:
        return to_gray(self.images[k])

    def undistort(self, pts: np.ndarray) -> np.ndarray:
        return self.intrinsics.undistort_pixels(pts).astype(np.float64)

    def outcome(
        self,
        system: str,
        index: int,
        method: str,
        R,
        t,
        points,
        pixels_ref,
        published: int | None = None,
    ) -> BatchOutcome:
        ref = self.start
        e_t, rot, baseline = _pose_errors(self.poses[ref], self.poses[index], R, t)
        return BatchOutcome(
            self.name,
            self.planar,
            system,
            self.start,
            True,
            method,
            float(index - ref),
            float((index if published is None else published) - ref),
            baseline,
            e_t,
            rot,
            depth_error(
                points, true_depths(pixels_ref, self.intrinsics, self.sequence.depth(ref))
            ),
            len(points),
            group=self.group,
            reference_offset=0.0,
        )


def add_sensor_noise(
    images: Sequence[np.ndarray], sigma: float, seed: tuple[int, int, str]
) -> list[np.ndarray]:
    """Frames plus Gaussian noise of ``sigma`` grey levels (8-bit, rounded and clipped).

    Args:
        seed: (noise seed, batch start, sequence name): the same triple, the same noise.

    Raises:
        ValueError: a frame is not 8-bit.
    """
    noise_seed, start, name = seed
    rng = np.random.default_rng([noise_seed, start, zlib.crc32(name.encode())])
    out = []
    for image in images:
        if image.dtype != np.uint8:
            raise ValueError(f'sensor noise needs 8-bit frames, got {image.dtype}')
        noisy = image.astype(np.float32) + rng.normal(0.0, sigma, image.shape).astype(np.float32)
        out.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
    return out


def _run_selector(
    batch: _Batch, models: ModelSet, config: SelectorConfig, tolerance: float
) -> BatchOutcome:
    selector = Selector(models, batch.intrinsics, replace(config, mode='once'))
    for k in range(len(batch.images)):
        i = batch.start + k
        result = selector.process(batch.images[k], int(batch.stamps_ns[i]))
        init = result.initialization
        if init is None:
            continue
        ref = int(np.searchsorted(batch.stamps_ns, init.reference_stamp_ns))
        cur = int(np.searchsorted(batch.stamps_ns, init.stamp_ns))
        # the selector may re-reference inside the batch: judge its pair
        batch_for_pair = batch.sub(ref, cur + 1) if ref != batch.start else batch
        out = batch_for_pair.outcome(
            INITSEL,
            cur,
            init.method.value,
            init.R,
            init.t,
            init.points,
            init.pixels_ref,
            published=i,
        )
        out = replace(
            out,
            start=batch.start,
            frames_to_init=float(cur - batch.start),
            frames_to_publish=float(i - batch.start),
            reference_offset=float(ref - batch.start),
        )
        return _compare_methods(batch_for_pair, ref, cur, out, config, tolerance)
    return batch.missed(INITSEL)


def _tracks_until(batch: _Batch, config: SelectorConfig, ref: int, cur: int):
    tracker = KltTracker(config.tracker, batch.intrinsics.field_mask())
    tracker.reset(batch.gray(ref - batch.start))
    for k in range(ref - batch.start + 1, cur - batch.start + 1):
        tracker.track(batch.gray(k))
    tracks = tracker.anchored()  # as the selector estimates geometry
    return batch.undistort(tracks.ref), batch.undistort(tracks.cur)


def _compare_methods(
    batch: _Batch, ref: int, cur: int, out: BatchOutcome, config: SelectorConfig, tolerance: float
) -> BatchOutcome:
    """E_t of each method (estimated and refined as the selector would) on the same pair."""
    p0, p1 = _tracks_until(batch, config, ref, cur)
    K = batch.intrinsics.K
    fire = initialize_pair(p0, p1, K, POSE_METHODS, ESTIMATES_ONLY)
    errors = {}
    for estimate in fire.estimates:
        m = estimate.method.value
        if not estimate.ok:
            errors[m] = math.nan
            continue
        seed = seed_map(
            estimate,
            p0,
            p1,
            K,
            refine=config.refine,
            as_plane=plane_is_the_scene(estimate, config.policy),
        )
        errors[m] = _pose_errors(batch.poses[ref], batch.poses[cur], seed.R, seed.t)[0]
    finite = {m: e for m, e in errors.items() if math.isfinite(e)}
    best = min(finite, key=finite.get) if finite else ''
    chosen_ok = bool(finite) and out.e_t <= min(finite.values()) + tolerance
    return replace(
        out,
        best_method=best,
        chosen_ok=chosen_ok,
        e_t_f=errors['F'],
        e_t_e=errors['E'],
        e_t_h=errors['H'],
    )


def _orb_attempt(p0, p1, K, version: OrbSlamVersion):
    scores = orbslam_scores(p0, p1)
    if not math.isfinite(scores.ratio):
        return None
    method = 'H' if scores.ratio > version.ratio_threshold else 'F'
    est = _estimate(method, p0, p1, K)
    if est and est.n_points >= ORB_MIN_POINTS and est.parallax_deg >= ORB_MIN_PARALLAX_DEG:
        return method, est.R, est.t, est.points, p0[est.indices]
    return None


def _vins_attempt(p0, p1, K):
    result = vins_relative_pose(p0, p1, K, run_ransac=False)
    if not result.accepted:
        return None
    tri = triangulate_pair(result.R, result.t, K, p0, p1)
    good = tri.in_front & (tri.reprojection_px <= 2.5)
    return 'E', result.R, result.t, tri.points[good], p0[good]


def _butt_attempt(p0, p1, K):
    disparity = np.linalg.norm(p1 - p0, axis=1)
    h_good, f_good = butt_rule(np.array([disparity.mean()]), np.array([disparity.std()]))
    if not h_good[0]:
        return None
    method = 'F' if f_good[0] else 'H'
    est = _estimate(method, p0, p1, K)
    if est is None:
        return None
    return method, est.R, est.t, est.points, p0[est.indices]


def _colmap_attempt(intrinsics: Intrinsics) -> Callable:
    from initsel_ros.learn.real_baselines.colmap import colmap_attempt

    return lambda a, b, K: colmap_attempt(a, b, intrinsics)


def _run_track_baselines(
    batch: _Batch, config: SelectorConfig, baselines: Sequence[str]
) -> list[BatchOutcome]:
    """The baselines that run on the batch's KLT tracks: the rules and COLMAP."""
    attempts: dict[str, Callable] = {}
    if 'colmap' in baselines:
        attempts[COLMAP_REAL] = _colmap_attempt(batch.intrinsics)
    if 'rules' in baselines:
        attempts[ORB2_RULE] = lambda a, b, K: _orb_attempt(a, b, K, OrbSlamVersion.ORB2)
        attempts[ORB3_RULE] = lambda a, b, K: _orb_attempt(a, b, K, OrbSlamVersion.ORB3)
        attempts[VINS_RULE] = _vins_attempt
        attempts[BUTT_RULE] = _butt_attempt
    if not attempts:
        return []
    found: dict[str, BatchOutcome] = {}
    tracker = KltTracker(config.tracker, batch.intrinsics.field_mask())
    tracker.reset(batch.gray(0))
    K = batch.intrinsics.K
    for k in range(1, len(batch.images)):
        tracker.track(batch.gray(k))
        tracks = tracker.anchored()  # what the selector estimates its geometry from
        if len(tracks) < config.policy.min_tracks:
            break  # the selector would re-reference here; the rules stop
        p0, p1 = batch.undistort(tracks.ref), batch.undistort(tracks.cur)
        for name, attempt in attempts.items():
            if name in found:
                continue
            hit = attempt(p0, p1, K)
            if hit is not None:
                method, R, t, points, pixels = hit
                found[name] = batch.outcome(name, batch.start + k, method, R, t, points, pixels)
        if len(found) == len(attempts):
            break
    return [found.get(name, batch.missed(name)) for name in attempts]


def run_orbslam3_batch(batch: _Batch, setup: Orbslam3Setup) -> BatchOutcome:
    """The real ORB-SLAM3 on the batch's frames, judged at its first initialization."""
    from initsel_ros.learn.real_baselines.orbslam3_runner import run_orbslam3

    gray = [batch.gray(k) for k in range(len(batch.images))]
    init = run_orbslam3(gray, batch.stamps_ns[batch.start : batch.stop], batch.intrinsics, setup)
    if init.status == 'failed':
        return batch.missed(ORBSLAM3_REAL, failed=True, detail=init.detail)
    if init.status != 'initialized':
        return batch.missed(ORBSLAM3_REAL)
    ref, cur = batch.start + init.reference, batch.start + init.current
    R, t = init.pose
    K = batch.intrinsics.K
    points = init.points
    in_front = points[:, 2] > 0
    pixels = (points[in_front] @ K.T)[:, :2] / points[in_front, 2:3]
    judged = batch.sub(ref, cur + 1) if ref != batch.start else batch
    out = judged.outcome(ORBSLAM3_REAL, cur, '', R, t, points[in_front], pixels)
    return replace(
        out,
        start=batch.start,
        frames_to_init=float(cur - batch.start),
        frames_to_publish=float(cur - batch.start),
        reference_offset=float(ref - batch.start),
    )


def evaluate_batch(
    path: str,
    start: int,
    length: int,
    model_path: str,
    config: SelectorConfig,
    tolerance: float = 0.05,
    baselines: bool | BaselineOptions = True,
    group: str = '',
    reader: Mapping[str, Any] | None = None,
) -> list[BatchOutcome]:
    """Every system's outcome on one batch (a process-pool task: arguments are picklable).

    ``baselines``: True = the rules, False = the selector only, or a :class:`BaselineOptions`.
    ``reader``: the sequence's reader options (``datasets.reader_options``).
    """
    options = _options(baselines)
    cv2.setNumThreads(1)
    sequence = _open_quietly(path, reader or {})
    batch = _Batch(sequence, start, length, group, options.sensor_noise, options.noise_seed)
    models = ModelSet.load(model_path)
    outcomes = [_run_selector(batch, models, config, tolerance)]
    if 'orbslam3' in options.baselines:
        outcomes.append(run_orbslam3_batch(batch, options.orbslam3))
    outcomes += _run_track_baselines(batch, config, options.baselines)
    seed = options.noise_seed if options.sensor_noise > 0 else -1
    return [replace(o, noise_seed=seed) for o in outcomes]


def _open_quietly(path: str, reader: Mapping[str, Any]):
    """A batch worker's sequence: opened once per process, without the readers' warnings
    (:func:`evaluate_sequences` has said them once already)."""
    from initsel_ros.datasets.cache import open_cached

    return open_cached(path, quiet=True, **reader)


def batch_windows(
    has_pose: np.ndarray, length: int, step: int
) -> tuple[list[tuple[int, int]], int]:
    """(first frame, frames) of the batches of a sequence whose frames have a ground-truth pose
    where ``has_pose``: one every ``step`` frames, ``length`` frames long (shorter at the
    end). Where a batch's first frame has no pose it starts on its first frame that has one
    (the initialization is judged against the batch's first frame, and the real TUM sequences
    start before their motion capture), keeping its last frame (of two batches moved to one
    frame, the longer is kept); a batch with fewer than 2 frames from there is left out, and
    one without any pose keeps its start (its initializations go unjudged). Returns (windows,
    how many batches were moved)."""
    n = len(has_pose)
    starts = range(0, max(n - length // 2, 1), step)
    windows: dict[int, int] = {}  # first frame -> frames (two batches moved to one frame: one)
    for s in starts:
        stop = min(s + length, n)
        posed = np.flatnonzero(has_pose[s:stop])
        first = s + int(posed[0]) if posed.size else s
        if stop - first < 2:
            continue
        windows[first] = stop - first
    return list(windows.items()), sum(first not in starts for first in windows)


def _options(baselines: bool | BaselineOptions) -> BaselineOptions:
    if isinstance(baselines, BaselineOptions):
        return baselines
    return BaselineOptions(('rules',) if baselines else ())


def evaluate_sequences(
    paths: Sequence[Path | str],
    model_path: Path | str,
    config: SelectorConfig | None = None,
    *,
    length: int = 60,
    step: int = 30,
    jobs: int = 2,
    tolerance: float = 0.05,
    baselines: bool | BaselineOptions = True,
    groups: dict[str, str] | None = None,
    noise_seeds: Sequence[int] | None = None,
    progress: Callable[[int, int], None] | None = None,
    nearest_tolerance: float | None = None,
    image_topic: str | None = None,
    kitti_sequence: str | None = None,
) -> list[BatchOutcome]:
    """Run :func:`evaluate_batch` over every batch of every sequence (in a process pool).

    ``nearest_tolerance``, ``image_topic`` and ``kitti_sequence`` go to the readers they apply
    to (``datasets.reader_options``).

    Batches start every ``step`` frames, on their first frame with a ground-truth pose
    (:func:`batch_windows`).

    Args:
        groups: sequence path (as given) or folder name -> group (one of :data:`GROUPS`);
            sequences it does not name get :func:`default_group`.
        noise_seeds: with sensor noise, run every batch once per seed (pooled in the table;
            default: the options' one seed).

    Raises:
        ValueError: a group is not one of :data:`GROUPS`.
    """
    from initsel_ros.datasets import open_sequence, reader_options
    from initsel_ros.datasets.cache import forget_sequences, keep_sequence

    config = config or SelectorConfig()
    options = _options(baselines)
    groups = groups or {}
    bad = {g for g in groups.values() if g not in GROUPS}
    if bad:
        raise ValueError(f'unknown groups {sorted(bad)}: choose from {GROUPS}')
    tasks = []
    forget_sequences()  # (what an earlier call left, had it failed: read the sequences afresh)
    for path in paths:
        reader = reader_options(
            path,
            nearest_tolerance=nearest_tolerance,
            image_topic=image_topic,
            sequence=kitti_sequence,
        )
        sequence = open_sequence(path, **reader)
        if jobs <= 1:  # the batches run in this process: they read this very sequence
            keep_sequence(sequence, str(path), **reader)
        windows, moved = batch_windows(sequence.has_pose, length, step)
        if moved:
            LOG.warning(
                '%s: %d batches start on frames without a ground-truth pose: each starts on '
                'its first frame with one',
                sequence.name,
                moved,
            )
        group = groups.get(str(path), groups.get(Path(path).name, ''))
        tasks += [(str(path), s, k, group, reader) for s, k in windows]
    outcomes: list[BatchOutcome] = []
    seeds = list(noise_seeds or [options.noise_seed]) if options.sensor_noise > 0 else [-1]
    args = [
        (p, s, n, str(model_path), config, tolerance, replace(options, noise_seed=seed), g, r)
        for seed in seeds
        for p, s, n, g, r in tasks
    ]
    if jobs <= 1:
        results: Iterable = (evaluate_batch(*a) for a in args)
        try:
            for k, res in enumerate(results):
                outcomes += res
                if progress:
                    progress(k + 1, len(args))
        finally:
            forget_sequences()  # (in this process: the next call reads the sequences afresh)
        return outcomes
    import multiprocessing

    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context('spawn')) as pool:
        for k, res in enumerate(pool.map(evaluate_batch, *zip(*args, strict=True))):
            outcomes += res
            if progress:
                progress(k + 1, len(args))
    return outcomes


@dataclass(frozen=True)
class SystemSummary:
    """One row of the seed-map table: a system on a group of sequences."""

    group: str
    system: str
    batches: int
    initialized: int
    failed: int
    median_e_t: float
    median_rotation_deg: float
    median_depth_error: float
    share_e_t_below_0_1: float
    chosen_ok_share: float
    median_frames_to_init: float
    median_frames_to_publish: float
    methods: str


def summarize(outcomes: Sequence[BatchOutcome]) -> list[SystemSummary]:
    """Per group (planar, non-planar, rotation/static) and system, the table's figures."""
    rows = []
    for group in GROUPS:
        for system in SYSTEMS:
            sel = [o for o in outcomes if o.system == system and o.table_group == group]
            if not sel:
                continue
            done = [o for o in sel if o.initialized]
            # judged against the ground truth: a pair whose frames have no pose has no
            # baseline (a pure rotation has one, 0, and no E_t: a miss, as before)
            judged = [o for o in done if math.isfinite(o.baseline_m)]
            if len(judged) < len(done):
                LOG.warning(
                    '%s, %s: %d of %d initializations have no ground-truth pose to judge them '
                    '(left out of E_t < 0.1 and chosen method best)',
                    group,
                    system,
                    len(done) - len(judged),
                    len(done),
                )
            counts: dict[str, int] = {}
            for o in done:
                if o.method:
                    counts[o.method] = counts.get(o.method, 0) + 1
            rows.append(
                SystemSummary(
                    group,
                    system,
                    len(sel),
                    len(done),
                    sum(o.failed for o in sel),
                    finite_median([o.e_t for o in done]),
                    finite_median([o.rotation_deg for o in done]),
                    finite_median([o.depth_error for o in done]),
                    float(np.mean([o.e_t < 0.1 for o in judged])) if judged else math.nan,
                    float(np.mean([o.chosen_ok for o in judged]))
                    if judged and system == INITSEL
                    else math.nan,
                    finite_median([o.frames_to_init for o in done]),
                    finite_median([o.frames_to_publish for o in done]),
                    ' '.join(f'{m}:{c}' for m, c in sorted(counts.items())),
                )
            )
    return rows


def summary_markdown(rows: Sequence[SystemSummary]) -> str:
    """The seed-map table as Markdown."""
    lines = [
        '| sequences | system | batches | initialized | failed | median E_t | median rotation '
        'error, deg | median depth error | E_t < 0.1 | chosen method best (+-0.05 E_t) | '
        'median frames to init | median frames to publish | methods |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    for r in rows:
        lines.append(
            f'| {r.group} | {r.system} | {r.batches} | {r.initialized} | {r.failed} | '
            f'{number(r.median_e_t)} | '
            f'{number(r.median_rotation_deg, 2)} | {number(r.median_depth_error)} | '
            f'{number(r.share_e_t_below_0_1, 2)} | {number(r.chosen_ok_share, 2)} | '
            f'{number(r.median_frames_to_init, 1)} | {number(r.median_frames_to_publish, 1)} | '
            f'{r.methods} |'
        )
    return '\n'.join(lines)


def outcomes_csv(outcomes: Sequence[BatchOutcome], path: Path) -> None:
    """Every batch outcome, one CSV row each."""
    import csv

    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'w', newline='') as f:
        writer = csv.DictWriter(
            f, fieldnames=list(asdict(outcomes[0]).keys()) if outcomes else ['sequence']
        )
        writer.writeheader()
        for o in outcomes:
            writer.writerow(asdict(o))


__all__ = [
    'BASELINES',
    'COLMAP_REAL',
    'GROUPS',
    'INITSEL',
    'ORBSLAM3_REAL',
    'RULE_SYSTEMS',
    'SYSTEMS',
    'BaselineOptions',
    'BatchOutcome',
    'SystemSummary',
    'add_sensor_noise',
    'default_group',
    'depth_error',
    'evaluate_batch',
    'evaluate_sequences',
    'outcomes_csv',
    'run_orbslam3_batch',
    'summarize',
    'summary_markdown',
]
