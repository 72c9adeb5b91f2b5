"""The model comparison as a Markdown table, a CSV and per-effect plots."""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from initsel_ros.learn.robustness.models import (
    COLUMNS,
    LEVELS,
    f1_score,
    format_number,
    is_model_row,
    slug,
)
from initsel_ros.markdown import markdown_table


# ----------------------------------------------------------------------------- comparison
def _pr(row: Mapping[str, Any], m: str) -> str:
    p, r = float(row[f'{m}_precision']), float(row[f'{m}_recall'])
    if math.isnan(p) and math.isnan(r):
        return '-'
    return f'{format_number(p)} / {format_number(r)}'


def comparison_markdown(rows: Sequence[Mapping[str, Any]], choice: str = '') -> str:
    """The comparison of :func:`compare_models` as Markdown: one row per effect x strength x
    system, then ``choice`` (the explanation of :func:`choose_model`) if given."""
    models = list(dict.fromkeys(r['system'] for r in rows if is_model_row(r)))
    lines = [
        f'Model files: {", ".join(f"`{m}`" for m in models) or "none"}; P / R: precision / '
        'recall of F, E, H (after the R veto for the model files) and of R; baselines have '
        "no R, and '-' where they have no such method.",
        '',
    ]
    columns = ('effect', 'strength', 'system', 'pairs', *(f'{m} P / R' for m in COLUMNS))
    columns += ('first yes good', 'false yes, baseline <= 5 cm', 'false yes, pure pan')
    counts = ('first_yes_good', 'false_yes_rotation', 'false_yes_pan')
    table = markdown_table(
        columns,
        (
            [r['effect'], r['level'], r['system'], r['pairs'], *(_pr(r, m) for m in COLUMNS)]
            + [format_number(r[k]) for k in counts]
            for r in rows
        ),
    )
    text = '\n'.join([*lines, table]) + '\n'
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
    model_like = {r['system'] for r in rows if is_model_row(r)}
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
        path = out_dir / f'precision_{slug(effect)}.png'
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


__all__ = [
    'CSV_COLUMNS',
    'comparison_markdown',
    'plot_comparison',
    'write_comparison_csv',
]
