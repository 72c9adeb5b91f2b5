"""``initsel dataset``'s table builder: every batch of every sequence, in a pool or on a cluster.

Each batch is tracked in one task and its pairs are labelled in chunks
(:mod:`initsel_ros.learn.pairs`); the tasks run in this process, in a local process pool or
on a dask.distributed cluster, and the rows come out in sequence, batch and frame order
whatever the executor.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

from initsel_ros.errors import DatasetError, InitselError
from initsel_ros.learn.labels import (
    NO_DEPTH,
)
from initsel_ros.learn.pairs import (
    BatchTask,
    DatasetConfig,
    batch_ranges,
    chunk_bounds,
    label_inputs,
    labelled_batches,
    open_cached,
    track_task,
)
from initsel_ros.learn.table import (
    PairTable,
)

LOG = logging.getLogger(__name__)


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
        sequence = _open_source(path, config)
        if not sequence.has_depth:
            LOG.info(
                '%s: no depth; pairs are labelled from E_t and the rotation error '
                '(scale_rule %s, E_R NaN)',
                sequence.name,
                NO_DEPTH,
            )
        if sequence.name in names:  # the pair table tells sequences apart by name
            other = sources[names.index(sequence.name)]
            raise DatasetError(
                f'{other} and {path} are both sequence {sequence.name!r}: the pair table '
                'tells sequences apart by name (give a sequence once; rename one of two '
                'different ones)'
            )
        names.append(sequence.name)
        for b, frames in labelled_batches(sequence, config):
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


def _open_source(path: str, config: DatasetConfig) -> Any:
    """The sequence of a source (cached); a reader's foreign error as a DatasetError."""
    try:
        return open_cached(path, config)
    except InitselError:
        raise
    except Exception as exc:  # readers may raise anything on foreign files
        reason = str(exc).strip() or 'no message'
        raise DatasetError(
            f'{path}: cannot open sequence: {type(exc).__name__}: {reason}'
        ) from exc


def sources_without_batches(sources: Sequence[str | Path], config: DatasetConfig) -> list[str]:
    """The sources that cannot give a pair whatever their tracks (no batch of 2 frames with a
    pose): known before any tracking, unlike a source whose pairs all lack correspondences."""
    return [
        str(source)
        for source in sources
        if not labelled_batches(_open_source(str(source), config), config, warn=False)
    ]


def explain_no_pairs(sources: Sequence[str | Path], config: DatasetConfig) -> str:
    """Why :func:`build_table` labelled no pair, one clause per source (for a one-line error)."""
    reasons = []
    for source in sources:
        seq = _open_source(str(source), config)
        n_posed = int(seq.has_pose.sum())
        batches = batch_ranges(len(seq), config.batch, config.stride)
        if n_posed == 0:
            reasons.append(f'{seq.name}: none of its {len(seq)} frames has a ground-truth pose')
        elif not batches:
            reasons.append(
                f'{seq.name}: {len(seq)} frames make no batch of 2 or more '
                f'(batch {config.batch}, stride {config.stride})'
            )
        elif not labelled_batches(seq, config, warn=False):
            reasons.append(
                f'{seq.name}: no batch has 2 frames with a pose '
                f'({n_posed} of {len(seq)} frames have one)'
            )
        else:
            reasons.append(
                f'{seq.name}: every pair had fewer than {config.min_tracks} '
                'correspondences or no pose'
            )
    return 'no pair could be labelled: ' + '; '.join(reasons)


__all__ = [
    'BuildStats',
    'Executor',
    'build_table',
    'explain_no_pairs',
    'sources_without_batches',
]
