"""Distillation: cheaper models that reproduce a model file's decisions.

A teacher model file scores every pair of a table; each student model, a tree ensemble
reading other (cheaper) inputs, is fitted by least squares to its teacher's logits (clipped to
+-:data:`LOGIT_CLIP`, where the sigmoid is flat) and keeps the teacher's threshold. No labels
are read, so any pairs serve. The report gives how often student and teacher decide alike.

Where the students' inputs cannot tell what the teacher's can, a student is unsure near its
threshold: ``referee`` names models for which the teacher's own model is kept in the file as
a referee, deciding the pairs whose student logit lies within a band of the threshold
(``models.Referee``). The band is the narrowest (in steps of :data:`BAND_STEP`) that holds
:data:`REFEREE_CAPTURE` of the pairs on which students fitted without their sequence
(:data:`REFEREE_FOLDS` folds, grouped by sequence) disagree with the teacher.
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from initsel_ros.errors import DatasetError
from initsel_ros.features import ALL_FEATURE_NAMES, FEATURE_NAMES
from initsel_ros.learn.table import PairTable, check_camera_features, input_columns, table_logits
from initsel_ros.learn.train import TreeConfig, export_trees, grouped_folds, impute
from initsel_ros.models import METHODS, ModelSet, Referee, logit
from initsel_ros.trees import TreeEnsembleModel

#: Teacher logits beyond this are clipped before fitting (probabilities 6e-6 and 1 - 6e-6).
LOGIT_CLIP = 12.0
LOG = logging.getLogger(__name__)
#: A referee's band holds this share of the out-of-fold disagreements with the teacher ...
REFEREE_CAPTURE = 0.9
#: ... measured with students fitted on this many folds of sequences ...
REFEREE_FOLDS = 3
#: ... and is a multiple of this many logits (at most :data:`BAND_MAX`).
BAND_STEP = 0.25
BAND_MAX = 6.0


@dataclass(frozen=True)
class DistillReport:
    """What :func:`distill_models` fitted.

    Attributes:
        models: the student model set (teacher thresholds).
        agreement: per model, the share of the table's pairs on which student and teacher
            both say yes or both say no.
        logit_rmse: per model, RMS difference of the logits (teacher's clipped).
        n_pairs: pairs fitted on.
        referee: per refereed model, how its band was chosen (:class:`RefereeBand`).
    """

    models: ModelSet
    agreement: dict[str, float]
    logit_rmse: dict[str, float]
    n_pairs: int
    referee: dict[str, RefereeBand] = field(default_factory=dict)


@dataclass(frozen=True)
class RefereeBand:
    """The band of one refereed model, from out-of-fold students.

    Attributes:
        band_logit: the band's half-width, logits.
        out_of_fold_agreement: share of pairs on which the out-of-fold student and the teacher
            decide alike, without the referee.
        captured: share of those disagreements inside the band.
        referred: share of all pairs inside the band (the pairs the referee decides).
    """

    band_logit: float
    out_of_fold_agreement: float
    captured: float
    referred: float


def teacher_logits(teacher: ModelSet, table: PairTable) -> dict[str, np.ndarray]:
    """The teacher's logits on every pair of ``table``, by model."""
    return table_logits(teacher, table)[0]


def _fit_student(
    name: str,
    features: tuple[str, ...],
    X: np.ndarray,
    z: np.ndarray,
    threshold: float,
    trees: TreeConfig,
    seed: int,
) -> TreeEnsembleModel:
    """One student: a GradientBoostingRegressor fitted to the clipped logits ``z``, as trees."""
    from sklearn.ensemble import GradientBoostingRegressor

    regressor = GradientBoostingRegressor(
        n_estimators=trees.n_trees,
        max_depth=trees.depth,
        learning_rate=trees.learning_rate,
        random_state=seed,
    ).fit(X, z)
    fitted, bias = export_trees(
        regressor.estimators_[:, 0], trees.learning_rate, X, regressor.predict(X)
    )
    return TreeEnsembleModel(name, features, tuple(fitted), bias, threshold)


def referee_band(
    student_logits: np.ndarray, teacher_logits: np.ndarray, threshold: float
) -> RefereeBand:
    """The narrowest band (a multiple of :data:`BAND_STEP`, at most :data:`BAND_MAX`) around
    ``threshold``'s logit holding :data:`REFEREE_CAPTURE` of the pairs on which the
    (out-of-fold) student and the teacher disagree; a band of 0 when they never disagree
    (no referee is needed). At :data:`BAND_MAX` ``captured`` may stay under the target."""
    cut = logit(threshold)
    if not np.isfinite(cut):
        raise DatasetError(f'a referee needs a threshold in (0, 1), got {threshold}')
    distance = np.abs(student_logits - cut)
    differ = (student_logits >= cut) != (teacher_logits >= cut)
    n_differ = int(np.count_nonzero(differ))
    if n_differ == 0:
        return RefereeBand(0.0, 1.0, 1.0, 0.0)
    band = BAND_STEP
    while band < BAND_MAX:
        if np.count_nonzero(differ & (distance < band)) >= REFEREE_CAPTURE * n_differ:
            break
        band += BAND_STEP
    inside = distance < band
    return RefereeBand(
        band_logit=band,
        out_of_fold_agreement=float(1.0 - np.mean(differ)),
        captured=float(np.count_nonzero(differ & inside) / n_differ),
        referred=float(np.mean(inside)),
    )


def _out_of_fold_logits(
    table: PairTable,
    X: np.ndarray,
    z: np.ndarray,
    name: str,
    features: tuple[str, ...],
    threshold: float,
    trees: TreeConfig,
    seed: int,
) -> np.ndarray:
    """Student logits of every pair from students fitted without its sequence's fold
    (``train.grouped_folds`` over whole sequences)."""
    groups = table.groups(by='sequence')
    n_sequences = len(np.unique(groups))
    if n_sequences < REFEREE_FOLDS:
        raise DatasetError(
            f'a referee band needs pairs of at least {REFEREE_FOLDS} sequences, got {n_sequences}'
        )
    out = np.empty(len(z))
    for held in grouped_folds(groups, REFEREE_FOLDS, seed):
        rest = np.ones(len(z), dtype=bool)
        rest[held] = False
        student = _fit_student(name, features, X[rest], z[rest], threshold, trees, seed)
        out[held] = student.decision_function(X[held])
    return out


def distill_models(
    table: PairTable,
    teacher: ModelSet,
    features: Sequence[str],
    trees: TreeConfig | None = None,
    *,
    seed: int = 0,
    description: dict[str, Any] | None = None,
    referee: Sequence[str] = (),
) -> DistillReport:
    """Fit a student tree ensemble per model to ``teacher``'s logits on ``table``.

    Args:
        table: pairs (labels are not read).
        teacher: the model file to imitate.
        features: the students' inputs, names of ``ALL_FEATURE_NAMES`` (in the teacher's
            scaling for the 23 paper features).
        trees: boosting settings (squared loss on the logit).
        seed: random seed of the estimators (and of the referee's folds).
        description: extra metadata for the training data (e.g. the input files).
        referee: models whose teacher model is kept as the file's referee (see the module
            docstring); the table then needs the teacher's inputs and 3 or more sequences.

    Raises:
        DatasetError: an empty table, an unknown feature or model name, or too few sequences
            for a referee band.
    """
    trees = trees or TreeConfig()
    features = tuple(n for n in ALL_FEATURE_NAMES if n in set(features))
    unknown = sorted(set(features).difference(ALL_FEATURE_NAMES))
    if unknown or not features:
        raise DatasetError(f'student features must be among {ALL_FEATURE_NAMES}, got {unknown}')
    if len(table) == 0:
        raise DatasetError('no pairs to distill on')
    if isinstance(referee, str):
        raise DatasetError(
            f'referee must be a sequence of model names, got the string {referee!r}'
        )
    bad = sorted(set(referee).difference(METHODS))
    if bad:
        raise DatasetError(f'referee models must be among {METHODS}, got {bad}')
    if teacher.referee is not None:
        raise DatasetError('the teacher has a referee of its own: distill from a file without')
    target = teacher_logits(teacher, table)
    check_camera_features(table, features)
    X = impute(table.matrix(input_columns(features, teacher.scaling)))
    students: dict[str, TreeEnsembleModel] = {}
    agreement, rmse, bands = {}, {}, {}
    for name in METHODS:
        z = np.clip(target[name], -LOGIT_CLIP, LOGIT_CLIP)
        threshold = teacher.models[name].threshold
        student = _fit_student(name, features, X, z, threshold, trees, seed)
        z_student = student.decision_function(X)
        cut = logit(threshold)
        same = (z_student >= cut) == (target[name] >= cut) if np.isfinite(cut) else np.ones(len(z))
        agreement[name] = float(np.mean(same))
        rmse[name] = float(np.sqrt(np.mean((z_student - z) ** 2)))
        metrics = {
            'family': 'trees+distilled',
            'train_pairs': len(table),
            'agreement_with_teacher': round(agreement[name], 4),
            'logit_rmse': round(rmse[name], 4),
        }
        if name in referee:
            oof = _out_of_fold_logits(table, X, z, name, features, threshold, trees, seed)
            band = referee_band(oof, target[name], threshold)
            metrics['referee'] = {k: round(v, 4) for k, v in vars(band).items()}
            if band.band_logit > 0.0:
                bands[name] = band
            else:
                LOG.info('referee %s: the students never disagree out of fold; none kept', name)
            if band.captured < REFEREE_CAPTURE:
                LOG.warning(
                    'referee %s: the widest band (%g logits) holds only %.0f %% of the '
                    'out-of-fold disagreements',
                    name,
                    band.band_logit,
                    100 * band.captured,
                )
        students[name] = replace(student, metrics=metrics)
    metadata = {
        'description': 'models F, E, H, R distilled from a teacher model file: each a '
        'GradientBoostingRegressor fitted to the teacher logits on the pairs, exported as '
        'trees, with the teacher thresholds'
        + (f"; the teacher's {', '.join(bands)} referee(s) near the threshold" if bands else ''),
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
    judge = None
    if bands:
        metadata['training']['referee'] = {
            'capture': REFEREE_CAPTURE,
            'folds': REFEREE_FOLDS,
            'band_step': BAND_STEP,
            'models': {m: {k: round(v, 4) for k, v in vars(b).items()} for m, b in bands.items()},
        }
        judge = Referee(
            ModelSet(
                {m: teacher.models[m] for m in bands},
                scaling=teacher.scaling,
                feature_names=FEATURE_NAMES,
                metadata={'source': 'the teacher of this file', 'teacher': teacher.metadata},
                partial=True,
            ),
            {m: b.band_logit for m, b in bands.items()},
        )
    models = ModelSet(
        students,
        scaling=teacher.scaling,
        feature_names=FEATURE_NAMES,
        metadata=metadata,
        referee=judge,
    )
    return DistillReport(models, agreement, rmse, len(table), bands)


__all__ = [
    'BAND_MAX',
    'BAND_STEP',
    'LOGIT_CLIP',
    'REFEREE_CAPTURE',
    'REFEREE_FOLDS',
    'DistillReport',
    'RefereeBand',
    'distill_models',
    'referee_band',
    'teacher_logits',
]
