"""``initsel demo``: render a sequence, run the selector on it live, and check it against truth.

The work is :mod:`initsel_ros.demo` (offline run, judging, report) and
:mod:`initsel_ros.ros.demo_live` (the live node), imported only when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from initsel_ros.cli import options
from initsel_ros.names import Mode


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel demo``."""
    options.add_work_option(
        parser,
        'folder for the rendered sequence (default: a temporary folder, '
        'removed afterwards); reused when it already holds enough frames',
    )
    options.add_source_option(parser, 'use this TUM folder or bag instead of rendering one')
    parser.add_argument('--frames', type=int, default=240, help='frames to render and play')
    parser.add_argument('--scene', default='structure_texture', help='scene to render')
    parser.add_argument('--trajectory', default='near', help='camera trajectory to render')
    parser.add_argument('--seed', type=int, default=0, help='rendering seed')
    options.add_mode_option(
        parser,
        Mode.ONCE,
        'stop after the first initialization (default), or re-anchor after each and judge '
        'every one',
    )
    options.add_models_option(parser)
    options.add_rate_option(parser, 'playback speed factor for the live run (1 = 30 Hz)')
    parser.add_argument(
        '--offline', action='store_true', help='run the selector directly, without ROS 2'
    )
    parser.add_argument(
        '--compressed',
        action='store_true',
        help='publish JPEG sensor_msgs/CompressedImage on image_raw/compressed '
        '(node parameter image_transport:=compressed)',
    )
    parser.add_argument(
        '--jpeg-quality', type=int, default=95, help='JPEG quality with --compressed (default 95)'
    )


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 when the first initialization (the one a SLAM system keeps) is good."""
    import shutil
    import tempfile

    from initsel_ros.demo import prepare_sequence, print_report, run_offline
    from initsel_ros.errors import InitselError
    from initsel_ros.models import ModelSet

    models_file = options.model_path(args.models)
    models = ModelSet.load(models_file)
    work = args.work
    temporary = work is None
    if temporary:
        work = Path(tempfile.mkdtemp(prefix='initsel-demo-'))
    try:
        seq = prepare_sequence(
            Path(work),
            args.source,
            scene=args.scene,
            trajectory=args.trajectory,
            seed=args.seed,
            frames=args.frames,
        )
        frames = min(args.frames, len(seq))
        live = not args.offline
        if live:
            from initsel_ros.ros import ros_available

            if not ros_available():
                print('rclpy is not importable: running offline (pip install -e ".[ros]")')
                live = False
        print(f'model file: {models_file}')
        transport = ', compressed (JPEG)' if live and args.compressed else ''
        print(
            f'running the selector {"live (ROS 2 node)" if live else "offline"} on '
            f'{seq.name}: {frames} frames, mode {args.mode}{transport}'
        )
        if live:
            from initsel_ros.ros.demo_live import run_live

            records, reasons = run_live(
                seq, args.models, args.mode, frames, args.rate, args.compressed, args.jpeg_quality
            )
        else:
            records, reasons = run_offline(seq, models, args.mode, frames)
        print_report(records, reasons, frames)
        if not records:
            raise InitselError('the selector never initialized on this sequence')
        return 0 if records[0].good else 1
    finally:
        if temporary:
            shutil.rmtree(work, ignore_errors=True)
