"""Message <-> numpy conversions of initsel_ros.ros.conversions (no node, no DDS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

import cv2
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointField
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
        (_raw('nv12', 4, 2, 8, 16), "unsupported image encoding 'nv12'"),
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


def test_camera_info_round_trips_a_fisheye_lens_as_equidistant():
    fisheye = Intrinsics(380.0, 380.0, 320.0, 240.0, 640, 480, (0.05, -0.01, 0.0, 0.0), True)
    msg = conv.intrinsics_to_camera_info(fisheye)
    assert msg.distortion_model == 'equidistant' and list(msg.d) == [0.05, -0.01, 0.0, 0.0]
    assert conv.camera_info_to_intrinsics(msg) == fisheye
    msg.d = [0.0] * 4  # still a fisheye (f-theta), not a pinhole
    assert conv.camera_info_to_intrinsics(msg).fisheye
    msg.d = [0.05, -0.01, 0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match=r'equidistant. model takes 4'):
        conv.camera_info_to_intrinsics(msg)


@pytest.mark.parametrize(
    ('k', 'size', 'model', 'match'),
    [
        ([0.0] * 9, (640, 480), 'plumb_bob', 'invalid K'),
        ([math.nan, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'invalid K'),
        ([500, 3, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'invalid K'),  # skew
        ([500, 0, 320, 0, 500, 240, 0, 0, 0], (640, 480), 'plumb_bob', 'invalid K'),
        ([1e307, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'plumb_bob', 'implausible'),
        ([500, 0, 320, 0, 500, 240, 0, 0, 1], (0, 0), 'plumb_bob', 'image size must be positive'),
        ([500, 0, 320, 0, 500, 240, 0, 0, 1], (640, 480), 'fov', 'not supported'),
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
    np.testing.assert_allclose(
        np.stack([cloud['x'], cloud['y'], cloud['z']], 1), points, rtol=1e-6
    )
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
    np.testing.assert_allclose(
        np.abs(conv.rotation_to_quaternion(half_turn)), [1, 0, 0, 0], atol=1e-12
    )


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


# ------------------------------------------------------------------ exact stamps (integer ns)
@pytest.mark.parametrize(
    ('sec', 'nanosec'),
    [
        (1_700_000_000, 666_666_985),
        (0, 0),
        (0, 1),
        (-1, 999_999_999),
        (-3, 876_543_211),
        (2**31 - 1, 999_999_999),
        (-(2**31), 0),
    ],
)
def test_stamps_map_to_integer_nanoseconds_and_back_field_by_field(sec, nanosec):
    from builtin_interfaces.msg import Time

    ns = conv.stamp_to_ns(Time(sec=sec, nanosec=nanosec))
    assert ns == sec * 10**9 + nanosec
    back = conv.ns_to_stamp(ns)
    assert (back.sec, back.nanosec) == (sec, nanosec)


def test_odd_nanosecond_unix_stamps_survive_many_frames_exactly():
    start = 1_700_000_000 * 10**9 + 666_666_985
    for k in range(0, 100_000, 997):
        ns = start + k * 33_333_333
        stamp = conv.ns_to_stamp(ns)
        assert conv.stamp_to_ns(stamp) == ns and 0 <= stamp.nanosec < 10**9


# ------------------------------------------------------------------------------ 16-bit images
def test_sixteen_bit_images_use_their_significant_bits():
    ten_bit = np.array([[0, 4, 1023]], np.uint16)
    assert conv.significant_bits(ten_bit) == 10
    np.testing.assert_array_equal(conv.to_8bit(ten_bit), [[0, 1, 255]])
    np.testing.assert_array_equal(conv.to_8bit(ten_bit, 12), [[0, 0, 63]])
    np.testing.assert_array_equal(conv.to_8bit(np.array([[5000]], np.uint16), 12), [[255]])
    np.testing.assert_array_equal(conv.to_8bit(np.array([[200]], np.uint16)), [[200]])
    msg = conv.numpy_to_image(ten_bit, 'mono16', is_bigendian=True)
    msg.encoding = '16UC1'
    np.testing.assert_array_equal(conv.image_to_cv(msg), [[0, 1, 255]])


# ------------------------------------------------------------------------ compressed images
@pytest.mark.parametrize(
    ('shape', 'dtype', 'fmt'),
    [
        ((24, 32), np.uint8, 'jpeg'),
        ((24, 32, 3), np.uint8, 'jpeg'),
        ((24, 32), np.uint8, 'png'),
        ((24, 32, 3), np.uint8, 'png'),
        ((24, 32), np.uint16, 'png'),
    ],
)
def test_compressed_images_decode_to_the_selector_input(shape, dtype, fmt):
    rng = np.random.default_rng(4)
    pixels = rng.integers(0, 4096 if dtype == np.uint16 else 256, shape).astype(dtype)
    msg = conv.numpy_to_compressed(pixels, fmt, frame_id='cam')
    depth = 16 if dtype == np.uint16 else 8
    encoding = f'{"mono" if len(shape) == 2 else "bgr"}{depth}'
    assert msg.format == f'{encoding}; {fmt} compressed {encoding}'
    decoded = conv.compressed_to_numpy(msg)
    assert decoded.shape == shape and decoded.dtype == dtype
    if fmt == 'png':
        np.testing.assert_array_equal(decoded, pixels)
    image = conv.compressed_to_cv(msg)
    assert image.dtype == np.uint8 and image.shape == shape
    if dtype == np.uint16:
        np.testing.assert_array_equal(image, conv.to_8bit(pixels))


def test_a_png_with_alpha_loses_its_alpha_channel():
    bgra = np.zeros((4, 6, 4), np.uint8)
    bgra[..., 2] = 200
    bgra[..., 3] = 17
    msg = CompressedImage(format='png', data=cv2.imencode('.png', bgra)[1].tobytes())
    np.testing.assert_array_equal(conv.compressed_to_cv(msg), bgra[..., :3])


def _png_declaring(width: int, height: int) -> bytes:
    data = bytearray(cv2.imencode('.png', np.zeros((2, 2), np.uint8))[1].tobytes())
    data[16:20], data[20:24] = width.to_bytes(4, 'big'), height.to_bytes(4, 'big')
    return bytes(data)


def _jpeg_declaring(width: int, height: int) -> bytes:
    data = bytearray(cv2.imencode('.jpg', np.zeros((8, 8), np.uint8))[1].tobytes())
    sof = data.index(b'\xff\xc0')
    data[sof + 5 : sof + 7], data[sof + 7 : sof + 9] = (
        height.to_bytes(2, 'big'),
        width.to_bytes(2, 'big'),
    )
    return bytes(data)


@pytest.mark.parametrize(
    ('data', 'fmt', 'match'),
    [
        (b'', 'jpeg', 'not JPEG or PNG'),
        (b'GIF89a....', 'gif', 'not JPEG or PNG'),
        (_png_declaring(100_000, 100_000), 'png', 'larger than'),  # a decompression bomb
        (_png_declaring(0, 5), 'png', 'says 0x5'),
        (_jpeg_declaring(65_535, 65_535), 'jpeg', 'larger than'),
        (b'\x89PNG\r\n\x1a\n' + bytes(8), 'png', 'corrupt header'),
        (b'\xff\xd8\xff', 'jpeg', 'corrupt header'),
        (_png_declaring(2, 2)[:40], 'png', 'cannot decode'),
        (b'\x89PNG\r\n\x1a\n', '16UC1; compressedDepth png', 'compressedDepth'),
    ],
)
def test_bad_compressed_images_raise_image_conversion_error(data, fmt, match):
    with pytest.raises(ImageConversionError, match=match):
        conv.compressed_to_cv(CompressedImage(format=fmt, data=data))


def test_numpy_to_compressed_refuses_unknown_formats():
    with pytest.raises(ImageConversionError, match="'jpeg' or 'png'"):
        conv.numpy_to_compressed(np.zeros((4, 4), np.uint8), 'webp')


# -------------------------------------------------------------------------------- distortion
@pytest.mark.parametrize('n', [1, 2, 3, 6, 7, 9, 13, 15])
def test_camera_info_with_a_distortion_length_opencv_rejects_is_a_config_error(n):
    msg = conv.intrinsics_to_camera_info(Intrinsics.tum_fr3())
    msg.d = [0.01] * n
    with pytest.raises(ConfigError, match=f'^{n} distortion coefficients'):
        conv.camera_info_to_intrinsics(msg)


@pytest.mark.parametrize('n', [0, 4, 5, 8, 12, 14])
def test_camera_info_with_a_distortion_length_opencv_takes_is_accepted(n):
    msg = conv.intrinsics_to_camera_info(Intrinsics.tum_fr3())
    msg.distortion_model = 'rational_polynomial' if n > 5 else 'plumb_bob'
    msg.d = [0.01] * n
    assert conv.camera_info_to_intrinsics(msg).distortion == (0.01,) * n


def test_an_all_zero_distortion_of_any_length_means_none():
    msg = conv.intrinsics_to_camera_info(Intrinsics.tum_fr3())
    msg.d = [0.0] * 3
    assert conv.camera_info_to_intrinsics(msg).distortion == ()
    with pytest.raises(ConfigError, match='3 distortion coefficients'):
        Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480, (0.1, 0.0, 0.0))


# ------------------------------------------------------------------------ binning and ROI
def _full_sensor_info(**fields) -> CameraInfo:
    msg = conv.intrinsics_to_camera_info(Intrinsics(800.0, 790.0, 752.0, 480.0, 1504, 960))
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


def test_camera_info_binning_and_roi_give_the_k_of_the_images_they_describe():
    from sensor_msgs.msg import RegionOfInterest

    binned = conv.camera_info_to_intrinsics(_full_sensor_info(binning_x=2, binning_y=2))
    assert binned == Intrinsics(400.0, 395.0, 376.0, 240.0, 752, 480)
    roi = RegionOfInterest(x_offset=200, y_offset=120, width=1000, height=600)
    crop = conv.camera_info_to_intrinsics(_full_sensor_info(roi=roi))
    assert crop == Intrinsics(800.0, 790.0, 552.0, 360.0, 1000, 600)  # focal lengths kept
    both = conv.camera_info_to_intrinsics(_full_sensor_info(roi=roi, binning_x=2, binning_y=2))
    assert both == Intrinsics(400.0, 395.0, 276.0, 180.0, 500, 300)
    # binning 0 is 1 (REP 104), an all-zero ROI the full sensor
    assert conv.camera_info_to_intrinsics(_full_sensor_info()).width == 1504


@pytest.mark.parametrize(
    'roi', [(1000, 0, 600, 480), (0, 0, 0, 480), (-1, 0, 10, 10), (0, 500, 100, 500)]
)
def test_a_camera_info_roi_beyond_the_sensor_is_refused(roi):
    from sensor_msgs.msg import RegionOfInterest

    x, y, w, h = roi
    msg = _full_sensor_info()
    try:
        msg.roi = RegionOfInterest(x_offset=x, y_offset=y, width=w, height=h)
    except AssertionError:  # a negative offset cannot even be set on the uint32 field
        return
    with pytest.raises(ConfigError, match='does not lie within the 1504x960 sensor'):
        conv.camera_info_to_intrinsics(msg)
