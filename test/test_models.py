"""Tests for initsel_ros.models: inference and the plain-text model file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from initsel_ros.errors import GeometryError, ModelFileError
from initsel_ros.features import N_FEATURES, Scaling
from initsel_ros.models import METHODS, LogisticModel, ModelSet, find_config_file


def make_set(seed: int = 0) -> ModelSet:
    rng = np.random.default_rng(seed)
    models = {
        m: LogisticModel(
            m,
            rng.normal(size=N_FEATURES),
            float(rng.normal()),
            0.3 + 0.1 * i,
            rng.normal(size=N_FEATURES),
            rng.uniform(0.5, 2, N_FEATURES),
            {'precision': 0.5},
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


# ------------------------------------------------------------- hostile model files (issue 11)
def _load_in_thread(path, timeout_s: float = 10.0):
    """ModelSet.load(path) in a thread: ('returned' | 'raised' | 'hung', value)."""
    import threading

    box: dict = {}

    def run():
        try:
            box['value'] = ('returned', ModelSet.load(path))
        except BaseException as exc:  # reported to the test
            box['value'] = ('raised', exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout_s)
    return box.get('value', ('hung', None)), thread


def test_a_fifo_as_model_file_fails_at_once_instead_of_blocking(tmp_path):
    import os

    fifo = tmp_path / 'models.json'
    os.mkfifo(fifo)
    (outcome, value), thread = _load_in_thread(fifo)
    if outcome == 'hung':  # unblock the reader (open a writer, close it) before failing
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        thread.join(5)
    assert outcome == 'raised', 'ModelSet.load blocked on a FIFO'
    assert isinstance(value, ModelFileError)
    assert 'not a regular file' in str(value) and str(fifo) in str(value)


@pytest.mark.parametrize('kind', ['dev_zero', 'directory'])
def test_devices_and_directories_are_one_model_file_error(tmp_path, kind):
    from pathlib import Path

    path = Path('/dev/zero') if kind == 'dev_zero' else tmp_path
    with pytest.raises(ModelFileError, match='not a regular file') as info:
        ModelSet.load(path)
    assert str(path) in str(info.value)
    assert '\n' not in str(info.value)


def test_an_oversized_model_file_is_refused_before_reading(tmp_path):
    from initsel_ros.models import MAX_FILE_BYTES

    path = tmp_path / 'huge.json'
    with path.open('wb') as handle:  # sparse: costs no disk
        handle.truncate(MAX_FILE_BYTES + 1)
    with pytest.raises(ModelFileError, match='larger than'):
        ModelSet.load(path)


def test_deeply_nested_json_is_a_model_file_error_not_recursion(tmp_path):
    path = tmp_path / 'deep.json'
    path.write_text('[' * 200_000 + ']' * 200_000)
    with pytest.raises(ModelFileError, match='nested deeper than') as info:
        ModelSet.load(path)
    assert str(path) in str(info.value)
    deep_dict = tmp_path / 'deep_dict.json'
    deep_dict.write_text('{"a": ' * 100_000 + '1' + '}' * 100_000)
    with pytest.raises(ModelFileError, match='nested deeper than'):
        ModelSet.load(deep_dict)


def test_brackets_and_escaped_quotes_inside_strings_do_not_count_as_nesting(tmp_path):
    data = make_set().to_dict()
    data['metadata'] = {'note': '[' * 5000 + '\\"{{{' + '\\\\', 'other': '}]' * 100}
    path = tmp_path / 'models.json'
    path.write_text(json.dumps(data))
    assert ModelSet.load(path).metadata == data['metadata']


def test_eval_on_a_deeply_nested_model_file_prints_one_line(tmp_path, capsys):
    from initsel_ros.cli import main

    path = tmp_path / 'deep.json'
    path.write_text('[' * 200_000 + ']' * 200_000)
    table = tmp_path / 'test.csv'
    table.write_text('sequence\n')
    assert main(['eval', str(table), '--models', str(path)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'deep.json' in err


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda d: d['models']['E'].update(weights=[[1.0]] * 23), 'weights must be a flat list'),
        (lambda d: d['models']['E'].update(weights=[[1.0] * 23]), 'weights must be a flat list'),
        (lambda d: d['models']['F'].update(mean=[[0.0]] * 23), 'mean must be a flat list'),
        (lambda d: d['models']['F'].update(scale=[[1.0]] * 23), 'scale must be a flat list'),
        (lambda d: d['models']['H'].update(weights=[True] * 23), 'weights must be a flat list'),
        (lambda d: d['models']['H'].update(weights=['1.0'] * 23), 'weights must be a flat list'),
        (lambda d: d['models']['R'].update(weights=5.0), 'weights must be a flat list'),
        (lambda d: d['models']['R'].update(bias=[1.0]), 'bias must be a finite number'),
        (lambda d: d['models']['R'].update(bias=None), 'bias must be a finite number'),
        (lambda d: d['models']['R'].update(threshold=[0.5]), 'threshold must be a number'),
        (lambda d: d['models']['R'].update(threshold=True), 'threshold must be a number'),
    ],
)
def test_the_schema_accepts_only_flat_lists_of_numbers(tmp_path, change, message):
    path = _edit(tmp_path, change)
    with pytest.raises(ModelFileError, match=message) as info:
        ModelSet.load(path)
    assert str(path) in str(info.value)


def test_logistic_model_refuses_a_two_dimensional_weight_array():
    with pytest.raises(ModelFileError, match='flat'):
        LogisticModel('E', np.ones((23, 1)), 0.0)


def _referee_section(data, band=1.0, seed=7):
    """A referee for R: another set's R model, at the file's R threshold."""
    judge = make_set(seed).to_dict()['models']['R']
    judge['threshold'] = data['models']['R']['threshold']
    return {'band_logit': {'R': band}, 'models': {'R': judge}, 'metadata': {'from': 'test'}}


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda r: r['band_logit'].update(R=0.0), r"band_logit\['R'\] must be > 0"),
        (lambda r: r['band_logit'].update(E=1.0), 'names models it does not hold'),
        (lambda r: r['models']['R'].update(threshold=0.9), 'decides at the threshold'),
        (lambda r: r.update(models={}), 'referee: "models"'),
        (lambda r: r['models'].update(X=r['models']['R']), 'referee: unknown models'),
        (lambda r: r['models']['R'].update(weights=[1.0] * 5), 'referee: .*weights'),
        (lambda r: r.update(band_logit=[1.0]), 'band_logit. must map'),
    ],
)
def test_malformed_referees_are_rejected(tmp_path, change, message):
    def edit(d):
        d['referee'] = _referee_section(d)
        change(d['referee'])

    with pytest.raises(ModelFileError, match=message):
        ModelSet.load(_edit(tmp_path, edit))


def test_the_referee_decides_only_within_its_band(tmp_path):
    rng = np.random.default_rng(5)
    p0 = rng.uniform(0, 640, (120, 2))
    p1 = p0 + rng.normal(0, 4, (120, 2)) + (6.0, 2.0)
    plain = make_set()
    data = plain.to_dict()

    def load(band):
        data['referee'] = _referee_section(data, band)
        path = tmp_path / f'ref{band}.json'
        path.write_text(json.dumps(data))
        return ModelSet.load(path)

    wide, narrow = load(1e6), load(1e-9)
    judge = wide.referee.models
    theirs = judge.predict_values(judge.input_values(p0, p1, 640, 480)[0])['R']
    ours = plain.predict_values(plain.input_values(p0, p1, 640, 480)[0])
    assert theirs != pytest.approx(ours['R'])
    probs, disparity, referred = wide.predict_points(p0, p1, 640, 480)
    assert referred == ('R',) and probs['R'] == pytest.approx(theirs)
    assert {m: probs[m] for m in 'FEH'} == pytest.approx({m: ours[m] for m in 'FEH'})
    assert disparity == pytest.approx(float(np.mean(np.hypot(*(p1 - p0).T))))
    probs, _, referred = narrow.predict_points(p0, p1, 640, 480)
    assert referred == () and probs == pytest.approx(ours)
    # the batch form decides the same rows
    X = wide.input_vector(p0, p1, 640, 480)[None]
    logits, rows = wide.review_logits(
        wide.logits_batch(X), judge.input_vector(p0, p1, 640, 480)[None]
    )
    assert rows.tolist() == [True]
    assert 1 / (1 + np.exp(-logits['R'][0])) == pytest.approx(theirs)
    with pytest.raises(GeometryError, match='referee'):
        wide.review_logits(wide.logits_batch(X), None)
    # a band between the two: the student's logit decides whether the referee is asked,
    # around the threshold in force (a policy override of R, other models the file's)
    z_ours = np.log(ours['R'] / (1 - ours['R']))
    threshold = plain.thresholds['R']
    distance = abs(z_ours - np.log(threshold / (1 - threshold)))
    for band, asked in ((distance * 1.01, True), (distance * 0.99, False)):
        model = load(band)
        _, _, referred = model.predict_points(p0, p1, 640, 480)
        assert referred == (('R',) if asked else ())
        _, rows = model.review_logits(
            model.logits_batch(X), judge.input_vector(p0, p1, 640, 480)[None]
        )
        assert rows.tolist() == [asked]
    at_student = {'R': 1 / (1 + np.exp(-z_ours))}  # a threshold right at the student's logit
    assert narrow.predict_points(p0, p1, 640, 480, at_student)[2] == ('R',)
    far = {'R': 1 / (1 + np.exp(-(z_ours + 2 * distance + 1)))}
    assert load(distance * 1.01).predict_points(p0, p1, 640, 480, far)[2] == ()
    # saved again, the referee stays
    wide.save(tmp_path / 'again.json')
    assert ModelSet.load(tmp_path / 'again.json').referee.band_logit == {'R': 1e6}


def test_an_installed_package_finds_its_share_without_the_ament_prefix_path(tmp_path):
    # before: a colcon install run without its setup script sourced looked everywhere but in
    # its own prefix (and listed one folder twice)
    from initsel_ros.config_files import _install_prefixes

    site = tmp_path / 'install' / 'lib' / 'python3.11' / 'site-packages'
    assert _install_prefixes(site / 'initsel_ros' / 'config_files.py') == [tmp_path / 'install']
    debian = tmp_path / 'usr' / 'local' / 'lib' / 'python3.12' / 'dist-packages' / 'initsel_ros'
    assert _install_prefixes(debian / 'x.py') == [tmp_path / 'usr' / 'local', tmp_path / 'usr']
    assert _install_prefixes(tmp_path / 'src' / 'initsel_ros' / 'x.py') == []


def test_config_dirs_look_in_the_prefix_the_package_is_installed_under(tmp_path, monkeypatch):
    from initsel_ros import config_files

    site = tmp_path / 'install' / 'lib' / 'python3.11' / 'site-packages'
    monkeypatch.setattr(config_files, '__file__', str(site / 'initsel_ros' / 'config_files.py'))
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    share = tmp_path / 'install' / 'share' / 'initsel_ros' / 'config'
    assert config_files.config_dirs()[0] == share
    share.mkdir(parents=True)
    (share / 'families.yaml').write_text('families: {}\n')
    assert config_files.find_config_file('families.yaml') == share / 'families.yaml'


def test_each_config_folder_is_looked_in_once(monkeypatch):
    import sys

    from initsel_ros.config_files import config_dirs

    monkeypatch.setenv('AMENT_PREFIX_PATH', f'{sys.prefix}:{sys.prefix}')
    dirs = config_dirs()
    assert len(dirs) == len(set(dirs))
