"""Evaluation of the models and the baselines on a test set of labelled pairs.

Pair level (the paper's tables): accuracy, precision, recall and F1 of models F, E, H, R, of
F/E/H after the R veto, and of the baselines (Butt et al. 2020, VINS-Mono, ORB-SLAM2/3), with
the paper's published numbers beside ours. Sequence level (what a SLAM user sees): frames until
the first 'yes' of each batch, whether that first initialization is good, and the rate of false
'yes' on pure rotation (ground-truth baseline <= 0.05 m) and on sequences named rotation/static.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from initsel_ros.learn import baselines
from initsel_ros.learn.baselines import ORB_MIN_PARALLAX_DEG, ORB_MIN_POINTS
from initsel_ros.learn.candidates import Candidate, FittedCandidate, fit_candidate
from initsel_ros.learn.table import PairTable, input_columns, table_probabilities
from initsel_ros.learn.train import TrainConfig, feature_columns, label_column
from initsel_ros.markdown import markdown_table, number
from initsel_ros.models import METHODS, ModelSet
from initsel_ros.policy import PolicyConfig, Reason, check_pose_batch, decide_batch

#: Families compared by default when training pairs are given.
DEFAULT_CANDIDATES: tuple[Candidate, ...] = tuple(Candidate)

LOG = logging.getLogger(__name__)

#: The paper's test results on fr3/structure_texture_near (accuracy, precision, recall, F1).
PAPER_RESULTS: dict[str, tuple[float, float, float, float]] = {
    'Butt 2020 F (mean)': (0.7589, 0.0811, 0.0133, 0.0229),
    'Butt 2020 H (mean)': (0.7401, 0.2852, 0.4601, 0.3521),
    'Model F': (0.6959, 0.3639, 0.5822, 0.4479),
    'Model E': (0.7326, 0.4290, 0.6453, 0.5154),
    'Model H': (0.8343, 0.3725, 0.1166, 0.1776),
    'Model R': (0.8380, 0.6091, 0.9302, 0.7362),
    'Model F after R veto': (0.7598, 0.4370, 0.4622, 0.4492),
    'Model E after R veto': (0.7815, 0.5041, 0.5256, 0.5146),
    'Model H after R veto': (0.8399, 0.3600, 0.0552, 0.0957),
}


@dataclass(frozen=True)
class Scores:
    """Binary classification figures."""

    accuracy: float
    precision: float
    recall: float
    f1: float
    predicted: int
    positives: int
    n: int

    def shown(self) -> tuple[float, float, float]:
        """(precision, recall, F1) for a table: NaN (a '-') where undefined, i.e. precision
        without a yes, recall without a positive, F1 without either, instead of the 0 the
        fields hold for threshold search."""
        precision = self.precision if self.predicted else math.nan
        recall = self.recall if self.positives else math.nan
        f1 = self.f1 if self.predicted and self.positives else math.nan
        return precision, recall, f1


def binary_scores(y: np.ndarray, pred: np.ndarray) -> Scores:
    """Accuracy, precision, recall, F1 of ``pred`` against ``y`` ((N,) bool each).

    Precision is 0 when nothing is predicted positive (and recall 0 without positives).
    """
    y = np.asarray(y).astype(bool)
    pred = np.asarray(pred).astype(bool)
    tp = int(np.sum(y & pred))
    npred, pos, n = int(pred.sum()), int(y.sum()), len(y)
    precision = tp / npred if npred else 0.0
    recall = tp / pos if pos else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    acc = float(np.mean(y == pred)) if n else math.nan
    return Scores(acc, precision, recall, f1, npred, pos, n)


def has_fire_path(table: PairTable) -> bool:
    """Whether the table holds the fire path's outcome (``initsel dataset --fire-path``)."""
    methods = np.asarray(table['fire_method'], dtype=object)
    return bool(np.isin(methods, ('E', 'F', 'H', 'none')).any())


def fire_path_h(
    table: PairTable,
    probabilities: Mapping[str, np.ndarray],
    thresholds: Mapping[str, float],
    et_max: float = 0.8,
) -> tuple[np.ndarray, np.ndarray]:
    """(published, good), (N,) bool each: pairs on which the per-frame decision starts the
    fire path (:func:`decision_rule` with the node's default ``PolicyConfig.r_veto``, F and
    E, so H's yes alone still starts it, and its ``min_tracks``) and the fire path publishes
    H; and of those, the ones whose pose (the best of the decompositions it keeps for the
    verification frames) is within ``et_max`` of the true direction, the E_t bound of the
    labels."""
    veto = tuple(sorted(PolicyConfig().r_veto))
    started = decision_rule(
        'the fire path', probabilities, thresholds, veto, np.asarray(table['n_tracks'])
    ).yes
    published = started & (np.asarray(table['fire_method'], dtype=object) == 'H')
    et = np.asarray(table['fire_et'], dtype=float)
    return published, published & (et < et_max)


def fire_path_h_scores(y: np.ndarray, published: np.ndarray, good: np.ndarray) -> Scores:
    """Scores of H as the fire path decides it (:func:`fire_path_h`): precision is the share
    of its H whose pose is good (``good``; its ambiguous H, kept with its rival for the
    verification frames, counts when either is), recall the share of the H-labelled pairs
    ``y`` on which it publishes H; no accuracy (the two do not share one confusion matrix)."""
    y, published, good = (np.asarray(a).astype(bool) for a in (y, published, good))
    npred, pos = int(published.sum()), int(y.sum())
    precision = int(good.sum()) / npred if npred else 0.0
    recall = int((published & y).sum()) / pos if pos else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return Scores(math.nan, precision, recall, f1, npred, pos, len(y))


@dataclass(frozen=True)
class EvalRow:
    """One line of the results table."""

    name: str
    group: str  # 'model', 'veto', 'baseline', 'candidate'
    label: str  # which label it is scored against: F, E, H or R
    scores: Scores
    paper: tuple[float, float, float, float] | None = None
    note: str = ''


@dataclass(frozen=True)
class SystemLevel:
    """Sequence-level behaviour of one decision rule."""

    name: str
    batches: int
    batches_with_yes: int
    median_frames_to_first_yes: float
    mean_frames_to_first_yes: float
    first_yes_good: float  # fraction of first 'yes' whose chosen method is labelled good
    false_yes_rotation: float  # 'yes' rate on pairs with baseline <= 0.05 m
    false_yes_named: dict[str, float] = field(default_factory=dict)  # per rotation/static seq


@dataclass(frozen=True)
class CandidateReport:
    """A candidate family's model against the model file's at equal recall.

    ``veto`` scores F, E and H after the R veto of the same family (None for R).
    ``decision_us`` is one decision of the family's four models on one input vector.
    """

    candidate: str
    model: str
    scores: Scores
    precision_at_file_recall: float
    file_precision: float
    file_recall: float
    decision_us: float
    veto: Scores | None = None


@dataclass(frozen=True)
class EvalReport:
    """Everything :func:`evaluate` measured."""

    rows: list[EvalRow]
    systems: list[SystemLevel]
    candidates: list[CandidateReport]
    probabilities: dict[str, np.ndarray]
    n_pairs: int
    sequences: dict[str, int]
    inference_ms_all_pairs: float
    decision_us: float
    model_description: str = ''
    referred_pairs: int = 0


# ----------------------------------------------------------------------------- decisions
@dataclass(frozen=True)
class Rule:
    """Per-pair decision of one system: yes (N,) bool and the chosen method (N,) str."""

    name: str
    yes: np.ndarray
    method: np.ndarray


def orbslam_scored(test: PairTable, warn: bool = True) -> np.ndarray:
    """(N,) bool: the pairs the table holds ORB-SLAM's H/F scores for (a table built with
    ``initsel dataset --no-orbslam`` has none: its ORB-SLAM rows are left out, with a
    warning, rather than shown as a baseline that never said yes)."""
    scored = np.isfinite(np.asarray(test['orb_ratio'], dtype=float))
    if warn and not scored.any():
        LOG.warning(
            'no pair has ORB-SLAM scores (initsel dataset --no-orbslam leaves them out): the '
            'ORB-SLAM baseline is left out'
        )
    return scored


def _orb_note(scored: np.ndarray) -> str:
    """What a row says of pairs without ORB-SLAM scores ('' when every pair has them)."""
    missing = int((~scored).sum())
    return f'; {missing} of {scored.size} pairs without scores count as no' if missing else ''


def _orb_accepts(test: PairTable, method: np.ndarray) -> np.ndarray:
    out = np.zeros(len(test), dtype=bool)
    for m in ('F', 'H'):
        sel = method == m
        out |= sel & (
            (np.asarray(test[f'{m}_ok']) == 1)
            & (np.asarray(test[f'{m}_n_points']) >= ORB_MIN_POINTS)
            & (np.asarray(test[f'{m}_parallax_deg']) >= ORB_MIN_PARALLAX_DEG)
        )
    return out


def _pose_ok(
    test: PairTable, method: np.ndarray, config: PolicyConfig | None = None
) -> np.ndarray:
    """The selector's pose check (``policy.check_pose_batch``) on the chosen method's estimate;
    as in the fire path, an F fails where E's estimate is refused for low parallax
    (``initialize._low_essential_parallax``; the table holds E's estimate on every pair, the
    fire path only where E was tried)."""
    config = config or PolicyConfig()
    out = np.zeros(len(test), dtype=bool)

    def reasons_of(m: str) -> np.ndarray:
        return check_pose_batch(
            np.asarray(test[f'{m}_ok']) == 1,
            np.asarray(test[f'{m}_n_points']),
            np.asarray(test[f'{m}_parallax_deg'], dtype=float),
            config,
            m,
            np.asarray(test['n_tracks']),
        )

    for m in ('F', 'E', 'H'):
        sel = np.asarray(method) == m
        if not sel.any():
            continue
        good = np.array([r is None for r in reasons_of(m)])
        if m == 'F':
            good &= np.array([r is not Reason.LOW_PARALLAX for r in reasons_of('E')])
        out |= sel & good
    return out


def baseline_rules(test: PairTable) -> dict[str, Rule]:
    """Sequence-level rules of the baselines (yes + chosen method per pair)."""
    n = len(test)
    rules = {}
    for stat in ('mean', 'median'):
        h, f = baselines.butt_rule(test[f'disp_{stat}_px'], test['disp_std_px'])
        method = np.where(f, 'F', 'H').astype(object)
        rules[f'Butt 2020 ({stat})'] = Rule(f'Butt 2020 ({stat})', h, method)
    vins = baselines.vins_rule(test['n_tracks'], test['vins_parallax_px'])
    e = np.full(n, 'E', dtype=object)
    rules['VINS-Mono rule'] = Rule('VINS-Mono rule', vins, e)
    inl = np.asarray(test['vins_inliers'])
    rules['VINS-Mono rule+RANSAC'] = Rule('VINS-Mono rule+RANSAC', vins & (inl > 12), e)
    for version in baselines.OrbSlamVersion if orbslam_scored(test, warn=False).any() else ():
        choice = baselines.orbslam_choice(test['orb_ratio'], version)
        name = f'ORB-SLAM{version.value}'
        rules[name] = Rule(name, _orb_accepts(test, choice), choice)
    return rules


def decision_rule(
    name: str,
    probs: Mapping[str, np.ndarray],
    thresholds: Mapping[str, float],
    veto: Sequence[str] = ('F', 'E'),
    n_tracks: np.ndarray | None = None,
) -> Rule:
    """The per-frame decision (``policy.decide_batch``) on table rows: thresholds, R veto,
    most confident candidate.

    This is the decision alone, not the fire path that follows it live (rotation test, GRIC
    selection, refinement, verification): ``initsel seedmap`` runs the live selector for that.

    Args:
        n_tracks: correspondences per row (None: every row has enough).
    """
    n = len(next(iter(probs.values())))
    config = PolicyConfig(r_veto=frozenset(veto))
    tracks = np.full(n, config.min_tracks) if n_tracks is None else np.asarray(n_tracks)
    batch = decide_batch(probs, thresholds, tracks, config)
    yes = batch.n_candidates > 0
    return Rule(name, yes, batch.first_method())


def _good(test: PairTable, method: np.ndarray) -> np.ndarray:
    out = np.zeros(len(test), dtype=bool)
    for m in ('F', 'E', 'H'):
        out |= (method == m) & (np.asarray(test[f'{m}_label']) == 1)
    return out


def system_level(test: PairTable, rule: Rule) -> SystemLevel:
    """Frames to the first 'yes' per batch, its quality, and false 'yes' on rotation."""
    groups = test.groups()
    frames = np.asarray(test['cur_index']) - np.asarray(test['ref_index'])
    good = _good(test, rule.method)
    firsts, quality = [], []
    unique = np.unique(groups)
    for g in unique:
        idx = np.flatnonzero(groups == g)
        idx = idx[np.argsort(frames[idx], kind='stable')]
        hits = idx[rule.yes[idx]]
        if len(hits):
            firsts.append(frames[hits[0]])
            quality.append(good[hits[0]])
    rot = np.asarray(test['R_label']) == 1
    named = {}
    seqs = np.asarray(test['sequence']).astype(str)
    for s in np.unique(seqs):
        if 'rotation' in s.lower() or 'static' in s.lower():
            sel = seqs == s
            named[str(s)] = float(np.mean(rule.yes[sel]))
    return SystemLevel(
        rule.name,
        len(unique),
        len(firsts),
        float(np.median(firsts)) if firsts else math.nan,
        float(np.mean(firsts)) if firsts else math.nan,
        float(np.mean(quality)) if quality else math.nan,
        float(np.mean(rule.yes[rot])) if rot.any() else math.nan,
        named,
    )


# ----------------------------------------------------------------------------- timing
def time_call(fn: Callable[[], Any], repeat: int = 2000) -> float:
    """Median-of-5 mean time of ``fn()`` in microseconds, on one thread (as a live node)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        fn()
        runs = []
        for _ in range(5):
            start = time.perf_counter()
            for _ in range(repeat):
                fn()
            runs.append((time.perf_counter() - start) / repeat * 1e6)
    return float(np.median(runs))


def precision_at_recall(y: np.ndarray, scores: np.ndarray, recall: float) -> float:
    """Highest precision among thresholds whose recall is at least ``recall``."""
    y = np.asarray(y).astype(bool)
    pos = int(y.sum())
    if pos == 0:
        return math.nan
    order = np.argsort(-np.asarray(scores, dtype=float), kind='stable')
    tp = np.cumsum(y[order])
    k = np.arange(1, len(y) + 1)
    rec = tp / pos
    prec = tp / k
    ok = rec >= recall - 1e-12
    return float(prec[ok].max()) if ok.any() else math.nan


# ----------------------------------------------------------------------------- evaluate
def describe_models(models: ModelSet) -> str:
    """Short family description of a model file, e.g. 'trees+extra' or 'F trees+extra, ...'."""
    fams = {}
    for m, model in models.models.items():
        extra = [f for f in model.features if f.startswith('x_')]
        fams[m] = model.kind + ('+extra' if extra else '')
    if len(set(fams.values())) == 1:
        return next(iter(fams.values()))
    return ', '.join(f'{m} {f}' for m, f in fams.items())


def evaluate(
    test: PairTable,
    models: ModelSet,
    *,
    train: PairTable | None = None,
    train_config: TrainConfig | None = None,
    candidates: Sequence[Candidate] = DEFAULT_CANDIDATES,
    et_max: float = 0.8,
) -> EvalReport:
    """Score models and baselines on ``test`` (see module docstring).

    Args:
        test: test pairs.
        models: the model file under test (its scaling and input names pick the feature
            columns).
        train: training pairs, or None: when given, the ``candidates`` families are fitted on
            them in memory (thresholds by grouped cross-validation on ``train``, never on
            ``test``) and compared with the model file at equal recall and after the R veto.
        et_max: the E_t bound of a good pose, for the row of H by the fire path (tables made
            with ``initsel dataset --fire-path``).
    """
    paper = test.matrix(feature_columns(models.scaling))
    finite = np.all(np.isfinite(paper), axis=1)
    if not finite.all():
        LOG.warning('ignoring %d test pairs with non-finite features', int((~finite).sum()))
        test = test.select(finite)
    start = time.perf_counter()
    probs, referred = table_probabilities(models, test)
    inference_ms = (time.perf_counter() - start) * 1e3
    first = test.select(np.arange(len(test)) < 1).matrix(
        input_columns(models.input_names, models.scaling)
    )
    x0 = first[0] if len(first) else np.zeros(len(models.input_names))
    decision_us = time_call(lambda: models.predict_proba(x0))
    thr = models.thresholds
    y = {m: np.asarray(test[label_column(m)]).astype(bool) for m in METHODS}
    fired = {m: probs[m] >= thr[m] for m in METHODS}
    rows: list[EvalRow] = []
    for m in METHODS:
        name = f'Model {m}'
        rows.append(
            EvalRow(name, 'model', m, binary_scores(y[m], fired[m]), PAPER_RESULTS.get(name))
        )
    for m in ('F', 'E', 'H'):
        name = f'Model {m} after R veto'
        rows.append(
            EvalRow(
                name,
                'veto',
                m,
                binary_scores(y[m], fired[m] & ~fired['R']),
                PAPER_RESULTS.get(name),
            )
        )
    if has_fire_path(test):
        rows.append(
            EvalRow(
                'H by the fire path',
                'veto',
                'H',
                fire_path_h_scores(y['H'], *fire_path_h(test, probs, thr, et_max)),
                note="a model's yes starts the fire path, which publishes H; precision: the "
                'share of its H whose pose is good',
            )
        )
    for stat in ('mean', 'median'):
        h, f = baselines.butt_rule(test[f'disp_{stat}_px'], test['disp_std_px'])
        for m, pred in (('F', f), ('H', h)):
            name = f'Butt 2020 {m} ({stat})'
            rows.append(
                EvalRow(name, 'baseline', m, binary_scores(y[m], pred), PAPER_RESULTS.get(name))
            )
    vins = baselines.vins_rule(test['n_tracks'], test['vins_parallax_px'])
    vins_full = vins & (np.asarray(test['vins_inliers']) > 12)
    for m in ('E', 'F'):
        rows.append(EvalRow(f'VINS-Mono rule -> {m}', 'baseline', m, binary_scores(y[m], vins)))
    rows.append(
        EvalRow(
            'VINS-Mono rule+RANSAC -> E',
            'baseline',
            'E',
            binary_scores(y['E'], vins_full),
            note='> 12 recoverPose inliers',
        )
    )
    scored = orbslam_scored(test)
    for version in baselines.OrbSlamVersion if scored.any() else ():
        choice = baselines.orbslam_choice(test['orb_ratio'], version)
        accepted = _orb_accepts(test, choice)
        for m in ('H', 'F'):
            rows.append(
                EvalRow(
                    f'ORB-SLAM{version.value} {m}',
                    'baseline',
                    m,
                    binary_scores(y[m], accepted & (choice == m)),
                    note=f'S_H/(S_H+S_F) {">" if m == "H" else "<="} '
                    f'{version.ratio_threshold:.2f}, >= {ORB_MIN_POINTS} points, '
                    f'parallax >= {ORB_MIN_PARALLAX_DEG:g} deg' + _orb_note(scored),
                )
            )
    # sequence level
    tracks = np.asarray(test['n_tracks'])
    rules = [
        decision_rule('Models (R veto on F, E)', probs, thr, n_tracks=tracks),
        decision_rule(
            'Models (R veto on F, E, H)', probs, thr, veto=('F', 'E', 'H'), n_tracks=tracks
        ),
    ]
    for rule, name in (
        (rules[0], 'Models + pose check'),
        (rules[1], 'Models (R veto on F, E, H) + pose check'),
    ):
        rules.append(Rule(name, rule.yes & _pose_ok(test, rule.method), rule.method))
    rules += list(baseline_rules(test).values())
    systems = [system_level(test, r) for r in rules]
    description = describe_models(models)
    cand_reports: list[CandidateReport] = []
    if train is not None:
        cfg = train_config or TrainConfig(scaling=models.scaling)
        cand_reports = [
            CandidateReport(
                f'model file ({description})',
                m,
                s := binary_scores(y[m], fired[m]),
                s.precision,
                s.precision,
                s.recall,
                decision_us,
                None if m == 'R' else binary_scores(y[m], fired[m] & ~fired['R']),
            )
            for m in METHODS
        ]
        for cand in candidates:
            cand_reports += _compare_family(cand, train, test, cfg, y, fired)
    seqs = {
        str(s): int(c)
        for s, c in zip(
            *np.unique(np.asarray(test['sequence']).astype(str), return_counts=True), strict=True
        )
    }
    return EvalReport(
        rows,
        systems,
        cand_reports,
        probs,
        len(test),
        seqs,
        inference_ms,
        decision_us,
        description,
        int(np.count_nonzero(referred)),
    )


def _compare_family(
    cand: Candidate,
    train: PairTable,
    test: PairTable,
    cfg: TrainConfig,
    y: Mapping[str, np.ndarray],
    fired_file: Mapping[str, np.ndarray],
) -> list[CandidateReport]:
    """Fit the four models of one family; score each alone, after its own R veto, and at the
    model file's recall; time one decision of the four."""
    fitted: dict[str, FittedCandidate] = {}
    for m in METHODS:
        f = fit_candidate(cand, m, train, cfg)
        if f is not None:
            fitted[m] = f
    if not fitted:
        return []
    Z = test.matrix(next(iter(fitted.values())).columns)
    scores = {m: f.score(Z) for m, f in fitted.items()}
    fired = {
        m: scores[m] >= (f.threshold.threshold if f.threshold else 0.5) for m, f in fitted.items()
    }
    z0 = np.where(np.isfinite(Z[0]), Z[0], 0.0) if len(Z) else np.zeros(Z.shape[1])
    models = {m: f.model_obj for m, f in fitted.items()}
    if len(models) == len(METHODS) and all(v is not None for v in models.values()):
        family_set = ModelSet(models, scaling=cfg.scaling)  # type: ignore[arg-type]
        x0 = _reorder(z0, fitted, family_set)
        decision = time_call(lambda: family_set.predict_proba(x0))
    else:  # scikit-learn references: four single-row calls
        slow = cand is Candidate.HGB_EXTRA
        decision = sum(
            time_call(lambda f=f: f.score_one(z0), repeat=50 if slow else 500)
            for f in fitted.values()
        )
    out = []
    for m in fitted:
        own = binary_scores(y[m], fired[m])
        base = binary_scores(y[m], fired_file[m])
        veto = None
        if m != 'R' and 'R' in fired:
            veto = binary_scores(y[m], fired[m] & ~fired['R'])
        out.append(
            CandidateReport(
                cand.value,
                m,
                own,
                precision_at_recall(y[m], scores[m], base.recall) if base.recall > 0 else math.nan,
                base.precision,
                base.recall,
                decision,
                veto,
            )
        )
    return out


def _reorder(z: np.ndarray, fitted: Mapping[str, FittedCandidate], models: ModelSet) -> np.ndarray:
    """A candidate row (its table columns) as the input vector of ``models``."""
    columns = next(iter(fitted.values())).columns
    wanted = input_columns(models.input_names, models.scaling)
    index = {c: i for i, c in enumerate(columns)}
    return z[[index[c] for c in wanted]]


# ----------------------------------------------------------------------------- formatting
def _f(value: float | None) -> str:
    return number(value, 4)


def results_markdown(report: EvalReport) -> str:
    """The pair-level table (ours beside the paper's), Markdown."""
    columns = ('classifier', 'label', 'accuracy', 'precision', 'recall', 'F1', 'yes')
    columns += ('positives', 'paper acc.', 'paper prec.', 'paper rec.', 'paper F1')
    rows = []
    for r in report.rows:
        s = r.scores
        scores = map(_f, (s.accuracy, *s.shown()))
        paper = map(_f, r.paper or (math.nan,) * 4)
        rows.append((r.name, r.label, *scores, s.predicted, s.positives, *paper))
    return markdown_table(columns, rows)


def systems_markdown(report: EvalReport) -> str:
    """The sequence-level table, Markdown."""
    columns = ('rule', 'batches', 'batches with a yes', 'median frames to first yes')
    columns += ('first yes good', 'false yes on rotation pairs')
    columns += ('yes rate on rotation/static seqs',)
    rows = []
    for s in report.systems:
        named = ', '.join(f'{k}: {v:.3f}' for k, v in s.false_yes_named.items()) or '-'
        rates = map(_f, (s.median_frames_to_first_yes, s.first_yes_good, s.false_yes_rotation))
        rows.append((s.name, s.batches, s.batches_with_yes, *rates, named))
    return markdown_table(columns, rows)


def candidates_markdown(report: EvalReport) -> str:
    """Candidate families vs the model file: alone, after the R veto, at equal recall."""
    if not report.candidates:
        return ''
    columns = ('model family', 'label', 'precision', 'recall', 'F1', 'precision after R veto')
    columns += ('recall after R veto', 'precision at model-file recall', 'model-file precision')
    columns += ('model-file recall', 'decision (4 models), us')
    rows = []
    for c in report.candidates:
        s, v = c.scores, c.veto
        vetoed = tuple(map(_f, v.shown()[:2])) if v else ('-', '-')
        alone = map(_f, s.shown())
        file = map(_f, (c.precision_at_file_recall, c.file_precision, c.file_recall))
        rows.append((c.candidate, c.model, *alone, *vetoed, *file, f'{c.decision_us:.1f}'))
    return markdown_table(columns, rows)


#: Targets of issue 10 on the near-like test set, after the R veto: (precision, recall).
TARGETS: dict[str, tuple[float, float]] = {'F': (0.8, 0.3), 'E': (0.8, 0.55), 'H': (0.8, 0.36)}


def verdict(report: EvalReport, budget_us: float = 50.0) -> str:
    """Per family: wins at equal recall, the after-veto targets met, the decision cost."""
    if not report.candidates:
        return 'No candidate families evaluated (pass --train to fit them).'
    out = []
    fams = list(dict.fromkeys(c.candidate for c in report.candidates))
    for fam in fams:
        rows = [c for c in report.candidates if c.candidate == fam]
        wins = [
            c.model
            for c in rows
            if np.isfinite(c.precision_at_file_recall)
            and c.precision_at_file_recall > c.file_precision + 1e-9
        ]
        met = [
            c.model
            for c in rows
            if c.veto is not None
            and c.model in TARGETS
            and c.veto.precision >= TARGETS[c.model][0]
            and c.veto.recall >= TARGETS[c.model][1]
        ]
        us = max(c.decision_us for c in rows)
        within = us <= budget_us
        line = f'{fam}: after-veto targets met for {", ".join(met) or "none"} of F, E, H; '
        if fam == report.model_description:
            line += "the model file's family; "
        elif not fam.startswith('model file'):
            line += (
                f"higher precision at the model file's recall for "
                f'{", ".join(wins) or "no model"} of {len(rows)}; '
            )
        out.append(
            line + f'{us:.0f} us per decision '
            f'({"within" if within else "over"} the {budget_us:.0f} us budget)'
        )
    targets = ', '.join(
        f'{m} precision >= {p:g} with recall >= {r:g}' for m, (p, r) in TARGETS.items()
    )
    return '\n'.join(f'- {line}' for line in out) + f'\n\nTargets (after the R veto): {targets}.'


def report_markdown(report: EvalReport) -> str:
    """The whole report, Markdown."""
    seqs = ', '.join(f'{k} ({v})' for k, v in report.sequences.items())
    parts = [
        f'# Evaluation on {report.n_pairs} pairs: {seqs}',
        '',
        '## Pair level (paper numbers: fr3/structure_texture_near, 1,062 pairs)',
        '',
        results_markdown(report),
        '',
        f'Model file: {report.model_description}. Inference over all {report.n_pairs} pairs: '
        f'{report.inference_ms_all_pairs:.2f} ms; one decision (4 models, one input vector, '
        f'extra features not included): {report.decision_us:.1f} us.'
        + (
            f" The file's referee decided a model on {report.referred_pairs} of the "
            f'{report.n_pairs} pairs.'
            if report.referred_pairs
            else ''
        ),
        '',
        '## Sequence level (per batch; frames counted from the reference)',
        '',
        systems_markdown(report),
    ]
    if report.candidates:
        parts += [
            '',
            '## Model families (fitted in memory on the training pairs; thresholds '
            'by grouped cross-validation on them)',
            '',
            candidates_markdown(report),
            '',
            verdict(report),
        ]
    return '\n'.join(parts) + '\n'


def _score_fields(s: Any) -> dict[str, Any]:
    """The CSV columns of one set of scores."""
    return {
        'accuracy': s.accuracy,
        'precision': s.precision,
        'recall': s.recall,
        'f1': s.f1,
        'predicted_yes': s.predicted,
        'positives': s.positives,
        'pairs': s.n,
    }


def results_csv_rows(report: EvalReport) -> list[dict[str, Any]]:
    """Pair-level table as row dicts (for CSV)."""
    out = []
    for r in report.rows:
        s = r.scores
        p = r.paper or (math.nan,) * 4
        out.append(
            {
                'classifier': r.name,
                'group': r.group,
                'label': r.label,
                **_score_fields(s),
                'paper_accuracy': p[0],
                'paper_precision': p[1],
                'paper_recall': p[2],
                'paper_f1': p[3],
                'note': r.note,
            }
        )
    for c in report.candidates:
        s = c.scores
        out.append(
            {
                'classifier': f'{c.candidate} {c.model}',
                'group': 'candidate',
                'label': c.model,
                **_score_fields(s),
                'paper_accuracy': math.nan,
                'paper_precision': math.nan,
                'paper_recall': math.nan,
                'paper_f1': math.nan,
                'note': f'precision at model-file recall {c.precision_at_file_recall:.4f}; '
                + (
                    f'after R veto precision {c.veto.precision:.4f} recall {c.veto.recall:.4f}; '
                    if c.veto
                    else ''
                )
                + f'{c.decision_us:.1f} us per decision',
            }
        )
    for sl in report.systems:
        out.append(
            {
                'classifier': f'sequence level: {sl.name}',
                'group': 'system',
                'label': '',
                'accuracy': math.nan,
                'precision': sl.first_yes_good,
                'recall': math.nan,
                'f1': math.nan,
                'predicted_yes': sl.batches_with_yes,
                'positives': math.nan,
                'pairs': sl.batches,
                'paper_accuracy': math.nan,
                'paper_precision': math.nan,
                'paper_recall': math.nan,
                'paper_f1': math.nan,
                'note': f'median frames to first yes {sl.median_frames_to_first_yes}; '
                f'false yes on rotation pairs {sl.false_yes_rotation:.4f}; '
                f'precision column = first yes good',
            }
        )
    return out


__all__ = [
    'DEFAULT_CANDIDATES',
    'PAPER_RESULTS',
    'TARGETS',
    'CandidateReport',
    'EvalReport',
    'EvalRow',
    'Rule',
    'Scores',
    'SystemLevel',
    'baseline_rules',
    'binary_scores',
    'candidates_markdown',
    'decision_rule',
    'describe_models',
    'evaluate',
    'precision_at_recall',
    'report_markdown',
    'results_csv_rows',
    'results_markdown',
    'system_level',
    'time_call',
    'verdict',
]
