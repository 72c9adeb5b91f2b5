"""Tests for initsel_ros.image: raw decode by encoding, grey, BGR, 16-bit scaling, JPEG/PNG."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from initsel_ros import image
from initsel_ros.errors import ImageConversionError


def test_decode_raw_honours_step_padding_and_big_endian():
    pixels = np.arange(12, dtype=np.uint16).reshape(3, 4) * 300
    rows = pixels.astype('>u2').tobytes()
    padded = b''.join(rows[r * 8 : (r + 1) * 8] + b'\0\0' for r in range(3))
    out = image.decode_raw(padded, 'mono16', 4, 3, 10, is_bigendian=True)
    assert out.dtype == np.uint16 and np.array_equal(out, pixels)


def test_decode_raw_rgb8_to_cv_is_bgr():
    rgb = np.zeros((2, 3, 3), np.uint8)
    rgb[..., 0] = 200
    out = image.to_cv(image.decode_raw(rgb.tobytes(), 'rgb8', 3, 2, 9), 'rgb8')
    assert out.shape == (2, 3, 3) and out[0, 0, 2] == 200 and out[0, 0, 0] == 0


@pytest.mark.parametrize(
    ('args', 'words'),
    [
        (('nv12', 2, 2, 4), 'unsupported'),
        (('yuv422', 1, 2, 4), 'even width'),
        (('mono8', 0, 2, 0), 'zero size'),
        (('mono8', 4, 2, 3), 'step'),
        (('mono8', 4, 4, 4), 'data has'),
    ],
)
def test_decode_raw_errors_are_image_conversion_errors(args, words):
    with pytest.raises(ImageConversionError, match=words):
        image.decode_raw(bytes(8), *args)


def test_16_bit_scaling_uses_the_bit_depth():
    twelve_bit = np.array([[0, 4095]], np.uint16)
    assert image.significant_bits(twelve_bit) == 12
    assert image.to_8bit(twelve_bit).tolist() == [[0, 255]]
    assert image.to_8bit(twelve_bit, 16).tolist() == [[0, 15]]
    assert image.to_cv(twelve_bit, 'mono16', 10).tolist() == [[0, 255]]  # saturates


def test_to_gray_and_to_bgr():
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255
    assert image.to_gray(bgr)[0, 0] == 76
    assert image.to_gray(np.full((2, 2), 65535, np.uint16))[0, 0] == 255
    assert image.to_bgr(np.full((2, 2), 7, np.uint8)).shape == (2, 2, 3)
    assert image.to_bgr(bgr) is bgr and image.to_bgr(bgr, copy=True) is not bgr
    assert image.to_bgr(np.zeros((2, 2, 4), np.uint16)).dtype == np.uint8
    for bad in (np.zeros((2, 2), np.float32), np.zeros((2, 2, 2), np.uint8)):
        with pytest.raises(ImageConversionError):
            image.to_bgr(bad)
    with pytest.raises(ImageConversionError):
        image.to_gray(np.zeros((0, 3), np.uint8))


def test_16_bit_pixels_asked_for_as_jpeg_are_png_not_cut_to_8_bits():
    grey = (np.arange(48, dtype=np.uint16).reshape(6, 8) * 853) % 40951  # up to 40,950
    data, fmt = image.encode_compressed(grey, 'jpeg')
    # before: OpenCV wrote 8-bit JPEG (maximum 255) under the label 'jpeg compressed mono16'
    assert fmt == 'mono16; png compressed mono16'
    assert np.array_equal(image.decode_compressed(data, fmt), grey)
    with pytest.raises(ImageConversionError, match='quality must be in 0-100'):
        image.encode_compressed(np.zeros((4, 4), np.uint8), 'jpeg', 101)


def test_compressed_round_trip_and_checks():
    grey = np.arange(48, dtype=np.uint16).reshape(6, 8) * 1000
    data, fmt = image.encode_compressed(grey, 'png')
    assert fmt == 'mono16; png compressed mono16'
    assert np.array_equal(image.decode_compressed(data, fmt), grey)
    bgr = np.full((16, 16, 3), 90, np.uint8)
    data, fmt = image.encode_compressed(bgr, 'jpeg', 90)
    assert image.decode_compressed(data, fmt).shape == (16, 16, 3)
    with pytest.raises(ImageConversionError, match='not JPEG or PNG'):
        image.decode_compressed(b'hello', 'jpeg')
    with pytest.raises(ImageConversionError, match='compressedDepth'):
        image.decode_compressed(data, '16UC1; compressedDepth')
    with pytest.raises(ImageConversionError, match="'jpeg' or 'png'"):
        image.encode_compressed(bgr, 'bmp')


def test_decompression_bomb_is_refused_before_decoding():
    _ok, buf = cv2.imencode('.png', np.zeros((4, 4), np.uint8))
    head = bytearray(buf.tobytes())
    head[16:20] = (1 << 14).to_bytes(4, 'big')
    head[20:24] = (1 << 14).to_bytes(4, 'big')
    with pytest.raises(ImageConversionError, match='larger than'):
        image.decode_compressed(bytes(head), 'png')


def test_significant_bits_ignore_a_few_hot_pixels_but_not_many():
    twelve = np.full((100, 100), 4000, np.uint16)
    assert image.significant_bits(twelve) == 12
    twelve[0, :10] = 65535  # 0.1 % of the pixels: hot pixels, ignored
    assert image.significant_bits(twelve) == 12
    twelve[1, :] = 65535  # 1 %: the image really uses 16 bits
    assert image.significant_bits(twelve) == 16
    assert image.significant_bits(np.array([[3, 65535]], np.uint16)) == 16  # tiny: the maximum


def test_a_stream_bit_depth_rises_only_after_several_frames_and_resets():
    depth = image.BitDepth()
    ten = np.full((10, 10), 1000, np.uint16)
    sixteen = np.full((10, 10), 60000, np.uint16)
    assert depth.update(ten) == 10
    assert [depth.update(sixteen) for _ in range(image.BIT_DEPTH_FRAMES)][-2:] == [10, 16]
    assert depth.update(ten) == 16  # never falls by itself
    depth.reset()
    assert depth.bits == 0 and depth.update(ten) == 10
    fixed = image.BitDepth(12)
    assert fixed.update(sixteen) == 12 and fixed.scale(ten).dtype == np.uint8
    assert image.BitDepth().scale(np.zeros((2, 2), np.uint8)).dtype == np.uint8
    with pytest.raises(ImageConversionError):
        image.BitDepth(7)


def test_compressed_size_comes_from_the_header_and_limits_apply_before_decoding():
    jpeg = cv2.imencode('.jpg', np.zeros((24, 32, 3), np.uint8))[1].tobytes()
    png = cv2.imencode('.png', np.zeros((5, 7), np.uint16))[1].tobytes()
    assert image.compressed_size(jpeg) == (32, 24) and image.compressed_size(png) == (7, 5)
    with pytest.raises(ImageConversionError, match='larger than the 700 pixels'):
        image.decode_compressed(jpeg, max_pixels=700)
    with pytest.raises(ImageConversionError, match='header says 32x24 but camera_info is'):
        image.decode_compressed(jpeg, size=(640, 480))
    assert image.decode_compressed(jpeg, size=(32, 24)).shape == (24, 32, 3)
    with pytest.raises(ImageConversionError, match='larger than the 10 pixels'):
        image.raw_to_cv(bytes(16), 'mono8', 4, 4, 4, max_pixels=10)


def test_encoding_names_are_read_in_any_case_and_depth_only_where_asked():
    assert image.raw_to_cv(bytes([7]), 'MONO8', 1, 1, 1).tolist() == [[7]]
    depth = np.array([[1.5, np.nan]], np.float32).tobytes()
    with pytest.raises(ImageConversionError, match='unsupported image encoding'):
        image.decode_raw(depth, '32FC1', 2, 1, 8)
    assert image.decode_raw(depth, '32fc1', 2, 1, 8, depth=True).dtype == np.float32


@pytest.mark.parametrize('encoding', ['yuv422', 'UYVY', 'yuv422_yuy2', 'yuyv'])
def test_usb_cameras_4_2_2_yuv_is_read(encoding):
    # before: 'unsupported image encoding' on every frame of a usb_cam driver's stream
    luma = np.arange(8 * 6, dtype=np.uint8).reshape(6, 8) * 5
    chroma = np.full_like(luma, 128)  # no colour: every channel is the luma
    first_is_chroma = encoding.lower() in ('yuv422', 'uyvy')
    pairs = np.stack((chroma, luma) if first_is_chroma else (luma, chroma), axis=-1)
    padded = np.zeros((6, 8 * 2 + 4), np.uint8)  # 4 bytes of row padding
    padded[:, :16] = pairs.reshape(6, 16)
    bgr = image.raw_to_cv(padded.tobytes(), encoding, 8, 6, 20)
    assert bgr.shape == (6, 8, 3)
    grey = np.clip(1.164 * (luma.astype(float) - 16.0), 0, 255)  # BT.601, video range
    np.testing.assert_allclose(bgr, np.repeat(grey[..., None], 3, axis=2), atol=1.5)


def test_tracking_factor_is_the_smallest_whole_factor_within_the_width():
    from initsel_ros.image import tracking_factor

    assert [tracking_factor(w, 1280) for w in (640, 1280, 1281, 1920, 2560, 3840)] == [
        1,
        1,
        2,
        2,
        2,
        3,
    ]
    assert tracking_factor(1920, 0) == 1  # 0: no limit


@pytest.mark.parametrize('dtype,channels', [(np.uint8, 1), (np.uint8, 3), (np.uint16, 1)])
def test_downscaled_averages_whole_blocks(dtype, channels):
    from initsel_ros.image import downscaled

    rng = np.random.default_rng(0)
    shape = (7, 9) if channels == 1 else (7, 9, channels)
    image = rng.integers(0, 200, size=shape).astype(dtype)
    assert downscaled(image, 1) is image
    small = downscaled(image, 2)
    assert small.shape[:2] == (3, 4) and small.dtype == dtype
    block = image[0:2, 2:4].astype(np.float64).mean(axis=(0, 1))
    np.testing.assert_allclose(small[0, 1], block, atol=0.5 + 1e-9)  # (rounded)
    bottom_right = image[4:6, 6:8].astype(np.float64).mean(axis=(0, 1))  # (row 6, column 8:
    np.testing.assert_allclose(small[2, 3], bottom_right, atol=0.5 + 1e-9)  # in no block)


@pytest.mark.parametrize('factor', [2, 3])
def test_binned_intrinsics_and_unbinned_pixels_agree_with_the_averaged_blocks(factor):
    from initsel_ros.camera import Intrinsics
    from initsel_ros.image import downscaled, unbinned_pixels

    camera = Intrinsics.tum_fr3()
    small = camera.binned(factor)
    assert (small.width, small.height) == (640 // factor, 480 // factor)
    assert small.fx == pytest.approx(camera.fx / factor)
    # the principal point maps back onto itself, and a small pixel onto its block's centre
    back = unbinned_pixels(np.array([[small.cx, small.cy], [0.0, 0.0]]), factor)
    np.testing.assert_allclose(back, [[camera.cx, camera.cy], [(factor - 1) / 2] * 2])
    # a bright spot's centroid lands where unbinned_pixels says
    image = np.zeros((480, 640), np.uint8)
    image[101 : 101 + 2 * factor, 203 : 203 + 2 * factor] = 255  # spot centre (205.5+, 102.5+)
    shrunk = downscaled(image, factor).astype(np.float64)
    ys, xs = np.indices(shrunk.shape)
    centroid = [(xs * shrunk).sum() / shrunk.sum(), (ys * shrunk).sum() / shrunk.sum()]
    want = [203 + factor - 0.5, 101 + factor - 0.5]
    np.testing.assert_allclose(unbinned_pixels(np.array(centroid), factor), want, atol=1e-9)
    assert camera.binned(1) is camera


def test_a_depth_encoding_on_the_image_topic_is_named_as_one():
    with pytest.raises(ImageConversionError, match=r"'32FC1' .*depth cameras publish depth"):
        image.encoding_info('32FC1')
