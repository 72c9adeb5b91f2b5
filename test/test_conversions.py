"""Message <-> numpy conversions of initsel_ros.ros.conversions (no node, no DDS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

import cv2
from sensor_msgs.msg import CameraInfo, Image, PointField
from std_msgs.msg import Header

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError, ImageConversionError
from initsel_ros.ros import conversions as conv


def _bgr(rng: np.random.Generator, h: int = 6, w: int = 10) -> np.ndarray:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


@pytest.mark.parametrize(
    ('encoding', 'shape', 'dtype'),
    [
        ('mono8', (5, 7), np.uint8),
        ('mono16', (5, 7), np.uint16),
        ('rgb8', (5, 7, 3), np.uint8),
        ('bgr8', (5, 7, 3), np.uint8),
        ('rgba8', (5, 7, 4), np.uint8),
        ('bgra8', (5, 7, 4), np.uint8),
        ('bayer_rggb8', (6, 8), np.uint8),
        ('bayer_bggr8', (6, 8), np.uint8),
        ('bayer_gbrg8', (6, 8), np.uint8),
        ('bayer_grbg8', (6, 8), np.uint8),
    ],
)
@pytest.mark.parametrize('padding', [0, 3])
def test_every_encoding_round_trips_with_and_without_row_padding(encoding, shape, dtype, padding):
    rng = np.random.default_rng(7)
    pixels = rng.integers(0, np.iinfo(dtype).max, shape, dtype=dtype, endpoint=True)
    row_bytes = shape[1] * (shape[2] if len(shape) == 3 else 1) * np.dtype(dtype).itemsize
    msg = conv.numpy_to_image(pixels, encoding, step=row_bytes + padding, frame_id='cam')
    assert msg.step == row_bytes + padding
    assert len(msg.data) == msg.step * shape[0]
    back = conv.image_to_numpy(msg)
    assert back.dtype == dtype
    np.testing.assert_array_equal(back, pixels)


def test_colour_encodings_all_become_the_same_bgr_image():
    bgr = _bgr(np.random.default_rng(1))
    rgb = bgr[..., ::-1]
    alpha = np.full((*bgr.shape[:2], 1), 200, np.uint8)
    messages = [
        conv.numpy_to_image(bgr, 'bgr8'),
        conv.numpy_to_image(np.ascontiguousarray(rgb), 'rgb8', step=3 * bgr.shape[1] + 5),
        conv.numpy_to_image(np.concatenate([rgb, alpha], axis=2), 'rgba8'),
        conv.numpy_to_image(np.concatenate([bgr, alpha], axis=2), 'bgra8'),
    ]
    for msg in messages:
        np.testing.assert_array_equal(conv.image_to_cv(msg), bgr, err_msg=msg.encoding)


@pytest.mark.parametrize('pattern', ['rggb', 'bggr', 'gbrg', 'grbg'])
def test_bayer_mosaic_of_a_flat_colour_debayers_to_that_colour(pattern):
    colour = {'b': 30, 'g': 120, 'r': 220}
    mosaic = np.zeros((8, 8), np.uint8)
    for (dy, dx), channel in zip([(0, 0), (0, 1), (1, 0), (1, 1)], pattern, strict=True):
        mosaic[dy::2, dx::2] = colour[channel]
    msg = conv.numpy_to_image(mosaic, f'bayer_{pattern}8')
    bgr = conv.image_to_cv(msg)
    assert bgr.shape == (8, 8, 3)
    np.testing.assert_array_equal(bgr[2:6, 2:6], np.broadcast_to([30, 120, 220], (4, 4, 3)))


def test_big_endian_mono16_reads_the_same_values_as_little_endian():
    pixels = np.array([[0, 1, 256], [4095, 65535, 513]], dtype=np.uint16)
    big = conv.numpy_to_image(pixels, 'mono16', is_bigendian=True)
    little = conv.numpy_to_image(pixels, 'mono16', is_bigendian=False)
    assert big.is_bigendian and not little.is_bigendian
    assert bytes(big.data) != bytes(little.data)
    np.testing.assert_array_equal(conv.image_to_numpy(big), pixels)
    np.testing.assert_array_equal(conv.image_to_numpy(little), pixels)
    np.testing.assert_array_equal(conv.image_to_cv(big), (pixels >> 8).astype(np.uint8))


def test_a_hand_built_big_endian_message_is_decoded():
    msg = Image(height=1, width=2, encoding='mono16', is_bigendian=1, step=4)
    msg.data = bytes([0x01, 0x02, 0xFF, 0x00])
    np.testing.assert_array_equal(conv.image_to_numpy(msg), [[0x0102, 0xFF00]])


def _raw(encoding: str, width: int, height: int, step: int, nbytes: int) -> Image:
    msg = Image(height=height, width=width, encoding=encoding, step=step)
    msg.data = bytes(nbytes)
    return msg


@pytest.mark.parametrize(
    ('msg', 'match'),
    [
        (_raw('rgb8', 4, 2, 11, 22), r'step 11 < width \* bytes per pixel = 12'),
        (_raw('mono16', 4, 2, 7, 14), 'step 7'),
        (_raw('mono8', 4, 3, 4, 11), 'data has 11 bytes, expected step \\* height = 12'),
        (_raw('bgr8', 4, 2, 16, 20), 'data has 20 bytes'),
        (_raw('yuv422', 4, 2, 8, 16), "unsupported image encoding 'yuv422'"),
        (_raw('32FC1', 4, 2, 16, 32), 'unsupported'),
        (_raw('', 4, 2, 4, 8), 'unsupported'),
        (_raw('mono8', 0, 2, 0, 0), 'zero size'),
        (_raw('mono8', 4, 0, 4, 0), 'zero size'),
    ],
)
def test_malformed_images_raise_image_conversion_error(msg, match):
    with pytest.raises(ImageConversionError, match=match):
        conv.image_to_cv(msg)


def test_numpy_to_image_rejects_an_array_that_does_not_match_the_encoding():
    with pytest.raises(ImageConversionError, match='3 channel'):
        conv.numpy_to_image(np.zeros((4, 4), np.uint8), 'rgb8')
    with pytest.raises(ImageConversionError, match='uint16'):
        conv.numpy_to_image(np.zeros((4, 4), np.uint8), 'mono16')


def test_image_data_is_stored_as_bytes_not_an_ndarray():
    msg = conv.numpy_to_image(np.zeros((480, 640, 3), np.uint8), 'bgr8')
    assert not isinstance(msg.data, np.ndarray)
    assert len(msg.data) == 480 * 640 * 3


def test_stamps_round_trip_to_the_nanosecond():
    stamp = conv.seconds_to_stamp(1341839327.392692)
    assert stamp.sec == 1341839327
    assert abs(stamp.nanosec - 392692000) < 300  # float64 resolution at 1.3e9 s
    assert abs(conv.stamp_to_seconds(stamp) - 1341839327.392692) < 1e-6
    with pytest.raises(ValueError, match='negative'):
        conv.seconds_to_stamp(-1.0)


def test_camera_info_round_trips_intrinsics_and_distortion():
    intr = Intrinsics(500.0, 510.0, 320.5, 240.5, 640, 480, (0.1, -0.05, 0.001, 0.002, 0.0))
    msg = conv.intrinsics_to_camera_info(intr, frame_id='cam')
    back = conv.camera_info_to_intrinsics(msg)
    assert back == intr
    plain = conv.camera_info_to_intrinsics(conv.intrinsics_to_camera_info(Intrinsics.tum_fr3()))
    assert plain == Intrinsics.tum_fr3()
    assert plain.distortion == ()
    coefficients = (0.1, -0.05, 0.0, 0.0, 0.01, 0.1, 0.0, 0.0)
    rational = Intrinsics(500.0, 510.0, 320.5, 240.5, 640, 480, coefficients)
    msg = conv.intrinsics_to_camera_info(rational)
    assert msg.distortion_model == 'rational_polynomial'
    assert conv.camera_info_to_intrinsics(msg) == rational


@pytest.mark.parametrize(
    ('k', 'size', 'model', 'match'),
    [
        ([0.0] * 9, (640, 480), 'plumb_bob', 'invalid K'),
        ([math.nan, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'invalid K'),
        ([500, 3, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'invalid K'),  # skew
        ([500, 0, 320, 0, 500, 240, 0, 0, 0], (640, 480), 'plumb_bob', 'invalid K'),
        ([1e307, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'implausible'),
        ([500, 0, 320, 0, 500, 240, 0, 0, 1], (0, 0), 'plumb_bob', 'zero image size'),
        ([500, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'equidistant', 'not supported'),
    ],
)
def test_invalid_camera_info_raises_config_error(k, size, model, match):
    msg = CameraInfo(width=size[0], height=size[1], distortion_model=model)
    msg.k = [float(v) for v in k]
    msg.d = [0.1, 0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match=match):
        conv.camera_info_to_intrinsics(msg)


def test_point_cloud_has_seven_float32_fields_and_round_trips():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(17, 3)) + np.array([0.0, 0.0, 2.0])
    ref, cur = rng.uniform(0, 640, (17, 2)), rng.uniform(0, 640, (17, 2))
    msg = conv.make_point_cloud(points, ref, cur, Header(frame_id='ref'))
    assert [f.name for f in msg.fields] == ['x', 'y', 'z', 'u0', 'v0', 'u1', 'v1']
    assert [f.offset for f in msg.fields] == [0, 4, 8, 12, 16, 20, 24]
    assert all(f.datatype == PointField.FLOAT32 and f.count == 1 for f in msg.fields)
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 17, 28, 28 * 17)
    assert not msg.is_bigendian and msg.is_dense
    assert len(msg.data) == 28 * 17
    cloud = conv.point_cloud_to_array(msg)
    np.testing.assert_allclose(np.stack([cloud['x'], cloud['y'], cloud['z']], 1), points,
                               rtol=1e-6)
    np.testing.assert_allclose(np.stack([cloud['u1'], cloud['v1']], 1), cur, rtol=1e-6)
    table = np.frombuffer(bytes(msg.data), dtype='<f4').reshape(17, 7)
    np.testing.assert_allclose(table[:, 3:5], ref, rtol=1e-6)


def test_empty_point_cloud_is_valid():
    msg = conv.make_point_cloud(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), Header())
    assert msg.width == 0 and len(msg.data) == 0
    assert conv.point_cloud_to_array(msg).shape == (0,)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    rvec = rng.normal(size=3)
    rvec *= rng.uniform(0.1, 3.0) / np.linalg.norm(rvec)
    return cv2.Rodrigues(rvec)[0]


def test_quaternions_round_trip_rotations():
    rng = np.random.default_rng(11)
    for _ in range(50):
        R = _random_rotation(rng)
        q = conv.rotation_to_quaternion(R)
        assert q[3] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-12
        np.testing.assert_allclose(conv.quaternion_to_rotation(q), R, atol=1e-10)
    np.testing.assert_allclose(conv.rotation_to_quaternion(np.eye(3)), [0, 0, 0, 1])
    half_turn = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(np.abs(conv.rotation_to_quaternion(half_turn)), [1, 0, 0, 0],
                               atol=1e-12)


def test_pose_is_the_current_camera_in_the_reference_frame():
    rng = np.random.default_rng(5)
    R, t = _random_rotation(rng), rng.normal(size=3)
    msg = conv.make_pose_stamped(R, t, Header(frame_id='ref_optical'))
    p = msg.pose.position
    np.testing.assert_allclose([p.x, p.y, p.z], -R.T @ t, atol=1e-12)
    o = msg.pose.orientation
    R_ref_cur = conv.quaternion_to_rotation([o.x, o.y, o.z, o.w])
    np.testing.assert_allclose(R_ref_cur, R.T, atol=1e-10)
    # A point seen in the current camera maps back to reference coordinates through the pose.
    x_ref = rng.normal(size=3)
    x_cur = R @ x_ref + t
    np.testing.assert_allclose(R_ref_cur @ x_cur + [p.x, p.y, p.z], x_ref, atol=1e-10)
    tf = conv.make_transform(R, t, Header(frame_id='ref_optical'), 'cam_optical')
    assert tf.child_frame_id == 'cam_optical' and tf.header.frame_id == 'ref_optical'
    assert tf.transform.translation.x == p.x and tf.transform.rotation.w == o.w


def test_pure_sideways_motion_gives_position_along_minus_t():
    # Camera moved 1 m to the right (+x): points move left in its frame, t = (-1, 0, 0).
    msg = conv.make_pose_stamped(np.eye(3), np.array([-1.0, 0.0, 0.0]), Header())
    assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == (1.0, 0.0, 0.0)
