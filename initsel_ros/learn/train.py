"""Training the F, E, H and R models from labelled pairs.

Each model is a scikit-learn ``LogisticRegression`` on standardized features (the
``StandardScaler`` statistics become the model file's ``mean`` and ``scale``). The decision
threshold is chosen for a target precision on out-of-fold predictions of a grouped K-fold
cross-validation (folds are whole batches, never single pairs, so neighbouring frames of one
batch never sit on both sides), then the model is refitted on all pairs. Everything is seeded.

Richer models (logistic regression with extra features, histogram gradient boosting, a small
MLP) are fitted in memory for comparison only (:func:`fit_candidate`); nothing is pickled.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from initsel_ros.errors import DatasetError
from initsel_ros.features import FEATURE_NAMES, Scaling
from initsel_ros.learn.labels import LabelConfig, relabel
from initsel_ros.learn.table import (
    EXTRA_NAMES,
    PairTable,
    free_feature_columns,
    paper_feature_columns,
)
from initsel_ros.models import METHODS, LogisticModel, ModelSet

LOG = logging.getLogger(__name__)

#: Bias of a model whose training data held a single class (it always or never fires).
CONSTANT_LOGIT = 12.0
#: Thresholds stay within [margin, 1 - margin].
THRESHOLD_MARGIN = 1e-4


class ClassWeight(str, Enum):
    """Class weighting of the logistic loss."""

    BALANCED = 'balanced'
    NONE = 'none'

    @property
    def sklearn(self) -> str | None:
        """The value scikit-learn expects."""
        return 'balanced' if self is ClassWeight.BALANCED else None


@dataclass(frozen=True)
class TrainConfig:
    """Training options.

    Attributes
    ----------
    scaling : Scaling
        Which feature columns the models read (written into the model file).
    C : float
        Inverse L2 regularization strength of LogisticRegression.
    class_weight : ClassWeight
        ``balanced`` reweights classes to equal total weight (F positives are rare on planar
        scenes); ``none`` leaves them as they are.
    target_precision : float
        The threshold is the lowest one whose out-of-fold precision reaches this.
    folds : int
        Grouped cross-validation folds (groups = batches).
    min_predicted : int
        A threshold must predict 'yes' on at least this many validation pairs.
    seed : int
        Seed of the fold assignment and of the estimators.
    labels : LabelConfig or None
        Relabel the table with these thresholds first (None = use its label columns).
    allow_degenerate : bool
        Accept a model whose training labels are all one class (it then always or never
        fires); by default that is a DatasetError.
    """

    scaling: Scaling = Scaling.RESOLUTION_FREE
    C: float = 1.0
    class_weight: ClassWeight = ClassWeight.BALANCED
    target_precision: float = 0.8
    folds: int = 5
    min_predicted: int = 5
    seed: int = 0
    labels: LabelConfig | None = None
    allow_degenerate: bool = False


def feature_columns(scaling: Scaling) -> tuple[str, ...]:
    """The 23 table columns holding features in ``scaling``."""
    if Scaling(scaling) is Scaling.PAPER:
        return paper_feature_columns()
    return free_feature_columns()


def label_column(model: str) -> str:
    """Table column holding the labels of ``model`` ('F', 'E', 'H' or 'R')."""
    return 'R_label' if model == 'R' else f'{model}_label'


def prepare(table: PairTable, config: TrainConfig) -> PairTable:
    """Relabel (when asked) and drop rows whose 23 features are not finite."""
    if config.labels is not None:
        table = PairTable(relabel(dict(table.columns), config.labels))
    X = table.matrix(feature_columns(config.scaling))
    finite = np.all(np.isfinite(X), axis=1)
    if not finite.all():
        LOG.warning('dropping %d pairs with non-finite features', int((~finite).sum()))
        table = table.select(finite)
    return table


# ----------------------------------------------------------------------------- folds
def grouped_folds(groups: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Assign whole groups to ``folds`` folds at random: list of validation index arrays."""
    unique = np.unique(groups)
    k = int(min(folds, len(unique)))
    if k < 2:
        raise DatasetError(
            f'need at least 2 batches for grouped validation, got {len(unique)}'
        )
    order = np.random.default_rng(seed).permutation(unique)
    fold_of = {g: i % k for i, g in enumerate(order)}
    assignment = np.array([fold_of[g] for g in groups])
    return [np.flatnonzero(assignment == i) for i in range(k)]


def out_of_fold_scores(
    X: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    fit: Callable[[np.ndarray, np.ndarray], Callable[[np.ndarray], np.ndarray]],
    folds: int,
    seed: int,
) -> np.ndarray:
    """(N,) scores of each pair from a model fitted without its batch.

    ``fit(X, y)`` returns a scoring function; a fold whose training part holds one class
    scores its pairs with that constant class.
    """
    scores = np.full(len(y), np.nan)
    for val in grouped_folds(groups, folds, seed):
        train = np.setdiff1d(np.arange(len(y)), val)
        if len(np.unique(y[train])) < 2:
            scores[val] = float(y[train][0]) if len(train) else 0.0
            continue
        scores[val] = fit(X[train], y[train])(X[val])
    return scores


# ----------------------------------------------------------------------------- thresholds
@dataclass(frozen=True)
class ThresholdChoice:
    """A decision threshold and its validation figures."""

    threshold: float
    precision: float
    recall: float
    f1: float
    accuracy: float
    predicted: int
    reached: bool
    rule: str

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the model file."""
        return {
            'threshold': self.threshold, 'precision': self.precision, 'recall': self.recall,
            'f1': self.f1, 'accuracy': self.accuracy, 'predicted_positive': self.predicted,
            'target_reached': self.reached, 'rule': self.rule,
        }


def _curve(y: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, ...]:
    """Candidate thresholds (descending unique scores) with tp, fp at 'score >= t'."""
    order = np.argsort(-scores, kind='stable')
    s, t = scores[order], y[order].astype(bool)
    tp = np.cumsum(t)
    fp = np.cumsum(~t)
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]  # last index of each distinct score
    return s[last], tp[last], fp[last]


def choose_threshold(
    y: np.ndarray, scores: np.ndarray, target_precision: float, min_predicted: int = 5
) -> ThresholdChoice:
    """Lowest threshold whose precision reaches ``target_precision`` (highest recall).

    When no threshold predicting at least ``min_predicted`` positives reaches the target, the
    threshold maximizing F0.5 (precision-weighted) is taken and ``reached`` is False.
    """
    y = np.asarray(y).astype(bool)
    scores = np.asarray(scores, dtype=float)
    n, pos = len(y), int(y.sum())
    if n == 0 or pos == 0 or pos == n:
        thr = 1.0 if pos == 0 else 0.0
        pred = scores >= thr
        return _summarize(y, pred, thr, pos == n and n > 0, 'single class')
    thr, tp, fp = _curve(y, scores)
    predicted = tp + fp
    precision = tp / predicted
    recall = tp / pos
    ok = (precision >= target_precision) & (predicted >= min_predicted)
    if ok.any():
        i = int(np.flatnonzero(ok)[np.argmax(recall[ok])])
        rule = f'lowest threshold with precision >= {target_precision:g}'
        reached = True
    else:
        beta2 = 0.25
        with np.errstate(invalid='ignore', divide='ignore'):
            fbeta = (1 + beta2) * precision * recall / (beta2 * precision + recall)
        fbeta = np.where(predicted >= min(min_predicted, pos), np.nan_to_num(fbeta), -1.0)
        i = int(np.argmax(fbeta))
        rule = f'precision {target_precision:g} unreachable: max F0.5'
        reached = False
    # keep away from 0 and 1: out-of-fold probabilities saturate in float64
    t = float(min(max(thr[i], THRESHOLD_MARGIN), 1.0 - THRESHOLD_MARGIN))
    return _summarize(y, scores >= t, t, reached, rule)


def _summarize(
    y: np.ndarray, pred: np.ndarray, thr: float, reached: bool, rule: str
) -> ThresholdChoice:
    tp = int(np.sum(pred & y))
    npred = int(pred.sum())
    pos = int(y.sum())
    precision = tp / npred if npred else 0.0
    recall = tp / pos if pos else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    acc = float(np.mean(pred == y)) if len(y) else math.nan
    return ThresholdChoice(thr, precision, recall, f1, acc, npred, reached, rule)


# ----------------------------------------------------------------------------- logistic
def fit_logistic(
    X: np.ndarray, y: np.ndarray, C: float, class_weight: ClassWeight, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Standardize and fit: returns (mean (D,), scale (D,), weights (D,), bias)."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.preprocessing import StandardScaler

    scaler = StandardScaler().fit(X)
    clf = LogisticRegression(
        C=C, class_weight=class_weight.sklearn, max_iter=5000, random_state=seed
    )
    clf.fit(scaler.transform(X), y)
    return (
        np.asarray(scaler.mean_, dtype=float), np.asarray(scaler.scale_, dtype=float),
        np.asarray(clf.coef_[0], dtype=float), float(clf.intercept_[0]),
    )


def _logistic_scorer(C: float, class_weight: ClassWeight, seed: int) -> Callable[..., Any]:
    def fit(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        mean, scale, w, b = fit_logistic(X, y, C, class_weight, seed)
        return lambda Z: 1.0 / (1.0 + np.exp(-(((Z - mean) / scale) @ w + b)))

    return fit


def check_classes(table: PairTable, allow_degenerate: bool = False) -> list[str]:
    """Models whose training labels hold a single class.

    Raises:
        DatasetError: when there are any and ``allow_degenerate`` is False (one line naming
            each such model with its class counts).
    """
    found, counts = [], []
    for name in METHODS:
        y = np.asarray(table[label_column(name)]).astype(int)
        pos = int(y.sum())
        if pos in (0, len(y)):
            found.append(name)
            counts.append(f'model {name}: {pos} positive, {len(y) - pos} negative')
    if found and not allow_degenerate:
        raise DatasetError(
            f'{"; ".join(counts)} training labels: a model trained on one class always or '
            'never fires; add pairs of the other class or pass --allow-degenerate'
        )
    return found


@dataclass(frozen=True)
class TrainReport:
    """What :func:`train_models` fitted and how it validated."""

    models: ModelSet
    choices: dict[str, ThresholdChoice]
    positives: dict[str, int]
    n_pairs: int
    n_batches: int


def train_models(
    table: PairTable,
    config: TrainConfig | None = None,
    *,
    description: dict[str, Any] | None = None,
) -> TrainReport:
    """Fit the four logistic models and choose their thresholds.

    Parameters
    ----------
    table : PairTable
        Labelled pairs (see :mod:`initsel_ros.learn.table`).
    config : TrainConfig
        Options.
    description : dict
        Extra metadata for the model file (e.g. the input files).
    """
    import sklearn

    config = config or TrainConfig()
    table = prepare(table, config)
    if len(table) == 0:
        raise DatasetError('no labelled pairs to train on')
    X = table.matrix(feature_columns(config.scaling))
    groups = table.groups()
    n_batches = len(np.unique(groups))
    models: dict[str, LogisticModel] = {}
    choices: dict[str, ThresholdChoice] = {}
    positives: dict[str, int] = {}
    fit = _logistic_scorer(config.C, config.class_weight, config.seed)
    degenerate = check_classes(table, config.allow_degenerate)
    for name in METHODS:
        y = np.asarray(table[label_column(name)]).astype(int)
        positives[name] = int(y.sum())
        if name in degenerate:
            LOG.warning('model %s: all %d training labels are %d; it will %s fire '
                        '(--allow-degenerate)', name, len(y), int(y[0]),
                        'always' if y[0] else 'never')
            always = positives[name] == len(y)
            mean, scale, w = X.mean(axis=0), np.ones(X.shape[1]), np.zeros(X.shape[1])
            bias = CONSTANT_LOGIT if always else -CONSTANT_LOGIT
            choice = choose_threshold(y, np.full(len(y), float(always)), 0.5)
        else:
            scores = out_of_fold_scores(X, y, groups, fit, config.folds, config.seed)
            choice = choose_threshold(y, scores, config.target_precision, config.min_predicted)
            mean, scale, w, bias = fit_logistic(X, y, config.C, config.class_weight, config.seed)
        choices[name] = choice
        models[name] = LogisticModel(
            name=name, weights=w, bias=bias, threshold=choice.threshold, mean=mean,
            scale=np.where(scale > 0, scale, 1.0),
            metrics={
                'validation': choice.to_dict(),
                'train_pairs': len(y),
                'train_positives': positives[name],
            },
        )
        LOG.info(
            'model %s: %d/%d positive; threshold %.3f, validation precision %.3f recall %.3f%s',
            name, positives[name], len(y), choice.threshold, choice.precision, choice.recall,
            '' if choice.reached else ' (target precision not reached)',
        )
    sequences = {
        str(s): int(n) for s, n in zip(*np.unique(table['sequence'].astype(str),
                                                  return_counts=True), strict=True)
    }
    labels = config.labels or LabelConfig()
    rules = sorted(set(np.asarray(table['scale_rule']).astype(str)))
    metadata = {
        'description': 'Troutman & Tuceryan 2021 models: scikit-learn LogisticRegression per '
                       'model on standardized features',
        'date': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
        'sklearn_version': sklearn.__version__,
        'numpy_version': np.__version__,
        'feature_scaling': Scaling(config.scaling).value,
        'training_data': {
            **(description or {}),
            'sequences': sequences,
            'pairs': len(table),
            'batches': n_batches,
            'sources': sorted(set(np.asarray(table['source']).astype(str))),
            'positives': positives,
        },
        'labels': {  # `initsel dataset` labels with the defaults unless relabelled here
            'et_max': labels.et_max,
            'er_max': labels.er_max,
            'rotation_baseline_m': labels.rotation_baseline_m,
            'scale_rule': rules[0] if len(rules) == 1 else rules,
            'relabelled_at_training': config.labels is not None,
        },
        'training': {
            'C': config.C,
            'class_weight': config.class_weight.value,
            'target_precision': config.target_precision,
            'min_predicted': config.min_predicted,
            'validation': f'grouped {config.folds}-fold cross-validation over batches, '
                          'out-of-fold probabilities; final fit on all pairs',
            'seed': config.seed,
            'degenerate_models': degenerate,
        },
    }
    model_set = ModelSet(models, scaling=config.scaling, feature_names=FEATURE_NAMES,
                         metadata=metadata)
    return TrainReport(model_set, choices, positives, len(table), n_batches)


# ----------------------------------------------------------------------------- richer models
class Candidate(str, Enum):
    """Model families compared in evaluation (fitted in memory, never saved)."""

    LOGISTIC = 'logistic'  # the shipped kind: 23 features
    LOGISTIC_EXTRA = 'logistic+extra'  # 23 + extra cheap features
    HGB_EXTRA = 'hgb+extra'  # HistGradientBoostingClassifier, 23 + extra
    MLP_EXTRA = 'mlp+extra'  # MLPClassifier (32, 16), 23 + extra

    @property
    def uses_extra(self) -> bool:
        """Whether the extra features are inputs."""
        return self is not Candidate.LOGISTIC


def candidate_columns(candidate: Candidate, scaling: Scaling) -> tuple[str, ...]:
    """Input columns of a candidate."""
    cols = feature_columns(scaling)
    return cols + EXTRA_NAMES if candidate.uses_extra else cols


@dataclass(frozen=True)
class FittedCandidate:
    """A model fitted in memory, with its threshold and a single-row scorer for timing."""

    candidate: Candidate
    model: str
    columns: tuple[str, ...]
    score: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    score_one: Callable[[np.ndarray], float] = field(repr=False)
    threshold: ThresholdChoice | None = None


def _impute(X: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(X), X, 0.0)


def _fitter(candidate: Candidate, config: TrainConfig) -> Callable[..., Any]:
    """fit(X, y) -> (batch scorer, single-row scorer) for a candidate family."""
    seed = config.seed

    def fit(X: np.ndarray, y: np.ndarray) -> tuple[Callable[..., Any], Callable[..., Any]]:
        X = _impute(X)
        if candidate in (Candidate.LOGISTIC, Candidate.LOGISTIC_EXTRA):
            mean, scale, w, b = fit_logistic(X, y, config.C, config.class_weight, seed)
            w_eff, b_eff = w / scale, b - w @ (mean / scale)

            def batch(Z: np.ndarray) -> np.ndarray:
                return 1.0 / (1.0 + np.exp(-(_impute(Z) @ w_eff + b_eff)))

            def one(z: np.ndarray) -> float:
                return 1.0 / (1.0 + math.exp(-(float(z @ w_eff) + b_eff)))

            return batch, one
        if candidate is Candidate.HGB_EXTRA:
            from sklearn.ensemble import HistGradientBoostingClassifier

            clf = HistGradientBoostingClassifier(
                max_iter=200, learning_rate=0.1, max_leaf_nodes=15,
                class_weight=config.class_weight.sklearn, random_state=seed,
            ).fit(X, y)

            def batch(Z: np.ndarray) -> np.ndarray:
                return clf.predict_proba(_impute(Z))[:, 1]

            def one(z: np.ndarray) -> float:
                return float(clf.predict_proba(z.reshape(1, -1))[0, 1])

            return batch, one
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPClassifier
        from sklearn.preprocessing import StandardScaler

        scaler = StandardScaler().fit(X)
        weights = None
        if config.class_weight is ClassWeight.BALANCED:  # MLP has no class_weight: resample
            pos = np.flatnonzero(y == 1)
            neg = np.flatnonzero(y == 0)
            rng = np.random.default_rng(seed)
            minority, majority = (pos, neg) if len(pos) < len(neg) else (neg, pos)
            extra = rng.choice(minority, len(majority) - len(minority), replace=True)
            weights = np.r_[np.arange(len(y)), extra]
        idx = np.arange(len(y)) if weights is None else weights
        with warnings.catch_warnings():  # a comparison model: a few unconverged runs are fine
            warnings.simplefilter('ignore', ConvergenceWarning)
            clf = MLPClassifier(
                hidden_layer_sizes=(32, 16), alpha=1e-3, max_iter=500, random_state=seed,
            ).fit(scaler.transform(X[idx]), y[idx])
        W = [np.asarray(c) for c in clf.coefs_]
        B = [np.asarray(c) for c in clf.intercepts_]
        mu, sd = scaler.mean_, scaler.scale_

        def forward(Z: np.ndarray) -> np.ndarray:
            h = (_impute(Z) - mu) / sd
            for Wi, Bi in zip(W[:-1], B[:-1], strict=True):
                h = np.maximum(h @ Wi + Bi, 0.0)
            z = h @ W[-1] + B[-1]
            return (1.0 / (1.0 + np.exp(-z))).reshape(-1)

        return forward, lambda z: float(forward(z.reshape(1, -1))[0])

    return fit


def fit_candidate(
    candidate: Candidate, model: str, train: PairTable, config: TrainConfig
) -> FittedCandidate | None:
    """Fit one candidate for one model on ``train`` (threshold from grouped out-of-fold
    scores, as for the shipped models). None when the labels hold a single class."""
    columns = candidate_columns(candidate, config.scaling)
    X = train.matrix(columns)
    y = np.asarray(train[label_column(model)]).astype(int)
    if len(np.unique(y)) < 2:
        return None
    fitter = _fitter(candidate, config)
    scores = out_of_fold_scores(
        X, y, train.groups(), lambda A, b: fitter(A, b)[0], config.folds, config.seed
    )
    choice = choose_threshold(y, scores, config.target_precision, config.min_predicted)
    batch, one = fitter(X, y)
    return FittedCandidate(candidate, model, columns, batch, one, choice)


def describe_inputs(paths: Sequence[str]) -> dict[str, Any]:
    """Metadata entry naming the training files."""
    return {'files': [str(p) for p in paths]}


__all__ = [
    'CONSTANT_LOGIT',
    'THRESHOLD_MARGIN',
    'Candidate',
    'ClassWeight',
    'FittedCandidate',
    'ThresholdChoice',
    'TrainConfig',
    'TrainReport',
    'candidate_columns',
    'check_classes',
    'choose_threshold',
    'describe_inputs',
    'feature_columns',
    'fit_candidate',
    'fit_logistic',
    'grouped_folds',
    'label_column',
    'out_of_fold_scores',
    'prepare',
    'train_models',
]
