"""ROS 1 and ROS 2 bags as sequences (read with rosbags' AnyReader), and bag writers.

Reading: the colour topic (rgb8/bgr8/mono8/... ``sensor_msgs/Image``, or
``sensor_msgs/CompressedImage`` jpeg/png, on the topic itself or on ``<topic>/compressed``
when the topic is absent), an optional depth topic
(32FC1 metres or 16UC1 millimetres), an optional ``CameraInfo`` topic for the intrinsics, and
ground truth from, in this order: a ``groundtruth`` file given, a ``geometry_msgs/PoseStamped``
topic (camera-to-world), a ``groundtruth.txt`` beside the bag, or ``/tf`` (the transform
``tf_parent`` -> ``tf_child``; TUM's bags publish /world -> /kinect, which is the mocap body
and not exactly the optical centre, so prefer the groundtruth.txt when you have it).
Images load lazily: the first pass records only timestamps (header stamps kept as exact
integer nanoseconds in ``Frame.stamp_ns``).

Writing (used by ``initsel synth --bag``): ``/camera/rgb/image_color`` (rgb8; or jpeg/png
``CompressedImage`` on ``/camera/rgb/image_color/compressed``),
``/camera/rgb/camera_info``, ``/camera/depth/image`` (32FC1, metres) and ``/groundtruth/pose``
(PoseStamped, camera-to-world, frame ``world``).
"""

from __future__ import annotations

import logging
import sqlite3
import struct
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from initsel_ros.camera import FISHEYE_LENGTH, Intrinsics
from initsel_ros.datasets.poses import (
    DEFAULT_MAX_GAP,
    check_trajectory,
    interpolate_poses,
    pose_matrices,
)
from initsel_ros.datasets.sequence import Sequence, paired_frames
from initsel_ros.datasets.tum import MAX_ASSOCIATION_DIFF, associate, read_trajectory
from initsel_ros.errors import ConfigError, DatasetError, ImageConversionError
from initsel_ros.image import decode_compressed, decode_raw, encode_compressed, to_cv
from initsel_ros.timestamps import ns_to_seconds, seconds_to_ns, split_ns, stamp_ns
from initsel_ros.transforms import matrix_to_pose

_LOG = logging.getLogger(__name__)

IMAGE_TOPIC = '/camera/rgb/image_color'
DEPTH_TOPIC = '/camera/depth/image'
INFO_TOPIC = '/camera/rgb/camera_info'
POSE_TOPIC = '/groundtruth/pose'
TF_TOPIC = '/tf'
CAMERA_FRAME = 'camera_rgb_optical_frame'
WORLD_FRAME = 'world'


def _read_errors() -> tuple[type[BaseException], ...]:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError

    return (
        AnyReaderError,
        Ros1ReaderError,
        Ros2ReaderError,
        OSError,
        ValueError,
        KeyError,
        IndexError,
        EOFError,
        struct.error,
        AssertionError,
        sqlite3.Error,
        MemoryError,
        OverflowError,
    )


def read_error_reason(exc: BaseException) -> str:
    """A readable reason for a reader exception (MemoryError and some others carry no text)."""
    if isinstance(exc, MemoryError):
        return (
            'a record claims more memory than is available (a corrupt length field; MemoryError)'
        )
    text = str(exc).strip()
    return text if text else type(exc).__name__


#: Message types a pose topic may carry (camera-to-world); others are ignored with a warning.
POSE_TYPES = ('PoseStamped', 'PoseWithCovarianceStamped', 'Odometry', 'TransformStamped')


def _type_name(msgtype: str) -> str:
    """'geometry_msgs/msg/PoseStamped' (or ROS 1's 'geometry_msgs/PoseStamped') ->
    'PoseStamped'."""
    return msgtype.rsplit('/', 1)[-1]


def _position_orientation(msg: Any, msgtype: str) -> tuple[Any, Any]:
    """The position and the orientation quaternion of a :data:`POSE_TYPES` message."""
    name = _type_name(msgtype)
    if name == 'TransformStamped':
        return msg.transform.translation, msg.transform.rotation
    pose = msg.pose.pose if name in ('PoseWithCovarianceStamped', 'Odometry') else msg.pose
    return pose.position, pose.orientation


def _stamp_ns(header: Any) -> int:
    return stamp_ns(header.stamp.sec, header.stamp.nanosec)


def _stamp(header: Any) -> float:
    return ns_to_seconds(_stamp_ns(header))


def _frame_stamps(
    path: Path, topic: str, header_ns: list[int], receive_ns: list[int]
) -> list[int]:
    """The frames' times: their header stamps, or the receive times when every header stamp is
    zero (a driver that does not stamp: the frames would all be at one time, replayed at once
    and given one ground-truth pose). That, header stamps out of the order of reception (the
    frames are sorted by them) and stamps repeated are said in a warning."""
    if len(header_ns) > 1 and not any(header_ns):
        _LOG.warning(
            '%s: every frame on %s has a zero header stamp: the times the bag received them '
            'are used instead',
            path,
            topic,
        )
        return list(receive_ns)
    in_reception = np.asarray(header_ns, dtype=np.int64)[np.argsort(receive_ns, kind='stable')]
    back = int(np.count_nonzero(np.diff(in_reception) < 0))
    if back:
        _LOG.warning(
            '%s: %d of %d frames on %s carry an earlier header stamp than the frame received '
            'before them: frames are read in the order of their header stamps',
            path,
            back,
            len(header_ns),
            topic,
        )
    repeated = int(np.count_nonzero(np.diff(np.sort(header_ns)) == 0))
    if repeated:
        _LOG.warning(
            '%s: %d of %d frames on %s carry the header stamp of another frame: such frames '
            'get one ground-truth pose, and only one of them a depth map',
            path,
            repeated,
            len(header_ns),
            topic,
        )
    return header_ns


def is_compressed_type(msgtype: str) -> bool:
    """True for ``sensor_msgs/(msg/)CompressedImage``."""
    return msgtype.rsplit('/', 1)[-1] == 'CompressedImage'


def image_from_compressed(msg: Any) -> np.ndarray:
    """A jpeg or png ``sensor_msgs/CompressedImage`` (:func:`initsel_ros.image.decode_compressed`,
    size checked before decoding): (H, W, 3) BGR or (H, W) grey, uint8 or uint16 (16-bit png).

    Raises:
        DatasetError: empty, too large, or not decodable as an image.
    """
    raw = msg.data
    data = (
        raw.view(np.uint8).ravel() if isinstance(raw, np.ndarray) else np.frombuffer(raw, np.uint8)
    )
    fmt = str(getattr(msg, 'format', ''))
    if data.size == 0:
        raise DatasetError(f'empty CompressedImage (format {fmt!r})')
    try:
        return decode_compressed(data, fmt)
    except ImageConversionError as exc:
        raise DatasetError(f'cannot decode CompressedImage: {exc}') from exc


def image_from_msg(msg: Any) -> np.ndarray:
    """A ``sensor_msgs/Image`` as numpy (:func:`initsel_ros.image.decode_raw`): colour and Bayer
    -> (H, W, 3) uint8 BGR, mono -> (H, W) uint8 or uint16, 32FC1 depth -> (H, W) float32
    metres (NaN -> 0).

    Raises:
        DatasetError: unsupported encoding or a data size that does not match.
    """
    try:
        pixels = decode_raw(
            np.asarray(msg.data, dtype=np.uint8),
            msg.encoding,
            msg.width,
            msg.height,
            msg.step,
            bool(msg.is_bigendian),
            depth=True,
        )
        if pixels.dtype == np.float32:
            return np.where(np.isfinite(pixels), pixels, 0).astype(np.float32)
        if pixels.dtype == np.uint16:
            return np.array(pixels)
        return np.array(to_cv(pixels, msg.encoding))
    except ImageConversionError as exc:
        raise DatasetError(str(exc)) from exc


class BagSequence(Sequence):
    """A ROS 1 (``.bag``) or ROS 2 (folder, sqlite3 or mcap) bag as a :class:`Sequence`.

    Args:
        path: the bag.
        image_topic, depth_topic, info_topic: camera topics (depth/info optional in the bag).
        pose_topic: PoseStamped ground truth (camera-to-world), used when present.
        tf_parent, tf_child: frames of the /tf ground truth (leading '/' ignored).
        groundtruth: a TUM trajectory file that overrides the bag's ground truth.
        intrinsics: overrides CameraInfo (default: CameraInfo, else TUM fr3).
        max_gap, nearest_tolerance: ground-truth interpolation (see ``interpolate_poses``).
        max_association_diff: colour/depth association tolerance, seconds.
        ground_truth: False leaves every frame without a pose: no pose or /tf messages are
            read, nor a trajectory file (a replay that does not publish it needs none).
    """

    def __init__(
        self,
        path: Path | str,
        *,
        image_topic: str = IMAGE_TOPIC,
        depth_topic: str = DEPTH_TOPIC,
        info_topic: str = INFO_TOPIC,
        pose_topic: str = POSE_TOPIC,
        tf_topic: str = TF_TOPIC,
        tf_parent: str = '/world',
        tf_child: str = '/kinect',
        groundtruth: Path | str | None = None,
        intrinsics: Intrinsics | None = None,
        max_gap: float = DEFAULT_MAX_GAP,
        nearest_tolerance: float = 0.0,
        max_association_diff: float = MAX_ASSOCIATION_DIFF,
        ground_truth: bool = True,
    ) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        path = Path(path)
        if not path.exists():
            raise DatasetError(f'{path}: bag not found')
        errors = _read_errors()
        self.path = path
        self._reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY))
        self._info_uncalibrated = False  # (_scan: a CameraInfo with fx <= 0 was seen)
        try:
            self._reader.open()
        except errors as exc:
            raise DatasetError(
                f'{path}: cannot open bag (truncated or corrupt?): {read_error_reason(exc)}'
            ) from exc
        try:
            scan = self._scan(
                image_topic,
                depth_topic,
                info_topic if intrinsics is None else '',  # (given: the bag's is not read)
                pose_topic if ground_truth else None,
                tf_topic if ground_truth else None,
                tf_parent.lstrip('/'),
                tf_child.lstrip('/'),
            )
        except errors as exc:
            self.close()
            raise DatasetError(
                f'{path}: cannot read bag (truncated or corrupt?): {read_error_reason(exc)}'
            ) from exc
        except DatasetError as exc:
            self.close()
            raise DatasetError(f'{path}: {exc}') from exc
        img_times, img_ords, img_ns, depth_times, self._depth_ords, depth_stamps = scan[:6]
        info, gt_bag, gt_source = scan[6:]
        if not img_ns:
            self.close()
            topics = sorted({c.topic for c in self._reader.connections})
            raise DatasetError(
                f'{path}: no messages on image topic {image_topic!r} (topics: {", ".join(topics)})'
            )
        img_ns = _frame_stamps(path, self.image_topic, img_ns, img_times)
        img_stamps = [ns_to_seconds(t) for t in img_ns]
        order = np.argsort(np.asarray(img_ns, dtype=np.int64), kind='stable')
        stamps = np.asarray(img_stamps)[order]
        stamps_ns = [img_ns[k] for k in order]
        self._img_times = np.asarray(img_times)[order]
        self._img_ords = np.asarray(img_ords, dtype=np.int64)[order]
        self._depth_times = np.asarray(depth_times, dtype=np.int64)
        depth_stamps_arr = np.asarray(depth_stamps, dtype=np.float64)
        match = associate(stamps, depth_stamps_arr, max_association_diff)
        self._depth_match = match

        beside = path.parent / 'groundtruth.txt' if path.is_file() else path / 'groundtruth.txt'
        if not ground_truth:
            gt = None
        elif groundtruth is not None:
            gt = read_trajectory(Path(groundtruth))
            gt_source = str(groundtruth)
        elif gt_source == 'pose':
            gt = gt_bag
        elif beside.is_file():
            gt = read_trajectory(beside)
            gt_source = str(beside)
        else:
            gt = gt_bag
        poses: list[np.ndarray | None] = [None] * len(stamps)
        if gt is not None and len(gt[0]):
            poses = pose_matrices(*interpolate_poses(stamps, *gt, max_gap, nearest_tolerance))
            missing = sum(p is None for p in poses)
            if missing:
                _LOG.warning(
                    '%s: %d of %d frames have no ground-truth pose (from %s)',
                    path,
                    missing,
                    len(poses),
                    gt_source,
                )
        elif ground_truth:
            _LOG.info('%s: no ground truth found%s', path, self._pose_topics_hint(pose_topic))
        self.groundtruth_source = gt_source if gt is not None else None
        if intrinsics is None and info is None:
            _LOG.warning(
                '%s: %s on %s: the TUM fr3 intrinsics are assumed (give the '
                "camera's own with --intrinsics)",
                path,
                'the CameraInfo is of an uncalibrated camera (K zero)'
                if self._info_uncalibrated
                else 'no CameraInfo',
                info_topic,
            )
        if intrinsics is None:
            intrinsics = info if info is not None else Intrinsics.tum_fr3()
        frames = paired_frames(stamps, stamps_ns, poses, depth_stamps_arr, match)
        name = path.stem if path.is_file() else path.resolve().name  # (a bag folder given as .)
        super().__init__(name, intrinsics, frames, path)
        self._depth_topic = depth_topic

    def _pose_topics_hint(self, pose_topic: str) -> str:
        """Why the bag gave no ground truth: its pose topic refused, or its pose-like topics,
        and where camera ground truth goes ('' when the bag has none)."""
        found = sorted(
            f'{c.topic} ({c.msgtype})'
            for c in self._reader.connections
            if _type_name(c.msgtype) in (*POSE_TYPES, 'PointStamped') and c.topic != pose_topic
        )
        refused = any(c.topic == pose_topic for c in self._reader.connections)
        if not (found or refused):
            return ''
        body = (
            ". For a body's poses (EuRoC's Vicon or Leica), write the camera's (body pose times "
            'body-to-camera) to groundtruth.txt (TUM format)'
        )
        if refused:  # (the reason was logged when the topic was read)
            others = f'; other pose-like topics: {", ".join(found)}' if found else ''
            return (
                f': {pose_topic} holds no usable camera poses (see above), and there is no '
                f'groundtruth.txt beside the bag{others}{body}'
            )
        return (
            f' on {pose_topic} (camera-to-world) nor in a groundtruth.txt beside the bag; '
            f'pose-like topics: {", ".join(found)}{body}'
        )

    def _scan(
        self,
        image_topic: str,
        depth_topic: str,
        info_topic: str,
        pose_topic: str | None,
        tf_topic: str | None,
        tf_parent: str,
        tf_child: str,
    ) -> tuple[Any, ...]:
        reader = self._reader
        topics = {c.topic for c in reader.connections}
        if image_topic not in topics and f'{image_topic}/compressed' in topics:
            _LOG.info('%s: no %s; reading %s/compressed', self.path, image_topic, image_topic)
            image_topic = f'{image_topic}/compressed'
        self.image_topic = image_topic
        conns = [
            c
            for c in reader.connections
            if c.topic in (image_topic, depth_topic, info_topic, pose_topic, tf_topic)
        ]
        for c in [c for c in conns if c.topic == pose_topic]:
            if _type_name(c.msgtype) not in POSE_TYPES:
                _LOG.warning(
                    '%s: %s is %s, not a pose (%s): not used as ground truth',
                    self.path,
                    c.topic,
                    c.msgtype,
                    ', '.join(POSE_TYPES),
                )
                conns.remove(c)
        self._img_conns = [c for c in conns if c.topic == image_topic]
        self._depth_conns = [c for c in conns if c.topic == depth_topic]
        for c in (*self._img_conns, *self._depth_conns):
            if c.msgtype.rsplit('/', 1)[-1] not in ('Image', 'CompressedImage'):
                raise DatasetError(
                    f'{c.topic} is {c.msgtype}, not sensor_msgs/Image or CompressedImage'
                )
        img_times, img_stamps, depth_times, depth_stamps = [], [], [], []
        # a message's place among those of its topic at the same receive time: two frames
        # recorded at one time are told apart by it (_message)
        img_ords, depth_ords, at_time = [], [], {}
        info: Intrinsics | None = None
        pose_rows: list[list[float]] = []
        tf_rows: list[list[float]] = []
        for conn, t_ns, raw in reader.messages(connections=conns):
            topic = conn.topic
            if topic in (image_topic, depth_topic):
                header = reader.deserialize(raw, conn.msgtype).header
                key = (topic == image_topic, t_ns)
                ordinal = at_time[key] = at_time.get(key, -1) + 1
                if topic == image_topic:
                    img_times.append(t_ns)
                    img_ords.append(ordinal)
                    img_stamps.append(_stamp_ns(header))
                else:
                    depth_times.append(t_ns)
                    depth_ords.append(ordinal)
                    depth_stamps.append(_stamp(header))
            elif topic == info_topic and info is None:
                msg = reader.deserialize(raw, conn.msgtype)
                k = np.asarray(getattr(msg, 'k', None) if hasattr(msg, 'k') else msg.K, float)
                d = np.asarray(getattr(msg, 'd', None) if hasattr(msg, 'd') else msg.D, float)
                if k.size == 9 and np.isfinite(k).all() and k[0] <= 0:  # REP 104: K = 0 is
                    self._info_uncalibrated = True  # an uncalibrated camera (or a part of one)
                elif k.size == 9:
                    try:
                        roi = msg.roi
                        info = Intrinsics.from_camera_info(
                            k.reshape(3, 3),
                            int(msg.width),
                            int(msg.height),
                            d.tolist(),
                            msg.distortion_model,
                            (msg.binning_x, msg.binning_y),
                            (roi.x_offset, roi.y_offset, roi.width, roi.height),
                        )
                    except ConfigError as exc:
                        raise DatasetError(f'bad CameraInfo: {exc}') from exc
            elif topic == pose_topic:
                msg = reader.deserialize(raw, conn.msgtype)
                p, o = _position_orientation(msg, conn.msgtype)
                pose_rows.append([_stamp(msg.header), p.x, p.y, p.z, o.x, o.y, o.z, o.w])
            elif topic == tf_topic:
                msg = reader.deserialize(raw, conn.msgtype)
                for tr in msg.transforms:
                    if (
                        tr.header.frame_id.lstrip('/') == tf_parent
                        and tr.child_frame_id.lstrip('/') == tf_child
                    ):
                        p, o = tr.transform.translation, tr.transform.rotation
                        tf_rows.append([_stamp(tr.header), p.x, p.y, p.z, o.x, o.y, o.z, o.w])
        gt, source = None, None
        for rows, name, topic in ((pose_rows, 'pose', pose_topic), (tf_rows, 'tf', tf_topic)):
            if rows:
                data = np.array(rows, dtype=np.float64)
                where = f'{self.path} {topic}'
                try:
                    gt = check_trajectory(data[:, 0], data[:, 1:4], data[:, 4:8], where)
                except DatasetError as exc:  # the images stay usable (replay needs no poses)
                    _LOG.warning('%s: not used as ground truth', exc)
                    continue
                source = name
                break
        return (
            img_times,
            img_ords,
            img_stamps,
            depth_times,
            depth_ords,
            depth_stamps,
            info,
            gt,
            source,
        )

    def _message(self, conns: list[Any], t_ns: int, ordinal: int = 0) -> Any:
        """The ``ordinal``-th message on ``conns`` received at ``t_ns`` (several frames may
        share a receive time)."""
        try:
            for k, (conn, _, raw) in enumerate(
                self._reader.messages(connections=conns, start=int(t_ns), stop=int(t_ns) + 1)
            ):
                if k == ordinal:
                    return self._reader.deserialize(raw, conn.msgtype)
        except _read_errors() as exc:
            raise DatasetError(
                f'{self.path}: cannot read message at {t_ns} ns: {read_error_reason(exc)}'
            ) from exc
        raise DatasetError(f'{self.path}: message at {t_ns} ns disappeared')

    def _load_native(self, i: int) -> np.ndarray:
        msg = self._message(self._img_conns, self._img_times[i], int(self._img_ords[i]))
        try:
            if is_compressed_type(self._img_conns[0].msgtype):
                return image_from_compressed(msg)
            img = image_from_msg(msg)
        except DatasetError as exc:
            raise DatasetError(f'{self.path}: {self.image_topic} frame {i}: {exc}') from exc
        if img.dtype == np.float32:
            raise DatasetError(
                f'{self.path}: {self.image_topic} is a depth image (32FC1), not a camera image'
            )
        return img

    def _load_depth(self, i: int) -> np.ndarray | None:
        j = self._depth_match[i]
        if j < 0:
            return None
        msg = self._message(self._depth_conns, self._depth_times[j], int(self._depth_ords[j]))
        depth = image_from_msg(msg)
        if depth.dtype == np.uint16:  # 16UC1: millimetres
            depth = depth.astype(np.float32) / np.float32(1000.0)
        elif depth.dtype != np.float32 or depth.ndim != 2:  # 32FC1: metres
            raise DatasetError(
                f'{self.path}: depth message {j} on {self._depth_topic} is not 16UC1 or '
                f'32FC1 ({getattr(msg, "encoding", "?")})'
            )
        return depth.astype(np.float32)

    def close(self) -> None:
        """Close the bag file."""
        reader = getattr(self, '_reader', None)
        if reader is not None and getattr(reader, 'isopen', False):
            reader.close()

    def __del__(self) -> None:
        try:  # never raise from a finalizer (at interpreter exit module globals may be gone)
            self.close()
        except Exception:
            return


def write_bag(
    sequence: Sequence,
    path: Path | str,
    fmt: str = 'ros2',
    *,
    storage: str = 'sqlite3',
    image_topic: str = IMAGE_TOPIC,
    depth_topic: str = DEPTH_TOPIC,
    info_topic: str = INFO_TOPIC,
    pose_topic: str = POSE_TOPIC,
    compressed: str | None = None,
    jpeg_quality: int = 90,
) -> Path:
    """Write a sequence to a ROS 1 bag file (``fmt='ros1'``) or a ROS 2 bag folder.

    Header stamps are the frames' exact ``stamp_ns``.

    Args:
        sequence: frames with images, optional depth and poses.
        path: output ``.bag`` file (ros1) or folder (ros2); must not exist.
        fmt: 'ros1' or 'ros2'.
        storage: ROS 2 storage plugin, 'sqlite3' or 'mcap'.
        compressed: None (rgb8 ``Image`` on ``image_topic``), or 'jpeg' / 'png':
            ``CompressedImage`` on ``<image_topic>/compressed`` instead.
        jpeg_quality: 0-100, for ``compressed='jpeg'``.

    Returns:
        ``path``.
    """
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if fmt not in ('ros1', 'ros2'):
        raise ConfigError(f"bag format must be 'ros1' or 'ros2', got {fmt!r}")
    if compressed not in (None, 'jpeg', 'png'):
        raise ConfigError(f"compressed must be None, 'jpeg' or 'png', got {compressed!r}")
    if not 0 <= int(jpeg_quality) <= 100:
        raise ConfigError(f'jpeg quality must be in 0-100, got {jpeg_quality}')
    if path.exists():
        raise DatasetError(f'{path}: already exists')
    if not path.parent.is_dir():
        raise DatasetError(f'{path.parent}: no such folder to write the bag in')
    if fmt == 'ros1':
        from rosbags.rosbag1 import Writer as Ros1Writer

        store = get_typestore(Stores.ROS1_NOETIC)
        writer: Any = Ros1Writer(path)
        serialize = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Ros2Writer

        plugins = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
        if storage not in plugins:
            raise ConfigError(f"storage must be 'sqlite3' or 'mcap', got {storage!r}")
        store = get_typestore(Stores.ROS2_JAZZY)
        writer = Ros2Writer(path, version=9, storage_plugin=plugins[storage])
        serialize = store.serialize_cdr
    T = store.types
    Image, Info = T['sensor_msgs/msg/Image'], T['sensor_msgs/msg/CameraInfo']
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    Pose, PoseStamped = T['geometry_msgs/msg/Pose'], T['geometry_msgs/msg/PoseStamped']
    Point, Quat = T['geometry_msgs/msg/Point'], T['geometry_msgs/msg/Quaternion']
    Roi = T['sensor_msgs/msg/RegionOfInterest']
    Compressed = T['sensor_msgs/msg/CompressedImage']
    ros1 = fmt == 'ros1'

    def header(t_ns: int, frame: str, seq: int) -> Any:
        sec, nanosec = split_ns(t_ns)
        t = Time(sec=sec, nanosec=nanosec)
        return (
            Header(seq=seq, stamp=t, frame_id=frame) if ros1 else Header(stamp=t, frame_id=frame)
        )

    cam = sequence.intrinsics
    K = cam.K.reshape(-1)
    P = np.array([[cam.fx, 0, cam.cx, 0], [0, cam.fy, cam.cy, 0], [0, 0, 1, 0]]).reshape(-1)
    model = cam.distortion_model
    dist = np.array(cam.distortion or [0.0] * (FISHEYE_LENGTH if cam.fisheye else 5), float)
    try:
        writer.open()
        if compressed is None:
            c_img = writer.add_connection(image_topic, Image.__msgtype__, typestore=store)
        else:
            c_img = writer.add_connection(
                f'{image_topic}/compressed', Compressed.__msgtype__, typestore=store
            )
        c_info = writer.add_connection(info_topic, Info.__msgtype__, typestore=store)
        c_depth = writer.add_connection(depth_topic, Image.__msgtype__, typestore=store)
        c_pose = writer.add_connection(pose_topic, PoseStamped.__msgtype__, typestore=store)
        for f in sequence.frames:
            t_ns = int(f.stamp_ns)
            hd = header(t_ns, CAMERA_FRAME, f.index)
            if compressed is None:
                rgb = cv2.cvtColor(sequence.image(f.index), cv2.COLOR_BGR2RGB)
                h, w = rgb.shape[:2]
                msg = Image(
                    header=hd,
                    height=h,
                    width=w,
                    encoding='rgb8',
                    is_bigendian=0,
                    step=w * 3,
                    data=rgb.reshape(-1),
                )
                writer.write(c_img, t_ns, serialize(msg, Image.__msgtype__))
            else:
                native = sequence.native_image(f.index)
                h, w = native.shape[:2]
                data, fmt = encode_compressed(native, compressed, jpeg_quality)
                cmsg = Compressed(header=hd, format=fmt, data=np.frombuffer(data, np.uint8))
                writer.write(c_img, t_ns, serialize(cmsg, Compressed.__msgtype__))
            roi = Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
            mats = {
                'D' if ros1 else 'd': dist,
                'K' if ros1 else 'k': K,
                'R' if ros1 else 'r': np.eye(3).reshape(-1),
                'P' if ros1 else 'p': P,
            }
            info = Info(
                header=hd,
                height=h,
                width=w,
                distortion_model=model,
                binning_x=0,
                binning_y=0,
                roi=roi,
                **mats,
            )
            writer.write(c_info, t_ns, serialize(info, Info.__msgtype__))
            depth = sequence.depth(f.index)
            if depth is not None:
                d_ns = seconds_to_ns(f.depth_stamp)
                dmsg = Image(
                    header=header(d_ns, CAMERA_FRAME, f.index),
                    height=h,
                    width=w,
                    encoding='32FC1',
                    is_bigendian=0,
                    step=w * 4,
                    data=np.ascontiguousarray(depth, '<f4').view(np.uint8).reshape(-1),
                )
                writer.write(c_depth, d_ns, serialize(dmsg, Image.__msgtype__))
            if f.pose is not None:
                t, q = matrix_to_pose(f.pose)
                pose = Pose(
                    position=Point(x=t[0], y=t[1], z=t[2]),
                    orientation=Quat(x=q[0], y=q[1], z=q[2], w=q[3]),
                )
                pmsg = PoseStamped(header=header(t_ns, WORLD_FRAME, f.index), pose=pose)
                writer.write(c_pose, t_ns, serialize(pmsg, PoseStamped.__msgtype__))
    finally:
        writer.close()
    return path


__all__ = [
    'BagSequence',
    'image_from_compressed',
    'image_from_msg',
    'is_compressed_type',
    'read_error_reason',
    'write_bag',
]
