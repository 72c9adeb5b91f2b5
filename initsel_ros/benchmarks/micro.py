"""In-process timings without ROS: the decision, the baselines, memory, dataset building.

(The per-frame path from an Image message is timed in :mod:`initsel_ros.ros.bench_frame`.)

Every function returns plain results; :mod:`initsel_ros.bench` prints and saves them.
"""

from __future__ import annotations

import gc
import logging
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.benchmarks.common import Timing, rss_bytes, time_calls

log = logging.getLogger(__name__)

Pairs = list[tuple[np.ndarray, np.ndarray]]


def decision_fn(models: Any, width: int, height: int) -> Callable[[np.ndarray, np.ndarray], Any]:
    """The selector's per-pair decision (``selector.decide_pair``, as ``Selector.process``)."""
    from initsel_ros.policy import PolicyConfig, effective_thresholds
    from initsel_ros.selector import decide_pair

    config = PolicyConfig()
    thresholds = effective_thresholds(models.thresholds, config)

    def run(p0: np.ndarray, p1: np.ndarray) -> Any:
        return decide_pair(models, thresholds, config, p0, p1, width, height)

    return run


def time_decision(models: Any, pairs: Pairs, repeat: int, width: int, height: int) -> Timing:
    """Decision time per correspondence set."""
    fn = decision_fn(models, width, height)
    return Timing('decision', time_calls(lambda i: fn(*pairs[i % len(pairs)]), repeat))


def time_decision_parts(
    models: Any, pairs: Pairs, repeat: int, width: int, height: int
) -> list[Timing]:
    """The decision split into model inputs, model scores and policy, each on its own inputs
    (as ``selector.decide_pair`` runs them), and the paper's 23 features alone."""
    from initsel_ros.features import raw_features
    from initsel_ros.policy import PolicyConfig, decide, effective_thresholds

    config = PolicyConfig()
    thresholds = effective_thresholds(models.thresholds, config)
    inputs = [models.input_values(p0, p1, width, height) for p0, p1 in pairs]
    probs = [models.predict_values(values) for values, _ in inputs]
    extra = f' + {len(models.extra_names)} extra features, one pass' if models.extra_names else ''
    return [
        Timing(
            f'  model inputs: 23 features{extra}',
            time_calls(
                lambda i: models.input_values(*pairs[i % len(pairs)], width, height), repeat
            ),
        ),
        Timing(
            '    the 23 features alone',
            time_calls(lambda i: raw_features(*pairs[i % len(pairs)]), repeat),
        ),
        Timing(
            '  four models',
            time_calls(lambda i: models.predict_values(inputs[i % len(pairs)][0]), repeat),
        ),
        Timing(
            '  policy',
            time_calls(
                lambda i: decide(
                    probs[i % len(pairs)],
                    thresholds,
                    len(pairs[i % len(pairs)][0]),
                    inputs[i % len(pairs)][1],
                    config,
                ),
                repeat,
            ),
        ),
    ]


def time_orbslam(pairs: Pairs, repeat: int, iterations: int = 200) -> Timing:
    """ORB-SLAM-style H/F selection (learn.baselines): both RANSACs and the ratio choice."""
    from initsel_ros.learn.baselines import orbslam_choice, orbslam_scores

    rng = np.random.default_rng(0)

    def run(i: int) -> None:
        p0, p1 = pairs[i % len(pairs)]
        scores = orbslam_scores(p0, p1, iterations=iterations, rng=rng)
        orbslam_choice(np.array([scores.ratio]))

    return Timing(
        f'ORB-SLAM H/F selection ({iterations} iterations each)', time_calls(run, repeat, warmup=1)
    )


def time_estimators(pairs: Pairs, K: np.ndarray, repeat: int) -> list[Timing]:
    """estimate_pose for F, E and H, each, and all three together."""
    from initsel_ros.geometry import Method, estimate_pose

    out = []
    for method in (Method.F, Method.E, Method.H):
        out.append(
            Timing(
                f'estimate_pose {method.value}',
                time_calls(
                    lambda i, m=method: estimate_pose(m, *pairs[i % len(pairs)], K),
                    repeat,
                    warmup=1,
                ),
            )
        )
    out.append(Timing('F + E + H outright', np.sum([t.seconds for t in out], axis=0)))
    return out


def time_fire(pairs: Pairs, K: np.ndarray, repeat: int) -> list[Timing]:
    """The once-per-initialization work: rotation guard, F, E, H estimates, GRIC selection,
    bundle adjustment.

    Parts are timed on the same pairs: the rotation guard (and, as its in-run baseline, its
    least-squares fit alone), the three estimates, the selection (with the E refit), and the
    two-view bundle adjustment of the winner.
    """
    from initsel_ros.geometry import Method, estimate_pose, rotation_only_residual_px
    from initsel_ros.model_selection import select_method
    from initsel_ros.refine import refine_two_view

    def estimates(i: int) -> list[Any]:
        p0, p1 = pairs[i % len(pairs)]
        return [estimate_pose(m, p0, p1, K) for m in (Method.F, Method.E, Method.H)]

    cached = [estimates(i) for i in range(len(pairs))]

    def select(i: int) -> Any:
        p0, p1 = pairs[i % len(pairs)]
        ests = cached[i % len(pairs)]
        return select_method(ests, ['' if e.ok else e.reason for e in ests], p0, p1, K)

    selections = [select(i) for i in range(len(pairs))]

    def refine(i: int) -> None:
        p0, p1 = pairs[i % len(pairs)]
        winner = selections[i % len(pairs)].winner
        est = next((e for e in cached[i % len(pairs)] if e.method is winner and e.ok), None)
        if est is not None:
            refine_two_view(est.R, est.t, est.points, p0[est.indices], p1[est.indices], K)

    def guard(i: int) -> float:
        return rotation_only_residual_px(*pairs[i % len(pairs)], K)

    def guard_least_squares(i: int) -> float:  # the search skipped: the pre-issue-13 cost
        return rotation_only_residual_px(*pairs[i % len(pairs)], K, enough_below_px=np.inf)

    guard_time = Timing('  rotation guard (least-median fit)', time_calls(guard, repeat, warmup=1))
    guard_baseline = Timing(
        '    its least-squares fit alone (the cost on a plain pan)',
        time_calls(guard_least_squares, repeat, warmup=1),
    )
    parts = [
        guard_time,
        Timing('  F + E + H estimates', time_calls(estimates, repeat, warmup=1)),
        Timing('  GRIC selection (with the E refit)', time_calls(select, repeat, warmup=1)),
        Timing('  two-view bundle adjustment of the winner', time_calls(refine, repeat, warmup=1)),
    ]
    total = Timing(
        'fire time: rotation guard + estimates + selection + bundle adjustment '
        '(once per initialization)',
        np.sum([p.seconds for p in parts], axis=0),
    )
    return [total, guard_time, guard_baseline, *parts[1:]]


@dataclass(frozen=True)
class MemoryResult:
    """Memory use of a Selector fed frames in a loop.

    Attributes:
        frames: frames processed.
        warmup: frames before the baseline measurement.
        traced_growth_bytes: growth of Python-allocated memory (tracemalloc) after warm-up.
        rss_growth_bytes: growth of the resident set size after warm-up.
        rss_end_bytes: resident set size at the end.
        seconds: wall-clock time of the run.
    """

    frames: int
    warmup: int
    traced_growth_bytes: int
    rss_growth_bytes: int
    rss_end_bytes: int
    seconds: float


def memory_growth(
    models: Any, intrinsics: Any, images: list[np.ndarray], frames: int, warmup: int = 100
) -> MemoryResult:
    """Feed ``frames`` frames (the images cycled, stamps increasing) to one Selector."""
    from initsel_ros.selector import Selector, SelectorConfig

    selector = Selector(models, intrinsics, SelectorConfig(mode='continuous'))
    n = len(images)
    start = time.perf_counter()
    gc.collect()
    tracemalloc.start()
    traced0 = rss0 = 0
    try:
        for k in range(frames):
            if k == warmup:
                gc.collect()
                traced0 = tracemalloc.get_traced_memory()[0]
                rss0 = rss_bytes()
            # Play forwards then backwards so the motion stays continuous.
            cycle = k % (2 * n - 2) if n > 1 else 0
            i = cycle if cycle < n else 2 * n - 2 - cycle
            selector.process(images[i], round(k * 1e9 / 30))
        gc.collect()
        traced1 = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    rss1 = rss_bytes()
    return MemoryResult(
        frames, warmup, traced1 - traced0, rss1 - rss0, rss1, time.perf_counter() - start
    )


@dataclass(frozen=True)
class DatasetResult:
    """Labelled pairs per second of ``build_table`` with ``jobs`` worker processes."""

    jobs: int
    pairs: int
    seconds: float

    @property
    def pairs_per_second(self) -> float:
        """Labelled pairs per wall-clock second."""
        return self.pairs / self.seconds if self.seconds > 0 else float('nan')


def dataset_speed(folder: Path, jobs: int, batch: int = 30, repeat: int = 1) -> DatasetResult:
    """Build the pair table of one sequence, ``repeat`` times over, with ``jobs`` processes
    (learn.pairs; the repeats amortize the workers' start-up as a longer dataset would)."""
    from initsel_ros.learn.build import build_table
    from initsel_ros.learn.pairs import DatasetConfig

    stats: list[Any] = []
    start = time.perf_counter()
    table = build_table(
        [folder] * max(1, repeat),
        DatasetConfig(batch=batch, jobs=jobs),
        progress=False,
        on_stats=stats.append,
    )
    seconds = stats[0].seconds if stats else time.perf_counter() - start
    return DatasetResult(jobs, len(table), seconds)


__all__ = [
    'DatasetResult',
    'MemoryResult',
    'dataset_speed',
    'decision_fn',
    'memory_growth',
    'time_decision',
    'time_decision_parts',
    'time_estimators',
    'time_orbslam',
]
