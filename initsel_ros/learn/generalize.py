"""Generalization: leave one scene family out, retrain without it, score on it.

The training sequences are grouped into named scene families (a YAML file of name patterns,
``config/families.yaml``). For each family in turn the models are trained by the same
recipe (a :class:`TrainConfig`) on the other families only, their thresholds chosen by
cross-validation on those, and they are scored on the family left out: precision and recall
of E, F and H after the R veto and of R, each only where the family has at least
``min_positives`` positives of that model. The worst family, next to the mean, is what a
user's scenes (a family no one trained on) can expect.

One family may be reserved as the final test: it is left out of every fold and scored only
by :func:`final_test`, once, by the models trained on all the others.
"""

from __future__ import annotations

import fnmatch
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.learn.evaluate import (
    binary_scores,
    fire_path_h,
    fire_path_h_scores,
    has_fire_path,
)
from initsel_ros.learn.labels import LabelConfig
from initsel_ros.learn.table import PairTable, table_probabilities
from initsel_ros.learn.train import (
    TrainConfig,
    label_column,
    prepare,
    threshold_curve,
    train_models,
)
from initsel_ros.markdown import markdown_table, number
from initsel_ros.models import METHODS, ModelSet

LOG = logging.getLogger(__name__)

#: A family is scored on a model only where it has at least this many positives of it.
MIN_POSITIVES = 30

#: The rows of the table: E, F and H after the R veto (as the policy uses them), and R.
SCORED = ('E', 'F', 'H', 'R')
#: The recall at which each model's ceiling on a held-out family is read: issue 21's bars
#: (E and F precision at recall 0.5, H at 0.3, R at 0.9).
CEILING_RECALL = {'E': 0.5, 'F': 0.5, 'H': 0.3, 'R': 0.9}
#: The row of H as the node decides it, where the tables hold the fire path's outcome
#: (``initsel dataset --fire-path``; ``evaluate.fire_path_h``).
FIRE_H = 'H by the fire path'


@dataclass(frozen=True)
class Families:
    """Named scene families: fnmatch patterns on sequence names, the first match wins.

    Attributes:
        patterns: family name -> its patterns, in file order.
        reserved: the family kept for the final test (never in a fold), or None.
    """

    patterns: dict[str, tuple[str, ...]]
    reserved: str | None = None

    def __post_init__(self) -> None:
        if not self.patterns:
            raise ConfigError('a families file must name at least one family')
        if self.reserved is not None and self.reserved not in self.patterns:
            raise ConfigError(f'the reserved family {self.reserved!r} is not one of the families')

    @classmethod
    def load(cls, path: Path) -> Families:
        """Read a families YAML file (``families: {name: [pattern, ...]}``, ``reserved``)."""
        import yaml

        try:
            data = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f'cannot read the families file {path}: {exc}') from exc
        if not isinstance(data, dict) or not isinstance(data.get('families'), dict):
            raise ConfigError(f'{path}: expected a mapping with a "families" mapping')
        unknown = sorted(set(data) - {'families', 'reserved'})
        if unknown:
            raise ConfigError(f'{path}: unknown keys {unknown} (known: families, reserved)')
        reserved = data.get('reserved')
        if reserved is not None and not isinstance(reserved, str):
            raise ConfigError(f'{path}: "reserved" must name one family, got {reserved!r}')
        patterns = {}
        for name, pats in data['families'].items():
            if isinstance(pats, str):
                pats = [pats]
            if not isinstance(pats, list) or not all(isinstance(p, str) for p in pats):
                raise ConfigError(f'{path}: family {name!r} needs a list of name patterns')
            patterns[str(name)] = tuple(pats)
        return cls(patterns, reserved)

    def family_of(self, sequence: str) -> str | None:
        """The family of one sequence name, or None when no pattern matches."""
        for name, pats in self.patterns.items():
            if any(fnmatch.fnmatchcase(sequence, p) for p in pats):
                return name
        return None

    def assign(self, sequences: Sequence[str] | np.ndarray) -> np.ndarray:
        """(N,) family name of each row's sequence; raises when a sequence has none."""
        names = np.asarray(sequences).astype(str)
        unique, inverse = np.unique(names, return_inverse=True)
        of = [self.family_of(s) for s in unique]
        missing = [s for s, f in zip(unique, of, strict=True) if f is None]
        if missing:
            raise ConfigError(
                f'sequences in no family: {", ".join(missing)} (add a pattern for them)'
            )
        return np.asarray(of, dtype=object)[inverse]


@dataclass(frozen=True)
class FamilyScore:
    """One model scored on one held-out family.

    Attributes:
        family: the family left out.
        model: E, F or H (after the R veto) or R.
        pairs: the family's pairs.
        positives: its positives of ``model``.
        precision, recall: at the thresholds chosen without the family; precision is NaN
            when the model never said yes there (shown as ``-``, and counted as the worst).
        scored: whether the family has enough positives to count (``min_positives``).
        ceiling: the highest precision any threshold of ``model`` (R's kept as chosen)
            gives on the family at recall >= ``CEILING_RECALL[model]``: a threshold chosen on the
            held-out family itself, what the scores allow there (NaN when no threshold
            reaches that recall, e.g. where R vetoes most positives; not for the fire path).
    """

    family: str
    model: str
    pairs: int
    positives: int
    precision: float
    recall: float
    scored: bool
    ceiling: float = math.nan


def score_family(
    models: ModelSet,
    test: PairTable,
    family: str,
    min_positives: int = MIN_POSITIVES,
    et_max: float = 0.8,
) -> list[FamilyScore]:
    """Score ``models`` (thresholds as they are) on the pairs of one family; with the fire
    path's outcome in the table, H by the fire path too (:func:`fire_path_h`)."""
    probs, _ = table_probabilities(models, test)
    fired = {m: probs[m] >= models.thresholds[m] for m in METHODS}
    out = []
    for m in SCORED:
        y = np.asarray(test[label_column(m)]).astype(bool)
        allowed = np.ones(len(y), dtype=bool) if m == 'R' else ~fired['R']
        s = binary_scores(y, fired[m] & allowed)
        score = _family_score(family, m, len(test), y, s.precision, s.recall, s.predicted,
                              min_positives)  # fmt: skip
        out.append(replace(score, ceiling=_ceiling(y, probs[m], allowed, CEILING_RECALL[m])))
    if has_fire_path(test):
        y = np.asarray(test[label_column('H')]).astype(bool)
        s = fire_path_h_scores(y, *fire_path_h(test, probs, models.thresholds, et_max))
        out.append(_family_score(family, FIRE_H, len(test), y, s.precision, s.recall,
                                 s.predicted, min_positives))  # fmt: skip
    return out


def _ceiling(y: np.ndarray, scores: np.ndarray, allowed: np.ndarray, at_recall: float) -> float:
    """The highest precision of 'score >= t' over thresholds t, the pairs not ``allowed``
    never said yes to, whose recall of all of ``y``'s positives is at least ``at_recall``
    (NaN when none is, or without positives)."""
    pos = int(y.sum())
    if pos == 0 or not allowed.any():
        return math.nan
    _, tp, fp = threshold_curve(y[allowed], np.asarray(scores, dtype=float)[allowed])
    precision, recall = tp / (tp + fp), tp / pos
    ok = recall >= at_recall
    return float(precision[ok].max()) if ok.any() else math.nan


def _family_score(
    family: str,
    model: str,
    pairs: int,
    y: np.ndarray,
    precision: float,
    recall: float,
    predicted: int,
    min_positives: int,
) -> FamilyScore:
    positives = int(y.sum())
    precision = precision if predicted else math.nan
    return FamilyScore(family, model, pairs, positives, precision, recall,
                       positives >= min_positives)  # fmt: skip


def cap_families(
    table: PairTable, assigned: np.ndarray, cap: int | None, seed: int = 0
) -> np.ndarray:
    """(N,) bool: every row, but at most ``cap`` random pairs of each family (whole batches
    are not kept together: a cap thins a large family evenly). None keeps every row."""
    keep = np.ones(len(table), dtype=bool)
    if cap is None:
        return keep
    if cap < 1:
        raise ConfigError(f'a family cap must be at least 1 pair, got {cap}')
    rng = np.random.default_rng(seed)
    for family in np.unique(assigned):
        rows = np.flatnonzero(assigned == family)
        if len(rows) > cap:
            keep[rng.choice(rows, len(rows) - cap, replace=False)] = False
    return keep


def leave_family_out(
    table: PairTable,
    families: Families,
    config: TrainConfig,
    min_positives: int = MIN_POSITIVES,
    family_cap: int | None = None,
) -> list[FamilyScore]:
    """Train without each family in turn (and without the reserved one) and score on it.

    The table is relabelled (``config.labels``) and cleaned as :func:`train_models` does,
    before the families are split, so the held-out pairs are scored on the labels the models
    learnt. A family of the file with no pairs is logged and left out. ``family_cap`` trains
    on at most that many pairs of each family (:func:`cap_families`; the held-out family is
    always scored on all its pairs), so that one large family does not set the others'
    class balance, and with it the thresholds.

    Raises:
        DatasetError: fewer than two families with pairs to hold out.
        ConfigError: a sequence in no family.
    """
    table, assigned, usable = _training_rows(table, families, config, family_cap)
    present = [f for f in families.patterns if f != families.reserved and (assigned == f).any()]
    empty = [f for f in families.patterns if f != families.reserved and f not in present]
    if empty:
        LOG.warning('families with no pairs in these tables, not scored: %s', ', '.join(empty))
    if len(present) < 2:
        raise DatasetError(f'leaving one family out needs two families with pairs: {present}')
    if not has_fire_path(table):
        LOG.warning(
            'the tables hold no fire-path outcome (initsel dataset --fire-path): no row of %s',
            FIRE_H,
        )
    scores: list[FamilyScore] = []
    for family in present:
        rows = usable & (assigned != family)
        scores += _score_held_out(table, assigned, rows, family, config, min_positives)
    return scores


def final_test(
    table: PairTable,
    families: Families,
    config: TrainConfig,
    min_positives: int = MIN_POSITIVES,
    family_cap: int | None = None,
) -> list[FamilyScore]:
    """The reserved family, scored once by the models trained on every other family (each
    capped to ``family_cap`` pairs, as in :func:`leave_family_out`)."""
    if families.reserved is None:
        raise ConfigError('the families file reserves no family for the final test')
    table, assigned, usable = _training_rows(table, families, config, family_cap)
    if not np.any(assigned == families.reserved):
        raise DatasetError(f'no pairs of the reserved family {families.reserved!r}')
    return _score_held_out(table, assigned, usable, families.reserved, config, min_positives)


def _training_rows(
    table: PairTable, families: Families, config: TrainConfig, family_cap: int | None
) -> tuple[PairTable, np.ndarray, np.ndarray]:
    """The table relabelled and cleaned as training does, each row's family, and the rows a
    fold may train on: not the reserved family, and at most ``family_cap`` of each family."""
    table = prepare(table, config)
    assigned = families.assign(table['sequence'])
    capped = cap_families(table, assigned, family_cap, config.seed)
    return table, assigned, (assigned != families.reserved) & capped


def _score_held_out(
    table: PairTable,
    assigned: np.ndarray,
    train_rows: np.ndarray,
    family: str,
    config: TrainConfig,
    min_positives: int,
) -> list[FamilyScore]:
    """Train on ``train_rows`` and score every pair of ``family``."""
    models = train_models(table.select(train_rows), config).models
    et_max = (config.labels or LabelConfig()).et_max
    return score_family(models, table.select(assigned == family), family, min_positives, et_max)


def generalization_markdown(
    scores: Sequence[FamilyScore], min_positives: int = MIN_POSITIVES
) -> str:
    """Per held-out family: precision / recall of each model (``*`` marks fewer positives
    than ``min_positives``, the value the scores were made with), then the mean and the worst
    family by precision of the scored rows, per model (a model that never said yes on a
    family, precision ``-``, is that model's worst)."""
    families = list(dict.fromkeys(s.family for s in scores))
    by = {(s.family, s.model): s for s in scores}
    scored = [m for m in (*SCORED, FIRE_H) if any(s.model == m for s in scores)]
    heads = [f'{m}{" after R veto" if m != "R" else ""}: precision / recall' for m in SCORED]
    if FIRE_H in scored:
        heads.append(f'{FIRE_H}: good share / recall')
    columns = ('held-out family', 'pairs', *(f'{h} (positives)' for h in heads))
    rows = []
    for f in families:
        cells = []
        for m in scored:
            s = by[(f, m)]
            mark = '' if s.scored else '*'
            cells.append(f'{number(s.precision)} / {number(s.recall)} ({s.positives}{mark})')
        rows.append((f, str(by[(f, SCORED[0])].pairs), *cells))
    mean_cells, worst_cells = [], []
    for m in scored:
        counted = [by[(f, m)] for f in families if by[(f, m)].scored]
        finite = [s for s in counted if math.isfinite(s.precision)]
        if not counted:
            mean_cells.append('-')
            worst_cells.append('-')
            continue
        mean_p = float(np.mean([s.precision for s in finite])) if finite else math.nan
        mean_r = float(np.mean([s.recall for s in counted]))
        mean_cells.append(f'{number(mean_p)} / {number(mean_r)}')
        # a family where the model never said yes has no precision: it is the worst
        worst = min(counted, key=lambda s: s.precision if math.isfinite(s.precision) else -1.0)
        worst_cells.append(f'{number(worst.precision)} / {number(worst.recall)} ({worst.family})')
    rows.append(('mean of the scored families', '', *mean_cells))
    rows.append(('worst family (by precision)', '', *worst_cells))
    ceilings = _ceiling_table(families, by, [m for m in SCORED if m in scored])
    note = (
        f'\n\n`*`: fewer than {min_positives} positives, not counted in the mean and the worst;'
        ' `-`: the model never said yes on that family (no precision; the mean leaves it out).'
    )
    if FIRE_H in scored:
        note += (
            f" {FIRE_H}: where a held-out model's yes starts the fire path (R silencing F and"
            ' E) and it publishes H, the share whose pose (the best of the decompositions kept'
            " for the verification frames) is within the labels' E_t bound, and the share of"
            ' the H-labelled pairs on which it publishes H.'
        )
    return markdown_table(columns, rows) + note + ceilings


def _ceiling_table(families: list[str], by: dict[tuple[str, str], FamilyScore],
                   models: list[str]) -> str:  # fmt: skip
    """The models' ceilings (:attr:`FamilyScore.ceiling`) per family, and the worst scored
    one per model: '' when no score holds one."""
    if not any(math.isfinite(by[(f, m)].ceiling) for f in families for m in models):
        return ''
    columns = ('held-out family', *(f'{m}{" after R veto" if m != "R" else ""}' for m in models))
    rows = [
        (f, *(number(by[(f, m)].ceiling) + ('' if by[(f, m)].scored else '*') for m in models))
        for f in families
    ]
    worst = []
    for m in models:
        counted = [by[(f, m)] for f in families if by[(f, m)].scored]
        low = min(counted, key=lambda s: s.ceiling if math.isfinite(s.ceiling) else -1.0,
                  default=None)  # fmt: skip
        worst.append('-' if low is None else f'{number(low.ceiling)} ({low.family})')
    rows.append(('worst scored family', *worst))
    return (
        '\n\nThe ceiling: the highest precision a threshold chosen on the held-out family'
        " itself gives there at the recall of issue 21's bar ("
        + ', '.join(f'{m} {CEILING_RECALL[m]:g}' for m in models)
        + '; R at its chosen threshold for the veto): what no choice of thresholds made'
        ' without the family can beat.\n\n' + markdown_table(columns, rows)
    )


__all__ = [
    'CEILING_RECALL',
    'FIRE_H',
    'MIN_POSITIVES',
    'SCORED',
    'Families',
    'FamilyScore',
    'cap_families',
    'final_test',
    'generalization_markdown',
    'leave_family_out',
    'score_family',
]
