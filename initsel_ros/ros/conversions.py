"""Conversions between ROS 2 messages and numpy, by hand (no cv_bridge, no sensor_msgs_py).

Images are read with ``np.frombuffer`` honouring ``step`` (row padding) and ``is_bigendian``;
compressed images (JPEG, PNG) are decoded with ``cv2.imdecode``; all of it lives in
:mod:`initsel_ros.image` (these are thin calls, for the tests, the bench and the fuzzer).
Messages are built with ``msg.data = array.tobytes()`` (assigning an ndarray is ~100x slower).
Poses follow OpenCV's two-view convention ``x_cur = R @ x_ref + t``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, TransformStamped
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2, PointField
from std_msgs.msg import Header

from initsel_ros import timestamps
from initsel_ros.camera import FISHEYE_LENGTH, Intrinsics
from initsel_ros.errors import ImageConversionError
from initsel_ros.image import (
    ENCODINGS,
    MAX_DECODED_PIXELS,
    BitDepth,
    EncodingInfo,
    decode_compressed,
    decode_raw,
    encode_compressed,
    raw_to_cv,
    significant_bits,
    to_8bit,
)
from initsel_ros.image import compressed_to_cv as image_compressed_to_cv
from initsel_ros.transforms import matrix_to_quaternion, quaternion_to_matrix

#: Point cloud fields published on ``init/points``: all float32, little-endian, in this order.
POINT_FIELDS: tuple[str, ...] = ('x', 'y', 'z', 'u0', 'v0', 'u1', 'v1')


# --------------------------------------------------------------------------------------- time
def stamp_to_seconds(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> float seconds."""
    return timestamps.ns_to_seconds(stamp_to_ns(stamp))


def stamp_to_ns(stamp: Time) -> int:
    """``builtin_interfaces/Time`` -> integer nanoseconds, exactly (may be negative)."""
    return timestamps.stamp_ns(stamp.sec, stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Integer nanoseconds -> ``builtin_interfaces/Time``, exactly (inverse of stamp_to_ns).

    Negative times keep ``0 <= nanosec < 1e9`` with a negative ``sec``, as ROS does.
    """
    sec, nanosec = timestamps.split_ns(ns)
    return Time(sec=sec, nanosec=nanosec)


def seconds_to_stamp(seconds: float) -> Time:
    """Float seconds (>= 0) -> ``builtin_interfaces/Time``, rounded to the nanosecond."""
    total_ns = timestamps.seconds_to_ns(seconds)
    if total_ns < 0:
        raise ValueError(f'ROS time cannot be negative: {seconds} s')
    return ns_to_stamp(total_ns)


# ------------------------------------------------------------------------------------- images
def image_to_numpy(msg: Image) -> np.ndarray:
    """Pixels of an Image message in its own channel order (:func:`initsel_ros.image.decode_raw`).

    Raises:
        ImageConversionError: unknown encoding, zero size, ``step`` shorter than a row, or
            ``data`` shorter than ``step * height``.
    """
    return decode_raw(msg.data, msg.encoding, msg.width, msg.height, msg.step, msg.is_bigendian)


def image_to_cv(
    msg: Image, bit_depth: int | BitDepth = 0, *, max_pixels: int = MAX_DECODED_PIXELS
) -> np.ndarray:
    """An Image message as the selector's input (:func:`initsel_ros.image.raw_to_cv`): the
    node's own conversion.

    Colour and Bayer encodings become BGR; mono16 and 16UC1 are scaled by their real range
    (:func:`to_8bit`: a 12-bit camera's 0..4095 becomes 0..255).

    Args:
        msg: the image.
        bit_depth: significant bits of 16-bit images (8-16); 0 = from this image's data; a
            :class:`~initsel_ros.image.BitDepth` = the stream's.
        max_pixels: larger images are refused (the node's ``max_image_pixels``).

    Raises:
        ImageConversionError: as :func:`image_to_numpy`, or more than ``max_pixels`` pixels.
    """
    return raw_to_cv(
        msg.data,
        msg.encoding,
        msg.width,
        msg.height,
        msg.step,
        msg.is_bigendian,
        bit_depth,
        max_pixels=max_pixels,
    )


# -------------------------------------------------------------------------- compressed images
def compressed_to_numpy(msg: CompressedImage) -> np.ndarray:
    """Decode a JPEG or PNG CompressedImage (:func:`initsel_ros.image.decode_compressed`).

    Raises:
        ImageConversionError: empty data, not JPEG/PNG (``compressedDepth`` included), larger
            than :data:`MAX_DECODED_PIXELS`, or corrupt.
    """
    return decode_compressed(msg.data, str(msg.format))


def compressed_to_cv(
    msg: CompressedImage,
    bit_depth: int | BitDepth = 0,
    *,
    max_pixels: int = MAX_DECODED_PIXELS,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """A CompressedImage as the selector's input (:func:`initsel_ros.image.compressed_to_cv`):
    the node's own conversion; ``size`` (width, height): refuse another size before decoding.

    Raises:
        ImageConversionError: as :func:`compressed_to_numpy`, more than ``max_pixels``
            pixels, or another size than ``size``.
    """
    return image_compressed_to_cv(
        msg.data, str(msg.format), bit_depth, max_pixels=max_pixels, size=size
    )


def numpy_to_compressed(
    pixels: np.ndarray,
    fmt: str = 'jpeg',
    *,
    quality: int = 95,
    stamp: Time | None = None,
    frame_id: str = '',
) -> CompressedImage:
    """Encode (H, W) grey or (H, W, 3) BGR pixels (uint8; uint16 for PNG) as a CompressedImage.

    ``format`` follows image_transport's convention, e.g. ``'bgr8; jpeg compressed bgr8'``.

    Raises:
        ImageConversionError: unknown ``fmt`` or pixels OpenCV cannot encode that way.
    """
    data, fmt_field = encode_compressed(pixels, fmt, quality)
    msg = CompressedImage()
    msg.header = Header(stamp=stamp or Time(), frame_id=frame_id)
    msg.format = fmt_field
    msg.data = data
    return msg


def numpy_to_image(
    pixels: np.ndarray,
    encoding: str,
    *,
    stamp: Time | None = None,
    frame_id: str = '',
    step: int | None = None,
    is_bigendian: bool = False,
) -> Image:
    """Build an Image message from an array laid out as ``encoding`` says.

    Args:
        pixels: (H, W) or (H, W, C) array; uint8, or uint16 for mono16.
        encoding: one of :data:`ENCODINGS`.
        stamp: header stamp (zero when None).
        frame_id: header frame id.
        step: row length in bytes, >= W * C * itemsize (rows are zero-padded); None = packed.
        is_bigendian: write multi-byte pixels big-endian.

    Raises:
        ImageConversionError: unknown encoding, or an array that does not match it.
    """
    info = ENCODINGS.get(encoding)
    if info is None:
        raise ImageConversionError(f'unsupported image encoding {encoding!r}')
    pixels = np.asarray(pixels)
    expected_ndim = 2 if info.channels == 1 else 3
    if (
        pixels.ndim != expected_ndim
        or (info.channels > 1 and pixels.shape[2] != info.channels)
        or pixels.dtype != np.dtype(info.dtype)
    ):
        raise ImageConversionError(
            f'{encoding} needs a {info.dtype} array with {info.channels} channel(s), got '
            f'{pixels.dtype} {pixels.shape}'
        )
    height, width = pixels.shape[:2]
    itemsize = pixels.dtype.itemsize
    row_bytes = width * info.channels * itemsize
    step = row_bytes if step is None else int(step)
    if step < row_bytes:
        raise ImageConversionError(f'step {step} < row size {row_bytes} bytes')
    if itemsize > 1:
        pixels = pixels.astype(pixels.dtype.newbyteorder('>' if is_bigendian else '<'))
    rows = np.ascontiguousarray(pixels).view(np.uint8).reshape(height, row_bytes)
    if step > row_bytes:
        padded = np.zeros((height, step), dtype=np.uint8)
        padded[:, :row_bytes] = rows
        rows = padded
    msg = Image()
    msg.header = Header(stamp=stamp or Time(), frame_id=frame_id)
    msg.height, msg.width, msg.step = int(height), int(width), int(step)
    msg.encoding = encoding
    msg.is_bigendian = bool(is_bigendian and itemsize > 1)
    msg.data = rows.tobytes()
    return msg


# -------------------------------------------------------------------------------- camera info
def camera_info_to_intrinsics(msg: CameraInfo) -> Intrinsics:
    """Intrinsics (and OpenCV distortion) from a CameraInfo message
    (:meth:`Intrinsics.from_camera_info`, which the bag readers use too).

    ``plumb_bob`` and ``rational_polynomial`` coefficients pass through to OpenCV's standard
    model, ``equidistant`` ones to its fisheye model; an empty model or all-zero ``d`` means
    no distortion, except for ``equidistant`` (an f-theta lens). ``binning`` and ``roi`` give
    the K and size of the images they describe (REP 104).

    Raises:
        ConfigError: K not finite, not of the form [fx 0 cx; 0 fy cy; 0 0 1], with focal
            lengths implausible for the image size, zero image size, a D of a length OpenCV
            does not take (4, 5, 8, 12, 14; 4 for ``equidistant``; all-zero D of any length
            = none), an unsupported distortion model with non-zero coefficients, or an ROI
            beyond the sensor.
    """
    roi = msg.roi
    return Intrinsics.from_camera_info(
        msg.k,
        int(msg.width),
        int(msg.height),
        msg.d,
        msg.distortion_model,
        (msg.binning_x, msg.binning_y),
        (roi.x_offset, roi.y_offset, roi.width, roi.height),
    )


def intrinsics_to_camera_info(
    intrinsics: Intrinsics, *, stamp: Time | None = None, frame_id: str = ''
) -> CameraInfo:
    """A CameraInfo message (identity R, P = [K | 0]) for ``intrinsics``.

    The distortion model is ``equidistant`` for a fisheye lens, ``plumb_bob`` for up to 5
    coefficients, else ``rational_polynomial`` (:attr:`Intrinsics.distortion_model`).
    """
    msg = CameraInfo()
    msg.header = Header(stamp=stamp or Time(), frame_id=frame_id)
    msg.width, msg.height = int(intrinsics.width), int(intrinsics.height)
    msg.distortion_model = intrinsics.distortion_model
    length = FISHEYE_LENGTH if intrinsics.fisheye else 5
    distortion = list(intrinsics.distortion) + [0.0] * max(0, length - len(intrinsics.distortion))
    msg.d = [float(d) for d in distortion]
    K = intrinsics.K
    msg.k = K.ravel().tolist()
    msg.r = np.eye(3).ravel().tolist()
    msg.p = np.hstack([K, np.zeros((3, 1))]).ravel().tolist()
    return msg


# -------------------------------------------------------------------------------- point cloud
def make_point_cloud(
    points: np.ndarray,
    pixels_ref: np.ndarray,
    pixels_cur: np.ndarray,
    header: Header,
) -> PointCloud2:
    """A PointCloud2 of triangulated points with their pixel coordinates.

    Args:
        points: (M, 3) points in the reference camera frame (scale: median depth 1).
        pixels_ref: (M, 2) pixels (u0, v0) in the reference image.
        pixels_cur: (M, 2) pixels (u1, v1) in the current image.
        header: stamp and frame id (the reference camera's optical frame).

    Returns:
        Unordered cloud (height 1, width M) with float32 fields :data:`POINT_FIELDS`,
        28 bytes per point, little-endian.
    """
    points = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    n = points.shape[0]
    pixels_ref = np.asarray(pixels_ref, dtype=np.float32).reshape(n, 2)
    pixels_cur = np.asarray(pixels_cur, dtype=np.float32).reshape(n, 2)
    table = np.hstack([points, pixels_ref, pixels_cur]).astype('<f4')
    msg = PointCloud2()
    msg.header = header
    msg.height, msg.width = 1, n
    msg.fields = [
        PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
        for i, name in enumerate(POINT_FIELDS)
    ]
    msg.is_bigendian = False
    msg.point_step = 4 * len(POINT_FIELDS)
    msg.row_step = msg.point_step * n
    msg.is_dense = bool(np.all(np.isfinite(table)))
    msg.data = np.ascontiguousarray(table).tobytes()
    return msg


_POINTFIELD_DTYPES = {
    PointField.INT8: 'i1',
    PointField.UINT8: 'u1',
    PointField.INT16: 'i2',
    PointField.UINT16: 'u2',
    PointField.INT32: 'i4',
    PointField.UINT32: 'u4',
    PointField.FLOAT32: 'f4',
    PointField.FLOAT64: 'f8',
}


def point_cloud_to_array(msg: PointCloud2) -> np.ndarray:
    """A PointCloud2 as a (height * width,) structured array with one column per field.

    Raises:
        ValueError: unknown field type or data shorter than the declared size.
    """
    order = '>' if msg.is_bigendian else '<'
    names, formats, offsets = [], [], []
    for field in msg.fields:
        if field.datatype not in _POINTFIELD_DTYPES:
            raise ValueError(f'point field {field.name!r} has unknown datatype {field.datatype}')
        base = order + _POINTFIELD_DTYPES[field.datatype]
        names.append(field.name)
        formats.append(base if field.count == 1 else (base, (field.count,)))
        offsets.append(field.offset)
    dtype = np.dtype(
        {'names': names, 'formats': formats, 'offsets': offsets, 'itemsize': msg.point_step}
    )
    n = msg.height * msg.width
    data = np.frombuffer(msg.data, dtype=np.uint8)
    if data.size < msg.point_step * n or msg.row_step * msg.height > data.size:
        raise ValueError(
            f'point cloud data has {data.size} bytes, expected {msg.row_step} x {msg.height}'
        )
    rows = data[: msg.row_step * msg.height].reshape(msg.height, msg.row_step)
    packed = np.ascontiguousarray(rows[:, : msg.point_step * msg.width])
    return packed.view(dtype).reshape(n)


# ---------------------------------------------------------------------------------------- pose
def rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix -> (4,) unit quaternion (x, y, z, w) with w >= 0."""
    return matrix_to_quaternion(np.asarray(R, dtype=float).reshape(3, 3))


def quaternion_to_rotation(q: Sequence[float]) -> np.ndarray:
    """(x, y, z, w) quaternion (any norm > 0) -> (3, 3) rotation matrix."""
    return quaternion_to_matrix(np.asarray(q, dtype=float))


def camera_pose_in_reference(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The current camera's pose in the reference camera frame, for ``x_cur = R x_ref + t``.

    Returns:
        (R_ref_cur (3, 3), position (3,)) with ``R_ref_cur = R.T`` and ``position = -R.T t``
        (the current optical centre in reference coordinates).
    """
    R = np.asarray(R, dtype=float).reshape(3, 3)
    t = np.asarray(t, dtype=float).reshape(3)
    return R.T, -R.T @ t


def make_pose_stamped(R: np.ndarray, t: np.ndarray, header: Header) -> PoseStamped:
    """PoseStamped of the current camera in the reference frame (``header.frame_id``)."""
    rotation, position = camera_pose_in_reference(R, t)
    return pose_stamped(rotation, position, header)


def pose_stamped(rotation: np.ndarray, position: np.ndarray, header: Header) -> PoseStamped:
    """PoseStamped of a (3, 3) ``rotation`` and (3,) ``position`` in ``header.frame_id``."""
    msg = PoseStamped()
    msg.header = header
    set_pose(msg.pose.position, msg.pose.orientation, position, rotation)
    return msg


def make_transform(
    R: np.ndarray, t: np.ndarray, header: Header, child_frame_id: str
) -> TransformStamped:
    """TF transform reference frame (``header.frame_id``) -> current camera frame."""
    rotation, position = camera_pose_in_reference(R, t)
    msg = TransformStamped()
    msg.header = header
    msg.child_frame_id = child_frame_id
    set_pose(msg.transform.translation, msg.transform.rotation, position, rotation)
    return msg


def set_pose(
    position_msg: object, orientation_msg: object, position: np.ndarray, rotation: np.ndarray
) -> None:
    """Write ``position`` (3,) and the (3, 3) ``rotation`` as a quaternion into the fields of a
    Point or Vector3 and of a Quaternion message."""
    position_msg.x, position_msg.y, position_msg.z = map(float, position)
    q = rotation_to_quaternion(rotation)
    orientation_msg.x, orientation_msg.y, orientation_msg.z, orientation_msg.w = map(float, q)


__all__ = [
    'ENCODINGS',
    'MAX_DECODED_PIXELS',
    'POINT_FIELDS',
    'EncodingInfo',
    'camera_info_to_intrinsics',
    'camera_pose_in_reference',
    'compressed_to_cv',
    'compressed_to_numpy',
    'image_to_cv',
    'image_to_numpy',
    'intrinsics_to_camera_info',
    'make_point_cloud',
    'make_pose_stamped',
    'make_transform',
    'ns_to_stamp',
    'numpy_to_compressed',
    'numpy_to_image',
    'point_cloud_to_array',
    'pose_stamped',
    'quaternion_to_rotation',
    'rotation_to_quaternion',
    'seconds_to_stamp',
    'set_pose',
    'significant_bits',
    'stamp_to_ns',
    'stamp_to_seconds',
    'to_8bit',
]
