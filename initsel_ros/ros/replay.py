"""``initsel replay SOURCE``: publish a TUM, EuRoC or KITTI folder or a ROS 1/2 bag as a camera.

Publishes ``image_raw`` (rgb8, bgr8, mono8 or as stored) or, with ``--compressed``,
``image_raw/compressed`` (sensor_msgs/CompressedImage, jpeg or png), and ``camera_info`` from
the dataset's calibration (with distortion D for EuRoC), at the recorded timing times
``--rate``, and optionally the ground truth as a PoseStamped. Header stamps are the source's
exact integer nanoseconds (``Frame.stamp_ns``). A frame larger than the Fast DDS shared-memory
segment is reported once (:class:`initsel_ros.ros.transport.OversizeMonitor`). rclpy is
imported inside :func:`run`; the options are :class:`ReplayOptions`, parsed by
:mod:`initsel_ros.cli.replay`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.image import to_8bit
from initsel_ros.ros.transport import OversizeMonitor

log = logging.getLogger(__name__)

#: Seconds to keep the node alive after the last frame so reliable messages get delivered.
LINGER_S = 0.5

#: Unreadable frames named one by one in warnings; the rest are only counted.
MAX_SKIP_WARNINGS = 5


@dataclass(frozen=True)
class ReplayOptions:
    """What one replay publishes and how: the options of ``initsel replay`` (their defaults
    and help are in :mod:`initsel_ros.cli.replay`).

    Attributes:
        source: TUM, EuRoC or KITTI folder, ROS 1 .bag file or ROS 2 bag folder.
        sequence: KITTI: the sequence, when ``source`` is the odometry root.
        camera: EuRoC and KITTI: which camera (``open_sequence``), or None for the default.
        bag_image_topic: bags: the image topic to read, or None for the default.
        intrinsics: TUM folders and bags: a YAML file of the camera's intrinsics (as
            ``intrinsics.yaml``) replacing the source's own, or None.
        rate: playback speed factor of the recorded timing.
        loop: start over at the end, until ^C.
        start: seconds skipped from the first frame.
        duration: seconds to publish, or None for the rest.
        encoding: rgb8, bgr8, mono8 or native (as stored).
        compressed: publish CompressedImage on ``<image_topic>/compressed`` instead of Image.
        compressed_format: jpeg or png.
        jpeg_quality: 0-100, with ``compressed`` jpeg.
        image_topic, camera_info_topic: where the frames and the calibration go.
        frame_id: frame id of images and camera_info.
        publish_groundtruth: also publish the ground-truth camera-to-world pose.
        groundtruth_topic, world_frame_id: its topic and frame id.
        restamp: stamp messages with the current time instead of the recorded one.
        wait_for_subscriber: seconds to wait for a subscriber on the image topic first.
        node_name: the publishing node's name.
    """

    source: Path
    sequence: str | None
    camera: str | None
    bag_image_topic: str | None
    intrinsics: Path | None
    rate: float
    loop: bool
    start: float
    duration: float | None
    encoding: str
    compressed: bool
    compressed_format: str
    jpeg_quality: int
    image_topic: str
    camera_info_topic: str
    frame_id: str
    publish_groundtruth: bool
    groundtruth_topic: str
    world_frame_id: str
    restamp: bool
    wait_for_subscriber: float
    node_name: str


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


def frame_pixels(sequence: object, index: int, encoding: str) -> tuple[np.ndarray, str]:
    """Frame ``index`` laid out for ``encoding`` ('rgb8', 'bgr8', 'mono8' or 'native'), and the
    ROS encoding name (native: mono8/mono16 for grey frames, bgr8 for colour)."""
    if encoding == 'native':
        native = sequence.native_image(index)  # type: ignore[attr-defined]
        if native.ndim == 2:
            return native, 'mono16' if native.dtype == np.uint16 else 'mono8'
        if native.dtype == np.uint16:
            native = to_8bit(native)
        return native, 'bgr8'
    if encoding == 'mono8':
        return sequence.gray(index), 'mono8'  # type: ignore[attr-defined]
    bgr = sequence.image(index)  # type: ignore[attr-defined]
    if encoding == 'bgr8':
        return bgr, 'bgr8'
    return np.ascontiguousarray(bgr[..., ::-1]), 'rgb8'


def open_source(options: ReplayOptions) -> object:
    """The sequence of ``options.source`` (with its ``sequence``, ``camera``,
    ``bag_image_topic`` and ``intrinsics``: :func:`initsel_ros.datasets.open_source`); its
    ground truth is read only when it is to be published."""
    from initsel_ros.datasets import open_source as open_dataset

    return open_dataset(
        options.source,
        sequence=options.sequence,
        camera=options.camera,
        bag_image_topic=options.bag_image_topic,
        intrinsics=options.intrinsics,
        ground_truth=options.publish_groundtruth,
    )


def run(options: ReplayOptions) -> int:
    """Publish the sequence; prints the number of frames published. 0 on success."""
    from initsel_ros.image import encode_compressed

    if not 0 <= options.jpeg_quality <= 100:
        raise ConfigError(f'--jpeg-quality must be in 0-100, got {options.jpeg_quality}')
    sequence = open_source(options)  # before rclpy: a bad source fails fast, with one line
    plan = plan_replay(
        sequence.stamps, rate=options.rate, start=options.start, duration=options.duration
    )

    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo, CompressedImage, Image
    from std_msgs.msg import Header

    from initsel_ros.ros import conversions as conv

    info_template = conv.intrinsics_to_camera_info(sequence.intrinsics, frame_id=options.frame_id)
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=5,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    shm = OversizeMonitor()  # warns once when frames exceed the Fast DDS SHM segment
    # cv2.imencode takes BGR: compressed colour frames are 'bgr8; jpeg compressed bgr8'
    layout = 'bgr8' if options.compressed and options.encoding == 'rgb8' else options.encoding

    rclpy.init(args=[])
    node = rclpy.create_node(options.node_name)
    published = passes = skipped = 0
    started = time.monotonic()
    try:
        if options.compressed:
            image_topic = f'{options.image_topic.rstrip("/")}/compressed'
            image_pub = node.create_publisher(CompressedImage, image_topic, qos)
        else:
            image_pub = node.create_publisher(Image, options.image_topic, qos)
        info_pub = node.create_publisher(CameraInfo, options.camera_info_topic, qos)
        gt_pub = (
            node.create_publisher(PoseStamped, options.groundtruth_topic, qos)
            if options.publish_groundtruth
            else None
        )
        if options.wait_for_subscriber > 0 and not _wait_for_subscriber(
            image_pub, options.wait_for_subscriber
        ):
            log.warning(
                'no subscriber on %s after %.1f s; publishing anyway',
                image_pub.topic_name,
                options.wait_for_subscriber,
            )
        kind = (
            f'{options.compressed_format} CompressedImage'
            if options.compressed
            else options.encoding
        )
        log.info(
            'replaying %s: %d frames at rate %g on %s (%s) and %s',
            sequence.name,
            plan.indices.size,
            options.rate,
            image_pub.topic_name,
            kind,
            info_pub.topic_name,
        )
        started = time.monotonic()
        while rclpy.ok():
            pass_start = started + passes * plan.period
            for index, offset in zip(plan.indices, plan.offsets, strict=True):
                if not _sleep_until(pass_start + offset):
                    break
                frame = sequence.frames[int(index)]
                if options.restamp:
                    stamp = node.get_clock().now().to_msg()
                else:
                    stamp = conv.ns_to_stamp(frame.stamp_ns)
                try:
                    pixels, encoding = frame_pixels(sequence, int(index), layout)
                except DatasetError as exc:  # a camera drops a frame; the replay goes on
                    skipped += 1
                    if skipped <= MAX_SKIP_WARNINGS:
                        log.warning('frame %d not published: %s', int(index), exc)
                    continue
                if options.compressed:
                    message = CompressedImage()
                    message.header = Header(stamp=stamp, frame_id=options.frame_id)
                    message.data, message.format = encode_compressed(
                        pixels, options.compressed_format, options.jpeg_quality
                    )
                else:
                    message = conv.numpy_to_image(
                        pixels, encoding, stamp=stamp, frame_id=options.frame_id
                    )
                shm.check(len(message.data), image_pub.topic_name)
                info_template.header.stamp = stamp
                info_pub.publish(info_template)  # first: a subscriber has it for the frame
                image_pub.publish(message)
                if gt_pub is not None and frame.pose is not None:
                    world = Header(stamp=stamp, frame_id=options.world_frame_id)
                    T_w_c = frame.pose  # camera-to-world
                    gt_pub.publish(conv.pose_stamped(T_w_c[:3, :3], T_w_c[:3, 3], world))
                published += 1
            else:
                passes += 1
                if options.loop and published:  # (a pass of unreadable frames only: stop)
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
    print(
        f'published {published} frames of {sequence.name} in {elapsed:.1f} s '
        f'({passes} full pass{"es" if passes != 1 else ""})'
        + (f'; {skipped} unreadable frames skipped' if skipped else '')
    )
    return 0 if published else 1


def _wait_for_subscriber(publisher: object, timeout: float) -> bool:
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


__all__ = [
    'ReplayOptions',
    'ReplayPlan',
    'frame_pixels',
    'open_source',
    'plan_replay',
    'run',
]
