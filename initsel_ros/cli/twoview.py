"""``initsel twoview``: a pair table of random two-view geometries (distillation pairs)."""

from __future__ import annotations

import argparse

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel twoview``."""
    parser.add_argument(
        '--out', required=True, type=options.output_file, help='output CSV (pair table)'
    )
    parser.add_argument(
        '--pairs',
        type=options.whole_number(1),
        default=6000,
        help='pairs per seed (default 6000)',
    )
    parser.add_argument(
        '--seed',
        type=int,
        nargs='+',
        default=[0],
        help='random seeds, one sequence of --pairs pairs each (default 0)',
    )
    parser.add_argument(
        '--width', type=options.whole_number(16), default=640, help='image width (default 640)'
    )
    parser.add_argument(
        '--height', type=options.whole_number(16), default=480, help='image height (default 480)'
    )


def run(args: argparse.Namespace) -> int:
    """Draw the pairs and write the table."""
    from initsel_ros.learn.table import PairTable, write_table
    from initsel_ros.learn.twoview import twoview_table

    tables = [twoview_table(args.pairs, s, args.width, args.height) for s in args.seed]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_table(PairTable.concat(tables), args.out)
    print(f'{args.out}: {args.pairs * len(args.seed)} random two-view pairs (no labels)')
    return 0
