"""``initsel bench``: what a decision, a frame and the node cost, against the baselines.

The measurements are :mod:`initsel_ros.bench` (which imports no ROS) and, for the sections that
need the node, :mod:`initsel_ros.ros`; both are imported only when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from initsel_ros.cli import options

#: Sections of the default run, each of which ``--skip`` can leave out.
SECTIONS = ('decision', 'frame', 'node', 'core', 'memory', 'dataset')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel bench``."""
    options.add_work_option(
        parser,
        'folder for the rendered sequence (default: temporary; reused '
        'when it already holds enough frames)',
    )
    parser.add_argument('--frames', type=int, default=90, help='frames to render (default 90)')
    options.add_models_option(
        parser, 'model file (default: config/models.json, else models fitted on random features)'
    )
    parser.add_argument(
        '--repeat',
        type=int,
        default=2000,
        help='timed repetitions of the decision (default 2000; the baselines use a tenth)',
    )
    parser.add_argument(
        '--node-frames', type=int, default=150, help='frames per node replay (default 150)'
    )
    parser.add_argument(
        '--core-frames',
        type=int,
        default=300,
        help='frames of each one-core run, unpinned and pinned (default 300, at 30 Hz)',
    )
    parser.add_argument(
        '--rates',
        type=float,
        nargs='+',
        default=[30.0, 60.0],
        help='node replay rates, Hz (default 30 60)',
    )
    parser.add_argument(
        '--long', action='store_true', help='memory over 10,000 frames instead of 1,000'
    )
    parser.add_argument(
        '--memory-frames',
        type=int,
        default=None,
        help='frames for the memory run (overrides --long)',
    )
    parser.add_argument(
        '--skip', nargs='+', choices=SECTIONS, default=[], help='leave out these sections'
    )
    parser.add_argument(
        '--json', type=Path, default=None, metavar='PATH', help='also save every figure as JSON'
    )
    parser.add_argument(
        '--profile',
        action='store_true',
        help='profile the per-frame path with pyinstrument and print it',
    )
    mode = parser.add_argument_group('other modes')
    mode.add_argument(
        '--flood',
        action='store_true',
        help='flood the node with large images instead of the benchmarks',
    )
    mode.add_argument(
        '--seconds', type=float, default=30.0, help='flood duration, seconds (default 30)'
    )
    mode.add_argument(
        '--flood-rate', type=float, default=200.0, help='flood publishing rate, Hz (default 200)'
    )
    mode.add_argument(
        '--flood-size',
        default='1920x1080',
        metavar='WxH',
        help='flood image size (default 1920x1080)',
    )
    mode.add_argument(
        '--flood-encoding',
        choices=('bgr8', 'mono8'),
        default='bgr8',
        help='flood image encoding (default bgr8)',
    )
    mode.add_argument(
        '--fuzz',
        type=int,
        default=None,
        metavar='N',
        help='fuzz image conversion and the node callbacks with N examples each '
        'instead of the benchmarks',
    )
    mode.add_argument(
        '--fuzz-extreme',
        action='store_true',
        help='with --fuzz: also send CameraInfo with any finite value (1e306, 5e-324, ...)',
    )


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks (or the flood, or the fuzzers); 0 when done."""
    from initsel_ros.bench import BenchOptions
    from initsel_ros.bench import run as bench

    return bench(options.options_from(args, BenchOptions))
