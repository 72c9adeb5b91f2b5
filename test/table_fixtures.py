"""A synthetic pair table shared by the training, table and evaluation tests."""

from __future__ import annotations

import zlib

import numpy as np

from initsel_ros.learn.table import PairTable, schema


def synthetic_table(
    n: int = 120, seed: int = 0, sequences: int = 2, **constant_labels: int
) -> PairTable:
    """A schema-complete table with learnable labels (features drive them), 6 batches of
    ``sequences`` sequences.

    Each column is drawn from its own generator (seeded by ``seed`` and the column's name), so
    a column added to the schema leaves the others' values as they were.
    ``constant_labels`` (e.g. ``R_label=1``) fixes whole label columns.
    """
    columns: dict[str, np.ndarray] = {}
    for name, kind in schema():
        rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
        if kind is float:
            columns[name] = rng.normal(size=n)
        elif kind is int:
            columns[name] = rng.integers(0, 2, n).astype(np.int64)
        else:
            columns[name] = np.full(n, 'median', dtype=object)
    columns['sequence'] = np.array([f'seq{i % sequences}' for i in range(n)], dtype=object)
    columns['batch'] = np.arange(n, dtype=np.int64) % 6
    signal = columns['free__disparity_mean']
    rng = np.random.default_rng([seed, zlib.crc32(b'labels')])
    for m in ('F', 'E', 'H'):
        columns[f'{m}_label'] = (signal + 0.3 * rng.normal(size=n) > 0).astype(np.int64)
    columns['R_label'] = (signal + 0.3 * rng.normal(size=n) < 0).astype(np.int64)
    for name, value in constant_labels.items():
        columns[name] = np.full(n, value, dtype=np.int64)
    return PairTable(columns)
