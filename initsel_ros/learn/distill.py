"""Distillation: cheaper models that reproduce a model file's decisions.

A teacher model file scores every pair of a table; each student model, a tree ensemble
reading other (cheaper) inputs, is fitted by least squares to its teacher's logits (clipped to
+-:data:`LOGIT_CLIP`, where the sigmoid is flat) and keeps the teacher's threshold. No labels
are read, so any pairs serve. The report gives how often student and teacher decide alike.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from initsel_ros.errors import DatasetError
from initsel_ros.features import ALL_FEATURE_NAMES, FEATURE_NAMES
from initsel_ros.learn.table import PairTable, input_columns
from initsel_ros.learn.train import TreeConfig, export_trees, impute
from initsel_ros.models import METHODS, ModelSet
from initsel_ros.trees import TreeEnsembleModel

#: Teacher logits beyond this are clipped before fitting (probabilities 6e-6 and 1 - 6e-6).
LOGIT_CLIP = 12.0


@dataclass(frozen=True)
class DistillReport:
    """What :func:`distill_models` fitted.

    Attributes:
        models: the student model set (teacher thresholds).
        agreement: per model, the share of the table's pairs on which student and teacher
            both say yes or both say no.
        logit_rmse: per model, RMS difference of the logits (teacher's clipped).
        n_pairs: pairs fitted on.
    """

    models: ModelSet
    agreement: dict[str, float]
    logit_rmse: dict[str, float]
    n_pairs: int


def teacher_logits(teacher: ModelSet, table: PairTable) -> dict[str, np.ndarray]:
    """The teacher's logits on every pair of ``table``, by model."""
    return teacher.logits_batch(table.matrix(input_columns(teacher.input_names, teacher.scaling)))


def distill_models(
    table: PairTable,
    teacher: ModelSet,
    features: Sequence[str],
    trees: TreeConfig | None = None,
    *,
    seed: int = 0,
    description: dict[str, Any] | None = None,
) -> DistillReport:
    """Fit a student tree ensemble per model to ``teacher``'s logits on ``table``.

    Args:
        table: pairs (labels are not read).
        teacher: the model file to imitate.
        features: the students' inputs, names of ``ALL_FEATURE_NAMES`` (in the teacher's
            scaling for the 23 paper features).
        trees: boosting settings (squared loss on the logit).
        seed: random seed of the estimators.
        description: extra metadata for the training data (e.g. the input files).

    Raises:
        DatasetError: an empty table, or an unknown feature name.
    """
    from sklearn.ensemble import GradientBoostingRegressor

    trees = trees or TreeConfig()
    features = tuple(n for n in ALL_FEATURE_NAMES if n in set(features))
    unknown = sorted(set(features).difference(ALL_FEATURE_NAMES))
    if unknown or not features:
        raise DatasetError(f'student features must be among {ALL_FEATURE_NAMES}, got {unknown}')
    if len(table) == 0:
        raise DatasetError('no pairs to distill on')
    target = teacher_logits(teacher, table)
    X = impute(table.matrix(input_columns(features, teacher.scaling)))
    students: dict[str, TreeEnsembleModel] = {}
    agreement, rmse = {}, {}
    for name in METHODS:
        z = np.clip(target[name], -LOGIT_CLIP, LOGIT_CLIP)
        regressor = GradientBoostingRegressor(
            n_estimators=trees.n_trees,
            max_depth=trees.depth,
            learning_rate=trees.learning_rate,
            random_state=seed,
        ).fit(X, z)
        fitted, bias = export_trees(
            regressor.estimators_[:, 0], trees.learning_rate, X, regressor.predict(X)
        )
        threshold = teacher.models[name].threshold
        student = TreeEnsembleModel(name, features, tuple(fitted), bias, threshold)
        z_student = student.decision_function(X)
        cut = np.log(threshold / (1.0 - threshold)) if 0.0 < threshold < 1.0 else None
        same = (z_student >= cut) == (target[name] >= cut) if cut is not None else np.ones(len(z))
        agreement[name] = float(np.mean(same))
        rmse[name] = float(np.sqrt(np.mean((z_student - z) ** 2)))
        students[name] = replace(
            student,
            metrics={
                'family': 'trees+distilled',
                'train_pairs': len(table),
                'agreement_with_teacher': round(agreement[name], 4),
                'logit_rmse': round(rmse[name], 4),
            },
        )
    metadata = {
        'description': 'models F, E, H, R distilled from a teacher model file: each a '
        'GradientBoostingRegressor fitted to the teacher logits on the pairs, exported as '
        'trees, with the teacher thresholds',
        'date': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
        'feature_scaling': teacher.scaling.value,
        'training_data': {**(description or {}), 'pairs': len(table)},
        'training': {
            'distilled': True,
            'features': list(features),
            'logit_clip': LOGIT_CLIP,
            'trees': {
                'n_trees': trees.n_trees,
                'depth': trees.depth,
                'learning_rate': trees.learning_rate,
                'estimator': 'sklearn GradientBoostingRegressor (squared error on the '
                'teacher logit), exported to JSON trees',
            },
            'seed': seed,
            'agreement_with_teacher': {m: round(a, 4) for m, a in agreement.items()},
        },
        'teacher': teacher.metadata,
    }
    models = ModelSet(
        students, scaling=teacher.scaling, feature_names=FEATURE_NAMES, metadata=metadata
    )
    return DistillReport(models, agreement, rmse, len(table))


__all__ = ['LOGIT_CLIP', 'DistillReport', 'distill_models', 'teacher_logits']
