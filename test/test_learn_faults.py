"""`initsel train` / `initsel eval` on hostile tables: one clear line, never a degenerate model.

Issue 11: a random-bytes CSV raised UnicodeDecodeError; a single-class table wrote a model that
always (or never) fires and exited 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from initsel_ros.cli import main
from initsel_ros.errors import DatasetError
from initsel_ros.learn.table import PairTable, read_table, schema, write_table
from initsel_ros.learn.train import TrainConfig, train_models


def synthetic_table(n: int = 120, seed: int = 0, **constant_labels: int) -> PairTable:
    """A schema-complete table with learnable labels (features drive them), 6 batches.

    ``constant_labels`` (e.g. ``R_label=1``) fixes whole label columns.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        row = {}
        for name, kind in schema():
            row[name] = float(rng.normal()) if kind is float else (
                int(rng.integers(0, 2)) if kind is int else 'median')
        row['sequence'] = f'seq{i % 2}'
        row['batch'] = i % 6
        signal = row['free__disparity_mean']
        for m in ('F', 'E', 'H'):
            row[f'{m}_label'] = int(signal + 0.3 * rng.normal() > 0)
        row['R_label'] = int(signal + 0.3 * rng.normal() < 0)
        row.update(constant_labels)
        rows.append(row)
    return PairTable.from_rows(rows)


@pytest.mark.parametrize('command', ['train', 'eval'])
def test_a_random_bytes_csv_is_one_line_naming_the_file(tmp_path, capsys, command):
    path = tmp_path / 'pairs.csv'
    path.write_bytes(np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(DatasetError, match=r'pairs\.csv'):
        read_table(path)
    argv = [command, str(path), '--out', str(tmp_path / 'm.json')] if command == 'train' else [
        command, str(path)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert 'pairs.csv' in err and 'Traceback' not in err


def test_a_nul_byte_csv_is_one_line_too(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    path.write_bytes(b'sequence,batch\n\x00\x00\x00\n')
    assert main(['train', str(path), '--out', str(tmp_path / 'm.json')]) == 1
    assert 'pairs.csv' in capsys.readouterr().err


def test_single_class_training_is_an_error_naming_the_model_and_counts(tmp_path, capsys):
    table = synthetic_table(R_label=1)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    out = tmp_path / 'models.json'
    assert main(['train', str(path), '--out', str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert 'R' in err and '120 positive' in err and '0 negative' in err
    assert '--allow-degenerate' in err
    assert not out.exists()


def test_allow_degenerate_writes_the_constant_model_with_a_warning(tmp_path, caplog):
    table = synthetic_table(R_label=1)
    path = tmp_path / 'pairs.csv'
    write_table(table, path)
    out = tmp_path / 'models.json'
    assert main(['train', str(path), '--out', str(out), '--allow-degenerate']) == 0
    assert 'always fire' in caplog.text
    from initsel_ros.models import ModelSet

    models = ModelSet.load(out)
    assert models.metadata['training']['degenerate_models'] == ['R']


def test_train_models_refuses_single_class_labels_by_default():
    with pytest.raises(DatasetError, match=r'model F: .*0 positive'):
        train_models(synthetic_table(F_label=0), TrainConfig())
    report = train_models(synthetic_table(F_label=0), TrainConfig(allow_degenerate=True))
    assert report.models.models['F'].bias < -math.log(1e4)
