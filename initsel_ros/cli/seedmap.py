"""``initsel seedmap``: accuracy of the published seed map, selector against the baselines."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from initsel_ros.cli.options import add_models_option, model_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel seedmap``."""
    parser.add_argument(
        'sequences',
        nargs='+',
        type=Path,
        metavar='SEQUENCE',
        help='sequences with ground truth and depth (TUM folders, bags); a '
        "name containing 'wall', 'floor' or 'planar' counts as planar",
    )
    add_models_option(parser)
    parser.add_argument(
        '--length',
        type=int,
        default=60,
        help='frames per batch; the selector starts fresh at each (default 60)',
    )
    parser.add_argument('--step', type=int, default=30, help='frames between batch starts')
    parser.add_argument(
        '--verify-frames',
        type=int,
        default=None,
        help="override the selector's verification frames (0 = off)",
    )
    parser.add_argument('--no-refine', action='store_true', help='turn the refinement off')
    parser.add_argument(
        '--r-veto',
        nargs='*',
        default=None,
        metavar='MODEL',
        choices=('F', 'E', 'H'),
        help="models silenced when model R fires (default: the selector's)",
    )
    parser.add_argument('--no-baselines', action='store_true', help='the selector only')
    parser.add_argument(
        '--min-rotation-residual',
        type=float,
        default=None,
        metavar='PX',
        help="override the policy's min_rotation_residual_px",
    )
    parser.add_argument('--jobs', type=int, default=2, help='worker processes')
    parser.add_argument(
        '--out-dir',
        type=Path,
        default=None,
        help='write seedmap.md and seedmap.csv (one row per batch and system)',
    )


def run(args: argparse.Namespace) -> int:
    """Evaluate and print the table."""
    from dataclasses import replace

    from initsel_ros.learn.seedmap import (
        evaluate_sequences,
        outcomes_csv,
        summarize,
        summary_markdown,
    )
    from initsel_ros.selector import SelectorConfig

    config = SelectorConfig(refine=not args.no_refine)
    if args.min_rotation_residual is not None:
        config = replace(
            config,
            policy=replace(config.policy, min_rotation_residual_px=args.min_rotation_residual),
        )
    if args.r_veto is not None:
        config = replace(config, policy=replace(config.policy, r_veto=frozenset(args.r_veto)))
    if args.verify_frames is not None:
        config = replace(config, verify=replace(config.verify, frames=args.verify_frames))

    def progress(done: int, total: int) -> None:
        print(f'\rbatches {done}/{total}', end='', file=sys.stderr, flush=True)

    outcomes = evaluate_sequences(
        args.sequences,
        model_path(args.models),
        config,
        length=args.length,
        step=args.step,
        jobs=args.jobs,
        baselines=not args.no_baselines,
        progress=progress,
    )
    print(file=sys.stderr)
    table = summary_markdown(summarize(outcomes))
    print(table)
    if args.out_dir is not None:
        args.out_dir.mkdir(parents=True, exist_ok=True)
        (args.out_dir / 'seedmap.md').write_text(table + '\n')
        outcomes_csv(outcomes, args.out_dir / 'seedmap.csv')
    return 0
