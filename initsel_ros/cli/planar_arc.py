"""``initsel planar_arc``: issue 20's planar-arc family against its oracle frames."""

from __future__ import annotations

import argparse
import sys

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel planar_arc``."""
    options.add_inputs_argument(
        parser,
        'sequences',
        'SEQUENCE',
        "rendered sequences (scripts/planar_arc.sh); names starting 'rotation' or "
        "'static' must not initialize",
    )
    options.add_models_option(parser)
    options.add_params_file_option(parser)
    options.add_out_dir_option(parser, 'write planar_arc.md and planar_arc.csv', required=True)
    options.add_jobs_option(parser, 1)
    parser.add_argument(
        '--orbslam3',
        action='store_true',
        help='also run the real ORB-SLAM3 on every sequence (scripts/setup_orbslam3.sh makes '
        'its venv) and judge its first initialization by the same bar',
    )
    options.add_orbslam3_options(parser)


def run(args: argparse.Namespace) -> int:
    """Evaluate the sequences, print the table and write it."""
    from initsel_ros.errors import ConfigError
    from initsel_ros.learn.planar_arc import evaluate_arcs, write_outputs

    config = options.selector_config(args, 'planar_arc')
    if config is None:
        return 2
    try:
        orbslam3 = options.orbslam3_setup(args) if args.orbslam3 else None
    except ConfigError as exc:
        print(f'initsel planar_arc: {exc}', file=sys.stderr)
        return 2
    outcomes = evaluate_arcs(
        args.sequences, options.model_path(args.models), config, args.jobs, orbslam3
    )
    print(write_outputs(outcomes, args.out_dir))
    return 0
