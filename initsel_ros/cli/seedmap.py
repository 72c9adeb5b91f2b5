"""``initsel seedmap``: accuracy of the published seed map, selector against the baselines."""

from __future__ import annotations

import argparse
import sys

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel seedmap``."""
    options.add_inputs_argument(
        parser,
        'sequences',
        'SEQUENCE',
        'sequences with ground truth (TUM, EuRoC and KITTI sequence folders, bags; the depth '
        'error needs depth); grouped by --group, '
        "else by name: 'rotation' or 'static' -> rotation/static, 'wall', 'floor' or "
        "'planar' -> planar, anything else non-planar",
    )
    parser.add_argument(
        '--group',
        action='append',
        default=[],
        metavar='SEQUENCE=GROUP',
        help='put a sequence (its path as given, or its folder name) in a table group: '
        'planar, non-planar or rotation/static (repeatable; overrides the name rule)',
    )
    options.add_models_option(parser)
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
        '--baselines',
        default='rules',
        metavar='LIST',
        help='comma-separated baselines beside initsel: rules (ORB-SLAM2/3, VINS-Mono, Butt '
        '2020 rules, re-implemented), colmap (pycolmap two-view geometry on the same tracks), '
        'orbslam3 (the real ORB-SLAM3, from scripts/setup_orbslam3.sh) (default rules)',
    )
    options.add_orbslam3_options(parser)
    parser.add_argument(
        '--sensor-noise',
        type=float,
        default=0.0,
        metavar='GREY',
        help='Gaussian noise added to every frame, grey levels (default 0: none)',
    )
    parser.add_argument(
        '--noise-seed',
        type=int,
        nargs='+',
        default=[0],
        metavar='SEED',
        help='seeds of the sensor noise; with several, every batch runs once per seed and '
        'the table pools them (default 0)',
    )
    options.add_params_file_option(parser)
    parser.add_argument(
        '--min-rotation-residual-sigma',
        type=float,
        default=None,
        metavar='RATIO',
        help="override the policy's min_rotation_residual_sigma (H alone is still tried from "
        'min_plane_residual_sigma, 2 by default; set that in a --params-file)',
    )
    parser.add_argument(
        '--nearest-tolerance',
        type=options.non_negative_seconds,
        default=None,
        metavar='S',
        help='TUM, EuRoC, bags: frames outside the ground truth take the nearest pose within S '
        'seconds (as initsel dataset)',
    )
    options.add_kitti_sequence_option(
        parser, 'KITTI: the sequence, when a SEQUENCE is the odometry root (as initsel dataset)'
    )
    parser.add_argument(
        '--image-topic',
        default=None,
        help='bags: the image topic (Image or CompressedImage; default '
        '/camera/rgb/image_color, or <it>/compressed when absent; as initsel dataset)',
    )
    options.add_jobs_option(parser, 2)
    options.add_out_dir_option(
        parser, 'write seedmap.md and seedmap.csv (one row per batch and system)'
    )


def run(args: argparse.Namespace) -> int:
    """Evaluate and print the table."""
    from dataclasses import replace

    from tqdm import tqdm

    from initsel_ros.errors import ConfigError
    from initsel_ros.learn.seedmap import (
        evaluate_sequences,
        outcomes_csv,
        summarize,
        summary_markdown,
    )

    config = options.selector_config(args, 'seedmap')
    if config is None:
        return 2
    if args.no_refine:
        config = replace(config, refine=False)
    if args.min_rotation_residual_sigma is not None:
        config = replace(
            config,
            policy=replace(
                config.policy, min_rotation_residual_sigma=args.min_rotation_residual_sigma
            ),
        )
    if args.r_veto is not None:
        config = replace(config, policy=replace(config.policy, r_veto=frozenset(args.r_veto)))
    if args.verify_frames is not None:
        config = replace(config, verify=replace(config.verify, frames=args.verify_frames))
    try:
        baselines = baseline_options(args)
        groups = parse_groups(args.group)
    except (ValueError, ConfigError) as exc:
        print(f'initsel seedmap: error: {exc}', file=sys.stderr)
        return 2

    with tqdm(desc='batches', unit='batch', disable=None) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        outcomes = evaluate_sequences(
            args.sequences,
            options.model_path(args.models),
            config,
            length=args.length,
            step=args.step,
            jobs=args.jobs,
            baselines=baselines,
            groups=groups,
            noise_seeds=args.noise_seed,
            progress=progress,
            nearest_tolerance=args.nearest_tolerance,
            image_topic=args.image_topic,
            kitti_sequence=args.sequence,
        )
    table = summary_markdown(summarize(outcomes))
    print(table)
    if args.out_dir is not None:
        args.out_dir.mkdir(parents=True, exist_ok=True)
        (args.out_dir / 'seedmap.md').write_text(table + '\n')
        outcomes_csv(outcomes, args.out_dir / 'seedmap.csv')
    return 0


def parse_groups(items: list[str]) -> dict[str, str]:
    """``SEQUENCE=GROUP`` items -> mapping.

    Raises:
        ValueError: an item is not ``SEQUENCE=GROUP`` or names an unknown group.
    """
    from initsel_ros.learn.seedmap import GROUPS

    groups = {}
    for item in items:
        name, sep, group = item.rpartition('=')
        if not sep or not name:
            raise ValueError(f'--group {item!r}: expected SEQUENCE=GROUP')
        if group not in GROUPS:
            raise ValueError(f'--group {item!r}: the group is one of {", ".join(GROUPS)}')
        groups[name] = group
    return groups


def baseline_options(args: argparse.Namespace):
    """The baselines to run, from --no-baselines / --baselines and the ORB-SLAM3 options.

    Raises:
        ValueError: an unknown baseline or bad noise.
        ConfigError: ORB-SLAM3 asked for but its venv or vocabulary is missing.
    """
    from initsel_ros.errors import ConfigError
    from initsel_ros.learn.seedmap import BaselineOptions

    names = () if args.no_baselines else tuple(n for n in args.baselines.split(',') if n)
    setup = None
    if 'orbslam3' in names:
        setup = options.orbslam3_setup(args)
    if 'colmap' in names:
        try:
            import pycolmap  # noqa: F401
        except ImportError as exc:
            msg = f"baseline 'colmap' needs pycolmap ({exc}): pip install -e '.[test]'"
            raise ConfigError(msg) from exc
    return BaselineOptions(names, setup, args.sensor_noise, args.noise_seed[0])
