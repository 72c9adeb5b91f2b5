"""``initsel trace``: what the selector did on a recorded sequence, frame by frame.

The offline twin of recording the node's ``~/status``: the same records
(:mod:`initsel_ros.trace`), without ROS, to see why a sequence initialized where it did, or
why it did not.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel trace``."""
    parser.add_argument(
        'source',
        type=Path,
        help='TUM folder (rgb.txt), EuRoC folder, KITTI odometry sequence folder (or root '
        'with --sequence), ROS 1 .bag file or ROS 2 bag folder',
    )
    options.add_kitti_sequence_option(
        parser, 'KITTI: the sequence, when SOURCE is the odometry root'
    )
    options.add_bag_image_topic_option(parser)
    options.add_camera_option(parser)
    options.add_intrinsics_option(parser)
    options.add_models_option(parser)
    options.add_params_file_option(parser)
    options.add_mode_option(
        parser,
        None,
        "what the selector does after an initialization (default: the parameter file's mode, "
        'else once)',
    )
    parser.add_argument('--start', type=int, default=0, help='first frame (default 0)')
    parser.add_argument(
        '--frames', type=int, default=None, help='frames to process (default: all)'
    )
    parser.add_argument(
        '--jsonl',
        type=Path,
        default=None,
        metavar='PATH',
        help="write every frame's ~/status record (the node's JSON, one line a frame) here",
    )
    parser.add_argument(
        '--all',
        action='store_true',
        help='print every frame, not only those where something happened (a new reference, '
        "a model's yes, a fire-path run, a verification step, an initialization, a warning)",
    )


def run(args: argparse.Namespace) -> int:
    """Run the selector over the source, print the eventful frames and a summary."""
    from initsel_ros.datasets import open_source
    from initsel_ros.models import ModelSet
    from initsel_ros.output import check_file_target
    from initsel_ros.trace import eventful, summary_line, trace_sequence

    if args.start < 0 or (args.frames is not None and args.frames < 1):
        print('initsel trace: error: --start must be >= 0 and --frames >= 1', file=sys.stderr)
        return 2
    settings = options.node_settings(args, 'trace')
    if settings is None:
        return 2
    config = settings.selector_config()
    if args.mode is not None:
        config = replace(config, mode=args.mode)
    if args.jsonl is not None:
        check_file_target(args.jsonl).parent.mkdir(parents=True, exist_ok=True)
    models = ModelSet.load(options.model_path(args.models))
    sequence = open_source(
        args.source,
        sequence=args.sequence,
        camera=args.camera,
        bag_image_topic=args.bag_image_topic,
        intrinsics=args.intrinsics,
        ground_truth=False,
    )
    stop = None if args.frames is None else args.start + args.frames
    reasons: Counter[str] = Counter()
    published: list[str] = []
    last_run = None  # (frame, record) of the last fire-path run: why a trace never published
    sink = args.jsonl.open('w', encoding='utf-8') if args.jsonl is not None else None
    try:
        for index, status in enumerate(
            trace_sequence(
                sequence, models, config, args.start, stop, settings.max_tracking_width
            ),
            start=args.start,
        ):
            reasons[status.reason.value] += 1
            if sink is not None:
                sink.write(status.to_json() + '\n')
            if status.method is not None:
                published.append(f'{status.method} at frame {index}')
            if status.rotation_test is not None or status.selection is not None:
                last_run = (index, status)
            if args.all or eventful(status):
                print(summary_line(status, index), flush=True)
    finally:
        if sink is not None:
            sink.close()
    total = sum(reasons.values())
    counts = ', '.join(f'{reason} {n}' for reason, n in reasons.most_common())
    print(f'{sequence.name}: {total} frames ({counts})')
    print(f'initialized: {"; ".join(published) if published else "never"}')
    if not published and last_run is not None:
        frame, record = last_run
        print(f'the last fire-path run, frame {frame}: {record.reason.value}: {record.detail}')
    if args.jsonl is not None:
        print(f'wrote {args.jsonl} ({total} records)')
    return 0
