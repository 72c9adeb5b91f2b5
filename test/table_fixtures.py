"""A synthetic pair table shared by the training, table and evaluation tests."""

from __future__ import annotations

import numpy as np

from initsel_ros.learn.table import PairTable, schema


def synthetic_table(
    n: int = 120, seed: int = 0, sequences: int = 2, **constant_labels: int
) -> PairTable:
    """A schema-complete table with learnable labels (features drive them), 6 batches of
    ``sequences`` sequences.

    ``constant_labels`` (e.g. ``R_label=1``) fixes whole label columns.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        row = {}
        for name, kind in schema():
            row[name] = (
                float(rng.normal())
                if kind is float
                else (int(rng.integers(0, 2)) if kind is int else 'median')
            )
        row['sequence'] = f'seq{i % sequences}'
        row['batch'] = i % 6
        signal = row['free__disparity_mean']
        for m in ('F', 'E', 'H'):
            row[f'{m}_label'] = int(signal + 0.3 * rng.normal() > 0)
        row['R_label'] = int(signal + 0.3 * rng.normal() < 0)
        row.update(constant_labels)
        rows.append(row)
    return PairTable.from_rows(rows)
