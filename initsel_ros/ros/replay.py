"""``initsel replay SOURCE``: publish a TUM folder or a ROS 1/2 bag as a live camera.

Publishes ``image_raw`` (rgb8 or bgr8) and ``camera_info`` with the recorded stamps at the
recorded timing times ``--rate``, and optionally the ground truth as a PoseStamped. rclpy is
imported inside :func:`run`, so ``initsel --help`` works without ROS.
"""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.errors import ConfigError

log = logging.getLogger(__name__)

#: Seconds to keep the node alive after the last frame so reliable messages get delivered.
LINGER_S = 0.5


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel replay``."""
    parser.add_argument('source', type=Path,
                        help='TUM folder (rgb.txt), ROS 1 .bag file or ROS 2 bag folder')
    parser.add_argument('--rate', type=float, default=1.0,
                        help='playback speed factor of the recorded timing (default 1)')
    parser.add_argument('--loop', action='store_true', help='start over at the end, until ^C')
    parser.add_argument('--start', type=float, default=0.0,
                        help='skip this many seconds from the first frame (default 0)')
    parser.add_argument('--duration', type=float, default=None,
                        help='publish only this many seconds of the recording')
    parser.add_argument('--encoding', choices=('rgb8', 'bgr8'), default='rgb8',
                        help='image encoding (default rgb8)')
    parser.add_argument('--image-topic', default='image_raw', help='default image_raw')
    parser.add_argument('--camera-info-topic', default='camera_info', help='default camera_info')
    parser.add_argument('--frame-id', default='camera_optical_frame',
                        help='frame id of images and camera_info (default camera_optical_frame)')
    parser.add_argument('--publish-groundtruth', action='store_true',
                        help='also publish the ground-truth camera-to-world pose (PoseStamped)')
    parser.add_argument('--groundtruth-topic', default='groundtruth/pose',
                        help='default groundtruth/pose')
    parser.add_argument('--world-frame-id', default='world',
                        help='frame id of the ground-truth poses (default world)')
    parser.add_argument('--restamp', action='store_true',
                        help='stamp messages with the current time instead of the recorded one')
    parser.add_argument('--wait-for-subscriber', type=float, default=0.0, metavar='SECONDS',
                        help='wait up to this long for a subscriber on the image topic first')
    parser.add_argument('--node-name', default='initsel_replay', help='default initsel_replay')


@dataclass(frozen=True)
class ReplayPlan:
    """Which frames to publish and when.

    Attributes:
        indices: (K,) frame indices in publication order (one pass).
        offsets: (K,) seconds after the start of a pass at which each is due (rate applied).
        period: seconds of one pass, for looping (last offset plus one mean frame interval).
    """

    indices: np.ndarray
    offsets: np.ndarray
    period: float


def plan_replay(
    stamps: np.ndarray, *, rate: float = 1.0, start: float = 0.0, duration: float | None = None
) -> ReplayPlan:
    """Select frames in ``[t0 + start, t0 + start + duration)`` and schedule them.

    Args:
        stamps: (N,) recorded frame times, seconds, non-decreasing.
        rate: speed factor (> 0).
        start: seconds skipped from the first frame (>= 0).
        duration: seconds to publish, or None for the rest.

    Raises:
        ConfigError: bad rate, start or duration, or no frame in the window.
    """
    stamps = np.asarray(stamps, dtype=np.float64)
    if not rate > 0:
        raise ConfigError(f'--rate must be positive, got {rate}')
    if start < 0 or (duration is not None and duration <= 0):
        raise ConfigError(f'--start must be >= 0 and --duration > 0, got {start}, {duration}')
    if stamps.size == 0:
        raise ConfigError('the sequence has no frames')
    begin = stamps[0] + start
    end = np.inf if duration is None else begin + duration
    indices = np.flatnonzero((stamps >= begin) & (stamps < end))
    if indices.size == 0:
        raise ConfigError(
            f'no frame between {start} s and {start + (duration or 0)} s of a '
            f'{stamps[-1] - stamps[0]:.1f} s recording'
        )
    selected = stamps[indices]
    offsets = (selected - selected[0]) / rate
    step = float(np.mean(np.diff(offsets))) if offsets.size > 1 else 1.0 / (30.0 * rate)
    return ReplayPlan(indices, offsets, float(offsets[-1] + step))


def run(args: argparse.Namespace) -> int:
    """Publish the sequence; prints the number of frames published. 0 on success."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo, Image
    from std_msgs.msg import Header

    from initsel_ros.datasets import open_sequence
    from initsel_ros.ros import conversions as conv

    sequence = open_sequence(args.source)
    plan = plan_replay(sequence.stamps, rate=args.rate, start=args.start,
                       duration=args.duration)
    info_template = conv.intrinsics_to_camera_info(sequence.intrinsics, frame_id=args.frame_id)
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)

    rclpy.init(args=[])
    node = rclpy.create_node(args.node_name)
    published = passes = 0
    started = time.monotonic()
    try:
        image_pub = node.create_publisher(Image, args.image_topic, qos)
        info_pub = node.create_publisher(CameraInfo, args.camera_info_topic, qos)
        gt_pub = (node.create_publisher(PoseStamped, args.groundtruth_topic, qos)
                  if args.publish_groundtruth else None)
        if args.wait_for_subscriber > 0 and not _wait_for_subscriber(
            node, image_pub, args.wait_for_subscriber
        ):
            log.warning('no subscriber on %s after %.1f s; publishing anyway',
                        image_pub.topic_name, args.wait_for_subscriber)
        log.info('replaying %s: %d frames at rate %g on %s (%s) and %s', sequence.name,
                 plan.indices.size, args.rate, image_pub.topic_name, args.encoding,
                 info_pub.topic_name)
        started = time.monotonic()
        while rclpy.ok():
            pass_start = started + passes * plan.period
            for index, offset in zip(plan.indices, plan.offsets, strict=True):
                if not _sleep_until(pass_start + offset):
                    break
                frame = sequence.frames[int(index)]
                bgr = sequence.image(int(index))
                if args.restamp:
                    stamp = node.get_clock().now().to_msg()
                else:
                    stamp = conv.seconds_to_stamp(frame.stamp)
                pixels = bgr if args.encoding == 'bgr8' else np.ascontiguousarray(bgr[..., ::-1])
                image = conv.numpy_to_image(pixels, args.encoding, stamp=stamp,
                                            frame_id=args.frame_id)
                info_template.header.stamp = stamp
                image_pub.publish(image)
                info_pub.publish(info_template)
                if gt_pub is not None and frame.pose is not None:
                    gt_pub.publish(_pose_message(
                        frame.pose, Header(stamp=stamp, frame_id=args.world_frame_id)))
                published += 1
            else:
                passes += 1
                if args.loop:
                    continue
            break
        if rclpy.ok():
            time.sleep(LINGER_S)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    elapsed = time.monotonic() - started
    print(f'published {published} frames of {sequence.name} in {elapsed:.1f} s '
          f'({passes} full pass{"es" if passes != 1 else ""})')
    return 0


def _wait_for_subscriber(node: object, publisher: object, timeout: float) -> bool:
    """Poll the graph until the publisher has a matched subscriber, at most ``timeout`` s."""
    import rclpy

    deadline = time.monotonic() + timeout
    while rclpy.ok() and time.monotonic() < deadline:
        if publisher.get_subscription_count() > 0:  # type: ignore[attr-defined]
            time.sleep(0.2)  # let discovery finish on the subscriber's side too
            return True
        time.sleep(0.05)
    return False


def _sleep_until(deadline: float) -> bool:
    """Sleep until ``deadline`` (monotonic s) in short steps; False once ROS shut down."""
    import rclpy

    while True:
        if not rclpy.ok():
            return False
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return True
        time.sleep(min(remaining, 0.05))


def _pose_message(T_w_c: np.ndarray, header: object) -> object:
    """PoseStamped of a (4, 4) camera-to-world matrix."""
    from geometry_msgs.msg import PoseStamped

    from initsel_ros.ros.conversions import rotation_to_quaternion

    msg = PoseStamped()
    msg.header = header
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, T_w_c[:3, 3])
    q = rotation_to_quaternion(T_w_c[:3, :3])
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = map(float, q)
    return msg


__all__ = ['ReplayPlan', 'add_arguments', 'plan_replay', 'run']
