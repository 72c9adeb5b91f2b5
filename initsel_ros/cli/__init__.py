"""The ``initsel`` command: a thin front end over the library's subcommands.

Each subcommand lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; modules are imported only when their subcommand runs (or for --help).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from initsel_ros.errors import InitselError

#: subcommand -> (module, one-line help). Modules import lazily.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    'synth': ('initsel_ros.synth.cli', 'render a TUM-format sequence with exact ground truth'),
    'dataset': ('initsel_ros.learn.cli_dataset', 'label pairs of TUM, EuRoC, KITTI, bag sources'),
    'train': ('initsel_ros.learn.cli_train', 'train the F/E/H/R models into a model file'),
    'eval': ('initsel_ros.learn.cli_eval', "print the paper's tables against the baselines"),
    'seedmap': ('initsel_ros.learn.cli_seedmap',
                'accuracy of the published seed map against the baselines'),
    'replay': ('initsel_ros.ros.replay', 'publish a TUM, EuRoC, KITTI folder or bag as a camera'),
    'bench': ('initsel_ros.bench', 'measure decision, per-frame and baseline costs'),
    'demo': ('initsel_ros.demo', 'render a sequence and initialize on it, end to end'),
    'pictures': ('initsel_ros.pictures', 'overlay videos, probability plots, README pictures'),
}


def build_parser() -> argparse.ArgumentParser:
    """The argparse tree; subcommands whose module is missing are left out."""
    parser = argparse.ArgumentParser(
        prog='initsel', description='initsel_ros offline tools (the live node is `selector`).'
    )
    parser.add_argument('-v', '--verbose', action='store_true', help='log debug messages')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name and module_name.startswith(exc.name):
                continue  # not built yet or not installed
            raise
        sub_parser = sub.add_parser(name, help=help_text, description=help_text)
        module.add_arguments(sub_parser)
        sub_parser.set_defaults(run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: parse, run the subcommand, map known errors to one line and exit 1."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format='%(levelname)s %(name)s: %(message)s',
    )
    if not getattr(args, 'run', None):
        parser.print_help()
        return 2
    try:
        return int(args.run(args))
    except InitselError as exc:
        print(f'initsel {args.command}: error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
