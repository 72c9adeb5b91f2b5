"""Gradient-boosted trees in the model file: export from scikit-learn, numpy inference, schema."""

from __future__ import annotations

import json

import numpy as np
import pytest

from initsel_ros.errors import GeometryError, ModelFileError
from initsel_ros.features import EXTRA_FEATURE_NAMES, FEATURE_NAMES, N_FEATURES
from initsel_ros.learn.train import ClassWeight, TreeConfig, fit_trees
from initsel_ros.models import METHODS, LogisticModel, ModelSet
from initsel_ros.trees import MAX_DEPTH, Tree, TreeEnsembleModel


def _data(n: int = 400, d: int = 6, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, d))
    y = ((X[:, 0] * X[:, 1] > 0) ^ (rng.random(n) < 0.1)).astype(int)
    return X, y


@pytest.mark.parametrize(('depth', 'n_trees'), [(1, 20), (3, 50), (5, 30)])
def test_exported_trees_reproduce_scikit_learn(depth, n_trees):
    from sklearn.ensemble import GradientBoostingClassifier
    from sklearn.utils.class_weight import compute_sample_weight

    X, y = _data()
    trees, bias = fit_trees(X, y, TreeConfig(n_trees, depth, 0.2), ClassWeight.BALANCED, 0)
    model = TreeEnsembleModel('F', tuple(f'f{i}' for i in range(X.shape[1])), tuple(trees), bias)
    ref = GradientBoostingClassifier(
        n_estimators=n_trees, max_depth=depth, learning_rate=0.2, random_state=0
    )
    ref.fit(X, y, sample_weight=compute_sample_weight('balanced', y))
    X_new, _ = _data(200, seed=1)
    np.testing.assert_allclose(
        model.predict_proba(X_new), ref.predict_proba(X_new)[:, 1], rtol=0, atol=1e-9
    )
    assert model.depth <= depth
    one = np.array([model.predict_proba(x) for x in X_new[:20]]).ravel()
    np.testing.assert_allclose(one, model.predict_proba(X_new[:20]), rtol=0, atol=1e-12)


def test_non_finite_inputs_count_as_zero():
    X, y = _data()
    trees, bias = fit_trees(X, y, TreeConfig(10, 2, 0.1), ClassWeight.NONE, 0)
    model = TreeEnsembleModel('F', tuple(f'f{i}' for i in range(6)), tuple(trees), bias)
    x = X[0].copy()
    x[[1, 3]] = (np.nan, np.inf)
    zeroed = x.copy()
    zeroed[[1, 3]] = 0.0
    assert model.predict_proba(x) == model.predict_proba(zeroed)


def _tree_models(seed: int = 0) -> dict[str, object]:
    """A mixed set: F trees on 23 + 2 extras, E logistic on 23, H logistic on 23 + 1 extra,
    R trees on the 23."""
    rng = np.random.default_rng(seed)
    X23 = rng.uniform(0, 1, (300, N_FEATURES))
    y = (X23[:, 1] > 0.5).astype(int)
    f_features = (*FEATURE_NAMES, 'x_homography_residual', 'x_disp_p50')
    f_trees, f_bias = fit_trees(
        np.c_[X23, rng.uniform(0, 1, (300, 2))], y, TreeConfig(15, 3, 0.1), ClassWeight.BALANCED, 0
    )
    r_trees, r_bias = fit_trees(X23, 1 - y, TreeConfig(10, 2, 0.1), ClassWeight.BALANCED, 0)
    h_features = (*FEATURE_NAMES, 'x_grid_entropy')
    return {
        'F': TreeEnsembleModel('F', f_features, tuple(f_trees), f_bias, 0.6),
        'E': LogisticModel('E', rng.normal(size=N_FEATURES), 0.1, 0.4),
        'H': LogisticModel('H', rng.normal(size=N_FEATURES + 1), -0.2, 0.5, features=h_features),
        'R': TreeEnsembleModel('R', FEATURE_NAMES, tuple(r_trees), r_bias, 0.3),
    }


def test_a_mixed_set_scores_each_model_on_its_own_named_features():
    models = _tree_models()
    ms = ModelSet(models)
    assert ms.extra_names == ('x_disp_p50', 'x_grid_entropy', 'x_homography_residual')
    assert ms.input_names == FEATURE_NAMES + ms.extra_names
    assert ms.kinds == {'F': 'trees', 'E': 'logistic', 'H': 'logistic', 'R': 'trees'}
    X = np.random.default_rng(3).uniform(0, 1, (50, len(ms.input_names)))
    batch = ms.predict_proba_batch(X)
    column = {n: i for i, n in enumerate(ms.input_names)}
    for m in METHODS:
        cols = [column[f] for f in models[m].features]
        np.testing.assert_allclose(batch[m], models[m].predict_proba(X[:, cols]), atol=1e-12)
        assert ms.predict_proba(X[7])[m] == pytest.approx(batch[m][7], abs=1e-12)
    with pytest.raises(GeometryError, match='26 inputs'):
        ms.predict_proba(X[0, :N_FEATURES])


def test_a_tree_model_file_round_trips_compactly(tmp_path):
    ms = ModelSet(_tree_models(), metadata={'note': 'unit test'})
    path = tmp_path / 'models.json'
    ms.save(path)
    loaded = ModelSet.load(path)
    X = np.random.default_rng(4).uniform(0, 1, (20, len(ms.input_names)))
    for m in METHODS:
        np.testing.assert_array_equal(
            loaded.predict_proba_batch(X)[m], ms.predict_proba_batch(X)[m]
        )
    text = path.read_text()
    assert json.loads(text)['version'] == 2
    assert '"feature": [' in text and len(text.splitlines()) < 400  # lists of numbers inline


def test_input_vector_computes_extra_features_only_when_a_model_reads_them(monkeypatch):
    import initsel_ros.features as features_module
    from initsel_ros.features import extra_features

    calls = []
    for name in ('_fit_features', '_linear_quantiles'):
        real = getattr(features_module, name)

        def spy(*args, _real=real, _name=name):
            calls.append(_name)
            return _real(*args)

        monkeypatch.setattr(features_module, name, spy)
    rng = np.random.default_rng(5)
    p0 = rng.uniform(0, 400, (60, 2))
    p1 = p0 + rng.normal(0, 2, p0.shape)
    logistic_only = ModelSet({m: LogisticModel(m, np.ones(N_FEATURES), 0.0) for m in METHODS})
    assert logistic_only.input_vector(p0, p1, 640, 480).shape == (N_FEATURES,)
    assert logistic_only.input_plan(640, 480).extra == ()
    assert calls == []
    ms = ModelSet(_tree_models())
    x = ms.input_vector(p0, p1, 640, 480)
    assert sorted(calls) == ['_fit_features', '_linear_quantiles']
    assert x.shape == (N_FEATURES + 3,)
    np.testing.assert_array_equal(x[N_FEATURES:], extra_features(p0, p1, 640, 480, ms.extra_names))


def test_decide_pair_feeds_the_extra_features_to_the_models():
    from initsel_ros.policy import PolicyConfig, effective_thresholds
    from initsel_ros.selector import decide_pair

    ms = ModelSet(_tree_models())
    rng = np.random.default_rng(6)
    p0 = rng.uniform(0, 400, (80, 2))
    p1 = p0 + rng.normal(0, 2, p0.shape) + 20
    policy = PolicyConfig()
    decision = decide_pair(
        ms, effective_thresholds(ms.thresholds, policy), policy, p0, p1, 640, 480
    )
    assert decision.probabilities == ms.predict_proba(ms.input_vector(p0, p1, 640, 480))


def _tree_file(tmp_path, change):
    data = ModelSet(_tree_models()).to_dict()
    change(data['models']['F'])
    path = tmp_path / 'bad.json'
    path.write_text(json.dumps(data))
    return path


def _first_tree(d):
    return d['trees'][0]


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (
            lambda d: _first_tree(d)['left'].__setitem__(0, 0),  # the root its own child
            'children must come after their parent',
        ),
        (lambda d: _first_tree(d)['left'].__setitem__(-1, 0), 'leaf .* must have left'),
        (lambda d: _first_tree(d)['feature'].__setitem__(0, 99), r'feature must lie in'),
        (
            lambda d: _first_tree(d).update(split=[[0.5]] * len(_first_tree(d)['split'])),
            'split must be a flat list',
        ),
        (lambda d: _first_tree(d).update(value=_first_tree(d)['value'][:-1]), 'value must have'),
        (
            lambda d: _first_tree(d).update(feature=[0.0] * len(_first_tree(d)['feature'])),
            'feature must be a flat list of .* integers',
        ),
        (lambda d: _first_tree(d).pop('split'), 'a tree must map exactly'),
        (lambda d: d.update(trees=[]), 'trees. must be a list of 1 to'),
        (lambda d: d.update(trees={'a': 1}), 'trees. must be a list of 1 to'),
        (lambda d: d.update(kind='forest'), "unknown kind 'forest'"),
        (lambda d: d['features'].__setitem__(0, 'x_magic'), 'unknown features'),
        (lambda d: d['features'].__setitem__(1, 'count'), 'lists a feature twice'),
        (lambda d: d.update(features=[[f] for f in d['features']]), 'list of feature names'),
        (lambda d: d.update(bias='high'), 'bias must be a finite number'),
    ],
)
def test_malformed_trees_are_rejected_with_the_file_name(tmp_path, change, message):
    path = _tree_file(tmp_path, change)
    with pytest.raises(ModelFileError, match=message) as info:
        ModelSet.load(path)
    assert str(path) in str(info.value)


def test_a_tree_deeper_than_the_bound_is_refused():
    k = 2 * (MAX_DEPTH + 1) + 1  # a chain: every inner node has a leaf on the left
    feature = np.full(k, -1)
    left = np.full(k, -1)
    right = np.full(k, -1)
    inner = np.arange(0, k - 1, 2)
    feature[inner] = 0
    left[inner] = inner + 1
    right[inner] = inner + 2
    tree = Tree(feature, np.zeros(k), left, right, np.zeros(k))
    with pytest.raises(ModelFileError, match='deeper than'):
        TreeEnsembleModel('F', FEATURE_NAMES, (tree,), 0.0)


def test_version_1_files_and_the_shipped_file_still_load(tmp_path):
    from initsel_ros.models import default_model_path

    rng = np.random.default_rng(7)
    legacy = {
        'format': 'initsel_ros/models',
        'version': 1,
        'scaling': 'resolution_free',
        'feature_names': list(FEATURE_NAMES),
        'metadata': {},
        'models': {
            m: {
                'weights': rng.normal(size=N_FEATURES).tolist(),
                'bias': 0.5,
                'threshold': 0.5,
                'mean': [0.0] * N_FEATURES,
                'scale': [1.0] * N_FEATURES,
            }
            for m in METHODS
        },
    }
    path = tmp_path / 'v1.json'
    path.write_text(json.dumps(legacy))
    old = ModelSet.load(path)
    assert old.input_names == FEATURE_NAMES and old.extra_names == ()
    assert set(old.kinds.values()) == {'logistic'}
    shipped = ModelSet.load(default_model_path())
    assert set(shipped.extra_names) <= set(EXTRA_FEATURE_NAMES)
    x = np.zeros(len(shipped.input_names))
    assert set(shipped.predict_proba(x)) == set(METHODS)


def test_the_leaf_table_scores_every_row_as_the_flat_trees_do():
    from initsel_ros.trees import FlatTrees, LeafTable, float32_splits, prepare

    X, y = _data(400, 6, seed=3)
    trees = []
    for depth in (1, 2, 3):  # shallow trees have leaves above depth 3: padded in the table
        fitted, _ = fit_trees(X, y, TreeConfig(12, depth, 0.3), ClassWeight.BALANCED, depth)
        trees += fitted
    columns = [np.arange(6)] * len(trees)
    starts = [0, 12, 24]
    table = LeafTable.build(trees, columns, starts)
    flat = FlatTrees.build(trees, columns)
    owner = np.repeat([0, 1, 2], 12)
    splits = np.concatenate([t.split[t.feature >= 0] for t in trees])
    rows = np.vstack(
        (
            _data(200, 6, seed=4)[0],
            np.tile(splits[:, None], (1, 6))[:60],  # inputs exactly on a split
            np.tile(np.nextafter(splits, np.inf)[:, None], (1, 6))[:60],  # just above it
        )
    )
    for x in prepare(rows):
        expected = np.bincount(owner, weights=flat.leaf_values(x), minlength=3)
        np.testing.assert_allclose(table.sums(x.astype(np.float32)), expected, atol=1e-12)
    # float32 x > float32_splits(s) exactly when float32 x > s, on both sides of each split
    s = splits[:50]
    for x32 in (s.astype(np.float32), np.nextafter(s.astype(np.float32), np.float32(np.inf))):
        np.testing.assert_array_equal(x32 > float32_splits(s), x32.astype(np.float64) > s)


def test_model_sets_with_deep_trees_score_one_vector_without_the_table():
    X, y = _data(300, N_FEATURES, seed=5)
    deep, deep_bias = fit_trees(X, y, TreeConfig(8, 5, 0.2), ClassWeight.NONE, 0)
    shallow, shallow_bias = fit_trees(X, y, TreeConfig(8, 3, 0.2), ClassWeight.NONE, 0)
    for trees, bias, tabled in ((deep, deep_bias, False), (shallow, shallow_bias, True)):
        models = {m: TreeEnsembleModel(m, FEATURE_NAMES, tuple(trees), bias) for m in METHODS}
        ms = ModelSet(models)
        assert (ms._table is not None) is tabled
        batch = ms.predict_proba_batch(X[:40])
        for i in range(40):
            one = ms.predict_values(X[i].tolist())
            for m in METHODS:
                assert one[m] == pytest.approx(batch[m][i], abs=1e-12)
