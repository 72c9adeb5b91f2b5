"""Sequences opened once per process (datasets.cache)."""

from __future__ import annotations

import logging
import shutil

import initsel_ros.datasets as datasets
from initsel_ros.datasets.cache import forget_sequences, keep_sequence, open_cached


def test_a_sequence_is_opened_once_per_path_and_reader_options(static_sequence, opened_sequences):
    forget_sequences()
    first = open_cached(static_sequence)
    assert open_cached(str(static_sequence)) is first  # the same path, as text
    other = open_cached(static_sequence, nearest_tolerance=0.5)
    assert other is not first
    assert [options for _, options in opened_sequences] == [{}, {'nearest_tolerance': 0.5}]
    forget_sequences()
    assert open_cached(static_sequence) is not first and len(opened_sequences) == 3
    kept = datasets.TumSequence(static_sequence)
    keep_sequence(kept, static_sequence, nearest_tolerance=0.5)
    assert open_cached(static_sequence, nearest_tolerance=0.5) is kept
    assert len(opened_sequences) == 3
    forget_sequences()


def test_a_quiet_open_logs_only_the_readers_errors(static_sequence, tmp_path, caplog):
    folder = shutil.copytree(static_sequence, tmp_path / 'static', symlinks=True)
    (folder / 'groundtruth.txt').unlink()  # the reader notes it
    forget_sequences()
    readers = logging.getLogger('initsel_ros.datasets')
    with caplog.at_level(logging.INFO, logger='initsel_ros.datasets'):
        open_cached(folder, quiet=True)
        assert 'no groundtruth.txt' not in caplog.text
        assert readers.level == logging.INFO  # restored
        open_cached(folder, quiet=True, nearest_tolerance=0.1)
        open_cached(folder, nearest_tolerance=0.2)
    assert caplog.text.count('no groundtruth.txt') == 1
    forget_sequences()
