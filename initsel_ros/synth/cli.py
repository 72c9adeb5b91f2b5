"""``initsel synth``: render a TUM-format sequence with exact ground truth."""

from __future__ import annotations

import argparse

SCENES = ('structure_texture', 'floor', 'zigzag', 'low_texture', 'wall')
TRAJECTORIES = ('near', 'far', 'rotation', 'forward', 'static', 'random', 'arc')


def _coefficients(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(','))
    except ValueError as exc:
        msg = f'expected comma-separated numbers, got {text!r}'
        raise argparse.ArgumentTypeError(msg) from exc
    if len(values) not in (4, 5, 8):
        raise argparse.ArgumentTypeError('distortion takes 4, 5 or 8 coefficients (OpenCV order)')
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel synth``."""
    parser.add_argument('--out', required=True, help='output TUM folder')
    parser.add_argument('--scene', choices=SCENES, default='structure_texture')
    parser.add_argument('--trajectory', choices=TRAJECTORIES, default='near')
    parser.add_argument('--frames', type=int, default=None,
                        help='number of frames (default: all 1099 of the near trajectory)')
    parser.add_argument('--start', type=int, default=0,
                        help='skip the first N frames of the trajectory')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--bag', action='append', choices=('ros1', 'ros2'), default=[],
                        help='also write a bag (may be given twice)')
    parser.add_argument('--width', type=int, default=None, help='image width, pixels')
    parser.add_argument('--height', type=int, default=None, help='image height, pixels')
    parser.add_argument('--noise', type=float, default=1.5,
                        help='Gaussian pixel noise sigma, grey levels (0 = off)')
    parser.add_argument('--blur', type=float, default=0.0, help='Gaussian blur sigma, pixels')
    parser.add_argument('--exposure', type=float, default=0.0,
                        help='slow exposure changes, relative amplitude (e.g. 0.15)')
    parser.add_argument('--distortion', type=_coefficients, default=(),
                        help='lens distortion k1,k2,p1,p2[,k3] (OpenCV model)')
    parser.add_argument('--png-compression', type=int, default=1, choices=range(10),
                        metavar='0-9', help='zlib level of the colour PNGs (default 1)')
    parser.add_argument('--workers', type=int, default=2, help='PNG writer threads')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')


def run(args: argparse.Namespace) -> int:
    """Render and print the measured speed."""
    from initsel_ros.synth.render import Effects
    from initsel_ros.synth.write import render

    result = render(
        args.out, args.scene, args.trajectory, args.frames, args.seed,
        width=args.width, height=args.height, distortion=tuple(args.distortion),
        effects=Effects(noise=args.noise, blur=args.blur, exposure=args.exposure),
        bags=tuple(args.bag), png_compression=args.png_compression, workers=args.workers,
        progress=not args.no_progress, start=args.start,
    )
    print(f'{result.path}: {result.frames} frames, {result.seconds:.1f} s, '
          f'{result.fps:.1f} frames/s (rendering + PNG writing)')
    for bag in result.bags:
        print(f'bag: {bag}')
    return 0
