"""Figures of an evaluation (matplotlib, Agg backend; the optional 'plot' extra).

- ``pr_<model>.png``: precision-recall curve of each model on the test pairs, the operating
  point of the model file's threshold, and the baselines as points.
- ``errors_vs_baseline.png``: median E_t and E_R per method against the ground-truth baseline
  (the paper's Figure 1).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.learn import baselines
from initsel_ros.learn.evaluate import EvalReport, binary_scores, orbslam_scored
from initsel_ros.learn.table import PairTable
from initsel_ros.learn.train import label_column
from initsel_ros.models import ModelSet
from initsel_ros.names import MODEL_NAMES, POSE_METHODS

LOG = logging.getLogger(__name__)


def _pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (optional dependency)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def _pr_curve(y: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(-scores, kind='stable')
    tp = np.cumsum(y[order])
    k = np.arange(1, len(y) + 1)
    pos = max(int(y.sum()), 1)
    return tp / pos, tp / k


def _baseline_points(test: PairTable, model: str) -> dict[str, np.ndarray]:
    points: dict[str, np.ndarray] = {}
    if model in ('F', 'H'):
        for stat in ('mean', 'median'):
            h, f = baselines.butt_rule(test[f'disp_{stat}_px'], test['disp_std_px'])
            points[f'Butt 2020 ({stat})'] = f if model == 'F' else h
        scored = orbslam_scored(test, warn=False).any()  # (evaluate has said it)
        for version in baselines.OrbSlamVersion if scored else ():
            choice = baselines.orbslam_choice(test['orb_ratio'], version)
            ok = (
                (choice == model)
                & (np.asarray(test[f'{model}_ok']) == 1)
                & (np.asarray(test[f'{model}_n_points']) >= baselines.ORB_MIN_POINTS)
                & (np.asarray(test[f'{model}_parallax_deg']) >= baselines.ORB_MIN_PARALLAX_DEG)
            )
            points[f'ORB-SLAM{version.value}'] = ok
    if model in ('E', 'F'):
        vins = baselines.vins_rule(test['n_tracks'], test['vins_parallax_px'])
        points['VINS-Mono rule'] = vins
        if model == 'E':
            points['VINS-Mono rule+RANSAC'] = vins & (np.asarray(test['vins_inliers']) > 12)
    if model == 'R':
        # disparity rules say 'no translation' when they do not fire
        h, _ = baselines.butt_rule(test['disp_mean_px'], test['disp_std_px'])
        points['Butt 2020 not H (mean)'] = ~h
    return points


def plot_precision_recall(
    test: PairTable, models: ModelSet, report: EvalReport, out_dir: Path
) -> list[Path]:
    """One PR figure per model; returns the written paths."""
    plt = _pyplot()
    paths = []
    markers = iter('osD^v<>P*X' * 3)
    for m in MODEL_NAMES:
        y = np.asarray(test[label_column(m)]).astype(bool)
        probs = report.probabilities[m]
        fig, ax = plt.subplots(figsize=(5.5, 4.5))
        if y.any():
            rec, prec = _pr_curve(y, probs)
            ax.plot(rec, prec, label=f'Model {m} ({models.models[m].kind})')
            s = binary_scores(y, probs >= models.thresholds[m])
            ax.plot([s.recall], [s.precision], 'k*', ms=12, label='model file threshold')
        for name, pred in _baseline_points(test, m).items():
            s = binary_scores(y, pred)
            ax.plot([s.recall], [s.precision], next(markers), ms=8, label=name)
        base = y.mean() if len(y) else 0.0
        ax.axhline(base, color='grey', lw=0.8, ls=':', label=f'positive rate {base:.2f}')
        ax.set_xlim(0, 1.02)
        ax.set_ylim(0, 1.02)
        ax.set_xlabel('recall')
        ax.set_ylabel('precision')
        ax.set_title(f'Model {m}: {int(y.sum())} positives of {len(y)} test pairs')
        ax.legend(fontsize=7, loc='lower left')
        fig.tight_layout()
        path = Path(out_dir) / f'pr_{m}.png'
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_errors_vs_baseline(
    table: PairTable, out_dir: Path, bins: int = 20, min_count: int = 5
) -> Path:
    """Median E_t and E_R per method against the ground-truth baseline (like Figure 1).

    Bins with fewer than ``min_count`` successful estimates are left out.
    """
    plt = _pyplot()
    baseline = np.asarray(table['gt_baseline_m'], dtype=float)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    finite = baseline[np.isfinite(baseline)]
    edges = np.linspace(0.0, float(finite.max()) if len(finite) else 1.0, bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    which = np.clip(np.digitize(baseline, edges) - 1, 0, bins - 1)
    for m in POSE_METHODS:
        for ax, col in zip(axes, (f'{m}_et', f'{m}_er'), strict=True):
            values = np.asarray(table[col], dtype=float)
            med = np.full(bins, np.nan)
            for b in range(bins):
                v = values[(which == b) & np.isfinite(values)]
                if len(v) >= min_count:
                    med[b] = np.median(v)
            ax.plot(centres, med, marker='.', label=m)
    axes[0].axhline(0.8, color='grey', ls=':', lw=0.8)
    axes[1].axhline(1.0, color='grey', ls=':', lw=0.8)
    axes[0].set_ylabel('median E_t (translation chordal error)')
    axes[1].set_ylabel('median E_R (m)')
    axes[1].set_yscale('log')
    for ax in axes:
        ax.set_xlabel('ground-truth baseline (m)')
        ax.legend()
    fig.suptitle(
        f'Pose error against baseline ({len(table)} pairs; failed estimates omitted, '
        f'bins with < {min_count} estimates omitted)'
    )
    fig.tight_layout()
    path = Path(out_dir) / 'errors_vs_baseline.png'
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_plots(
    test: PairTable, models: ModelSet, report: EvalReport, out_dir: Path
) -> list[Path]:
    """All figures into ``out_dir``; an empty list when matplotlib is not installed."""
    try:
        _pyplot()
    except ImportError:
        LOG.warning('matplotlib not installed (pip install initsel_ros[plot]): no plots')
        return []
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = plot_precision_recall(test, models, report, out_dir)
    paths.append(plot_errors_vs_baseline(test, out_dir))
    return paths


__all__ = ['plot_errors_vs_baseline', 'plot_precision_recall', 'write_plots']
