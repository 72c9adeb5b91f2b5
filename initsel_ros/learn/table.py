"""The labelled-pairs table: a plain CSV with a fixed, documented schema.

One row per (reference frame, current frame) pair. Columns (see docs/learning.md):

- identity: ``sequence, batch, ref_index, cur_index, ref_stamp, cur_stamp, source, width,
  height, n_tracks``
- ground truth: ``gt_baseline_m, gt_rotation_deg, gt_parallax_deg, gt_static_share,
  gt_plane_share, gt_rotation_share, R_label`` (the median parallax angle of the pair's
  points, the share of its tracks the ground truth explains as a static scene, the share on
  its largest plane and the share the rotation alone explains, all NaN without depth)
- the 23 features twice: ``paper__<name>`` (the authors' 640x480 scaling) and ``free__<name>``
  (resolution-free scaling); training picks one set through the model file's scaling
- extra cheap features: ``x_*`` (see :data:`EXTRA_NAMES`)
- pixel disparity statistics for the baselines: ``disp_mean_px, disp_median_px, disp_std_px``
- per method m in F, E, H: ``m_ok, m_reason, m_et, m_er, m_er_first_two, m_er_median,
  m_n_points, m_n_gt_points, m_parallax_deg, m_label``
- ``scale_rule`` (which E_R scale gave ``m_er`` and the labels)
- baselines computed from the correspondences: ``orb_s_h, orb_s_f, orb_ratio, vins_parallax_px,
  vins_inliers, vins_et``

Files are written to a temporary name in the same folder, then renamed.
"""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.errors import DatasetError
from initsel_ros.features import (
    CAMERA_FEATURE_NAMES,
    EXTRA_FEATURE_NAMES,
    FEATURE_NAMES,
    Scaling,
)
from initsel_ros.models import ModelSet
from initsel_ros.names import POSE_METHODS as METHODS_FEH  # the pose methods, in table order
from initsel_ros.output import atomic_text
from initsel_ros.trees import sigmoid

LOG = logging.getLogger(__name__)

#: Extra cheap features (beyond the paper's 23), all resolution-free: the columns hold
#: ``features.extra_features`` of each pair.
EXTRA_NAMES: tuple[str, ...] = EXTRA_FEATURE_NAMES

PAPER_PREFIX = 'paper__'
FREE_PREFIX = 'free__'

ID_COLUMNS: tuple[tuple[str, type], ...] = (
    ('sequence', str),
    ('batch', int),
    ('ref_index', int),
    ('cur_index', int),
    ('ref_stamp', float),
    ('cur_stamp', float),
    ('source', str),
    ('width', int),
    ('height', int),
    ('n_tracks', int),
    ('gt_baseline_m', float),
    ('gt_rotation_deg', float),
    ('gt_parallax_deg', float),
    ('gt_static_share', float),
    ('gt_plane_share', float),
    ('gt_rotation_share', float),
    ('R_label', int),
)

#: Columns added after tables were first written: an older table without them reads as NaN.
ADDED_COLUMNS: tuple[str, ...] = (
    'gt_parallax_deg',
    'x_rotation_departure',
    'gt_static_share',
    'gt_plane_share',
    'gt_rotation_share',
    'x_rotation_departure_focal',
    'fire_method',
    'fire_et',
    'fire_rotation_statistic',
)

BASELINE_COLUMNS: tuple[tuple[str, type], ...] = (
    ('disp_mean_px', float),
    ('disp_median_px', float),
    ('disp_std_px', float),
    ('orb_s_h', float),
    ('orb_s_f', float),
    ('orb_ratio', float),
    ('vins_parallax_px', float),
    ('vins_inliers', int),
    ('vins_et', float),
)

METHOD_FIELDS: tuple[tuple[str, type], ...] = (
    ('ok', int),
    ('reason', str),
    ('et', float),
    ('er', float),
    ('er_first_two', float),
    ('er_median', float),
    ('n_points', int),
    ('n_gt_points', int),
    ('parallax_deg', float),
    ('label', int),
)


def method_columns(method: str) -> tuple[tuple[str, type], ...]:
    """Columns of one method, e.g. ``E_et``."""
    return tuple((f'{method}_{name}', kind) for name, kind in METHOD_FIELDS)


def paper_feature_columns() -> tuple[str, ...]:
    """The 23 feature columns in the paper's scaling."""
    return tuple(PAPER_PREFIX + name for name in FEATURE_NAMES)


def free_feature_columns() -> tuple[str, ...]:
    """The 23 feature columns in the resolution-free scaling."""
    return tuple(FREE_PREFIX + name for name in FEATURE_NAMES)


def input_columns(names: Sequence[str], scaling: Scaling | str) -> tuple[str, ...]:
    """Table columns holding the model inputs ``names`` (paper or extra features).

    The 23 paper features come from the ``paper__`` or ``free__`` columns of ``scaling``; the
    extra features from their own ``x_*`` columns.
    """
    prefix = PAPER_PREFIX if Scaling(scaling) is Scaling.PAPER else FREE_PREFIX
    out = []
    for name in names:
        if name in EXTRA_FEATURE_NAMES:
            out.append(name)
        elif name in FEATURE_NAMES:
            out.append(prefix + name)
        else:
            raise DatasetError(f'unknown feature {name!r}')
    return tuple(out)


def schema() -> tuple[tuple[str, type], ...]:
    """All columns, in file order, with their Python types."""
    cols: list[tuple[str, type]] = list(ID_COLUMNS)
    cols += [(c, float) for c in paper_feature_columns()]
    cols += [(c, float) for c in free_feature_columns()]
    cols += [(c, float) for c in EXTRA_NAMES]
    cols += list(BASELINE_COLUMNS)
    for m in METHODS_FEH:
        cols += list(method_columns(m))
    cols.append(('scale_rule', str))
    cols += [('fire_method', str), ('fire_et', float), ('fire_rotation_statistic', float)]
    return tuple(cols)


def _format(value: Any, kind: type) -> str:
    if kind is float:
        v = float(value)
        if math.isnan(v):
            return 'nan'
        if math.isinf(v):
            return 'inf' if v > 0 else '-inf'
        return repr(v)
    if kind is int:
        return str(int(value))
    return str(value)


@dataclass(frozen=True)
class PairTable:
    """Column-oriented table: name -> (N,) numpy array (object arrays for strings)."""

    columns: Mapping[str, np.ndarray]

    def __len__(self) -> int:
        first = next(iter(self.columns.values()), None)
        return 0 if first is None else len(first)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError as exc:
            raise DatasetError(f'pair table has no column {name!r}') from exc

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def select(self, mask: np.ndarray) -> PairTable:
        """Rows where ``mask`` (bool (N,) or index array) holds."""
        return PairTable({k: v[mask] for k, v in self.columns.items()})

    def matrix(self, names: Sequence[str]) -> np.ndarray:
        """(N, len(names)) float64 matrix of the named columns."""
        return np.column_stack([np.asarray(self[n], dtype=np.float64) for n in names])

    def groups(self, by: str = 'batch') -> np.ndarray:
        """(N,) int group id per (sequence, batch), or per sequence with ``by='sequence'``:
        the unit of train/validation splits."""
        keys = np.asarray(self['sequence'], dtype=str)
        if by == 'batch':
            keys = np.char.add(keys, np.asarray(self['batch'], dtype=str))
        elif by != 'sequence':
            raise ValueError(f"groups by 'batch' or 'sequence', not {by!r}")
        _, ids = np.unique(keys, return_inverse=True)
        return ids

    @classmethod
    def from_rows(cls, rows: Iterable[Mapping[str, Any]]) -> PairTable:
        """Build from row dicts holding every schema column."""
        rows = list(rows)
        cols: dict[str, np.ndarray] = {}
        for name, kind in schema():
            values = [row[name] for row in rows]
            if kind is str:
                cols[name] = np.array(values, dtype=object)
            else:
                cols[name] = np.array(values, dtype=np.float64 if kind is float else np.int64)
        return cls(cols)

    @classmethod
    def concat(cls, tables: Sequence[PairTable]) -> PairTable:
        """Rows of several tables with the same columns."""
        if not tables:
            return cls.from_rows([])
        names = list(tables[0].columns)
        return cls({n: np.concatenate([t[n] for t in tables]) for n in names})


def write_table(table: PairTable, path: Path) -> None:
    """Write ``table`` as CSV (header + one row per pair) atomically (temp file + rename).

    Raises:
        OutputError: ``path`` is a folder.
    """
    cols = schema()
    with atomic_text(path, newline='') as handle:
        writer = csv.writer(handle)
        writer.writerow([name for name, _ in cols])
        data = [(table[name], kind) for name, kind in cols]
        for i in range(len(table)):
            writer.writerow([_format(d[i], kind) for d, kind in data])


def read_table(path: Path) -> PairTable:
    """Read a CSV written by :func:`write_table`; raises DatasetError on schema mismatch."""
    path = Path(path)
    try:
        with path.open(newline='', encoding='utf-8') as handle:
            reader = csv.reader(handle)
            header = next(reader)
            raw = list(reader)
    except UnicodeDecodeError as exc:
        raise DatasetError(
            f'{path}: not a text CSV pair table (binary content at byte {exc.start})'
        ) from exc
    except StopIteration as exc:
        raise DatasetError(f'{path}: cannot read pair table: the file is empty') from exc
    except (OSError, csv.Error) as exc:
        raise DatasetError(f'{path}: cannot read pair table: {exc}') from exc
    cols = schema()
    added = [name for name in ADDED_COLUMNS if name not in header]
    if added:
        LOG.warning('%s: an older pair table without %s: read as NaN', path, ', '.join(added))
    missing = [name for name, _ in cols if name not in header and name not in added]
    if missing:
        raise DatasetError(
            f'{path}: not a pair table of this version, missing columns {missing[:5]}'
            f'{" ..." if len(missing) > 5 else ""}'
        )
    index = {name: i for i, name in enumerate(header)}
    out: dict[str, np.ndarray] = {}
    for name, kind in cols:
        if name in added:
            out[name] = np.full(len(raw), np.nan)
            continue
        j = index[name]
        try:
            values = [row[j] for row in raw]
            if kind is str:
                out[name] = np.array(values, dtype=object)
            elif kind is float:
                out[name] = np.array(values, dtype=np.float64) if values else np.zeros(0)
            else:
                out[name] = np.array([int(v) for v in values], dtype=np.int64)
        except (IndexError, ValueError) as exc:
            bad = _first_bad_line(raw, len(header), j, kind)
            raise DatasetError(
                f'{path}: column {name!r} is malformed (first bad line: {bad}): {exc}'
            ) from exc
        if name.endswith(BINARY_SUFFIXES):
            wrong = np.flatnonzero((out[name] != 0) & (out[name] != 1))
            if len(wrong):
                raise DatasetError(
                    f'{path}: column {name!r} must hold 0 or 1, got {out[name][wrong[0]]} on '
                    f'line {wrong[0] + 2} ({len(wrong)} rows)'
                )
    return PairTable(out)


#: Columns that hold 0 or 1 (labels and success flags).
BINARY_SUFFIXES = ('_label', '_ok')


def _first_bad_line(raw: list[list[str]], width: int, column: int, kind: type) -> int | str:
    """The file line (header = 1) of the first row that is short or whose ``column`` does not
    parse as ``kind``; 'unknown' when none is found."""
    for k, row in enumerate(raw):
        if len(row) != width:
            return k + 2
        try:
            kind(row[column])
        except ValueError:
            return k + 2
    return 'unknown'


def read_tables(paths: Sequence[Path]) -> PairTable:
    """Rows of several CSV files."""
    return PairTable.concat([read_table(p) for p in paths])


def check_camera_features(table: PairTable, names: Sequence[str]) -> None:
    """Raise when a feature of ``names`` that needs the camera is missing on pairs whose
    linear homography exists (a table written before the feature, read as NaN: a model would
    read 0, which for ``x_rotation_departure`` says "exactly a rotation").

    Raises:
        DatasetError: naming the feature and how many pairs lack it.
    """
    fitted = np.isfinite(np.asarray(table['x_homography_dlt_residual'], dtype=float))
    for name in CAMERA_FEATURE_NAMES:
        if name not in names:
            continue
        missing = int(np.count_nonzero(fitted & ~np.isfinite(np.asarray(table[name], float))))
        if missing:
            raise DatasetError(
                f'{name} is missing on {missing} of {len(table)} pairs that have a homography '
                f'fit: pair tables written before it (rebuild them with `initsel dataset`); '
                f'or leave it out (`initsel train --extra-features` without it)'
            )


def table_logits(models: ModelSet, table: PairTable) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The logits of ``models`` on every pair of ``table``, by model, its referee deciding
    where it should (:meth:`ModelSet.review_logits`); and the (N,) rows it decided.

    Raises:
        DatasetError: a feature the models read that the table lacks
            (:func:`check_camera_features`).
    """
    check_camera_features(table, models.input_names)
    if models.referee is not None:
        check_camera_features(table, models.referee_input_names)
    logits = models.logits_batch(table.matrix(input_columns(models.input_names, models.scaling)))
    if models.referee is None:
        return logits, np.zeros(len(table), dtype=bool)
    judged = table.matrix(input_columns(models.referee_input_names, models.scaling))
    return models.review_logits(logits, judged)


def table_probabilities(
    models: ModelSet, table: PairTable
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`table_logits` as probabilities."""
    logits, referred = table_logits(models, table)
    return {m: sigmoid(z) for m, z in logits.items()}, referred


__all__ = [
    'EXTRA_NAMES',
    'FREE_PREFIX',
    'METHODS_FEH',
    'PAPER_PREFIX',
    'PairTable',
    'check_camera_features',
    'free_feature_columns',
    'input_columns',
    'method_columns',
    'paper_feature_columns',
    'read_table',
    'read_tables',
    'schema',
    'table_logits',
    'table_probabilities',
    'write_table',
]
