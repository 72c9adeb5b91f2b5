"""Tests for initsel_ros.learn.table: CSV round trip and unreadable tables.

Issue 11: a random-bytes CSV raised UnicodeDecodeError in `initsel train` / `initsel eval`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.cli import main
from initsel_ros.errors import DatasetError
from initsel_ros.learn.table import PairTable, read_table, schema, write_table


def _random_rows(rng: np.random.Generator, n: int) -> list[dict]:
    rows = []
    for i in range(n):
        row = {}
        for name, kind in schema():
            if kind is float:
                row[name] = float(rng.normal())
            elif kind is int:  # labels and success flags are 0 or 1
                high = 2 if name.endswith(('_label', '_ok')) else 100
                row[name] = int(rng.integers(0, high))
            else:
                row[name] = f'text {i}; with spaces'
        rows.append(row)
    rows[0]['E_et'] = math.nan
    rows[0]['E_er'] = math.inf
    rows[1]['sequence'] = 'a "quoted", comma name'
    return rows


def test_csv_round_trip_keeps_every_column_and_value(tmp_path):
    rng = np.random.default_rng(0)
    table = PairTable.from_rows(_random_rows(rng, 5))
    path = tmp_path / 'sub' / 'pairs.csv'
    write_table(table, path)
    back = read_table(path)
    assert len(back) == 5
    assert list(back.columns) == [name for name, _ in schema()]
    for name, kind in schema():
        a, b = table[name], back[name]
        if kind is float:
            np.testing.assert_array_equal(a, b)  # repr round-trips floats, nan and inf
        else:
            assert a.tolist() == b.tolist()
    assert back['sequence'][1] == 'a "quoted", comma name'
    assert [p.name for p in path.parent.iterdir()] == ['pairs.csv']  # no temp file left


def test_reading_a_foreign_csv_names_the_file_and_missing_columns(tmp_path):
    path = tmp_path / 'other.csv'
    path.write_text('a,b\n1,2\n')
    with pytest.raises(DatasetError, match=r'other\.csv.*missing columns'):
        read_table(path)
    with pytest.raises(DatasetError, match='cannot read'):
        read_table(tmp_path / 'absent.csv')


@pytest.mark.parametrize('command', ['train', 'eval'])
def test_a_random_bytes_csv_is_one_line_naming_the_file(tmp_path, capsys, command):
    path = tmp_path / 'pairs.csv'
    path.write_bytes(np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(DatasetError, match=r'pairs\.csv'):
        read_table(path)
    argv = (
        [command, str(path), '--out', str(tmp_path / 'm.json')]
        if command == 'train'
        else [command, str(path)]
    )
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert 'pairs.csv' in err and 'Traceback' not in err


def test_a_nul_byte_csv_is_one_line_too(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    path.write_bytes(b'sequence,batch\n\x00\x00\x00\n')
    assert main(['train', str(path), '--out', str(tmp_path / 'm.json')]) == 1
    assert 'pairs.csv' in capsys.readouterr().err


@pytest.mark.parametrize('column', ['gt_parallax_deg', 'gt_static_share'])
def test_an_older_table_without_an_added_column_reads_it_as_nan(tmp_path, caplog, column):
    import csv

    from table_fixtures import synthetic_table

    path = tmp_path / 'old.csv'
    write_table(synthetic_table(n=12), path)
    assert np.isfinite(read_table(path)[column]).all()
    with path.open(newline='') as handle:
        rows = list(csv.reader(handle))
    j = rows[0].index(column)
    with path.open('w', newline='') as handle:
        csv.writer(handle).writerows([r[:j] + r[j + 1 :] for r in rows])
    table = read_table(path)
    assert np.isnan(table[column]).all() and len(table) == 12
    assert f'an older pair table without {column}: read as NaN' in caplog.text


@pytest.mark.parametrize(
    ('column', 'value', 'match'),
    [
        ('F_label', '2', r"column 'F_label' must hold 0 or 1, got 2 on line 5"),
        ('R_label', '-1', r"column 'R_label' must hold 0 or 1, got -1 on line 5"),
        ('E_label', 'nan', r"column 'E_label' is malformed \(first bad line: 5\)"),
        ('H_label', '0.5', r"column 'H_label' is malformed \(first bad line: 5\)"),
    ],
)
def test_a_label_that_is_not_0_or_1_is_refused_with_its_line(tmp_path, column, value, match):
    # before: 2 crashed `initsel train` in the tree export, and `initsel eval` counted it as
    # a positive; a NaN label's line was 'unknown'
    import csv

    from table_fixtures import synthetic_table

    from initsel_ros.errors import DatasetError

    path = tmp_path / 'table.csv'
    write_table(synthetic_table(n=6), path)
    with path.open(newline='') as handle:
        rows = list(csv.reader(handle))
    rows[4][rows[0].index(column)] = value  # file line 5
    with path.open('w', newline='') as handle:
        csv.writer(handle).writerows(rows)
    with pytest.raises(DatasetError, match=match):
        read_table(path)


def test_a_camera_feature_missing_from_an_older_table_is_a_clear_error(tmp_path, caplog):
    """A table written before x_rotation_departure reads it as NaN, which a model would read
    as 0 ("exactly a rotation"): training on it, distilling on it and scoring a model that
    reads it are errors that say what to do; leaving the feature out trains as before."""
    from table_fixtures import synthetic_table

    from initsel_ros.errors import DatasetError
    from initsel_ros.learn.table import read_table, table_probabilities, write_table
    from initsel_ros.learn.train import TrainConfig, train_models

    table = synthetic_table(n=120)
    path = tmp_path / 'old.csv'
    write_table(table, path)
    text = path.read_text().splitlines()
    header = text[0].split(',')
    k = header.index('x_rotation_departure')
    path.write_text(
        '\n'.join(','.join(c for j, c in enumerate(line.split(',')) if j != k) for line in text)
        + '\n'
    )
    with caplog.at_level('WARNING'):
        old = read_table(path)
    assert 'x_rotation_departure' in caplog.text
    with pytest.raises(DatasetError, match='x_rotation_departure is missing on 120 of 120'):
        train_models(old, TrainConfig(folds=2))
    others = tuple(n for n in TrainConfig().extra if n != 'x_rotation_departure')
    models = train_models(old, TrainConfig(folds=2, extra=others)).models
    assert 'x_rotation_departure' not in models.input_names
    table_probabilities(models, old)  # a model that does not read it scores the old table
    reading = train_models(table, TrainConfig(folds=2)).models
    with pytest.raises(DatasetError, match='rebuild them'):
        table_probabilities(reading, old)
