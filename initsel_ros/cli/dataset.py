"""``initsel dataset``: label every pair of TUM, EuRoC or KITTI folders or bags into a CSV pair
table."""

from __future__ import annotations

import argparse
import sys

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel dataset``."""
    parser.add_argument(
        'sources',
        nargs='+',
        metavar='SOURCE',
        help='TUM folder, EuRoC folder (holding mav0), KITTI odometry sequence '
        'folder (or root with --sequence), ROS 1 .bag or ROS 2 bag, with '
        'ground truth; without depth, labels come from E_t and the '
        'rotation error',
    )
    parser.add_argument(
        '--out', required=True, type=options.output_file, help='output CSV (pair table)'
    )
    parser.add_argument(
        '--batch',
        type=int,
        default=90,
        help='frames per batch; each is paired with its first (default 90; '
        'the paper tests with 30)',
    )
    parser.add_argument(
        '--source',
        choices=('klt', 'orb'),
        default='klt',
        help='correspondences: KLT tracks through the batch, or ORB matches '
        '(sparse or distant frames) (default klt)',
    )
    options.add_jobs_option(parser, 2, 'worker processes (default 2)')
    parser.add_argument(
        '--chunk',
        type=options.whole_number(0),
        default=10,
        help='pairs per labelling task; a batch is tracked in one task and '
        'labelled in chunks across the workers (default 10; 0 = whole batch)',
    )
    parser.add_argument(
        '--executor',
        choices=('processes', 'dask'),
        default='processes',
        help='processes: a local pool of --jobs; dask: a dask.distributed '
        'cluster (pip extra "cluster") (default processes)',
    )
    parser.add_argument(
        '--scheduler',
        default=None,
        metavar='ADDRESS',
        help='dask scheduler address (default: a LocalCluster of --jobs '
        'workers on this machine); SOURCE paths must exist on the workers',
    )
    parser.add_argument(
        '--stride',
        type=options.whole_number(1),
        default=1,
        help='use every n-th frame (default 1: all)',
    )
    parser.add_argument(
        '--max-features',
        type=options.whole_number(8),
        default=300,
        help='KLT features per reference frame (default 300)',
    )
    parser.add_argument(
        '--min-tracks',
        type=options.whole_number(0),
        default=8,
        help='skip pairs with fewer correspondences (default 8)',
    )
    options.add_scale_rule_option(
        parser,
        'median',
        'E_R scale alignment feeding the labels (both are stored; default median)',
    )
    parser.add_argument(
        '--nearest-tolerance',
        type=options.non_negative_seconds,
        default=None,
        metavar='S',
        help='TUM, EuRoC, bags: frames outside the ground truth take the '
        'nearest pose within S seconds',
    )
    options.add_kitti_sequence_option(
        parser, 'KITTI: the sequence, when a SOURCE is the odometry root'
    )
    parser.add_argument(
        '--image-topic',
        default=None,
        help='bags: the image topic (Image or CompressedImage; default '
        '/camera/rgb/image_color, or <it>/compressed when absent)',
    )
    options.add_camera_option(parser)
    options.add_intrinsics_option(parser)
    parser.add_argument(
        '--no-orbslam', action='store_true', help='skip the ORB-SLAM H/F scoring baseline (faster)'
    )
    parser.add_argument(
        '--fire-path',
        action='store_true',
        help="also run the node's whole fire path on each pair (E, F and H tried): the method "
        "it publishes, or 'none', in the fire_method column (about 20 ms a pair)",
    )
    parser.add_argument('--quiet', action='store_true', help='no progress bar')


def run(args: argparse.Namespace) -> int:
    """Build the table and write it atomically."""
    import numpy as np

    from initsel_ros.camera import Intrinsics
    from initsel_ros.errors import DatasetError
    from initsel_ros.learn.build import (
        BuildStats,
        build_table,
        explain_no_pairs,
        sources_without_batches,
    )
    from initsel_ros.learn.correspondences import Source
    from initsel_ros.learn.labels import NO_DEPTH, LabelConfig, ScaleRule
    from initsel_ros.learn.pairs import DatasetConfig
    from initsel_ros.learn.table import write_table
    from initsel_ros.tracking import TrackerConfig

    config = DatasetConfig(
        batch=args.batch,
        source=Source(args.source),
        jobs=args.jobs,
        min_tracks=args.min_tracks,
        tracker=TrackerConfig(max_features=args.max_features),
        label=LabelConfig(scale_rule=ScaleRule(args.scale_rule)),
        orbslam_iterations=0 if args.no_orbslam else 200,
        stride=args.stride,
        nearest_tolerance=args.nearest_tolerance,
        sequence=args.sequence,
        camera=args.camera,
        image_topic=args.image_topic,
        intrinsics=None if args.intrinsics is None else Intrinsics.load_yaml(args.intrinsics),
        chunk=args.chunk,
        executor=args.executor,
        scheduler=args.scheduler,
        fire_path=args.fire_path,
    )
    _warn_unused_options(args)
    hopeless = sources_without_batches(args.sources, config)
    if hopeless:  # (docs/datasets.md: a source with no pair is an error; said before the work)
        raise DatasetError(f'{explain_no_pairs(hopeless, config)}; {args.out} not written')
    stats: list[BuildStats] = []
    table = build_table(args.sources, config, progress=not args.quiet, on_stats=stats.append)
    if len(table) == 0:
        raise DatasetError(f'{explain_no_pairs(args.sources, config)}; {args.out} not written')
    s = stats[0]
    labelled = set(np.asarray(table['sequence']).astype(str))
    empty = [
        src for src, name in zip(args.sources, s.sequences, strict=True) if name not in labelled
    ]
    write_table(table, args.out)
    if empty:  # found only after the work (too few correspondences): the table is kept
        raise DatasetError(
            f"{explain_no_pairs(empty, config)}; {args.out} written with the other sources' "
            f'{len(table)} pairs only'
        )
    positives = (
        ', '.join(f'{m} {int(table[f"{m}_label"].sum())}' for m in ('F', 'E', 'H'))
        + f', R {int(table["R_label"].sum())}'
    )
    no_depth = int(np.sum(np.asarray(table['scale_rule']).astype(str) == NO_DEPTH))
    if no_depth:
        positives += (
            f'; {no_depth} pairs labelled without depth (E_t and rotation error '
            f'< {config.label.rotation_error_max_deg:g} deg)'
        )
    print(
        f'{args.out}: {s.pairs} pairs from {s.batches} batches of {len(s.sequences)} '
        f'sequence(s) in {s.seconds:.1f} s ({s.pairs_per_second:.0f} pairs/s); '
        f'positives: {positives}',
        file=sys.stdout,
    )
    return 0


def _warn_unused_options(args: argparse.Namespace) -> None:
    """Say so when --image-topic, --nearest-tolerance or --sequence fits none of the sources
    (each applies to its kind only, as ``datasets.reader_options`` gives them to the readers,
    so mixed sources take them where they fit, silently)."""
    import logging

    from initsel_ros.datasets import reader_options

    given = {
        name: value
        for name, value in (
            ('image_topic', args.image_topic),
            ('nearest_tolerance', args.nearest_tolerance),
            ('sequence', args.sequence),
        )
        if value is not None
    }
    taken = set().union(*(reader_options(source, **given) for source in args.sources))
    unused = [f'--{name.replace("_", "-")}' for name in given if name not in taken]
    if unused:
        logging.getLogger(__name__).warning(
            'no source is of a kind these options apply to, so they are ignored: %s',
            ', '.join(unused),
        )
