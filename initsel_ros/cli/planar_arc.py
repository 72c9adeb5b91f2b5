"""``initsel planar_arc``: issue 20's planar-arc family against its oracle frames."""

from __future__ import annotations

import argparse

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


def run(args: argparse.Namespace) -> int:
    """Evaluate the sequences, print the table and write it."""
    from initsel_ros.learn.planar_arc import evaluate_arcs, write_outputs

    config = options.selector_config(args, 'planar_arc')
    if config is None:
        return 2
    outcomes = evaluate_arcs(
        args.sequences, options.model_path(args.models), config, jobs=args.jobs
    )
    print(write_outputs(outcomes, args.out_dir))
    return 0
