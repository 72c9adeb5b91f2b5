"""``initsel pictures``: overlay videos, probability plots and the README pictures.

Default output folders are relative to the working directory. The drawing is
:mod:`initsel_ros.pictures` (OpenCV, matplotlib), imported only when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from initsel_ros.cli import options
from initsel_ros.names import Mode


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel pictures``."""
    parser.add_argument(
        '--out',
        type=Path,
        default=None,
        help='regenerate the README pictures into this folder '
        '(rotation_veto.png, initialization.png, probabilities.png; default '
        'docs/images under the working directory)',
    )
    options.add_work_option(parser, 'folder for rendered sequences (reused; default: temporary)')
    options.add_source_option(parser, 'a TUM folder or bag to draw instead of the README pictures')
    parser.add_argument(
        '--video',
        type=Path,
        default=None,
        help='with --source: overlay video (.mp4) or folder for PNG frames',
    )
    parser.add_argument(
        '--plot',
        type=Path,
        default=None,
        help='with --source: probabilities-over-time figure (.png)',
    )
    options.add_models_option(parser)
    parser.add_argument(
        '--frames',
        type=int,
        default=None,
        help='frames to process (default: all; 240 for the README pictures)',
    )
    parser.add_argument('--start', type=int, default=0, help='first frame (with --source)')
    options.add_mode_option(parser, Mode.CONTINUOUS, 'selector mode (with --source)')


def run(args: argparse.Namespace) -> int:
    """Draw what the selector saw; returns the exit code."""
    from initsel_ros.errors import ConfigError
    from initsel_ros.models import ModelSet
    from initsel_ros.pictures import (
        README_IMAGES,
        groundtruth_baselines,
        iter_overlays,
        make_readme_pictures,
        plot_probabilities,
        write_overlay_video,
    )
    from initsel_ros.selector import SelectorConfig

    models = ModelSet.load(options.model_path(args.models))
    if args.source is None:
        out = args.out or README_IMAGES
        paths = make_readme_pictures(out, args.work, models, frames=args.frames or 240)
        for p in paths:
            print(f'{p} ({p.stat().st_size // 1024} KiB)')
        return 0
    if args.video is None and args.plot is None:
        raise ConfigError('--source needs --video and/or --plot')
    from initsel_ros.datasets import open_sequence

    seq = open_sequence(args.source)
    stop = None if args.frames is None else args.start + args.frames
    config = SelectorConfig(mode=args.mode)
    if args.video is not None:
        run_ = write_overlay_video(seq, models, args.video, config, args.start, stop)
        print(f'{run_.output}: {run_.frames_written} frames')
        results, indices, thresholds = run_.results, run_.indices, run_.thresholds
    else:
        results, indices, thresholds = [], [], {}
        for i, res, _ov, sel in iter_overlays(seq, models, config, args.start, stop):
            results.append(res)
            indices.append(i)
            thresholds = dict(sel.thresholds)
    if args.plot is not None:
        baselines = groundtruth_baselines(seq, results, indices)
        print(
            plot_probabilities(results, baselines, args.plot, thresholds, indices, title=seq.name)
        )
    return 0
