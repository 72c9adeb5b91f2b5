"""Tests for initsel_ros.models: inference and the plain-text model file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from initsel_ros.errors import ModelFileError
from initsel_ros.features import N_FEATURES, Scaling
from initsel_ros.models import METHODS, LogisticModel, ModelSet, find_config_file


def make_set(seed: int = 0) -> ModelSet:
    rng = np.random.default_rng(seed)
    models = {
        m: LogisticModel(
            m, rng.normal(size=N_FEATURES), float(rng.normal()), 0.3 + 0.1 * i,
            rng.normal(size=N_FEATURES), rng.uniform(0.5, 2, N_FEATURES), {'precision': 0.5},
        )
        for i, m in enumerate(METHODS)
    }
    return ModelSet(models, Scaling.PAPER, metadata={'trained_on': 'unit test'})


def test_probabilities_are_the_standardized_logistic_of_each_model():
    ms = make_set()
    x = np.random.default_rng(5).normal(size=N_FEATURES)
    probs = ms.predict_proba(x)
    for m in METHODS:
        model = ms.models[m]
        z = model.weights @ ((x - model.mean) / model.scale) + model.bias
        assert probs[m] == pytest.approx(1 / (1 + np.exp(-z)))
    batch = ms.predict_proba_batch(np.stack([x, x]))
    assert batch['E'].shape == (2,)
    assert batch['E'][1] == pytest.approx(probs['E'])


def test_extreme_logits_do_not_overflow():
    ms = make_set()
    p = ms.predict_proba(np.full(N_FEATURES, 1e6))
    assert all(0.0 <= v <= 1.0 for v in p.values())


def test_model_file_round_trips(tmp_path):
    ms = make_set()
    path = tmp_path / 'models.json'
    ms.save(path)
    loaded = ModelSet.load(path)
    assert loaded.scaling is Scaling.PAPER
    assert loaded.thresholds == ms.thresholds
    assert loaded.metadata == {'trained_on': 'unit test'}
    x = np.linspace(-1, 1, N_FEATURES)
    assert loaded.predict_proba(x) == pytest.approx(ms.predict_proba(x))
    assert not list(tmp_path.glob('*.tmp'))


def _edit(tmp_path, change):
    data = make_set().to_dict()
    change(data)
    path = tmp_path / 'bad.json'
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda d: d['models'].pop('R'), 'missing models: R'),
        (lambda d: d['models']['E'].update(weights=[1.0] * 22), 'weights must have 23'),
        (lambda d: d['models']['F'].update(bias='x'), 'non-numeric'),
        (lambda d: d['models']['H'].update(threshold=1.5), r'threshold must be in \[0, 1\]'),
        (lambda d: d['models']['H'].update(scale=[0.0] * 23), 'scale value must be positive'),
        (lambda d: d['models']['E'].update(mean=[float('nan')] * 23), 'NaN'),
        (lambda d: d.update(format='something'), 'not an initsel_ros model file'),
        (lambda d: d.update(version=99), 'unsupported model file version'),
        (lambda d: d.update(scaling='metric'), 'unknown scaling'),
        (lambda d: d['feature_names'].reverse(), 'feature_names do not match'),
        (lambda d: d['models'].update(E=[1, 2]), 'expected a mapping'),
        (lambda d: d.update(feature_names=5), 'feature_names. must be a list'),
        (lambda d: d.update(metadata='trained'), 'metadata. must be a mapping'),
    ],
)
def test_malformed_model_files_are_rejected_with_the_file_name(tmp_path, change, message):
    path = _edit(tmp_path, change)
    with pytest.raises(ModelFileError, match=message) as info:
        ModelSet.load(path)
    assert str(path) in str(info.value)


def test_missing_and_non_json_files_are_clear_errors(tmp_path):
    with pytest.raises(ModelFileError, match='cannot read model file'):
        ModelSet.load(tmp_path / 'nope.json')
    bad = tmp_path / 'broken.json'
    bad.write_text('{"format": ')
    with pytest.raises(ModelFileError, match='not valid JSON'):
        ModelSet.load(bad)


def test_packaged_config_is_found_through_ament_prefix_then_source_tree(tmp_path, monkeypatch):
    share = tmp_path / 'share' / 'initsel_ros' / 'config'
    share.mkdir(parents=True)
    (share / 'fastdds_shm.xml').write_text('<dds/>')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    assert find_config_file('fastdds_shm.xml') == share / 'fastdds_shm.xml'
    monkeypatch.setenv('AMENT_PREFIX_PATH', '')
    assert find_config_file('fastdds_shm.xml').parent.name == 'config'
    with pytest.raises(ModelFileError, match='looked in'):
        find_config_file('does-not-exist.json')
