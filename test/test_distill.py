"""Tests for initsel_ros.learn.distill and ``initsel train --distill``."""

from __future__ import annotations

import numpy as np
import pytest
from table_fixtures import synthetic_table

from initsel_ros.cli import main
from initsel_ros.errors import DatasetError
from initsel_ros.features import FEATURE_NAMES
from initsel_ros.learn.distill import distill_models, teacher_logits
from initsel_ros.learn.table import input_columns, write_table
from initsel_ros.learn.train import TrainConfig, TreeConfig, train_models
from initsel_ros.models import METHODS, ModelSet

STUDENT_INPUTS = ('disparity_mean', 'disparity_std', 'x_flow_coherence', 'x_point_spread')


def _teacher(table):
    return train_models(table, TrainConfig(trees=TreeConfig(20, 3, 0.2))).models


def test_students_reproduce_the_teachers_decisions_from_other_inputs():
    table = synthetic_table(240, seed=1)
    teacher = _teacher(table)
    report = distill_models(table, teacher, STUDENT_INPUTS, TreeConfig(40, 3, 0.2))
    students = report.models
    assert students.thresholds == teacher.thresholds
    for name in METHODS:
        model = students.models[name]
        assert model.features == STUDENT_INPUTS and model.kind == 'trees'
        assert model.metrics['family'] == 'trees+distilled'
    # the labels follow disparity_mean, which the students read: they decide as the teacher
    assert min(report.agreement.values()) > 0.9
    X = table.matrix(input_columns(students.input_names, students.scaling))
    z = students.logits_batch(X)
    target = teacher_logits(teacher, table)
    for name in METHODS:
        assert np.sqrt(np.mean((z[name] - np.clip(target[name], -12, 12)) ** 2)) == (
            pytest.approx(report.logit_rmse[name], rel=1e-6)
        )
    assert students.metadata['teacher'] == teacher.metadata
    assert students.metadata['training']['features'] == list(STUDENT_INPUTS)


def test_distillation_refuses_an_empty_table_and_unknown_inputs():
    table = synthetic_table(60)
    teacher = _teacher(table)
    with pytest.raises(DatasetError, match='student features'):
        distill_models(table, teacher, ('x_magic',))
    with pytest.raises(DatasetError, match='no pairs'):
        distill_models(table.select(np.zeros(len(table), bool)), teacher, FEATURE_NAMES)


def test_cli_distills_a_model_file_into_the_inputs_named(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    write_table(synthetic_table(180, seed=2), path)
    teacher = tmp_path / 'teacher.json'
    assert main(['train', str(path), '--out', str(teacher), '--trees', '15']) == 0
    student = tmp_path / 'student.json'
    argv = ['train', str(path), '--distill', str(teacher), '--out', str(student)]
    argv += ['--paper-features', 'disparity_mean', 'disparity_std', '--trees', '20']
    argv += ['--extra-features', 'x_flow_coherence', 'x_homography_dlt_residual']
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert 'distilled from' in out and '| model | threshold | agreement |' in out
    ms = ModelSet.load(student)
    assert ms.thresholds == ModelSet.load(teacher).thresholds
    assert ms.input_names[23:] == ('x_flow_coherence', 'x_homography_dlt_residual')
    assert all(len(m.trees) == 20 for m in ms.models.values())
    # a set that reads no direction bin skips their pass (they read 0.0)
    assert not ms.input_plan(640, 480).directions


def test_sequence_grouped_validation_keeps_each_sequence_in_one_fold(monkeypatch):
    from initsel_ros.learn import train as train_module

    table = synthetic_table(120)
    by_sequence = table.groups(by='sequence')
    assert len(np.unique(by_sequence)) == 2 and len(np.unique(table.groups())) == 6
    folded = []  # the groups the folds were made of, one entry per model

    def spy(groups, folds, seed, unit='batch', _real=train_module.grouped_folds):
        folded.append(np.asarray(groups).copy())
        assert unit == 'sequence'  # (said in its error when there are too few)
        return _real(groups, folds, seed, unit)

    monkeypatch.setattr(train_module, 'grouped_folds', spy)
    report = train_models(table, TrainConfig(group_by='sequence', trees=TreeConfig(10, 2, 0.3)))
    assert report.models.metadata['training']['validation_groups'] == 'sequence'
    assert len(folded) == len(METHODS)
    for groups in folded:  # whole sequences: two groups, each pair with its sequence's
        np.testing.assert_array_equal(groups, by_sequence)
    with pytest.raises(ValueError, match='batch'):
        table.groups(by='frame')


def test_referee_band_is_the_narrowest_holding_nine_tenths_of_the_disagreements():
    from initsel_ros.learn.distill import BAND_STEP, referee_band

    threshold = 0.5  # logit 0
    rng = np.random.default_rng(0)
    student = rng.uniform(-5.0, 5.0, 1000)
    teacher = student.copy()
    # 10 disagreements: 9 within 0.6 logits of the threshold, one at 3.1
    differ = np.r_[np.flatnonzero(np.abs(student) < 0.6)[:9], np.argmax(np.abs(student) > 3.1)]
    teacher[differ] = -student[differ]
    band = referee_band(student, teacher, threshold)
    assert band.band_logit == pytest.approx(np.ceil(0.6 / BAND_STEP) * BAND_STEP)
    assert band.captured == pytest.approx(0.9)
    assert band.out_of_fold_agreement == pytest.approx(0.99)
    assert band.referred == pytest.approx(np.mean(np.abs(student) < band.band_logit))
    with pytest.raises(DatasetError, match='threshold'):
        referee_band(student, teacher, 1.0)
    # a student that never disagrees needs no referee: band 0, no pair referred
    alike = referee_band(student, student.copy(), threshold)
    assert alike.band_logit == 0.0 and alike.referred == 0.0 and alike.captured == 1.0


def test_a_referee_decides_where_the_student_is_unsure(tmp_path):
    from initsel_ros.learn.table import table_logits

    table = synthetic_table(300, seed=3, sequences=5)
    teacher = _teacher(table)
    weak = ('x_point_spread', 'x_flow_coherence')  # noise: the students are unsure
    plain = distill_models(table, teacher, weak, TreeConfig(20, 3, 0.2))
    report = distill_models(table, teacher, weak, TreeConfig(20, 3, 0.2), referee=('R',))
    models = report.models
    assert models.referee is not None and set(models.referee.band_logit) == {'R'}
    band = report.referee['R']
    assert band.band_logit == models.referee.band_logit['R'] > 0
    assert band.captured >= 0.9 and 0 < band.referred <= 1
    assert models.referee.models.models['R'] is teacher.models['R']
    assert models.models['R'].metrics['referee']['band_logit'] == band.band_logit
    # the file keeps it: saved and loaded, the same decisions
    path = tmp_path / 'm.json'
    models.save(path)
    loaded = ModelSet.load(path)
    assert loaded.referee.band_logit == models.referee.band_logit
    z, referred = table_logits(loaded, table)
    z_plain, none = table_logits(plain.models, table)
    target = teacher_logits(teacher, table)
    cut = np.log(teacher.thresholds['R'] / (1 - teacher.thresholds['R']))
    inside = np.abs(z_plain['R'] - cut) < band.band_logit
    assert not none.any() and np.array_equal(referred, inside) and inside.any()
    np.testing.assert_allclose(z['R'][inside], target['R'][inside])
    np.testing.assert_allclose(z['R'][~inside], z_plain['R'][~inside])
    for name in 'FEH':  # only R is refereed
        np.testing.assert_allclose(z[name], z_plain[name])
    agree = lambda zr: np.mean((zr >= cut) == (target['R'] >= cut))  # noqa: E731
    assert agree(z['R']) > agree(z_plain['R'])


def test_referee_needs_distillation_and_sequences(tmp_path, capsys):
    path = tmp_path / 'pairs.csv'
    write_table(synthetic_table(60), path)
    assert main(['train', str(path), '--out', str(tmp_path / 'm.json'), '--referee', 'R']) != 0
    assert 'it needs --distill TEACHER' in capsys.readouterr().err
    table = synthetic_table(60, sequences=2)
    with pytest.raises(DatasetError, match='at least 3 sequences'):
        distill_models(table, _teacher(table), STUDENT_INPUTS, referee=('R',))
    with pytest.raises(DatasetError, match='referee models'):
        distill_models(table, _teacher(table), STUDENT_INPUTS, referee=('X',))
    with pytest.raises(DatasetError, match='sequence of model names'):
        distill_models(table, _teacher(table), STUDENT_INPUTS, referee='RE')
