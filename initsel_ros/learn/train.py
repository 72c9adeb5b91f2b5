"""Training the F, E, H and R models from labelled pairs.

Each model belongs to a family (:class:`Family`): scikit-learn ``LogisticRegression`` on
standardized features (the ``StandardScaler`` statistics become the model file's ``mean`` and
``scale``) or a scikit-learn ``GradientBoostingClassifier`` exported to plain JSON trees
(:mod:`initsel_ros.trees`, evaluated in numpy), on the 23 paper features with or without the
extra features. The decision threshold is chosen for a target precision on out-of-fold
predictions of a grouped K-fold cross-validation (folds are whole batches, never single pairs,
so neighbouring frames of one batch never sit on both sides), then the model is refitted on all
pairs. Everything is seeded.

Other families (histogram gradient boosting through scikit-learn, a small MLP) are fitted in
memory for comparison only (:mod:`initsel_ros.learn.candidates`); nothing is pickled.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import TYPE_CHECKING, Any

import numpy as np

from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.features import EXTRA_FEATURE_NAMES, FEATURE_NAMES, Scaling
from initsel_ros.learn.labels import LabelConfig, relabel
from initsel_ros.learn.table import (
    PairTable,
    check_camera_features,
    free_feature_columns,
    input_columns,
    paper_feature_columns,
)
from initsel_ros.models import METHODS, LogisticModel, Model, ModelSet
from initsel_ros.trees import Tree, TreeEnsembleModel

if TYPE_CHECKING:
    from initsel_ros.learn.generalize import Families

LOG = logging.getLogger(__name__)

#: Bias of a model whose training data held a single class (it always or never fires).
CONSTANT_LOGIT = 12.0
#: Thresholds stay within [margin, 1 - margin].
THRESHOLD_MARGIN = 1e-4
#: With family folds, where no threshold holds the target on the worst family, the threshold
#: keeps at least this share of the positives (issue 21's bar: precision at recall 0.5).
FALLBACK_MIN_RECALL = 0.5


class ClassWeight(str, Enum):
    """Class weighting of the logistic loss."""

    BALANCED = 'balanced'
    NONE = 'none'

    @property
    def sklearn(self) -> str | None:
        """The value scikit-learn expects."""
        return 'balanced' if self is ClassWeight.BALANCED else None


class Family(str, Enum):
    """What a model is: its kind and whether it reads the extra features."""

    LOGISTIC = 'logistic'  # the paper's: logistic regression on the 23 features
    LOGISTIC_EXTRA = 'logistic+extra'  # 23 + the extra features
    TREES = 'trees'  # gradient-boosted trees on the 23 features
    TREES_EXTRA = 'trees+extra'  # gradient-boosted trees on 23 + the extra features

    @property
    def kind(self) -> str:
        """'logistic' or 'trees' (the model file's ``kind``)."""
        return 'trees' if self.value.startswith('trees') else 'logistic'

    @property
    def uses_extra(self) -> bool:
        """Whether the extra features are inputs."""
        return self.value.endswith('+extra')


#: The family ``initsel train`` uses unless told otherwise (the shipped model file's).
DEFAULT_FAMILY = Family.TREES_EXTRA


@dataclass(frozen=True)
class TreeConfig:
    """Gradient boosting settings (scikit-learn's ``GradientBoostingClassifier`` defaults).

    Attributes:
        n_trees: boosting stages (one regression tree each).
        depth: maximum depth of each tree.
        learning_rate: shrinkage of each tree's contribution (folded into the exported leaf
            values).
    """

    n_trees: int = 100
    depth: int = 3
    learning_rate: float = 0.1

    def __post_init__(self) -> None:
        from initsel_ros.trees import MAX_DEPTH, MAX_TREES

        if not 1 <= self.n_trees <= MAX_TREES:
            raise ConfigError(f'the number of trees must be in [1, {MAX_TREES}]')
        if not 1 <= self.depth <= MAX_DEPTH:
            raise ConfigError(f'the tree depth must be in [1, {MAX_DEPTH}]')
        if not 0.0 < self.learning_rate <= 1.0:
            raise ConfigError('the learning rate must be in (0, 1]')


@dataclass(frozen=True)
class TrainConfig:
    """Training options.

    Attributes:
        scaling: which feature columns the models read (written into the model file).
        C: inverse L2 regularization strength of LogisticRegression.
        class_weight: ``balanced`` reweights classes to equal total weight (F positives are
            rare on planar scenes); ``none`` leaves them as they are.
        target_precision: the threshold is the lowest one whose out-of-fold precision reaches
            this.
        threshold_prior: None (default): that precision is measured on the training mix as
            it is, so it depends on the mix's share of positives; a share p in (0, 1): it is
            measured as if positives were p of the pairs (from the true and false positive
            rates alone), a threshold that does not move with the mix's base rate.
        threshold_priors: per-model shares overriding ``threshold_prior``, e.g. ``{'R': 0.15}``.
        group_by: the unit of the validation folds: ``batch`` (a pair's batch),
            ``sequence`` (its whole sequence: a fold then holds scenes and motions the models
            were not fitted on, so thresholds are chosen for sequences never seen) or
            ``family`` (its scene family of ``scene_families``: one fold per family, each
            scored by models fitted without it, and the threshold must also hold the target
            on the worst family: :func:`choose_threshold`).
        scene_families: the scene families of ``group_by='family'``.
        min_family_positives: with ``group_by='family'``, a family's precision counts for the
            threshold only where it holds at least this many positives of the model.
        family_precision: with ``group_by='family'``, the precision the worst family must
            reach (None: ``target_precision``).
        folds: grouped cross-validation folds (groups = batches or sequences; with
            ``group_by='family'`` there is one fold per family and this is not read).
        min_predicted: a threshold must predict 'yes' on at least this many validation pairs.
        seed: seed of the fold assignment and of the estimators.
        labels: relabel the table with these thresholds first (None = use its label columns).
        allow_degenerate: accept a model whose training labels are all one class (it then
            always or never fires); by default that is a DatasetError.
        family: family of every model not in ``families``.
        families: per-model family, e.g. ``{'F': Family.TREES_EXTRA}``.
        extra: the extra features a ``+extra`` family reads (default all of them).
        paper: the paper's 23 features a ``+extra`` family reads (default all of them; the
            plain families read all 23, as the paper's models).
        trees: gradient boosting settings of the tree families.
        rotation_min_static_share: None (default): R learns from every pair; a share s in
            (0, 1]: R leaves out of its training the R-positive pairs (the camera only
            rotated) whose tracks the ground truth explains as a static scene for less than
            s of them (``gt_static_share``; pairs without depth are kept). The pair features
            are least-squares sums, so a few tracks on an object that moves on its own put a
            pan's residuals where a translating camera's are; the live node's rotation test
            is robust to them (least-median), R's features are not (docs/learning.md).
    """

    scaling: Scaling = Scaling.RESOLUTION_FREE
    C: float = 1.0
    class_weight: ClassWeight = ClassWeight.BALANCED
    target_precision: float = 0.8
    threshold_prior: float | None = None
    threshold_priors: dict[str, float] = field(default_factory=dict)
    group_by: str = 'batch'
    folds: int = 5
    min_predicted: int = 5
    seed: int = 0
    labels: LabelConfig | None = None
    allow_degenerate: bool = False
    family: Family = DEFAULT_FAMILY
    families: dict[str, Family] = field(default_factory=dict)
    extra: tuple[str, ...] = EXTRA_FEATURE_NAMES
    paper: tuple[str, ...] = FEATURE_NAMES
    trees: TreeConfig = field(default_factory=TreeConfig)
    rotation_min_static_share: float | None = None
    scene_families: Families | None = None
    min_family_positives: int = 30
    family_precision: float | None = None

    def __post_init__(self) -> None:
        unknown = [n for n in self.extra if n not in EXTRA_FEATURE_NAMES]
        if unknown:
            raise ConfigError(
                f'unknown extra features {unknown}; known: {", ".join(EXTRA_FEATURE_NAMES)}'
            )
        unknown = [n for n in self.paper if n not in FEATURE_NAMES]
        if unknown:
            raise ConfigError(
                f'unknown paper features {unknown}; known: {", ".join(FEATURE_NAMES)}'
            )
        for name, share in [('', self.threshold_prior), *self.threshold_priors.items()]:
            if name and name not in METHODS:
                raise ConfigError(f'threshold prior of an unknown model {name!r}')
            if share is not None and not 0.0 < share < 1.0:
                raise ConfigError(f'threshold_prior must be in (0, 1), got {share}')
        if self.group_by not in GROUP_BY:
            raise ConfigError(f'group_by must be one of {", ".join(GROUP_BY)}')
        if self.group_by == 'family' and self.scene_families is None:
            raise ConfigError("group_by 'family' needs the scene families (scene_families)")
        if self.family_precision is not None and not 0.0 < self.family_precision <= 1.0:
            raise ConfigError(f'family_precision must be in (0, 1], got {self.family_precision}')
        bad = [m for m in self.families if m not in METHODS]
        if bad:
            raise ConfigError(f'unknown models {bad} (models: {", ".join(METHODS)})')
        share = self.rotation_min_static_share
        if share is not None and not (math.isfinite(share) and 0.0 < share <= 1.0):
            raise ConfigError(f'rotation_min_static_share must be in (0, 1], got {share}')

    def prior_of(self, model: str) -> float | None:
        """The threshold prior of ``model`` (None: the training mix's own share)."""
        return self.threshold_priors.get(model, self.threshold_prior)

    def family_of(self, model: str) -> Family:
        """The family of ``model``."""
        return Family(self.families.get(model, self.family))

    def features_of(self, family: Family) -> tuple[str, ...]:
        """Input feature names of a family."""
        if not Family(family).uses_extra:
            return FEATURE_NAMES
        paper = tuple(n for n in FEATURE_NAMES if n in self.paper)
        return paper + tuple(n for n in EXTRA_FEATURE_NAMES if n in self.extra)


def feature_columns(scaling: Scaling) -> tuple[str, ...]:
    """The 23 table columns holding features in ``scaling``."""
    if Scaling(scaling) is Scaling.PAPER:
        return paper_feature_columns()
    return free_feature_columns()


def rotation_training_rows(table: PairTable, config: TrainConfig) -> np.ndarray:
    """(N,) bool: the pairs R learns from (every pair unless
    ``config.rotation_min_static_share`` leaves out R positives with moving objects)."""
    keep = np.ones(len(table), dtype=bool)
    if config.rotation_min_static_share is None:
        return keep
    share = np.asarray(table['gt_static_share'], dtype=float)
    positive = np.asarray(table[label_column('R')]).astype(bool)
    unknown = int(np.sum(positive & ~np.isfinite(share)))
    if unknown:
        LOG.warning(
            'model R: %d of %d positive pairs have no static share (no depth, or a table '
            'written before gt_static_share): kept',
            unknown,
            int(positive.sum()),
        )
    with np.errstate(invalid='ignore'):
        keep &= ~(positive & (share < config.rotation_min_static_share))
    return keep


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
#: The units a validation fold can be made of (TrainConfig.group_by).
GROUP_BY = ('batch', 'sequence', 'family')


def validation_groups(table: PairTable, config: TrainConfig) -> np.ndarray:
    """(N,) int group of each pair for the validation folds (``config.group_by``)."""
    if config.group_by != 'family':
        return table.groups(by=config.group_by)
    assert config.scene_families is not None  # (checked by TrainConfig)
    _, ids = np.unique(config.scene_families.assign(table['sequence']), return_inverse=True)
    return ids


def grouped_folds(
    groups: np.ndarray, folds: int, seed: int, unit: str = 'batch'
) -> list[np.ndarray]:
    """Assign whole groups (each a ``unit``: batch or sequence) to ``folds`` folds at random:
    list of validation index arrays."""
    unique = np.unique(groups)
    if folds < 2:
        raise DatasetError(f'grouped validation needs at least 2 folds, got {folds}')
    if len(unique) < 2:
        plural = {'batch': 'batches', 'family': 'families'}.get(unit, f'{unit}s')
        raise DatasetError(f'grouped validation needs at least 2 {plural}, got {len(unique)}')
    k = int(min(folds, len(unique)))
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
    unit: str = 'batch',
) -> np.ndarray:
    """(N,) scores of each pair from a model fitted without its group (a ``unit``: batch
    or sequence).

    ``fit(X, y)`` returns a scoring function; a fold whose training part holds one class
    scores its pairs with that constant class.
    """
    scores = np.full(len(y), np.nan)
    for val in grouped_folds(groups, folds, seed, unit):
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
            'threshold': self.threshold,
            'precision': self.precision,
            'recall': self.recall,
            'f1': self.f1,
            'accuracy': self.accuracy,
            'predicted_positive': self.predicted,
            'target_reached': self.reached,
            'rule': self.rule,
        }


def threshold_curve(y: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, ...]:
    """Candidate thresholds (descending unique scores) with tp, fp at 'score >= t'."""
    order = np.argsort(-scores, kind='stable')
    s, t = scores[order], y[order].astype(bool)
    tp = np.cumsum(t)
    fp = np.cumsum(~t)
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]  # last index of each distinct score
    return s[last], tp[last], fp[last]


def choose_threshold(
    y: np.ndarray,
    scores: np.ndarray,
    target_precision: float,
    min_predicted: int = 5,
    prior: float | None = None,
    groups: np.ndarray | None = None,
    min_group_positives: int = 30,
    group_target: float | None = None,
) -> ThresholdChoice:
    """Lowest threshold whose precision reaches ``target_precision`` (highest recall).

    When no threshold predicting at least ``min_predicted`` positives reaches the target, the
    threshold maximizing F0.5 (precision-weighted) is taken and ``reached`` is False. With a
    ``prior`` the precision is that of a mix whose share of positives is ``prior``:
    ``prior TPR / (prior TPR + (1 - prior) FPR)`` (the reported figures stay those of ``y``).
    With ``groups`` (each pair's scene family, whose scores came from models fitted without
    it), the precision of every group holding at least ``min_group_positives`` positives
    must reach ``group_target`` (default ``target_precision``) as well (a group the
    threshold predicts nothing on passes): a threshold for families never seen; where none
    does, the threshold with the worst such group's highest precision among those keeping
    ``FALLBACK_MIN_RECALL`` of the positives.
    """
    y = np.asarray(y).astype(bool)
    scores = np.asarray(scores, dtype=float)
    n, pos = len(y), int(y.sum())
    if n == 0 or pos == 0 or pos == n:
        thr = 1.0 if pos == 0 else 0.0
        pred = scores >= thr
        return _summarize(y, pred, thr, pos == n and n > 0, 'single class')
    thr, tp, fp = threshold_curve(y, scores)
    predicted = tp + fp
    precision = tp / predicted
    recall = tp / pos
    at = ''
    if prior is not None:
        weighted_tp, weighted_fp = prior * recall, (1.0 - prior) * fp / (n - pos)
        with np.errstate(invalid='ignore', divide='ignore'):
            precision = np.where(predicted > 0, weighted_tp / (weighted_tp + weighted_fp), 0.0)
        at = f' at a {prior:g} share of positives'
    ok = (precision >= target_precision) & (predicted >= min_predicted)
    worst = ''
    if groups is not None:
        group_target = target_precision if group_target is None else group_target
        group_precision = _worst_group_precision(
            y, scores, np.asarray(groups), thr, min_group_positives
        )
        ok &= group_precision >= group_target
        worst = f' and >= {group_target:g} on the worst family'
    if ok.any():
        i = int(np.flatnonzero(ok)[np.argmax(recall[ok])])
        rule = f'lowest threshold with precision >= {target_precision:g}{at}{worst}'
        reached = True
    elif groups is not None:
        # the worst family's precision as high as it goes while half the positives stay
        kept = (recall >= FALLBACK_MIN_RECALL) & (predicted >= min(min_predicted, pos))
        i = int(
            np.flatnonzero(kept)[
                np.argmax(np.where(np.isfinite(group_precision), group_precision, -1.0)[kept])
            ]
        )
        rule = (
            f"precision {target_precision:g}{at}{worst} unreachable: the worst family's "
            f'highest precision at recall >= {FALLBACK_MIN_RECALL:g}'
        )
        reached = False
    else:
        beta2 = 0.25
        with np.errstate(invalid='ignore', divide='ignore'):
            fbeta = (1 + beta2) * precision * recall / (beta2 * precision + recall)
        fbeta = np.where(predicted >= min(min_predicted, pos), np.nan_to_num(fbeta), -1.0)
        i = int(np.argmax(fbeta))
        rule = f'precision {target_precision:g}{at} unreachable: max F0.5'
        reached = False
    # keep away from 0 and 1: out-of-fold probabilities saturate in float64
    t = float(min(max(thr[i], THRESHOLD_MARGIN), 1.0 - THRESHOLD_MARGIN))
    return _summarize(y, scores >= t, t, reached, rule)


def _worst_group_precision(
    y: np.ndarray,
    scores: np.ndarray,
    groups: np.ndarray,
    thresholds: np.ndarray,
    min_positives: int,
) -> np.ndarray:
    """At each of ``thresholds``: the least precision of 'score >= threshold' over the
    groups with at least ``min_positives`` positives (+inf where no such group has a yes)."""
    worst = np.full(len(thresholds), np.inf)
    for g in np.unique(groups):
        member = groups == g
        if int(y[member].sum()) < min_positives:
            continue
        s_pos, s_neg = np.sort(scores[member & y]), np.sort(scores[member & ~y])
        tp = len(s_pos) - np.searchsorted(s_pos, thresholds, side='left')
        fp = len(s_neg) - np.searchsorted(s_neg, thresholds, side='left')
        with np.errstate(invalid='ignore', divide='ignore'):
            worst = np.minimum(worst, np.where(tp + fp > 0, tp / (tp + fp), np.inf))
    return worst


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
        np.asarray(scaler.mean_, dtype=float),
        np.asarray(scaler.scale_, dtype=float),
        np.asarray(clf.coef_[0], dtype=float),
        float(clf.intercept_[0]),
    )


def impute(X: np.ndarray) -> np.ndarray:
    """Non-finite values (an extra feature without a fit) -> 0, as the live models do."""
    return np.where(np.isfinite(X), X, 0.0)


def fit_trees(
    X: np.ndarray, y: np.ndarray, config: TreeConfig, class_weight: ClassWeight, seed: int
) -> tuple[list[Tree], float]:
    """Gradient boosting, exported: (trees with the learning rate folded in, bias logit).

    The export is checked against scikit-learn's own ``decision_function`` on ``X``.
    """
    from sklearn.ensemble import GradientBoostingClassifier
    from sklearn.utils.class_weight import compute_sample_weight

    X = impute(X)
    weight = compute_sample_weight('balanced', y) if class_weight is ClassWeight.BALANCED else None
    clf = GradientBoostingClassifier(
        n_estimators=config.n_trees,
        max_depth=config.depth,
        learning_rate=config.learning_rate,
        random_state=seed,
    ).fit(X, y, sample_weight=weight)
    return export_trees(clf.estimators_[:, 0], config.learning_rate, X, clf.decision_function(X))


def export_trees(
    estimators: Sequence[Any], learning_rate: float, X: np.ndarray, reference: np.ndarray
) -> tuple[list[Tree], float]:
    """scikit-learn boosting stages as (trees with the learning rate folded in, bias), checked
    against the estimator's own output ``reference`` on ``X`` (its logit or prediction)."""
    trees = []
    for estimator in estimators:
        t = estimator.tree_
        leaf = t.children_left < 0
        trees.append(
            Tree(
                feature=np.where(leaf, -1, t.feature).astype(np.int64),
                split=np.where(leaf, 0.0, t.threshold),
                left=np.where(leaf, -1, t.children_left).astype(np.int64),
                right=np.where(leaf, -1, t.children_right).astype(np.int64),
                value=np.where(leaf, learning_rate * t.value[:, 0, 0], 0.0),
            )
        )
    probe = TreeEnsembleModel('probe', tuple(map(str, range(X.shape[1]))), tuple(trees), 0.0)
    sums = probe.decision_function(X)
    bias = float(np.median(reference - sums))
    error = float(np.max(np.abs(reference - (sums + bias)))) if len(X) else 0.0
    if error > 1e-6:
        raise RuntimeError(f'tree export disagrees with scikit-learn by {error:.3g}')
    return trees, bias


def fit_model(
    family: Family,
    name: str,
    features: tuple[str, ...],
    X: np.ndarray,
    y: np.ndarray,
    config: TrainConfig,
) -> Model:
    """One model of ``family`` fitted on ``X`` (columns = ``features``), threshold 0.5."""
    X = impute(X)
    if Family(family).kind == 'trees':
        trees, bias = fit_trees(X, y, config.trees, config.class_weight, config.seed)
        return TreeEnsembleModel(name, features, tuple(trees), bias)
    mean, scale, w, b = fit_logistic(X, y, config.C, config.class_weight, config.seed)
    return LogisticModel(name, w, b, 0.5, mean, np.where(scale > 0, scale, 1.0), features=features)


def _scorer(family: Family, features: tuple[str, ...], config: TrainConfig) -> Callable[..., Any]:
    """fit(X, y) -> scoring function, for out-of-fold scores (the exported model scores)."""

    def fit(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        model = fit_model(family, 'fold', features, X, y, config)
        return lambda Z: model.predict_proba(impute(Z))

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

    Args:
        table: labelled pairs (see :mod:`initsel_ros.learn.table`).
        config: options.
        description: extra metadata for the model file (e.g. the input files).
    """
    import sklearn

    config = config or TrainConfig()
    table = prepare(table, config)
    if len(table) == 0:
        raise DatasetError('no labelled pairs to train on')
    groups = validation_groups(table, config)
    by_family = config.group_by == 'family'
    folds = len(np.unique(groups)) if by_family else config.folds
    n_batches = len(np.unique(table.groups()))
    models: dict[str, Model] = {}
    choices: dict[str, ThresholdChoice] = {}
    positives: dict[str, int] = {}
    rotation_left_out = 0  # R positives the static-share rule left out
    degenerate = check_classes(table, config.allow_degenerate)
    for name in METHODS:
        family = config.family_of(name)
        features = config.features_of(family)
        check_camera_features(table, features)
        X = impute(table.matrix(input_columns(features, config.scaling)))
        y = np.asarray(table[label_column(name)]).astype(int)
        model_groups = groups
        if name == 'R' and config.rotation_min_static_share is not None:
            keep = rotation_training_rows(table, config)
            X, y, model_groups = X[keep], y[keep], groups[keep]
            rotation_left_out = int((~keep).sum())
            LOG.info(
                'model R: %d positive pairs whose tracks are under %.2f static left out',
                rotation_left_out,
                config.rotation_min_static_share,
            )
        positives[name] = int(y.sum())
        if name in degenerate:
            LOG.warning(
                'model %s: all %d training labels are %d; it will %s fire (--allow-degenerate)',
                name,
                len(y),
                int(y[0]),
                'always' if y[0] else 'never',
            )
            always = positives[name] == len(y)
            model: Model = LogisticModel(
                name,
                np.zeros(len(features)),
                CONSTANT_LOGIT if always else -CONSTANT_LOGIT,
                0.5,
                X.mean(axis=0),
                np.ones(len(features)),
                features=features,
            )
            choice = choose_threshold(y, np.full(len(y), float(always)), 0.5)
        else:
            scores = out_of_fold_scores(
                X,
                y,
                model_groups,
                _scorer(family, features, config),
                folds,
                config.seed,
                config.group_by,
            )
            choice = choose_threshold(
                y,
                scores,
                config.target_precision,
                config.min_predicted,
                config.prior_of(name),
                model_groups if by_family else None,
                config.min_family_positives,
                config.family_precision,
            )
            model = fit_model(family, name, features, X, y, config)
        choices[name] = choice
        models[name] = replace(
            model,
            threshold=choice.threshold,
            metrics={
                'family': family.value if name not in degenerate else 'constant',
                'validation': choice.to_dict(),
                'train_pairs': len(y),
                'train_positives': positives[name],
            },
        )
        LOG.info(
            'model %s (%s): %d/%d positive; threshold %.3f, validation precision %.3f '
            'recall %.3f%s',
            name,
            family.value,
            positives[name],
            len(y),
            choice.threshold,
            choice.precision,
            choice.recall,
            '' if choice.reached else ' (target precision not reached)',
        )
    sequences = {
        str(s): int(n)
        for s, n in zip(*np.unique(table['sequence'].astype(str), return_counts=True), strict=True)
    }
    labels = config.labels or LabelConfig()
    rules = sorted(set(np.asarray(table['scale_rule']).astype(str)))
    metadata = {
        'description': 'Troutman & Tuceryan 2021 models F, E, H, R; per model: '
        'scikit-learn LogisticRegression on standardized features, or '
        'GradientBoostingClassifier exported as trees (see "families")',
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
            'rotation_label': labels.rotation_label,
            **(
                {'rotation_parallax_deg': labels.rotation_parallax_deg}
                if labels.rotation_label == 'parallax'
                else {}
            ),
            **(
                {'rotation_test_bar': labels.rotation_test_bar}
                if labels.rotation_label == 'test'
                else {}
            ),
            **({'method_label': labels.method_label} if labels.method_label != 'good' else {}),
            **({'best_margin': labels.best_margin} if labels.method_label == 'best' else {}),
            **(
                {'dominant_share': labels.dominant_share}
                if labels.method_label == 'determined' or labels.rotation_label == 'flow'
                else {}
            ),
            'scale_rule': rules[0] if len(rules) == 1 else rules,
            'relabelled_at_training': config.labels is not None,
        },
        'training': {
            'C': config.C,
            'class_weight': config.class_weight.value,
            'target_precision': config.target_precision,
            'threshold_prior': {m: config.prior_of(m) for m in METHODS},
            'validation_groups': config.group_by,
            **(
                {'scene_families': {k: list(v) for k, v in config.scene_families.patterns.items()}}
                if by_family and config.scene_families is not None
                else {}
            ),
            'min_predicted': config.min_predicted,
            'validation': (
                f'grouped {folds}-fold cross-validation over {config.group_by}s'
                if not by_family
                else f'one fold per scene family ({folds}), each scored by models fitted '
                f'without it; thresholds also held at precision '
                f'{config.family_precision or config.target_precision:g} on the worst family '
                f'with at least {config.min_family_positives} positives'
            )
            + ', out-of-fold probabilities; final fit on all pairs',
            'seed': config.seed,
            **(
                {
                    'rotation_min_static_share': config.rotation_min_static_share,
                    'rotation_pairs_left_out': rotation_left_out,
                }
                if config.rotation_min_static_share is not None
                else {}
            ),
            'degenerate_models': degenerate,
            'families': {m: config.family_of(m).value for m in METHODS},
            'extra_features': [n for n in EXTRA_FEATURE_NAMES if n in config.extra],
            'paper_features': [n for n in FEATURE_NAMES if n in config.paper],
            'trees': {
                'n_trees': config.trees.n_trees,
                'depth': config.trees.depth,
                'learning_rate': config.trees.learning_rate,
                'estimator': 'sklearn GradientBoostingClassifier (log-loss), '
                'exported to JSON trees',
            },
        },
    }
    model_set = ModelSet(
        models, scaling=config.scaling, feature_names=FEATURE_NAMES, metadata=metadata
    )
    return TrainReport(model_set, choices, positives, len(table), n_batches)


def describe_inputs(paths: Sequence[str]) -> dict[str, Any]:
    """Metadata entry naming the training files."""
    return {'files': [str(p) for p in paths]}


__all__ = [
    'CONSTANT_LOGIT',
    'DEFAULT_FAMILY',
    'THRESHOLD_MARGIN',
    'ClassWeight',
    'Family',
    'ThresholdChoice',
    'TrainConfig',
    'TrainReport',
    'TreeConfig',
    'check_classes',
    'choose_threshold',
    'describe_inputs',
    'export_trees',
    'feature_columns',
    'fit_logistic',
    'fit_model',
    'fit_trees',
    'grouped_folds',
    'impute',
    'label_column',
    'out_of_fold_scores',
    'prepare',
    'rotation_training_rows',
    'threshold_curve',
    'train_models',
]
