"""The offline tools on inputs a user gets wrong (a black-box probe's findings, 2026-12-06)."""

from __future__ import annotations

import logging
import os
import shutil
import stat

import numpy as np
import pytest

from initsel_ros.cli import main
from initsel_ros.errors import DatasetError
from initsel_ros.output import OutputError


def _refused(argv: list[str], capsys) -> str:
    """argparse's refusal of ``argv`` (exit 2), as its message."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err


def test_an_output_that_is_a_folder_is_refused_before_any_work(static_sequence, tmp_path, capsys):
    # before: dataset and train did all their work, then crashed in os.replace
    err = _refused(['dataset', str(static_sequence), '--out', str(tmp_path)], capsys)
    assert f'{tmp_path} is a folder: give the name of a file to write' in err
    err = _refused(['train', 'pairs.csv', '--out', str(tmp_path)], capsys)
    assert 'is a folder' in err


def test_the_writers_refuse_a_folder_leave_nothing_behind_and_follow_the_umask(tmp_path):
    from initsel_ros.learn.table import PairTable, write_table
    from initsel_ros.models import ModelSet, default_model_path

    models = ModelSet.load(default_model_path())
    with pytest.raises(OutputError, match='is a folder'):
        models.save(tmp_path)
    with pytest.raises(OutputError, match='is a folder'):
        write_table(PairTable.from_rows([]), tmp_path)
    assert list(tmp_path.iterdir()) == []  # before: a models.tmp was left in the folder
    old = os.umask(0o022)
    try:
        write_table(PairTable.from_rows([]), tmp_path / 'pairs.csv')
        models.save(tmp_path / 'models.json')
    finally:
        os.umask(old)
    for name in ('pairs.csv', 'models.json'):  # before: pair tables were 0600
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ['models.json', 'pairs.csv']


def test_a_written_file_reaches_the_disk_before_it_replaces_the_old_one(tmp_path, monkeypatch):
    from initsel_ros import output

    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(output.os, 'fsync', lambda fd: events.append('fsync') or real_fsync(fd))
    monkeypatch.setattr(
        output.os, 'replace', lambda a, b: events.append('replace') or real_replace(a, b)
    )
    with output.atomic_text(tmp_path / 'table.csv') as handle:
        handle.write('a,b\n')
    assert events == ['fsync', 'replace']
    assert (tmp_path / 'table.csv').read_text() == 'a,b\n'


@pytest.mark.parametrize(
    'option,value,reason',
    [
        ('--stride', '0', 'under 1'),
        ('--stride', '-1', 'under 1'),
        ('--jobs', '0', 'under 1'),
        ('--chunk', '-1', 'under 0'),
        ('--min-tracks', '-1', 'under 0'),
        ('--max-features', '0', 'under 8'),
        ('--nearest-tolerance', 'nan', 'not a finite number'),
        ('--nearest-tolerance', '-1', 'not a finite number >= 0'),
    ],
)
def test_dataset_options_out_of_range_are_refused(
    static_sequence, tmp_path, capsys, option, value, reason
):
    argv = ['dataset', str(static_sequence), '--out', str(tmp_path / 'p.csv'), option, value]
    err = _refused(argv, capsys)
    assert option in err and reason in err


def test_a_euroc_time_listed_with_two_images_is_refused(tmp_path):
    # before: both frames were read, with one stamp and one pose
    from initsel_ros.datasets.euroc import read_image_listing

    listing = tmp_path / 'data.csv'
    listing.write_text(
        '#timestamp [ns],filename\n'
        '1403636579763555584,1403636579763555584.png\n'
        '1403636579813555456,1403636579813555456.png\n'
        '1403636579813555456,1403636579863555584.png\n'
    )
    with pytest.raises(DatasetError, match=r'data.csv:4: time 1403636579813555456 is also line 3'):
        read_image_listing(listing)
    listing.write_text(
        '#timestamp [ns],filename\n'
        '1403636579813555456,b.png\n'
        '1403636579763555584,a.png\n'
        '1403636579813555456,b.png\n'
    )
    assert read_image_listing(listing) == (
        [1403636579763555584, 1403636579813555456],
        ['a.png', 'b.png'],
    )


def test_a_ros2_bag_given_as_dot_is_named_after_its_folder(near_bag_ros2, monkeypatch):
    from initsel_ros.datasets import open_sequence

    monkeypatch.chdir(near_bag_ros2)
    assert open_sequence('.').name == near_bag_ros2.name


def test_a_source_that_gives_no_pair_among_others_is_an_error(static_sequence, tmp_path, capsys):
    # before: its pairs were simply missing, exit 0
    posed_nowhere = tmp_path / 'no_poses'
    shutil.copytree(static_sequence, posed_nowhere)
    lines = (posed_nowhere / 'groundtruth.txt').read_text().splitlines()
    (posed_nowhere / 'groundtruth.txt').write_text(
        '\n'.join(line for line in lines if line.startswith('#')) + '\n'
    )
    out = tmp_path / 'pairs.csv'
    argv = ['dataset', str(static_sequence), str(posed_nowhere), '--out', str(out)]
    assert main([*argv, '--batch', '30', '--jobs', '1', '--quiet', '--no-orbslam']) == 1
    err = capsys.readouterr().err
    assert 'no_poses: none of its' in err and 'not written' in err and not out.exists()


def test_eval_leaves_out_an_orbslam_baseline_the_table_does_not_hold(near_evaluation, caplog):
    # near_pair_table is built with --no-orbslam: before, its ORB-SLAM rows read as a
    # baseline that had said no to every pair
    from initsel_ros.learn.evaluate import baseline_rules, evaluate

    table, models, report = near_evaluation
    assert not np.isfinite(np.asarray(table['orb_ratio'], dtype=float)).any()
    assert not any('ORB-SLAM' in row.name for row in report.rows)
    assert not any('ORB-SLAM' in name for name in baseline_rules(table))
    with caplog.at_level(logging.WARNING):
        evaluate(table, models)
    assert 'the ORB-SLAM baseline is left out' in caplog.text


def test_the_pair_table_docs_name_every_extra_feature_column_and_the_count():
    import re
    from pathlib import Path

    from initsel_ros.learn.table import schema

    text = (Path(__file__).resolve().parent.parent / 'docs' / 'learning.md').read_text()
    section = text[text.index('### The pair table (CSV schema)') : text.index('## 2. Training')]
    named = set(re.findall(r'`([A-Za-z0-9_]+)`', section))
    columns = [name for name, _ in schema()]
    assert [n for n in columns if n.startswith('x_') and n not in named] == []
    assert f'{len(columns)} columns' in section


def test_the_quaternion_warning_names_the_file_column_order(caplog):
    from initsel_ros.datasets.poses import check_trajectory

    q = np.array([[0.0, 0.0, 0.0, 2.0], [0.0, 0.0, 0.0, 2.0]])
    with caplog.at_level(logging.WARNING):
        check_trajectory(np.array([0, 1]), np.zeros((2, 3)), q, 'data.csv', 'w x y z')
    assert 'check the column order (w x y z)' in caplog.text  # before: (x y z w) for EuRoC


def test_an_unknown_option_is_refused_with_the_subcommand_usage(capsys):
    err = _refused(['dataset', 'x', '--out', 'y.csv', '--bogus'], capsys)
    assert err.startswith('usage: initsel dataset') and 'unrecognized arguments: --bogus' in err
    err = _refused(['train', 'pairs.csv', '--out', 'm.json', '--folds', '1'], capsys)
    assert '--folds' in err and 'under 2' in err  # before: 'need at least 2 batches ... got 2'


def test_reader_options_that_fit_no_source_are_said_to_be_ignored(
    static_sequence, tmp_path, caplog
):
    argv = ['dataset', str(static_sequence), '--out', str(tmp_path / 'p.csv'), '--batch', '30']
    argv += ['--jobs', '1', '--quiet', '--no-orbslam', '--image-topic', '/cam/image']
    with caplog.at_level(logging.WARNING):
        assert main([*argv, '--sequence', '03']) == 0
    assert 'so they are ignored: --image-topic, --sequence' in caplog.text
