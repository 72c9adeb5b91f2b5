"""``initsel planar_arc``: issue 20's planar-arc family against its oracle frames."""

from __future__ import annotations

import argparse
from pathlib import Path

from initsel_ros.cli.options import add_inputs_argument, add_models_option, model_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel planar_arc``."""
    add_inputs_argument(
        parser,
        'sequences',
        'SEQUENCE',
        "rendered sequences (scripts/planar_arc.sh); names starting 'rotation' or "
        "'static' must not initialize",
    )
    add_models_option(parser)
    parser.add_argument(
        '--out-dir', type=Path, required=True, help='write planar_arc.md and planar_arc.csv'
    )
    parser.add_argument('--jobs', type=int, default=1, help='worker processes')


def run(args: argparse.Namespace) -> int:
    """Evaluate the sequences, print the table and write it."""
    from initsel_ros.learn.planar_arc import evaluate_arcs, write_outputs

    outcomes = evaluate_arcs(args.sequences, model_path(args.models), jobs=args.jobs)
    print(write_outputs(outcomes, args.out_dir))
    return 0
