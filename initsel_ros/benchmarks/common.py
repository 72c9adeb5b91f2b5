"""Shared pieces of the benchmarks: timing statistics, memory, models and test data."""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.errors import InitselError

log = logging.getLogger(__name__)

#: Size of the benchmark images and number of tracks, as the task specifies.
WIDTH, HEIGHT, TRACKS = 640, 480, 300


@dataclass(frozen=True)
class Timing:
    """Wall-clock samples of one operation.

    Attributes:
        name: what was timed.
        seconds: (N,) float64 samples, seconds.
    """

    name: str
    seconds: np.ndarray

    @property
    def median(self) -> float:
        """Median, seconds."""
        return float(np.median(self.seconds))

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile, seconds."""
        return float(np.percentile(self.seconds, q))

    def to_dict(self) -> dict[str, float]:
        """Median, p90, p99, min and max in microseconds, and the sample count."""
        s = self.seconds * 1e6
        return {
            'n': int(s.size),
            'median_us': float(np.median(s)),
            'p90_us': float(np.percentile(s, 90)),
            'p99_us': float(np.percentile(s, 99)),
            'min_us': float(s.min()),
            'max_us': float(s.max()),
        }


def time_calls(fn: Callable[[int], Any], repeat: int, warmup: int = 3) -> np.ndarray:
    """Time ``fn(i)`` for i in range(repeat) after ``warmup`` untimed calls.

    Returns:
        (repeat,) float64 seconds per call.
    """
    for i in range(warmup):
        fn(i)
    out = np.empty(repeat, dtype=np.float64)
    clock = time.perf_counter
    for i in range(repeat):
        t0 = clock()
        fn(i)
        out[i] = clock() - t0
    return out


def rss_bytes(pid: int | None = None) -> int:
    """Resident set size of a process (default: this one), bytes; 0 when unknown."""
    path = Path(f'/proc/{pid or os.getpid()}/statm')
    try:
        pages = int(path.read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return 0
    return pages * os.sysconf('SC_PAGE_SIZE')


def random_models(
    seed: int = 0, features: np.ndarray | None = None, positive_rate: float = 0.5
) -> Any:
    """A ModelSet fitted with scikit-learn on random (or given) features and random labels.

    Only the shapes matter for timing; the probabilities mean nothing. With ``features``
    ((N, 23) rows computed from real correspondences) and a low ``positive_rate`` the models
    fire about that often on similar pairs, as trained models do on most frames.
    """
    from sklearn.linear_model import LogisticRegression
    from sklearn.preprocessing import StandardScaler

    from initsel_ros.features import N_FEATURES, Scaling
    from initsel_ros.models import LogisticModel, ModelSet
    from initsel_ros.names import MODEL_NAMES

    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 1.0, size=(2000, N_FEATURES)) if features is None else features
    scaler = StandardScaler().fit(X)
    scale = np.where(scaler.scale_ > 0, scaler.scale_, 1.0)
    Xs = (X - scaler.mean_) / scale
    models = {}
    for name in MODEL_NAMES:
        y = rng.random(len(X)) < positive_rate
        y[:2] = (True, False)  # both classes present
        fit = LogisticRegression(max_iter=500).fit(Xs, y.astype(int))
        models[name] = LogisticModel(
            name,
            fit.coef_[0],
            float(fit.intercept_[0]),
            0.5,
            scaler.mean_,
            scale,
            {'note': 'random labels, benchmark only'},
        )
    source = 'random features' if features is None else f'{len(X)} feature rows'
    return ModelSet(
        models,
        Scaling.RESOLUTION_FREE,
        metadata={'trained_on': f'{source} with random labels (initsel bench)'},
    )


def sequence_features(seq: Any, span: int = 30, max_features: int = TRACKS) -> np.ndarray:
    """(N, 23) features of every frame against a reference every ``span`` frames (KLT)."""
    from initsel_ros.features import Scaling, pair_features
    from initsel_ros.tracking import KltTracker, TrackerConfig

    tracker = KltTracker(TrackerConfig(max_features=max_features))
    intr = seq.intrinsics
    rows = []
    for i in range(len(seq)):
        gray = seq.gray(i)
        if i % span == 0:
            tracker.reset(gray)
            continue
        tracks = tracker.track(gray)
        if len(tracks) >= 8:
            rows.append(
                pair_features(
                    tracks.ref, tracks.cur, intr.width, intr.height, Scaling.RESOLUTION_FREE
                )
            )
    return np.array(rows).reshape(-1, 23)


def bench_models(path: Path | None, seq: Any = None) -> tuple[Any, Path | None, str]:
    """The model file to benchmark with, else models fitted on the fly.

    Without a model file, the models are fitted on the features of ``seq`` (when given) with
    random labels, 5 % positive, so they fire on few frames; else on random features.

    Returns:
        (ModelSet, path of the file or None, a one-line description for the output).
    """
    from initsel_ros.models import ModelSet, default_model_path

    if path is None:
        try:
            path = default_model_path()
        except InitselError:
            path = None
    if path is not None and Path(path).is_file():
        return ModelSet.load(path), Path(path), f'model file {path}'
    if seq is None:
        return (
            random_models(),
            None,
            'no model file found: models fitted with scikit-learn on random features '
            '(realistic shapes, meaningless probabilities)',
        )
    features = sequence_features(seq)
    return (
        random_models(features=features, positive_rate=0.05),
        None,
        "no model file found: models fitted with scikit-learn on this sequence's "
        f'{len(features)} feature rows with random labels (5 % positive): realistic '
        'shapes, meaningless probabilities',
    )


def render_bench_sequence(folder: Path, frames: int, seed: int = 0) -> Any:
    """Render (or reuse) a 640x480 synthetic sequence and open it.

    Raises:
        InitselError: when the renderer is not available in this installation.
    """
    from initsel_ros.datasets import open_sequence

    folder = Path(folder)
    if (folder / 'rgb.txt').is_file():
        seq = open_sequence(folder)
        if len(seq) >= frames:
            return seq
    try:
        from initsel_ros.synth import render_sequence
    except ImportError as exc:
        raise InitselError(
            f'the renderer (initsel_ros.synth.render_sequence) is missing: {exc}'
        ) from exc
    log.info('rendering %d frames into %s', frames, folder)
    render_sequence(folder, scene='structure_texture', trajectory='near', frames=frames, seed=seed)
    return open_sequence(folder)


def correspondence_sets(
    seq: Any, n_sets: int, span: int = 12, max_features: int = TRACKS
) -> list[tuple[np.ndarray, np.ndarray]]:
    """KLT correspondences between frames ``span`` apart, from several references.

    Returns:
        Up to ``n_sets`` pairs of (N, 2) float32 pixel arrays (N close to ``max_features``).
    """
    from initsel_ros.tracking import KltTracker, TrackerConfig

    tracker = KltTracker(TrackerConfig(max_features=max_features))
    out = []
    n = len(seq)
    step = max(1, (n - span - 1) // max(n_sets, 1))
    for ref in range(0, max(n - span, 1), step):
        tracker.reset(seq.gray(ref))
        tracks = None
        for i in range(ref + 1, min(ref + span + 1, n)):
            tracks = tracker.track(seq.gray(i))
        if tracks is not None and len(tracks) >= 8:
            out.append((tracks.ref.copy(), tracks.cur.copy()))
        if len(out) >= n_sets:
            break
    if not out:
        raise InitselError(f'no correspondences could be tracked in {seq}')
    return out


@dataclass(frozen=True)
class FirePair:
    """A pair the selector would initialize on: KLT tracks and the ground-truth motion.

    Attributes:
        ref, cur: frame indices.
        p0, p1: (N, 2) float64 pixels in the reference and current frame.
        R_gt: (3, 3) ground-truth rotation, reference to current.
        t_gt: (3,) ground-truth translation, reference to current, metres.
    """

    ref: int
    cur: int
    p0: np.ndarray
    p1: np.ndarray
    R_gt: np.ndarray
    t_gt: np.ndarray


#: Frames between the reference and the current frame of the fire-time pairs, and between
#: successive references. On the near trajectory the camera first turns: the rotation test
#: passes 15-60 frames after a reference, where the selector fires.
FIRE_SPANS = tuple(range(15, 61, 5))
FIRE_REFERENCE_STEP = 7


def fire_pairs(
    seq: Any, n_pairs: int, max_features: int = TRACKS, min_tracks: int = 50
) -> list[FirePair]:
    """Distinct pairs of ``seq`` whose fire path ends in a refined winner.

    References every :data:`FIRE_REFERENCE_STEP` frames, current frames :data:`FIRE_SPANS`
    later (KLT as the selector tracks); a pair is kept when
    :func:`~initsel_ros.initialize.initialize_pair` with F, E and H (refinement off) passes
    the rotation test and leaves a winner: the pairs the bundle adjustment runs on.

    Returns:
        Up to ``n_pairs`` pairs, in frame order (fewer when the sequence has fewer).
    """
    from initsel_ros.geometry import Method
    from initsel_ros.initialize import FireConfig, initialize_pair
    from initsel_ros.metrics import relative_pose
    from initsel_ros.policy import Reason
    from initsel_ros.tracking import KltTracker, TrackerConfig

    K = seq.intrinsics.K
    poses = seq.poses()
    unrefined = FireConfig(refine=False)
    tracker = KltTracker(TrackerConfig(max_features=max_features))
    out: list[FirePair] = []
    n = len(seq)
    for ref in range(0, max(n - min(FIRE_SPANS), 0), FIRE_REFERENCE_STEP):
        tracker.reset(seq.gray(ref))
        for cur in range(ref + 1, min(ref + max(FIRE_SPANS), n - 1) + 1):
            tracks = tracker.track(seq.gray(cur))
            if len(tracks) < min_tracks:
                break
            if cur - ref not in FIRE_SPANS or not np.isfinite(poses[[ref, cur]]).all():
                continue
            p0, p1 = tracks.ref.astype(np.float64), tracks.cur.astype(np.float64)
            fire = initialize_pair(p0, p1, K, (Method.F, Method.E, Method.H), unrefined)
            if fire.reason is not Reason.INITIALIZED:
                continue
            R_gt, t_gt = relative_pose(poses[ref], poses[cur])
            out.append(FirePair(ref, cur, p0, p1, R_gt, t_gt))
            if len(out) >= n_pairs:
                return out
    return out


__all__ = [
    'FIRE_REFERENCE_STEP',
    'FIRE_SPANS',
    'HEIGHT',
    'TRACKS',
    'WIDTH',
    'FirePair',
    'Timing',
    'bench_models',
    'correspondence_sets',
    'fire_pairs',
    'random_models',
    'render_bench_sequence',
    'rss_bytes',
    'sequence_features',
    'time_calls',
]
