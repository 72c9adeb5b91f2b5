"""Robustness to camera effects: the tracker's photometric modes, and the shipped models.

Two measurements on sequences rendered for the purpose (``initsel_ros.synth``):

``tracker``: for each brightness condition (clean, auto-exposure ramps) and each
:class:`~initsel_ros.tracking.Photometric` mode, KLT tracks over 30-frame batches are compared
with the rendered ground truth (track error: the reference pixel moved with its depth and the
true relative pose), and the seed map of an E 5-point pose (the fire path's estimator,
:func:`initsel_ros.initialize.initialize_pair`) with the true pose (E_t, rotation error,
median depth error) on every pair with a baseline of at least 5 cm.

``models``: for each effect of :data:`initsel_ros.synth.realism.EFFECT_LEVELS` at the clean,
default and strong strengths, a near-like sequence (and a pure-rotation one) is rendered,
labelled once with ``initsel dataset``'s machinery (:mod:`initsel_ros.learn.pairs`, points
undistorted first as the selector does) and scored with every model file given
(:func:`initsel_ros.learn.evaluate.evaluate`, the same pairs for each): precision and recall of
F/E/H after the R veto and of R, the share of good first initializations, and false 'yes' on
pure rotation. The baselines of the same report (:data:`BASELINES`: ORB-SLAM2/3, VINS-Mono
rule+RANSAC, Butt 2020) get rows of their own. :func:`choose_model` then picks the file to ship.

Run ``python -m initsel_ros.learn.robustness tracker --out DIR``, or::

    python -m initsel_ros.learn.robustness models --out DIR \
        --models shipped=config/models.json --models effects_mix=/tmp/x.json \
        --markdown FILE.md --csv FILE.csv --plots PLOT_DIR
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import logging
import math
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.initialize import FireConfig, initialize_pair
from initsel_ros.metrics import relative_pose, rotation_error_deg, translation_chordal_error
from initsel_ros.tracking import KltTracker, Photometric, TrackerConfig

LOG = logging.getLogger(__name__)

#: Brightness conditions of the tracker comparison: name -> gain_ramp (() = clean).
RAMPS: dict[str, tuple[float, ...]] = {
    'clean': (),
    'ramp 0.6->1.4 / 2 s': (0.6, 1.4, 2.0),
    'ramp 1.4->0.6 / 1 s': (1.4, 0.6, 1.0, 0.3),
    'ramp 0.4->1.8 / 1 s': (0.4, 1.8, 1.0, 0.3),
    'all effects (default), ramp 0.6->1.4 / 2 s': (),
    'clean, seed 100': (),
}


def _all_effects() -> tuple[Any, tuple[float, ...]]:
    from initsel_ros.synth.realism import effect_level

    effects, distortion, _ = effect_level('all', 'default')
    return effects, distortion


#: Further conditions: name -> () -> (Effects, distortion)
EXTRA_CONDITIONS = {'all effects (default), ramp 0.6->1.4 / 2 s': _all_effects}
#: Conditions rendered with another seed (noise and textures): the spread between
#: 'clean' and 'clean, seed 100' is the noise level of the figures
NOISE_SEEDS = {'clean, seed 100': 100}
#: Sequences of the tracker comparison: name -> render() arguments.
TRACKER_SEQUENCES: dict[str, dict[str, Any]] = {
    'near': {'trajectory': 'near', 'start': 80},
    'far': {'trajectory': 'far', 'start': 80},
    'random': {'trajectory': 'random', 'seed': 3},
    'forward': {'trajectory': 'forward'},
}
MIN_BASELINE_M = 0.05
#: The fire path's estimators alone (no rotation test, selection or refinement).
ESTIMATES_ONLY = FireConfig(rotation_test=False, select=False, refine=False)


# ----------------------------------------------------------------------------- ground truth
def true_positions(
    p0: np.ndarray, depth: np.ndarray, camera: Intrinsics, T_ref: np.ndarray, T_cur: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where reference pixels truly are in the current frame (with the camera's distortion).

    Returns:
        ``(pixels (N, 2), points (N, 3) in the reference camera frame, valid (N,) bool)``;
        invalid where the reference depth is missing.
    """
    h, w = depth.shape
    xy = np.rint(p0).astype(np.int64)
    z = depth[np.clip(xy[:, 1], 0, h - 1), np.clip(xy[:, 0], 0, w - 1)].astype(np.float64)
    und = camera.undistort_pixels(p0).astype(np.float64)
    rays = np.column_stack(
        [(und - [camera.cx, camera.cy]) / [camera.fx, camera.fy], np.ones(len(und))]
    )
    X = rays * z[:, None]
    R, t = relative_pose(T_ref, T_cur)
    Xc = X @ R.T + t
    dist = np.array(camera.distortion) if camera.has_distortion else None
    proj, _ = cv2.projectPoints(Xc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, dist)
    return proj.reshape(-1, 2), X, (z > 0) & (Xc[:, 2] > 0.05)


@dataclass(frozen=True)
class PairResult:
    """One reference/current pair of a tracker run."""

    frames: int
    tracks: int
    track_err_px: float  # median over the pair's tracks
    far_share: float  # tracks more than 2 px off
    baseline_m: float
    et: float
    rot_deg: float
    depth_err: float  # median relative depth error of the seed map (median scale)
    points: int


def _seed_map(
    p0: np.ndarray,
    p1: np.ndarray,
    X_gt: np.ndarray,
    valid: np.ndarray,
    camera: Intrinsics,
    T_ref: np.ndarray,
    T_cur: np.ndarray,
) -> tuple[float, float, float, int]:
    """E 5-point pose of a pair against the truth: (E_t, rotation error deg, depth error,
    points); NaN when the estimate fails."""
    u0, u1 = camera.undistort_pixels(p0), camera.undistort_pixels(p1)
    est = initialize_pair(u0, u1, camera.K, ('E',), ESTIMATES_ONLY).estimates[0]
    if not est.ok:
        return math.nan, math.nan, math.nan, 0
    R_gt, t_gt = relative_pose(T_ref, T_cur)
    et = translation_chordal_error(t_gt, est.t)
    rot = rotation_error_deg(R_gt, est.R)
    idx = est.indices[valid[est.indices]]
    if len(idx) < 2:
        return et, rot, math.nan, est.n_points
    z_gt, z_est = X_gt[idx, 2], est.points[valid[est.indices], 2]
    scale = float(
        np.median(
            np.linalg.norm(X_gt[idx], axis=1)
            / np.linalg.norm(est.points[valid[est.indices]], axis=1)
        )
    )
    depth_err = float(np.median(np.abs(scale * z_est - z_gt) / z_gt))
    return et, rot, depth_err, est.n_points


def track_sequence(
    sequence: Any, config: TrackerConfig, batch: int = 30, min_frames: int = 1
) -> tuple[list[PairResult], int]:
    """Track every 30-frame batch and measure every pair against the ground truth.

    Returns:
        The pairs, and the number of frames the tracker's photometric mapping changed.
    """
    camera = sequence.intrinsics
    out = []
    remaps = 0
    for b0 in range(0, len(sequence) - batch + 1, batch):
        tracker = KltTracker(config)
        tracker.reset(sequence.gray(b0))
        depth = sequence.depth(b0)
        T_ref = sequence.frames[b0].pose
        for j in range(b0 + 1, b0 + batch):
            tracks = tracker.track(sequence.gray(j))
            if j - b0 < min_frames or len(tracks) < 8:
                continue
            T_cur = sequence.frames[j].pose
            truth, X_gt, valid = true_positions(tracks.ref, depth, camera, T_ref, T_cur)
            err = np.linalg.norm(tracks.cur - truth, axis=1)[valid]
            baseline = float(np.linalg.norm(relative_pose(T_ref, T_cur)[1]))
            seed = (math.nan, math.nan, math.nan, 0)
            if baseline >= MIN_BASELINE_M:
                seed = _seed_map(tracks.ref, tracks.cur, X_gt, valid, camera, T_ref, T_cur)
            out.append(
                PairResult(
                    j - b0,
                    len(tracks),
                    float(np.median(err)),
                    float(np.mean(err > 2.0)),
                    baseline,
                    *seed,
                )
            )
        remaps += tracker.photometric_remaps
    return out, remaps


def _summary(results: Sequence[PairResult]) -> dict[str, float]:
    last = [r for r in results if r.frames == max(p.frames for p in results)]
    seed = [r for r in results if r.baseline_m >= MIN_BASELINE_M]
    et = np.array([r.et for r in seed])
    rot = np.array([r.rot_deg for r in seed])
    dep = np.array([r.depth_err for r in seed])
    ok = np.isfinite(et)
    return {
        'tracks_end': float(np.mean([r.tracks for r in last])),
        'track_err_px': float(np.median([r.track_err_px for r in results])),
        'lost_pairs': float(np.mean([r.track_err_px > 2.0 for r in results])),
        'far_share': float(np.mean([r.far_share for r in results])),
        'pairs': float(len(seed)),
        'et_median': float(np.median(et[ok])) if ok.any() else math.nan,
        'et_p90': float(np.percentile(et[ok], 90)) if ok.any() else math.nan,
        'rot_median': float(np.median(rot[ok])) if ok.any() else math.nan,
        'rot_p90': float(np.percentile(rot[ok], 90)) if ok.any() else math.nan,
        'depth_err_median': float(np.nanmedian(dep[ok])) if ok.any() else math.nan,
        'bad_share': float(np.mean(~ok | (et >= 0.2) | (rot >= 1.0))) if len(et) else math.nan,
    }


def compare_trackers(
    out_dir: Path,
    frames: int = 120,
    modes: Iterable[Photometric] = tuple(Photometric),
    sequences: dict[str, dict[str, Any]] | None = None,
    ramps: dict[str, tuple[float, ...]] | None = None,
) -> list[dict[str, Any]]:
    """Render the sequences under each brightness condition and compare the tracker modes.

    Returns:
        One row per (condition, mode): the :func:`_summary` figures pooled over sequences,
        plus the tracking time per frame (ms, images decoded beforehand).
    """
    from initsel_ros.datasets import open_sequence
    from initsel_ros.synth import Effects, render

    sequences = TRACKER_SEQUENCES if sequences is None else sequences
    ramps = RAMPS if ramps is None else ramps
    rows = []
    for cond, ramp in ramps.items():
        pooled: dict[Photometric, list[PairResult]] = {m: [] for m in modes}
        seconds = dict.fromkeys(modes, 0.0)
        remaps = dict.fromkeys(modes, 0)
        n_frames = 0
        for name, kwargs in sequences.items():
            path = out_dir / f'{name}_{_slug(cond)}'
            if not (path / 'rgb.txt').is_file():
                effects, distortion = Effects(gain_ramp=ramp), ()
                if cond in EXTRA_CONDITIONS:
                    effects, distortion = EXTRA_CONDITIONS[cond]()
                render(
                    path,
                    frames=frames,
                    effects=effects,
                    distortion=distortion,
                    **{**kwargs, 'seed': kwargs.get('seed', 0) + NOISE_SEEDS.get(cond, 0)},
                )
            seq = _Cached(open_sequence(path))
            for i in range(len(seq)):  # decode before timing
                seq.gray(i)
                seq.depth(i)
            n_frames += len(seq)
            for mode in modes:
                start = time.perf_counter()
                results, n_remaps = track_sequence(
                    seq, dataclasses.replace(TrackerConfig(), photometric=mode)
                )
                seconds[mode] += time.perf_counter() - start
                pooled[mode] += results
                remaps[mode] += n_remaps
        for mode in modes:
            rows.append(
                {
                    'condition': cond,
                    'mode': mode.value,
                    **_summary(pooled[mode]),
                    'seconds_per_frame': seconds[mode] / max(n_frames, 1),
                    'remaps': remaps[mode] / max(n_frames, 1),
                }
            )
            LOG.info('%s %s: %s', cond, mode.value, rows[-1])
    return rows


def _slug(text: str) -> str:
    return ''.join(c if c.isalnum() else '_' for c in text).strip('_')


class _Cached:
    """A sequence whose grey frames and depth maps are decoded once (for fair timings)."""

    def __init__(self, sequence: Any) -> None:
        self._seq = sequence
        self.intrinsics = sequence.intrinsics
        self.frames = sequence.frames
        self.name = sequence.name
        self._gray: dict[int, np.ndarray] = {}
        self._depth: dict[int, np.ndarray | None] = {}

    def __len__(self) -> int:
        return len(self._seq)

    def gray(self, i: int) -> np.ndarray:
        if i not in self._gray:
            self._gray[i] = self._seq.gray(i)
        return self._gray[i]

    def depth(self, i: int) -> np.ndarray | None:
        if i not in self._depth:
            self._depth[i] = self._seq.depth(i)
        return self._depth[i]

    def image(self, i: int) -> np.ndarray:
        return self._seq.image(i)


def tracker_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The tracker comparison as a Markdown table."""
    head = (
        '| condition | photometric | tracks at frame 29 | track error px (median) | '
        'tracks > 2 px | pairs with median error > 2 px | E_t median | E_t p90 | '
        'rotation median deg | rotation p90 deg | '
        'depth error median | bad seeds (E_t >= 0.2 or rot >= 1 deg) | tracking ms/frame | '
        'frames remapped |'
    )
    lines = [head, '|' + '---|' * 14]
    for r in rows:
        lines.append(
            f'| {r["condition"]} | {r["mode"]} | {r["tracks_end"]:.0f} | '
            f'{r["track_err_px"]:.2f} | {100 * r["far_share"]:.1f} % | '
            f'{100 * r["lost_pairs"]:.1f} % | {r["et_median"]:.3f} | '
            f'{r["et_p90"]:.3f} | {r["rot_median"]:.2f} | {r["rot_p90"]:.2f} | '
            f'{100 * r["depth_err_median"]:.1f} % | {100 * r["bad_share"]:.1f} % | '
            f'{1e3 * r["seconds_per_frame"]:.1f} | {100 * r["remaps"]:.0f} % |'
        )
    return '\n'.join(lines) + '\n'


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
    from initsel_ros.learn.pairs import DatasetConfig, batch_ranges, label_sequence_batch

    config = config or DatasetConfig(batch=30, jobs=1)
    rows = []
    for b, frames in enumerate(batch_ranges(len(sequence), config.batch, config.stride)):
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


# ----------------------------------------------------------------------------- comparison
def _is_model(row: Mapping[str, Any]) -> bool:
    return row['kind'] == 'model'


def _num(v: Any) -> str:
    v = float(v)
    return '-' if math.isnan(v) else f'{v:.2f}'


def _pr(row: Mapping[str, Any], m: str) -> str:
    p, r = float(row[f'{m}_precision']), float(row[f'{m}_recall'])
    if math.isnan(p) and math.isnan(r):
        return '-'
    return f'{_num(p)} / {_num(r)}'


def comparison_markdown(rows: Sequence[Mapping[str, Any]], choice: str = '') -> str:
    """The comparison of :func:`compare_models` as Markdown: one row per effect x strength x
    system, then ``choice`` (the explanation of :func:`choose_model`) if given."""
    models = list(dict.fromkeys(r['system'] for r in rows if _is_model(r)))
    lines = [
        f'Model files: {", ".join(f"`{m}`" for m in models) or "none"}; P / R: precision / '
        'recall of F, E, H (after the R veto for the model files) and of R; baselines have '
        "no R, and '-' where they have no such method.",
        '',
        '| effect | strength | system | pairs | F P / R | E P / R | H P / R | R P / R | '
        'first yes good | false yes, baseline <= 5 cm | false yes, pure pan |',
        '|' + '---|' * 11,
    ]
    for r in rows:
        lines.append(
            f'| {r["effect"]} | {r["level"]} | {r["system"]} | {r["pairs"]} | '
            + ' | '.join(_pr(r, m) for m in COLUMNS)
            + f' | {_num(r["first_yes_good"])} | {_num(r["false_yes_rotation"])} | '
            f'{_num(r["false_yes_pan"])} |'
        )
    text = '\n'.join(lines) + '\n'
    return text + (f'\n{choice.strip()}\n' if choice else '')


#: Columns of the comparison CSV.
CSV_COLUMNS = (
    'effect',
    'level',
    'system',
    'kind',
    'pairs',
    *(f'{m}_{k}' for m in COLUMNS for k in ('precision', 'recall', 'f1')),
    'first_yes_good',
    'false_yes_rotation',
    'false_yes_pan',
)


def write_comparison_csv(rows: Sequence[Mapping[str, Any]], path: Path) -> Path:
    """Every figure of the comparison as CSV (:data:`CSV_COLUMNS`, with each column's F1
    computed from P and R by :func:`f1_score`; NaN written as an empty field)."""

    def cell(v: Any) -> Any:
        if isinstance(v, float):
            return '' if math.isnan(v) else f'{v:.6g}'
        return v

    path = Path(path)
    with path.open('w', newline='') as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_COLUMNS, extrasaction='ignore')
        writer.writeheader()
        for r in rows:
            full = {
                **r,
                **{f'{m}_f1': f1_score(r[f'{m}_precision'], r[f'{m}_recall']) for m in COLUMNS},
            }
            writer.writerow({k: cell(full.get(k, math.nan)) for k in CSV_COLUMNS})
    return path


def _effects_of(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    effects = list(dict.fromkeys(r['effect'] for r in rows if r['level'] != 'clean'))
    return effects or ['none']


def _series(
    rows: Sequence[Mapping[str, Any]], effect: str, system: str, key: str
) -> tuple[list[int], list[float]]:
    """x (index in LEVELS) and y of one system's figure along the strengths of an effect;
    the clean rows (effect 'none') are shared by every effect."""
    xs, ys = [], []
    for i, level in enumerate(LEVELS):
        for r in rows:
            if (
                r['system'] == system
                and r['level'] == level
                and (level == 'clean' or r['effect'] == effect)
            ):
                v = float(r[key])
                if not math.isnan(v):
                    xs.append(i)
                    ys.append(v)
                break
    return xs, ys


def plot_comparison(rows: Sequence[Mapping[str, Any]], out_dir: Path) -> list[Path]:
    """Figures of the comparison (matplotlib, Agg).

    ``precision_<effect>.png``: precision of F, E, H (after the R veto for the model files)
    and of R against the effect's strength, one line per system (model files solid,
    baselines dashed); ``false_yes_pan.png``: the share of 'yes' on the pure pan against
    strength, one panel per effect.

    Returns:
        The written paths.
    """
    from initsel_ros.learn.plots import _pyplot

    plt = _pyplot()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    systems = list(dict.fromkeys(r['system'] for r in rows))
    model_like = {r['system'] for r in rows if _is_model(r)}
    colours = {s: plt.get_cmap('tab10')(i % 10) for i, s in enumerate(systems)}

    def draw(ax: Any, effect: str, key: str) -> None:
        for s in systems:
            xs, ys = _series(rows, effect, s, key)
            if xs:
                solid = s in model_like
                ax.plot(
                    xs,
                    ys,
                    marker='o' if solid else 's',
                    ls='-' if solid else '--',
                    lw=2.0 if solid else 1.2,
                    color=colours[s],
                    label=s,
                )
        ax.set_xticks(range(len(LEVELS)), LEVELS)
        ax.set_xlim(-0.3, len(LEVELS) - 0.7)
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel('effect strength')
        ax.grid(alpha=0.3)

    def legend(fig: Any) -> None:
        handles, labels = {}, []
        for ax in fig.axes:
            for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
                if lab not in handles:
                    handles[lab] = h
                    labels.append(lab)
        fig.legend(
            [handles[lab] for lab in labels],
            labels,
            loc='lower center',
            ncol=min(len(labels), 4),
            fontsize=8,
        )

    paths = []
    effects = _effects_of(rows)
    for effect in effects:
        fig, axes = plt.subplots(1, len(COLUMNS), figsize=(14, 4.2), sharey=True)
        for ax, m in zip(axes, COLUMNS, strict=True):
            draw(ax, effect, f'{m}_precision')
            ax.set_title(f'{m} (model files: after the R veto)' if m != 'R' else 'R (model files)')
        axes[0].set_ylabel('precision')
        fig.suptitle(
            'Precision on clean data' if effect == 'none' else f'Precision under {effect}'
        )
        legend(fig)
        fig.tight_layout(rect=(0, 0.12, 1, 1))
        path = out_dir / f'precision_{_slug(effect)}.png'
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    ncol = min(len(effects), 4)
    nrow = -(-len(effects) // ncol)
    fig, axes = plt.subplots(
        nrow, ncol, figsize=(max(3.6 * ncol, 9.0), 3.0 * nrow + 1.2), sharey=True, squeeze=False
    )
    for ax, effect in zip(axes.flat, effects, strict=False):
        draw(ax, effect, 'false_yes_pan')
        ax.set_title(effect)
    for ax in axes[:, 0]:
        ax.set_ylabel("share of 'yes' on the pure pan")
    for ax in list(axes.flat)[len(effects) :]:
        ax.set_visible(False)
    fig.suptitle("False 'yes' on the pure pan against effect strength (lower is better)")
    legend(fig)
    fig.tight_layout(rect=(0, 0.8 / (3.0 * nrow + 1.2), 1, 1))
    path = out_dir / 'false_yes_pan.png'
    fig.savefig(path, dpi=110)
    plt.close(fig)
    paths.append(path)
    return paths


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
    models = list(dict.fromkeys(r['system'] for r in rows if _is_model(r)))
    if reference not in models:
        raise ValueError(f'reference {reference!r} not among the model files {models}')

    clean = {r['system']: r for r in rows if _is_model(r) and r['level'] == 'clean'}
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
                    losses.append(f'{m} {_num(mine)} < {_num(ref)} - {max_clean_loss:g}')
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


# ----------------------------------------------------------------------------- CLI
def parse_model_args(values: Sequence[str] | None) -> dict[str, Path]:
    """``--models`` values as name -> path: ``NAME=PATH``, or a bare ``PATH`` named by its
    file stem; none: ``{'shipped': the packaged config/models.json}``.

    Raises:
        ValueError: two files with the same name.
    """
    from initsel_ros.models import default_model_path

    if not values:
        return {'shipped': Path(default_model_path())}
    out: dict[str, Path] = {}
    for value in values:
        name, sep, path = value.partition('=')
        if not sep:
            name, path = Path(value).stem, value
        if name in out:
            raise ValueError(f'model name {name!r} given twice (use NAME=PATH)')
        out[name] = Path(path)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m initsel_ros.learn.robustness tracker|models --out DIR``."""
    parser = argparse.ArgumentParser(
        prog='python -m initsel_ros.learn.robustness', description=__doc__.split('\n\n')[0]
    )
    sub = parser.add_subparsers(dest='what', required=True)
    trk = sub.add_parser('tracker', help='compare the photometric modes of the tracker')
    trk.add_argument('--out', type=Path, required=True, help='folder for the rendered sequences')
    trk.add_argument('--frames', type=int, default=120)
    trk.add_argument('--markdown', type=Path, default=None, help='also write the table here')
    mod = sub.add_parser(
        'models', help='model files and baselines per effect, and the file to ship'
    )
    mod.add_argument('--out', type=Path, required=True, help='folder for the rendered sequences')
    mod.add_argument(
        '--models',
        action='append',
        default=None,
        metavar='[NAME=]PATH',
        help='model file, repeatable; a bare PATH is named by its file stem '
        '(default: shipped=the packaged config/models.json)',
    )
    mod.add_argument(
        '--reference',
        default=None,
        help="model name the others must match on clean data (default: 'shipped' if given, "
        'else the first)',
    )
    mod.add_argument(
        '--max-clean-loss',
        type=float,
        default=0.05,
        help='largest clean-precision loss against the reference (default 0.05)',
    )
    mod.add_argument(
        '--effects',
        nargs='+',
        default=None,
        help='effects (default: every one of EFFECT_LEVELS, then all together)',
    )
    mod.add_argument('--no-baselines', action='store_true', help='model files only')
    mod.add_argument(
        '--frames',
        type=int,
        nargs=2,
        default=None,
        metavar=('NEAR', 'ROTATION'),
        help='shorter sequences for a quick look (default: 150 and 60 frames); their figures '
        'differ from the full run (a 31-frame pan is its fastest second only)',
    )
    mod.add_argument('--markdown', type=Path, default=None, help='also write the table here')
    mod.add_argument('--csv', type=Path, default=None, help='write every figure here')
    mod.add_argument('--plots', type=Path, default=None, help='folder for the PNG figures')
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    cv2.setNumThreads(1)
    if args.what == 'tracker':
        text = tracker_markdown(compare_trackers(args.out, args.frames))
    else:
        try:
            models = parse_model_args(args.models)
        except ValueError as exc:
            parser.error(str(exc))
        reference = args.reference or ('shipped' if 'shipped' in models else next(iter(models)))
        if reference not in models:
            parser.error(f'--reference {reference!r} is not one of {", ".join(models)}')
        rows = compare_models(
            args.out,
            models,
            args.effects,
            frames=tuple(args.frames) if args.frames else None,
            baselines=not args.no_baselines,
        )
        _, why = choose_model(rows, reference, args.max_clean_loss)
        text = comparison_markdown(rows, why)
        if args.csv:
            write_comparison_csv(rows, args.csv)
        if args.plots:
            try:
                plot_comparison(rows, args.plots)
            except ImportError:
                LOG.warning('matplotlib not installed (pip install initsel_ros[plot]): no plots')
    if args.markdown:
        args.markdown.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
