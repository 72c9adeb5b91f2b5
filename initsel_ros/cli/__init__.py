"""The ``initsel`` command: a thin front end over the library's subcommands.

Each subcommand is one module of this package exposing ``add_arguments(parser)`` and
``run(args) -> int``. These modules import only the standard library and
:mod:`initsel_ros.names` at module level: the work (OpenCV, scikit-learn, rclpy) is imported
inside ``run``, so ``initsel --help`` and ``initsel SUB --help`` stay light. A subcommand module
that fails to import is an error (:class:`SubcommandImportError`), never silently left out.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from initsel_ros.errors import InitselError

#: subcommand -> (module, one-line help).
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    'synth': ('initsel_ros.cli.synth', 'render a TUM-format sequence with exact ground truth'),
    'dataset': ('initsel_ros.cli.dataset', 'label pairs of TUM, EuRoC, KITTI, bag sources'),
    'twoview': (
        'initsel_ros.cli.twoview',
        'random two-view pairs without images or labels, to distill on',
    ),
    'train': ('initsel_ros.cli.train', 'train the F/E/H/R models into a model file'),
    'eval': ('initsel_ros.cli.eval', "print the paper's tables against the baselines"),
    'seedmap': (
        'initsel_ros.cli.seedmap',
        'accuracy of the published seed map against the baselines',
    ),
    'planar_arc': (
        'initsel_ros.cli.planar_arc',
        "issue 20's planes from sideways arcs against their oracle frames",
    ),
    'orbvocab': (
        'initsel_ros.cli.orbvocab',
        'train the substitute ORB vocabulary the real ORB-SLAM3 baseline loads',
    ),
    'replay': ('initsel_ros.cli.replay', 'publish a TUM, EuRoC, KITTI folder or bag as a camera'),
    'bench': ('initsel_ros.cli.bench', 'measure decision, per-frame and baseline costs'),
    'demo': ('initsel_ros.cli.demo', 'render a sequence and initialize on it, end to end'),
    'pictures': ('initsel_ros.cli.pictures', 'overlay videos, probability plots, README pictures'),
    'trace': (
        'initsel_ros.cli.trace',
        "what the selector did on a recorded sequence, frame by frame (~/status's records)",
    ),
    'robustness': (
        'initsel_ros.cli.robustness',
        'the tracker under brightness changes; model files under camera effects',
    ),
}


class SubcommandImportError(InitselError):
    """A subcommand's module cannot be imported (a broken install or a bug)."""


def build_parser() -> argparse.ArgumentParser:
    """The argparse tree of every subcommand.

    Raises:
        SubcommandImportError: a subcommand's module fails to import.
    """
    parser = argparse.ArgumentParser(
        prog='initsel', description='initsel_ros offline tools (the live node is `selector`).'
    )
    parser.add_argument('-v', '--verbose', action='store_true', help='log debug messages')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            msg = f'subcommand {name!r}: cannot import {module_name}: {exc}'
            raise SubcommandImportError(msg) from exc
        sub_parser = sub.add_parser(name, help=help_text, description=help_text)
        module.add_arguments(sub_parser)
        sub_parser.set_defaults(run=module.run, parser=sub_parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: parse, run the subcommand, map known errors to one line and exit 1."""
    try:
        parser = build_parser()
    except SubcommandImportError as exc:
        print(f'initsel: error: {exc}', file=sys.stderr)
        return 1
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # said by the subcommand's parser: its usage, not the top level's
        getattr(args, 'parser', parser).error(f'unrecognized arguments: {" ".join(unknown)}')
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


__all__ = ['SUBCOMMANDS', 'SubcommandImportError', 'build_parser', 'main']


if __name__ == '__main__':
    sys.exit(main())
