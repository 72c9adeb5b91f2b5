"""``initsel robustness``: the tracker under brightness changes; model files under effects."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from initsel_ros.cli import options

LOG = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel robustness tracker|models``."""
    sub = parser.add_subparsers(dest='what', required=True)
    trk = sub.add_parser('tracker', help='compare the photometric modes of the tracker')
    trk.add_argument('--out', type=Path, required=True, help='folder for the rendered sequences')
    trk.add_argument('--frames', type=int, default=120)
    trk.add_argument('--markdown', type=Path, default=None, help='also write the table here')
    mod = sub.add_parser(
        'models', help='model files and baselines per effect, and the file to ship'
    )
    mod.add_argument('--out', type=Path, required=True, help='folder for the rendered sequences')
    options.add_named_models_option(mod)
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


def run(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    if args.what == 'tracker':
        text = run_tracker(args.out, args.frames)
    else:
        try:
            models = options.named_model_paths(args.models)
        except ValueError as exc:
            print(f'initsel robustness: {exc}', file=sys.stderr)
            return 2
        reference = args.reference or ('shipped' if 'shipped' in models else next(iter(models)))
        if reference not in models:
            print(
                f'initsel robustness: --reference {reference!r} is not one of {", ".join(models)}',
                file=sys.stderr,
            )
            return 2
        text = run_models(
            args.out,
            models,
            reference,
            effects=args.effects,
            frames=tuple(args.frames) if args.frames else None,
            baselines=not args.no_baselines,
            max_clean_loss=args.max_clean_loss,
            csv_path=args.csv,
            plots=args.plots,
        )
    if args.markdown:
        args.markdown.write_text(text)
    sys.stdout.write(text)
    return 0


def run_tracker(out: Path, frames: int) -> str:
    """The tracker comparison's Markdown table."""
    import cv2

    from initsel_ros.learn.robustness import compare_trackers, tracker_markdown

    cv2.setNumThreads(1)
    return tracker_markdown(compare_trackers(out, frames))


def run_models(
    out: Path,
    models: dict[str, Path],
    reference: str,
    *,
    effects: list[str] | None = None,
    frames: tuple[int, int] | None = None,
    baselines: bool = True,
    max_clean_loss: float = 0.05,
    csv_path: Path | None = None,
    plots: Path | None = None,
) -> str:
    """The model comparison's Markdown table (and its CSV and plots when asked)."""
    import cv2

    from initsel_ros.learn.robustness import (
        choose_model,
        compare_models,
        comparison_markdown,
        plot_comparison,
        write_comparison_csv,
    )

    cv2.setNumThreads(1)
    rows = compare_models(out, models, effects, frames=frames, baselines=baselines)
    _, why = choose_model(rows, reference, max_clean_loss)
    if csv_path:
        write_comparison_csv(rows, csv_path)
    if plots:
        try:
            plot_comparison(rows, plots)
        except ImportError:
            LOG.warning('matplotlib not installed (pip install initsel_ros[plot]): no plots')
    return comparison_markdown(rows, why)
