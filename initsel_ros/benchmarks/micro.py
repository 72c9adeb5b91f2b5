"""In-process timings without ROS: the decision, the baselines, memory, dataset building.

(The per-frame path from an Image message is timed in :mod:`initsel_ros.ros.bench_frame`.)

Every function returns plain results; :mod:`initsel_ros.bench` prints and saves them.
"""

from __future__ import annotations

import gc
import logging
import os
import shutil
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from initsel_ros.benchmarks.common import Timing, rss_bytes, time_calls
from initsel_ros.geometry import (
    RADIAL_FOCAL_SCALES,
    ROTATION_FOCAL_SCALES,
    ROTATION_RADIAL_TERMS,
)

if TYPE_CHECKING:
    from initsel_ros.features import Camera

log = logging.getLogger(__name__)

Pairs = list[tuple[np.ndarray, np.ndarray]]


def decision_fn(
    models: Any, width: int, height: int, camera: Camera | None = None
) -> Callable[[np.ndarray, np.ndarray], Any]:
    """The selector's per-pair decision (``selector.decide_pair``, as ``Selector.process``;
    ``camera`` = (fx, fy, cx, cy) for the features that need it)."""
    from initsel_ros.policy import PolicyConfig, effective_thresholds
    from initsel_ros.selector import decide_pair

    config = PolicyConfig()
    thresholds = effective_thresholds(models.thresholds, config)

    def run(p0: np.ndarray, p1: np.ndarray) -> Any:
        return decide_pair(models, thresholds, config, p0, p1, width, height, camera)

    return run


def time_decision_parts(
    models: Any, pairs: Pairs, repeat: int, width: int, height: int, camera: Camera | None = None
) -> list[Timing]:
    """The decision split into model inputs, model scores and policy, each on its own inputs
    (as ``selector.decide_pair`` runs them), and the paper's 23 features alone."""
    from initsel_ros.features import raw_features
    from initsel_ros.policy import PolicyConfig, decide, effective_thresholds

    config = PolicyConfig()
    thresholds = effective_thresholds(models.thresholds, config)
    inputs = [models.input_values(p0, p1, width, height, camera) for p0, p1 in pairs]
    probs = [models.predict_values(values) for values, _ in inputs]
    extra = f' + {len(models.extra_names)} extra features, one pass' if models.extra_names else ''
    paper = (
        '23 features'
        if models.input_plan(width, height, camera).directions
        else ('15 features (no direction bins)')
    )
    return [
        *_referee_parts(models, pairs, repeat, width, height, thresholds, camera),
        Timing(
            f'  model inputs: {paper}{extra}',
            time_calls(
                lambda i: models.input_values(*pairs[i % len(pairs)], width, height, camera),
                repeat,
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


def _referee_parts(
    models: Any,
    pairs: Pairs,
    repeat: int,
    width: int,
    height: int,
    thresholds: dict[str, float],
    camera: Camera | None = None,
) -> list[Timing]:
    """Where a model file has a referee: the decision timed apart on the sets the referee
    decides and on the others (the median of all sets hides the referee when it decides on
    fewer than half of them)."""
    if models.referee is None:
        return []
    decide = decision_fn(models, width, height, camera)
    asked = [
        bool(models.predict_points(p0, p1, width, height, thresholds, camera)[2])
        for p0, p1 in pairs
    ]
    out = []
    for label, chosen in (('decides', True), ('does not decide', False)):
        sets = [pair for pair, a in zip(pairs, asked, strict=True) if a == chosen]
        if sets:
            out.append(
                Timing(
                    f'  decision where the referee {label} ({len(sets)} of {len(pairs)} sets)',
                    time_calls(lambda i, s=sets: decide(*s[i % len(s)]), max(repeat // 2, 1)),
                )
            )
    return out


@dataclass(frozen=True)
class PairedTimes:
    """The decision and ORB-SLAM's selection timed in alternating rounds on the same pairs.

    A burst of load on a shared machine then slows both in the same round, and the ratio of
    their medians per round (``ratios``) is what the target is judged on.
    """

    decision: Timing
    orbslam: Timing
    ratios: np.ndarray  # (rounds,) ORB-SLAM median / decision median, per round

    @property
    def ratio(self) -> float:
        """Median over the rounds of the per-round ratio."""
        return float(np.median(self.ratios))


def time_decision_against_orbslam(
    models: Any,
    pairs: Pairs,
    repeat: int,
    width: int,
    height: int,
    rounds: int = 10,
    iterations: int = 200,
    camera: Camera | None = None,
) -> PairedTimes:
    """``repeat`` decisions and ``repeat / 10`` ORB-SLAM selections (at least 20), in
    ``rounds`` alternating rounds (see :class:`PairedTimes`)."""
    from initsel_ros.learn.baselines import orbslam_choice, orbslam_scores

    decide = decision_fn(models, width, height, camera)
    rng = np.random.default_rng(0)

    def orb(i: int) -> None:
        p0, p1 = pairs[i % len(pairs)]
        scores = orbslam_scores(p0, p1, iterations=iterations, rng=rng)
        orbslam_choice(np.array([scores.ratio]))

    n_decision = max(repeat // rounds, 1)
    n_orb = max(repeat // 10, 20) // rounds + 1
    decisions, orbs, ratios = [], [], []
    for r in range(rounds):
        d = time_calls(lambda i: decide(*pairs[i % len(pairs)]), n_decision, warmup=3)
        o = time_calls(orb, n_orb, warmup=1 if r == 0 else 0)
        decisions.append(d)
        orbs.append(o)
        ratios.append(float(np.median(o) / np.median(d)))
    return PairedTimes(
        Timing('decision', np.concatenate(decisions)),
        Timing(f'ORB-SLAM H/F selection ({iterations} iterations each)', np.concatenate(orbs)),
        np.array(ratios),
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


@dataclass(frozen=True)
class FireTimes:
    """The fire path timed on pairs whose winner is refined, and the solvers compared.

    Attributes:
        pairs: distinct pairs timed.
        total: :func:`~initsel_ros.initialize.initialize_pair` with F, E and H, per call.
        parts: its steps, each timed alone on the same pairs (:data:`FIRE_PARTS`); the
            rotation test's single fit under the nominal K is not a step of the total.
        solvers: the bundle adjustment by the general solvers on the same pairs
            (:mod:`initsel_ros.benchmarks.solvers`), name -> timing (Ceres only when pyceres
            is installed).
        e_t: median E_t over the pairs: ``'before'`` refinement, then after it by each
            solver (``'Schur LM'`` and the names of ``solvers``).
    """

    pairs: int
    total: Timing
    parts: list[Timing]
    solvers: dict[str, Timing]
    e_t: dict[str, float]

    @property
    def guard_share(self) -> float:
        """The rotation test's median over the fire time's median."""
        return self.parts[0].median / self.total.median


#: Names of the fire path's steps, in :attr:`FireTimes.parts` order.
FIRE_PARTS = (
    f'rotation test (least-quantile fits under {len(ROTATION_FOCAL_SCALES)} focal scales at '
    f'once, least-squares ones under {len(ROTATION_RADIAL_TERMS)} radial terms x '
    f'{RADIAL_FOCAL_SCALES} scales, noise from H- and F-RANSAC)',
    'the rotation fit under the nominal K alone, noise known (not in the total)',
    'F + E + H estimates',
    'GRIC selection (with the E refit)',
    'E refit (refine_essential)',
    'bundle adjustment of the winner (Schur-complement LM)',
)


def time_fire(pairs: list[Any], K: np.ndarray, repeat: int) -> FireTimes:
    """The once-per-initialization work on ``pairs`` (:func:`~initsel_ros.benchmarks.common.
    fire_pairs`): ``initialize_pair`` with F, E and H, ``repeat`` calls cycling over them, and
    each of its steps alone as often.

    The bundle adjustment is also run by scipy's ``least_squares`` and by Ceres (when pyceres
    is installed) on the same estimates, twice per pair, and the median E_t of the winners is
    measured before refinement and after each solver.
    """
    from initsel_ros.benchmarks.solvers import (
        ceres_available,
        ceres_two_view,
        schur_two_view,
        scipy_two_view,
    )
    from initsel_ros.geometry import Method, estimate_pose, rotation_test
    from initsel_ros.initialize import FireConfig, initialize_pair
    from initsel_ros.metrics import translation_chordal_error
    from initsel_ros.model_selection import select_method
    from initsel_ros.policy import check_pose
    from initsel_ros.refine import refine_essential, two_view_problem

    config = FireConfig()
    policy = config.policy
    methods = (Method.F, Method.E, Method.H)
    m = len(pairs)
    fired = [initialize_pair(p.p0, p.p1, K, methods, config) for p in pairs]
    winners = [next(e for e in f.estimates if e.method is f.selection.winner) for f in fired]

    def total(i: int) -> Any:
        pair = pairs[i % m]
        return initialize_pair(pair.p0, pair.p1, K, methods, config)

    def guard(i: int) -> float:  # (the fire path's terms: its pairs have no distortion)
        pair = pairs[i % m]
        return rotation_test(pair.p0, pair.p1, K, radial_terms=config.radial_terms).statistic

    noise = [rotation_test(p.p0, p.p1, K).noise_px for p in pairs]

    def one_fit(i: int) -> float:  # the guard's fit without its noise estimate and scales
        pair = pairs[i % m]
        return rotation_test(pair.p0, pair.p1, K, (1.0,), noise_px=noise[i % m]).residual_px

    def estimates(i: int) -> list[Any]:
        ests = [estimate_pose(method, pairs[i % m].p0, pairs[i % m].p1, K) for method in methods]
        return [check_pose(e, policy) for e in ests]

    def select(i: int) -> Any:
        f = fired[i % m]
        problems = ['' if c is None else 'failed' for c in f.checks]
        return select_method(f.estimates, problems, pairs[i % m].p0, pairs[i % m].p1, K)

    def e_refit(i: int) -> Any:
        est, pair = fired[i % m].estimate(Method.E), pairs[i % m]
        if est is not None and est.ok:
            refine_essential(est.R, est.t, pair.p0[est.inliers], pair.p1[est.inliers], K)

    def adjust(solver: Any, i: int) -> Any:
        w, pair = winners[i % m], pairs[i % m]
        return solver(
            two_view_problem(w.R, w.t, w.points, pair.p0[w.indices], pair.p1[w.indices], K)
        )

    parts = [
        Timing(FIRE_PARTS[0], time_calls(guard, repeat, warmup=1)),
        Timing(FIRE_PARTS[1], time_calls(one_fit, repeat, warmup=1)),
        Timing(FIRE_PARTS[2], time_calls(estimates, repeat, warmup=1)),
        Timing(FIRE_PARTS[3], time_calls(select, repeat, warmup=1)),
        Timing(FIRE_PARTS[4], time_calls(e_refit, repeat, warmup=1)),
        Timing(FIRE_PARTS[5], time_calls(lambda i: adjust(schur_two_view, i), repeat, warmup=1)),
    ]
    fire_time = Timing('fire time', time_calls(total, repeat, warmup=1))
    before = [translation_chordal_error(p.t_gt, w.t) for p, w in zip(pairs, winners, strict=True)]
    e_t = {'before': float(np.median(before))}
    named = [('Schur LM', schur_two_view), ('scipy least_squares (trf, lsmr)', scipy_two_view)]
    if ceres_available():
        named.append(('Ceres (pyceres, dense Schur, a Python cost per point)', ceres_two_view))
    solvers: dict[str, Timing] = {}
    for name, solver in named:
        results = [adjust(solver, i) for i in range(m)]
        e_t[name] = float(
            np.median(
                [
                    translation_chordal_error(p.t_gt, r.t)
                    for p, r in zip(pairs, results, strict=True)
                ]
            )
        )
        if name != 'Schur LM':
            seconds = time_calls(lambda i, s=solver: adjust(s, i), 2 * m, warmup=0)
            solvers[name] = Timing(name, seconds)
    return FireTimes(m, fire_time, parts, solvers, e_t)


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


def _link_or_copy(source: str, target: str) -> None:
    """A hard link, or a copy where the two are on different file systems."""
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def dataset_speed(folder: Path, jobs: int, batch: int = 30, repeat: int = 1) -> DatasetResult:
    """Build the pair table of one sequence, ``repeat`` times over, with ``jobs`` processes
    (learn.pairs; the repeats amortize the workers' start-up as a longer dataset would)."""
    import tempfile

    from initsel_ros.learn.build import build_table
    from initsel_ros.learn.pairs import DatasetConfig

    stats: list[Any] = []
    with tempfile.TemporaryDirectory(prefix='initsel-bench-dataset-') as tmp:
        # the repeats under names of their own (a pair table refuses one name twice), as
        # hard links: no frame is copied
        sources = [Path(folder)]
        for k in range(1, max(1, repeat)):
            copy = Path(tmp) / f'{Path(folder).resolve().name}_{k}'
            shutil.copytree(Path(folder).resolve(), copy, copy_function=_link_or_copy)
            sources.append(copy)
        start = time.perf_counter()
        table = build_table(
            sources, DatasetConfig(batch=batch, jobs=jobs), progress=False, on_stats=stats.append
        )
        seconds = stats[0].seconds if stats else time.perf_counter() - start
    return DatasetResult(jobs, len(table), seconds)


__all__ = [
    'FIRE_PARTS',
    'DatasetResult',
    'FireTimes',
    'MemoryResult',
    'PairedTimes',
    'dataset_speed',
    'decision_fn',
    'memory_growth',
    'time_decision_against_orbslam',
    'time_decision_parts',
    'time_estimators',
    'time_fire',
]
