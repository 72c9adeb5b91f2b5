"""Model families compared by ``initsel eval --train`` (fitted in memory, never saved).

The four shippable families (:class:`~initsel_ros.learn.train.Family`) are fitted exactly as
``initsel train`` fits them; two scikit-learn references (histogram gradient boosting, an MLP)
show what the model file cannot hold. Thresholds come from grouped cross-validation on the
training pairs, as for the shipped models.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any

import numpy as np

from initsel_ros.learn.table import PairTable, input_columns
from initsel_ros.learn.train import (
    ClassWeight,
    Family,
    ThresholdChoice,
    TrainConfig,
    choose_threshold,
    fit_model,
    impute,
    label_column,
    out_of_fold_scores,
)
from initsel_ros.models import Model


class Candidate(str, Enum):
    """Model families compared in evaluation (fitted in memory on the training pairs).

    The first four are the shippable families (:class:`Family`, numpy inference); the last two
    are scikit-learn references that the model file cannot hold.
    """

    LOGISTIC = 'logistic'
    LOGISTIC_EXTRA = 'logistic+extra'
    TREES = 'trees'
    TREES_EXTRA = 'trees+extra'
    HGB_EXTRA = 'hgb+extra'  # HistGradientBoostingClassifier (200 iterations), sklearn
    MLP_EXTRA = 'mlp+extra'  # MLPClassifier (32, 16), forward pass in numpy

    @property
    def uses_extra(self) -> bool:
        """Whether the extra features are inputs."""
        return self.value.endswith('+extra')

    @property
    def family(self) -> Family | None:
        """The model-file family, or None for the scikit-learn references."""
        try:
            return Family(self.value)
        except ValueError:
            return None


def candidate_columns(candidate: Candidate, config: TrainConfig) -> tuple[str, ...]:
    """Table columns a candidate reads."""
    features = config.features_of(
        Family.LOGISTIC_EXTRA if candidate.uses_extra else Family.LOGISTIC
    )
    return input_columns(features, config.scaling)


@dataclass(frozen=True)
class FittedCandidate:
    """A model fitted in memory, with its threshold and a single-row scorer for timing."""

    candidate: Candidate
    model: str
    columns: tuple[str, ...]
    score: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    score_one: Callable[[np.ndarray], float] = field(repr=False)
    threshold: ThresholdChoice | None = None
    model_obj: Model | None = field(default=None, repr=False)  # families: the fitted model


def _reference_fitter(candidate: Candidate, config: TrainConfig) -> Callable[..., Any]:
    """fit(X, y) -> (batch scorer, single-row scorer, None) for the scikit-learn references."""
    seed = config.seed

    def fit(X: np.ndarray, y: np.ndarray) -> tuple[Any, ...]:
        X = impute(X)
        if candidate is Candidate.HGB_EXTRA:
            from sklearn.ensemble import HistGradientBoostingClassifier

            clf = HistGradientBoostingClassifier(
                max_iter=200,
                learning_rate=0.1,
                max_leaf_nodes=15,
                class_weight=config.class_weight.sklearn,
                random_state=seed,
            ).fit(X, y)

            def batch(Z: np.ndarray) -> np.ndarray:
                return clf.predict_proba(impute(Z))[:, 1]

            def one(z: np.ndarray) -> float:
                return float(clf.predict_proba(z.reshape(1, -1))[0, 1])

            return batch, one, None
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPClassifier
        from sklearn.preprocessing import StandardScaler

        scaler = StandardScaler().fit(X)
        idx = np.arange(len(y))
        if config.class_weight is ClassWeight.BALANCED:  # MLP has no class_weight: resample
            pos = np.flatnonzero(y == 1)
            neg = np.flatnonzero(y == 0)
            rng = np.random.default_rng(seed)
            minority, majority = (pos, neg) if len(pos) < len(neg) else (neg, pos)
            extra = rng.choice(minority, len(majority) - len(minority), replace=True)
            idx = np.r_[idx, extra]
        with warnings.catch_warnings():  # a comparison model: a few unconverged runs are fine
            warnings.simplefilter('ignore', ConvergenceWarning)
            clf = MLPClassifier(
                hidden_layer_sizes=(32, 16),
                alpha=1e-3,
                max_iter=500,
                random_state=seed,
            ).fit(scaler.transform(X[idx]), y[idx])
        W = [np.asarray(c) for c in clf.coefs_]
        B = [np.asarray(c) for c in clf.intercepts_]
        mu, sd = scaler.mean_, scaler.scale_

        def forward(Z: np.ndarray) -> np.ndarray:
            h = (impute(Z) - mu) / sd
            for Wi, Bi in zip(W[:-1], B[:-1], strict=True):
                h = np.maximum(h @ Wi + Bi, 0.0)
            z = h @ W[-1] + B[-1]
            return (1.0 / (1.0 + np.exp(-z))).reshape(-1)

        return forward, lambda z: float(forward(z.reshape(1, -1))[0]), None

    return fit


def _family_fitter(
    family: Family, features: tuple[str, ...], config: TrainConfig
) -> Callable[..., Any]:
    def fit(X: np.ndarray, y: np.ndarray) -> tuple[Any, ...]:
        model = fit_model(family, 'candidate', features, X, y, config)

        def batch(Z: np.ndarray) -> np.ndarray:
            return model.predict_proba(impute(Z))

        def one(z: np.ndarray) -> float:
            return float(model.predict_proba(z))

        return batch, one, model

    return fit


def fit_candidate(
    candidate: Candidate, model: str, train: PairTable, config: TrainConfig
) -> FittedCandidate | None:
    """Fit one candidate for one model on ``train`` (threshold from grouped out-of-fold
    scores, as for the shipped models). None when the labels hold a single class."""
    columns = candidate_columns(candidate, config)
    X = train.matrix(columns)
    y = np.asarray(train[label_column(model)]).astype(int)
    if len(np.unique(y)) < 2:
        return None
    family = candidate.family
    if family is not None:
        features = config.features_of(family)
        fitter = _family_fitter(family, features, config)
    else:
        fitter = _reference_fitter(candidate, config)
    scores = out_of_fold_scores(
        X, y, train.groups(), lambda A, b: fitter(A, b)[0], config.folds, config.seed
    )
    choice = choose_threshold(y, scores, config.target_precision, config.min_predicted)
    batch, one, fitted = fitter(X, y)
    if fitted is not None:
        fitted = replace(fitted, name=model, threshold=choice.threshold)
    return FittedCandidate(candidate, model, columns, batch, one, choice, fitted)


__all__ = [
    'Candidate',
    'FittedCandidate',
    'candidate_columns',
    'fit_candidate',
]
