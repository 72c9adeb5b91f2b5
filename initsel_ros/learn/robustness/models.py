"""Model files under camera effects: the same labelled pairs for every file and baseline.

For each effect of :data:`initsel_ros.synth.realism.EFFECT_LEVELS` at the clean, default and
strong strengths, a near-like sequence (and a pure-rotation one) is rendered, labelled once
with ``initsel dataset``'s own function (:func:`initsel_ros.learn.pairs.label_sequence_batch`)
and scored with every model file given (:func:`initsel_ros.learn.evaluate.evaluate`, the same
pairs for each): precision and recall of F/E/H after the R veto and of R, the share of good
first initializations, and false 'yes' on pure rotation. The baselines of the same report
(:data:`BASELINES`: ORB-SLAM2/3, VINS-Mono rule+RANSAC, Butt 2020) get rows of their own.
:func:`choose_model` then picks the file to ship (``initsel robustness models``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

LOG = logging.getLogger(__name__)


# ----------------------------------------------------------------------------- models
#: Levels of the model robustness table.
LEVELS = ('clean', 'default', 'strong')


#: The near-like test sequence and the pure-rotation one of each effect and strength.
TEST_SEQUENCE = {'trajectory': 'near', 'start': 80, 'frames': 150}


ROTATION_SEQUENCE = {'trajectory': 'rotation', 'frames': 60}


def label_sequence(sequence: Any, config: Any = None) -> list[dict[str, Any]]:
    """Table rows of every 30-frame batch of a sequence, exactly as ``initsel dataset`` labels
    them (:func:`initsel_ros.learn.pairs.label_sequence_batch`: tracked points undistorted
    first, as the selector does, and depth read where the distorted reference pixel lies)."""
    from initsel_ros.learn.pairs import DatasetConfig, label_sequence_batch, labelled_batches

    config = config or DatasetConfig(batch=30, jobs=1)
    rows = []
    for b, frames in labelled_batches(sequence, config):
        rows += label_sequence_batch(sequence, b, frames, config)
    return rows


def _render_case(
    out_dir: Path, effect: str, level: str, kind: str, frames: int | None = None
) -> Path:
    """Render (once: cached in ``out_dir``) the near-like or pure-rotation case of an effect.

    ``frames`` overrides the spec's length (the folder name says so, so caches do not mix).
    """
    from initsel_ros.synth import render
    from initsel_ros.synth.realism import effect_level

    effects, distortion, scene = effect_level(effect, level)
    spec = dict(TEST_SEQUENCE if kind == 'near' else ROTATION_SEQUENCE)
    name = f'{kind}_{"clean" if level == "clean" else f"{effect}_{level}"}'
    if frames is not None and frames != spec['frames']:
        spec['frames'] = frames
        name += f'_{frames}f'
    path = out_dir / name
    if not (path / 'rgb.txt').is_file():
        render(path, scene=scene, effects=effects, distortion=distortion, **spec)
    return path


#: Methods of the comparison's columns (F, E, H after the R veto, and R).
COLUMNS = ('F', 'E', 'H', 'R')


#: The models' sequence-level system in :func:`initsel_ros.learn.evaluate.evaluate`.
MODEL_SYSTEM = 'Models (R veto on F, E)'


#: The models' pair-level rows: column -> row name in the evaluation report.
MODEL_ROWS = {**{m: f'Model {m} after R veto' for m in 'FEH'}, 'R': 'Model R'}


#: Baselines of the comparison: sequence-level system name (in the evaluation report) ->
#: {column: pair-level row name}. Columns a baseline lacks stay NaN ('-' in the table).
BASELINES: dict[str, dict[str, str]] = {
    'ORB-SLAM2': {'F': 'ORB-SLAM2 F', 'H': 'ORB-SLAM2 H'},
    'ORB-SLAM3': {'F': 'ORB-SLAM3 F', 'H': 'ORB-SLAM3 H'},
    'VINS-Mono rule+RANSAC': {'E': 'VINS-Mono rule+RANSAC -> E'},
    'Butt 2020 (mean)': {'F': 'Butt 2020 F (mean)', 'H': 'Butt 2020 H (mean)'},
}


def is_model_row(row: Mapping[str, Any]) -> bool:
    return row['kind'] == 'model'


def format_number(v: Any) -> str:
    v = float(v)
    return '-' if math.isnan(v) else f'{v:.2f}'


def slug(text: str) -> str:
    """A name fit for a file or folder: every non-alphanumeric character becomes '_'."""
    return ''.join(c if c.isalnum() else '_' for c in text).strip('_')


def f1_score(precision: float, recall: float) -> float:
    """F1 from precision and recall, NaN-safe.

    0 when either is 0 (a rule that never fires, or never hits, scores 0 even where its
    precision is undefined); NaN when the other is NaN (e.g. no positives); else the
    harmonic mean.
    """
    p, r = float(precision), float(recall)
    if p == 0.0 or r == 0.0:
        return 0.0
    if math.isnan(p) or math.isnan(r):
        return math.nan
    return 2.0 * p * r / (p + r)


def _system_row(
    effect: str,
    level: str,
    system: str,
    kind: str,
    report: Any,
    rows_by_column: dict[str, str],
    sequence_system: str,
) -> dict[str, Any]:
    """One table row: P, R, F1 per column and the sequence-level figures of one system."""
    scores = {r.name: r.scores for r in report.rows}
    seq = next(s for s in report.systems if s.name == sequence_system)
    row: dict[str, Any] = {
        'effect': 'none' if level == 'clean' else effect,
        'level': level,
        'system': system,
        'kind': kind,
        'pairs': report.n_pairs,
    }
    for m in COLUMNS:
        sc = scores[rows_by_column[m]] if m in rows_by_column else None
        # A system that says yes on no pair has no precision (NaN, '-'), not a precision of 0.
        p = sc.precision if sc and sc.predicted > 0 else math.nan
        r = sc.recall if sc else math.nan
        row[f'{m}_precision'], row[f'{m}_recall'] = p, r
    row['first_yes_good'] = seq.first_yes_good
    row['false_yes_rotation'] = seq.false_yes_rotation
    pan = [v for k, v in seq.false_yes_named.items() if k.startswith('rotation')]
    row['false_yes_pan'] = float(np.mean(pan)) if pan else math.nan
    return row


def compare_models(
    out_dir: Path,
    models: Mapping[str, Path],
    effects: Sequence[str] | None = None,
    levels: Sequence[str] = LEVELS,
    frames: tuple[int, int] | None = None,
    baselines: bool = True,
) -> list[dict[str, Any]]:
    """Score several model files and the baselines on the same labelled pairs, per effect
    and strength.

    Each (effect, level) case is rendered and labelled once (cached across calls in
    ``out_dir``); every model file is evaluated on that same table, and the baselines are
    taken from the first model file's report (they do not depend on the models).

    Args:
        out_dir: folder for the rendered sequences.
        models: name -> model file, in table order.
        effects: effects of :data:`~initsel_ros.synth.realism.EFFECT_LEVELS` or 'all'
            (default: every effect, then 'all').
        levels: strengths among 'clean', 'default', 'strong'. The clean case is the same for
            every effect: it gives one set of rows, with effect 'none'.
        frames: (near, rotation) sequence lengths instead of :data:`TEST_SEQUENCE`'s and
            :data:`ROTATION_SEQUENCE`'s (short runs, tests).
        baselines: also add the rows of :data:`BASELINES`.

    Returns:
        One row per (effect, level, system): ``effect``, ``level``, ``system``, ``kind``
        ('model' or 'baseline'), ``pairs``, ``{F,E,H,R}_{precision,recall}`` (F, E, H
        after the R veto for the models; NaN where a system has no such method),
        ``first_yes_good``, ``false_yes_rotation`` (pairs with a baseline <= 5 cm) and
        ``false_yes_pan`` (the pure-rotation sequence) of its sequence-level system.
    """
    from initsel_ros.datasets import open_sequence
    from initsel_ros.learn.evaluate import evaluate
    from initsel_ros.learn.table import PairTable
    from initsel_ros.models import ModelSet
    from initsel_ros.synth.realism import EFFECT_LEVELS

    if not models:
        raise ValueError('compare_models needs at least one model file')
    loaded = {name: ModelSet.load(path) for name, path in models.items()}
    names = [*EFFECT_LEVELS, 'all'] if effects is None else list(effects)
    lengths = (
        {'near': None, 'rotation': None}
        if frames is None
        else dict(zip(('near', 'rotation'), frames, strict=True))
    )
    cache: dict[Path, list[dict[str, Any]]] = {}
    out: list[dict[str, Any]] = []
    clean_done = False
    for effect in names:
        known = EFFECT_LEVELS.get(effect, {'default': {}, 'strong': {}})
        for level in levels:
            if (level == 'strong' and 'strong' not in known) or (level == 'clean' and clean_done):
                continue  # the clean sequences are the same for every effect: one set of rows
            clean_done |= level == 'clean'
            pairs = []
            for kind in ('near', 'rotation'):
                path = _render_case(out_dir, effect, level, kind, lengths[kind])
                if path not in cache:
                    cache[path] = label_sequence(open_sequence(path))
                pairs += cache[path]
            table = PairTable.from_rows(pairs)
            first = None
            for name, model_set in loaded.items():
                report = evaluate(table, model_set)
                first = first or report
                out.append(
                    _system_row(effect, level, name, 'model', report, MODEL_ROWS, MODEL_SYSTEM)
                )
                LOG.info('%s', out[-1])
            if baselines and first is not None:
                for system, by_column in BASELINES.items():
                    out.append(
                        _system_row(effect, level, system, 'baseline', first, by_column, system)
                    )
    return out


def choose_model(
    rows: Sequence[Mapping[str, Any]], reference: str = 'shipped', max_clean_loss: float = 0.05
) -> tuple[str, str]:
    """Choose the model file to ship from the rows of :func:`compare_models`.

    Only model files compete (baselines are ignored). Score of a file: the mean over its
    non-clean (effect, level) rows of ``mean(F1 of F, E, H after the R veto, F1 of R) -
    false_yes_pan``; F1 comes from P and R (:func:`f1_score`: a file that never fires scores
    0) and firing on the pure pan is penalised. A file is eligible when its clean precision
    of F, E, H and R is each at most ``max_clean_loss`` below the ``reference`` file's; the
    reference is always eligible. The eligible file with the highest score wins; ties (and
    a score that cannot be computed) go to the reference.

    Returns:
        ``(winner, explanation)``: the explanation is a short Markdown paragraph with each
        file's score and eligibility.

    Raises:
        ValueError: ``reference`` has no rows.
    """
    models = list(dict.fromkeys(r['system'] for r in rows if is_model_row(r)))
    if reference not in models:
        raise ValueError(f'reference {reference!r} not among the model files {models}')

    clean = {r['system']: r for r in rows if is_model_row(r) and r['level'] == 'clean'}
    scores: dict[str, float] = {}
    reasons: dict[str, str] = {}
    n_rows = 0
    for name in models:
        per_row = []
        for r in rows:
            if r['system'] != name or r['level'] == 'clean':
                continue
            f1 = np.array([f1_score(r[f'{m}_precision'], r[f'{m}_recall']) for m in COLUMNS])
            if np.isnan(f1).all():
                continue
            pan = float(r['false_yes_pan'])
            per_row.append(float(np.nanmean(f1)) - (0.0 if math.isnan(pan) else pan))
        n_rows = max(n_rows, len(per_row))
        scores[name] = float(np.mean(per_row)) if per_row else math.nan
        if name == reference:
            reasons[name] = 'reference'
        elif name not in clean or reference not in clean:
            reasons[name] = 'not eligible: no clean rows to compare'
        else:
            losses = []
            for m in COLUMNS:
                mine = float(clean[name][f'{m}_precision'])
                ref = float(clean[reference][f'{m}_precision'])
                if math.isnan(ref) or math.isnan(mine):
                    continue  # undefined (no 'yes' at all): a loss of recall, not of precision
                if mine < ref - max_clean_loss - 1e-9:
                    losses.append(
                        f'{m} {format_number(mine)} < {format_number(ref)} - {max_clean_loss:g}'
                    )
            reasons[name] = (
                'not eligible: clean precision ' + ', '.join(losses) if losses else 'eligible'
            )
    winner = reference
    for name in models:
        ok = reasons[name] in ('eligible', 'reference')
        if ok and not math.isnan(scores[name]):
            best = scores[winner]
            if math.isnan(best) or scores[name] > best + 1e-12:
                winner = name
    listing = '; '.join(f'`{n}` {_score(scores[n])} ({reasons[n]})' for n in models)
    text = (
        f'**Choice of the model file.** Score: mean over the {n_rows} non-clean effect rows '
        'of the mean F1 of F, E, H after the R veto and of R, minus the false-yes share on '
        f'the pure pan; eligible: clean precision of each at most {max_clean_loss:g} below '
        f"the reference `{reference}`'s. {listing}. Chosen: `{winner}`."
    )
    return winner, text


def _score(v: float) -> str:
    return 'score -' if math.isnan(v) else f'score {v:.3f}'


__all__ = [
    'BASELINES',
    'COLUMNS',
    'LEVELS',
    'MODEL_ROWS',
    'MODEL_SYSTEM',
    'ROTATION_SEQUENCE',
    'TEST_SEQUENCE',
    'choose_model',
    'compare_models',
    'f1_score',
    'format_number',
    'is_model_row',
    'label_sequence',
    'slug',
]
