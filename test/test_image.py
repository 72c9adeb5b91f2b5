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
        (('yuv422', 2, 2, 4), 'unsupported'),
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
