"""The parallel dataset builder (tracking per batch, labelling per chunk, dask) keeps every row.

The reference is the builder's former loop, pair by pair in one process: track the batch, label
each pair from the depth map, make its row. Every executor must write the same CSV text.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import pytest

from initsel_ros.errors import DatasetError
from initsel_ros.learn.build import build_table
from initsel_ros.learn.correspondences import Pair, klt_pairs
from initsel_ros.learn.labels import label_pair
from initsel_ros.learn.pairs import DatasetConfig, batch_ranges, chunk_bounds, pair_row
from initsel_ros.learn.table import PairTable, write_table


def _reference_rows(folder: Path, config: DatasetConfig) -> list[dict]:
    """The pre-chunking builder: one loop over the pairs of each batch."""
    from initsel_ros.datasets import open_sequence

    sequence = open_sequence(folder)
    intr = sequence.intrinsics
    rows = []
    for b, frames in enumerate(batch_ranges(len(sequence), config.batch, config.stride)):
        T_ref = sequence.frames[frames[0]].pose
        depth = sequence.depth(frames[0])
        for pair in klt_pairs(sequence, frames, config.tracker):
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
            labels = label_pair(
                pair.p0,
                pair.p1,
                intr.K,
                depth,
                T_ref,
                T_cur,
                config.label,
                depth_pixels=depth_pixels,
            )
            stamps = (
                float(sequence.frames[frames[0]].stamp),
                float(sequence.frames[pair.cur_index].stamp),
            )
            rows.append(
                pair_row(
                    sequence.name,
                    b,
                    pair,
                    stamps,
                    (intr.width, intr.height),
                    intr.K,
                    labels,
                    config.source,
                    config,
                )
            )
    return rows


def _csv(table: PairTable, path: Path) -> str:
    write_table(table, path)
    return path.read_text()


@pytest.fixture(scope='module')
def reference(near_sequence, tmp_path_factory):
    config = DatasetConfig(batch=30, jobs=1)
    rows = _reference_rows(near_sequence, config)
    assert len(rows) > 50  # 2 batches of 29 pairs, minus pairs without enough tracks
    return _csv(PairTable.from_rows(rows), tmp_path_factory.mktemp('ref') / 'ref.csv')


@pytest.mark.parametrize(('jobs', 'chunk'), [(1, 10), (2, 7), (2, 0)])
def test_every_executor_writes_the_reference_rows(near_sequence, reference, tmp_path, jobs, chunk):
    table = build_table(
        [near_sequence], DatasetConfig(batch=30, jobs=jobs, chunk=chunk), progress=False
    )
    assert _csv(table, tmp_path / 'new.csv') == reference


def test_in_process_build_restores_opencv_threads(near_sequence):
    threads = cv2.getNumThreads()
    build_table([near_sequence], DatasetConfig(batch=30, jobs=1, stride=6), progress=False)
    assert cv2.getNumThreads() == threads


def test_chunk_bounds_cover_every_pair_once():
    assert chunk_bounds(29, 10) == [(0, 10), (10, 20), (20, 29)]
    assert chunk_bounds(29, 0) == [(0, 29)]
    assert chunk_bounds(0, 10) == []
    covered = [i for start, stop in chunk_bounds(95, 7) for i in range(start, stop)]
    assert covered == list(range(95))


def test_scheduler_without_dask_executor_is_refused(near_sequence):
    with pytest.raises(DatasetError, match='--executor dask'):
        build_table([near_sequence], DatasetConfig(scheduler='tcp://127.0.0.1:1'), progress=False)


def test_dask_executor_without_dask_says_how_to_install(near_sequence, monkeypatch):
    monkeypatch.setitem(sys.modules, 'dask.distributed', None)  # import fails
    with pytest.raises(DatasetError, match='cluster'):
        build_table([near_sequence], DatasetConfig(batch=30, executor='dask'), progress=False)


def test_dask_executor_writes_the_reference_rows(near_sequence, reference, tmp_path):
    distributed = pytest.importorskip('dask.distributed')
    threads = cv2.getNumThreads()
    cluster = distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
    )
    try:
        config = DatasetConfig(
            batch=30, executor='dask', scheduler=cluster.scheduler_address, chunk=8
        )
        table = build_table([near_sequence], config, progress=False)
    finally:
        cluster.close()
        cv2.setNumThreads(threads)
    assert _csv(table, tmp_path / 'dask.csv') == reference
