"""``initsel synth``: render a TUM-format sequence with exact ground truth."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

SCENES = ('structure_texture', 'floor', 'zigzag', 'low_texture', 'wall', 'repeated', 'storeroom')
#: Keys of ``initsel_ros.synth.realism.EFFECT_LEVELS`` (not imported: ``--help`` stays light;
#: a test holds the two equal).
EFFECT_NAMES = (
    'motion_blur',
    'rolling_shutter',
    'exposure_ramp',
    'vignetting',
    'noise',
    'jpeg',
    'distortion',
    'low_texture',
    'repeated_texture',
    'movers',
)
TRAJECTORIES = ('near', 'far', 'rotation', 'forward', 'static', 'random', 'arc')


def _numbers(text: str, counts: tuple[int, ...], wrong_count: str) -> tuple[float, ...]:
    """Comma-separated numbers, as many as one of ``counts``; argparse's error otherwise."""
    try:
        values = tuple(float(v) for v in text.split(','))
    except ValueError as exc:
        msg = f'expected comma-separated numbers, got {text!r}'
        raise argparse.ArgumentTypeError(msg) from exc
    if len(values) not in counts:
        raise argparse.ArgumentTypeError(wrong_count)
    return values


def _coefficients(text: str) -> tuple[float, ...]:
    return _numbers(text, (4, 5, 8), 'distortion takes 4, 5 or 8 coefficients (OpenCV order)')


def _gain_ramp(text: str) -> tuple[float, ...]:
    return _numbers(text, (3, 4), 'gain ramp takes FROM,TO,SECONDS[,START]')


#: The arc geometry options, each an :class:`initsel_ros.synth.trajectories.ArcPath` field:
#: name -> (option, metavar, help).
ARC_OPTIONS: dict[str, tuple[str, str, str]] = {
    'distance': ('--arc-distance', 'M', 'start distance from the target, metres (default 3.5)'),
    'extent': (
        '--arc-extent',
        'M',
        'sideways amplitude, metres, reached at frame 75 (default 0.3)',
    ),
    'centring': (
        '--arc-centring',
        '0-1',
        'share of the rotation keeping the target centred (default 1; 0 = pure translation)',
    ),
    'elevation_deg': (
        '--arc-elevation',
        'DEG',
        'viewing elevation, degrees (default: the nominal 33; 70: from above)',
    ),
}
#: The single-effect options, each an :class:`initsel_ros.synth.effects.Effects` field:
#: name -> (type, metavar or None, help). Off unless given; a value given replaces the one
#: ``--effect`` or ``--realism`` sets.
EFFECT_OPTIONS: dict[str, tuple[Callable[[str], Any], str | None, str]] = {
    'noise': (float, None, 'Gaussian read noise sigma, grey levels (default 1.5; 0 = off)'),
    'full_well': (
        float,
        'ELECTRONS',
        'electrons at grey level 255: shot noise (default 0 = off; a small sensor: 5000-20000)',
    ),
    'blur': (float, None, 'Gaussian defocus blur sigma, pixels'),
    'exposure_time': (
        float,
        'SECONDS',
        'shutter open time: motion blur along the trajectory (e.g. 0.01)',
    ),
    'line_delay': (float, 'SECONDS', 'rolling shutter, seconds per row (e.g. 3e-5)'),
    'gain_ramp': (
        _gain_ramp,
        'FROM,TO,SECONDS[,START]',
        'linear gain ramp, e.g. 0.6,1.4,2 (auto-exposure)',
    ),
    'exposure': (float, None, 'slow random exposure changes, relative amplitude (e.g. 0.15)'),
    'vignetting': (float, None, 'fraction of the cos^4 falloff, 0-1'),
    'jpeg_quality': (int, '1-100', 'write the colour frames as JPEG of this quality'),
    'movers': (int, None, 'independently moving textured boards in front of the scene'),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel synth``."""
    parser.add_argument('--out', required=True, help='output TUM folder')
    parser.add_argument(
        '--scene',
        choices=SCENES,
        default=None,
        help="scene (default: the one an --effect names, else 'structure_texture')",
    )
    parser.add_argument('--trajectory', choices=TRAJECTORIES, default='near')
    parser.add_argument(
        '--frames',
        type=int,
        default=None,
        help='number of frames (default: all 1099 of the near trajectory)',
    )
    parser.add_argument(
        '--start', type=int, default=0, help='skip the first N frames of the trajectory'
    )
    parser.add_argument('--seed', type=int, default=0)
    arc = parser.add_argument_group(
        'arc geometry (any of these: the arc trajectory about the scene target, '
        'initsel_ros.synth.trajectories.ArcPath; none: the fixed 1.3 m, +-25 deg swing)'
    )
    for name, (flag, metavar, help_text) in ARC_OPTIONS.items():
        arc.add_argument(
            flag, type=float, default=None, metavar=metavar, dest=f'arc_{name}', help=help_text
        )
    arc.add_argument(
        '--arc-straight',
        action='store_true',
        help='slide on a straight line instead of the circle about the target',
    )
    parser.add_argument(
        '--focal-error',
        type=float,
        default=0.0,
        metavar='FRACTION',
        help='write the focal lengths this much too long into intrinsics.yaml (0.1 = 10 %%)',
    )
    parser.add_argument(
        '--bag',
        action='append',
        choices=('ros1', 'ros2'),
        default=[],
        help='also write a bag (may be given twice)',
    )
    parser.add_argument('--width', type=int, default=None, help='image width, pixels')
    parser.add_argument('--height', type=int, default=None, help='image height, pixels')
    parser.add_argument(
        '--hfov',
        type=float,
        default=None,
        metavar='DEG',
        help='horizontal field of view, degrees (default: the TUM fr3 camera, 62 deg)',
    )
    effects = parser.add_argument_group(
        'camera effects (off unless given; with --realism they replace the drawn values)'
    )
    effects.add_argument(
        '--realism',
        action='store_true',
        help='draw every effect and the distortion at random from --seed '
        '(ranges in docs/synth.md)',
    )
    effects.add_argument(
        '--effect',
        action='append',
        default=[],
        choices=EFFECT_NAMES,
        help='a named effect at --strength (initsel_ros.synth.realism.EFFECT_LEVELS; '
        'repeatable; the options below override its values)',
    )
    effects.add_argument(
        '--strength',
        choices=('default', 'strong'),
        default='default',
        help="strength of the --effect ones: 'default' (a common camera) or 'strong'",
    )
    for name, (kind, metavar, help_text) in EFFECT_OPTIONS.items():
        flag = '--' + name.replace('_', '-')
        effects.add_argument(flag, type=kind, default=None, metavar=metavar, help=help_text)
    effects.add_argument(
        '--distortion',
        type=_coefficients,
        default=(),
        help='lens distortion k1,k2,p1,p2[,k3] (OpenCV model), or k1,k2,k3,k4 with --fisheye',
    )
    effects.add_argument(
        '--fisheye',
        action='store_true',
        help='render through a fisheye (equidistant) lens: --distortion gives its k1,k2,k3,k4 '
        '(none: an f-theta lens); intrinsics.yaml and CameraInfo say so',
    )
    parser.add_argument(
        '--png-compression',
        type=int,
        default=1,
        choices=range(10),
        metavar='0-9',
        help='zlib level of the colour PNGs (default 1)',
    )
    parser.add_argument('--workers', type=int, default=2, help='PNG writer threads')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')


def run(args: argparse.Namespace) -> int:
    """Render and print the effects and the measured speed."""
    import dataclasses

    from initsel_ros.synth.effects import Effects
    from initsel_ros.synth.realism import draw_realism, effect_fields
    from initsel_ros.synth.trajectories import ArcPath
    from initsel_ros.synth.write import render

    named, named_distortion, named_scene = (
        effect_fields(args.effect, args.strength) if args.effect else ({}, (), None)
    )
    given = named | {
        name: getattr(args, name) for name in EFFECT_OPTIONS if getattr(args, name) is not None
    }
    distortion = tuple(args.distortion or ()) or named_distortion
    if args.realism:
        drawn = draw_realism(args.seed)
        effects = dataclasses.replace(drawn.effects, **given)
        distortion = distortion or (() if args.fisheye else drawn.distortion)
    else:
        effects = Effects(**given)
    arc_options = {name: getattr(args, f'arc_{name}') for name in ARC_OPTIONS}
    arc_given = {k: v for k, v in arc_options.items() if v is not None}
    arc = None
    if arc_given or args.arc_straight:
        if args.trajectory != 'arc':
            print('initsel synth: the --arc-* options need --trajectory arc', file=sys.stderr)
            return 2
        arc = ArcPath(**arc_given, straight=args.arc_straight)
    result = render(
        args.out,
        args.scene or named_scene or 'structure_texture',
        args.trajectory,
        args.frames,
        args.seed,
        width=args.width,
        height=args.height,
        distortion=distortion,
        effects=effects,
        bags=tuple(args.bag),
        png_compression=args.png_compression,
        workers=args.workers,
        progress=not args.no_progress,
        start=args.start,
        realism=args.realism,
        arc=arc,
        focal_error=args.focal_error,
        hfov_deg=args.hfov,
        fisheye=args.fisheye,
    )
    changed = {k: v for k, v in result.effects.to_dict().items() if v != Effects().to_dict()[k]}
    print(
        'effects: '
        + (', '.join(f'{k}={v}' for k, v in changed.items()) or 'none')
        + (f', distortion={list(result.distortion)}' if result.distortion else '')
        + (' (fisheye)' if args.fisheye else '')
    )
    print(
        f'{result.path}: {result.frames} frames, {result.seconds:.1f} s, '
        f'{result.fps:.1f} frames/s (rendering + image writing)'
    )
    for bag in result.bags:
        print(f'bag: {bag}')
    return 0
