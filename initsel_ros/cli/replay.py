"""``initsel replay SOURCE``: publish a TUM, EuRoC or KITTI folder or a ROS 1/2 bag as a camera.

The publishing loop is :func:`initsel_ros.ros.replay.run`; rclpy is imported only there.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel replay``."""
    parser.add_argument(
        'source',
        type=Path,
        help='TUM folder (rgb.txt), EuRoC folder (holding mav0, or mav0), KITTI '
        'odometry sequence folder (or root with --sequence), ROS 1 .bag '
        'file or ROS 2 bag folder',
    )
    options.add_kitti_sequence_option(
        parser, 'KITTI: the sequence, when SOURCE is the odometry root'
    )
    options.add_bag_image_topic_option(parser)
    options.add_camera_option(parser)
    options.add_intrinsics_option(parser)
    options.add_rate_option(parser, 'playback speed factor of the recorded timing (default 1)')
    parser.add_argument('--loop', action='store_true', help='start over at the end, until ^C')
    parser.add_argument(
        '--start',
        type=float,
        default=0.0,
        help='skip this many seconds from the first frame (default 0)',
    )
    parser.add_argument(
        '--duration',
        type=float,
        default=None,
        help='publish only this many seconds of the recording',
    )
    parser.add_argument(
        '--encoding',
        choices=('rgb8', 'bgr8', 'mono8', 'native'),
        default='rgb8',
        help='image encoding (default rgb8); native = as stored: mono8 or '
        'mono16 for grey sources (EuRoC, KITTI, 16-bit PNGs), else bgr8',
    )
    parser.add_argument(
        '--compressed',
        action='store_true',
        help='publish sensor_msgs/CompressedImage on <image topic>/compressed '
        'instead of Image (same stamps and timing; colour is encoded '
        'from bgr8, grey from mono8 or mono16)',
    )
    parser.add_argument(
        '--compressed-format',
        choices=('jpeg', 'png'),
        default='jpeg',
        help='with --compressed (default jpeg; 16-bit images are always png)',
    )
    parser.add_argument(
        '--jpeg-quality',
        type=int,
        default=90,
        metavar='0-100',
        help='with --compressed jpeg (default 90)',
    )
    parser.add_argument('--image-topic', default='image_raw', help='default image_raw')
    parser.add_argument('--camera-info-topic', default='camera_info', help='default camera_info')
    parser.add_argument(
        '--frame-id',
        default='camera_optical_frame',
        help='frame id of images and camera_info (default camera_optical_frame)',
    )
    parser.add_argument(
        '--publish-groundtruth',
        action='store_true',
        help='also publish the ground-truth camera-to-world pose (PoseStamped)',
    )
    parser.add_argument(
        '--groundtruth-topic', default='groundtruth/pose', help='default groundtruth/pose'
    )
    parser.add_argument(
        '--world-frame-id',
        default='world',
        help='frame id of the ground-truth poses (default world)',
    )
    parser.add_argument(
        '--restamp',
        action='store_true',
        help='stamp messages with the current time instead of the recorded one',
    )
    parser.add_argument(
        '--wait-for-subscriber',
        type=float,
        default=0.0,
        metavar='SECONDS',
        help='wait up to this long for a subscriber on the image topic first',
    )
    parser.add_argument('--node-name', default='initsel_replay', help='default initsel_replay')


def run(args: argparse.Namespace) -> int:
    """Publish the sequence (see :func:`initsel_ros.ros.replay.run`)."""
    from initsel_ros.ros.replay import ReplayOptions
    from initsel_ros.ros.replay import run as replay

    return replay(options.options_from(args, ReplayOptions))
