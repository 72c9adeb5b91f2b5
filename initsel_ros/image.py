"""Images without ROS: decode by encoding, to grey, to BGR, 16-bit scaling, JPEG/PNG.

The one home of image decoding and normalization: the node's message conversions
(:mod:`initsel_ros.ros.conversions`), the selector (:func:`to_gray`), the datasets and the
overlay (:func:`to_bgr`) use it. Raw images are read with ``np.frombuffer`` honouring ``step``
(row padding) and the byte order; compressed ones are decoded with ``cv2.imdecode`` after a
header check. Every failure is an :class:`~initsel_ros.errors.ImageConversionError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from initsel_ros.errors import ImageConversionError


@dataclass(frozen=True)
class EncodingInfo:
    """Layout of one ``sensor_msgs/Image`` encoding."""

    channels: int
    dtype: str  # numpy dtype name of one channel, native order
    #: cv2 code turning the raw (H, W) or (H, W, C) array into BGR, or None
    to_bgr: int | None


#: Supported encodings (sensor_msgs/image_encodings.hpp names).
ENCODINGS: dict[str, EncodingInfo] = {
    'mono8': EncodingInfo(1, 'uint8', None),
    'mono16': EncodingInfo(1, 'uint16', None),
    '16UC1': EncodingInfo(1, 'uint16', None),
    'rgb8': EncodingInfo(3, 'uint8', cv2.COLOR_RGB2BGR),
    'bgr8': EncodingInfo(3, 'uint8', None),
    'rgba8': EncodingInfo(4, 'uint8', cv2.COLOR_RGBA2BGR),
    'bgra8': EncodingInfo(4, 'uint8', cv2.COLOR_BGRA2BGR),
    # OpenCV names Bayer patterns after the second row, so RGGB is its BayerBG (as cv_bridge).
    'bayer_rggb8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerBG2BGR),
    'bayer_bggr8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerRG2BGR),
    'bayer_gbrg8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerGR2BGR),
    'bayer_grbg8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerGB2BGR),
}

#: Largest compressed image decoded, pixels (its header is read first: no decompression bomb).
MAX_DECODED_PIXELS = 1 << 26
_PNG_MAGIC = b'\x89PNG\r\n\x1a\n'
_JPEG_MAGIC = b'\xff\xd8'


# ---------------------------------------------------------------------------- raw images
def decode_raw(
    data: bytes | bytearray | memoryview | np.ndarray,
    encoding: str,
    width: int,
    height: int,
    step: int,
    is_bigendian: bool = False,
) -> np.ndarray:
    """Raw image bytes (a ``sensor_msgs/Image``'s fields) as an array in their channel order.

    Args:
        data: the pixel bytes, ``step * height`` at least.
        encoding: one of :data:`ENCODINGS` (``sensor_msgs/image_encodings.hpp`` names).
        width: pixels per row.
        height: rows.
        step: bytes per row, padding included.
        is_bigendian: byte order of 16-bit encodings.

    Returns:
        (H, W) for mono and Bayer encodings (raw mosaic), (H, W, C) otherwise; uint8, or
        uint16 (native byte order) for mono16. A view on ``data`` when no copy is needed.

    Raises:
        ImageConversionError: unknown encoding, zero size, ``step`` shorter than a row, or
            ``data`` shorter than ``step * height``.
    """
    info = ENCODINGS.get(encoding)
    if info is None:
        raise ImageConversionError(
            f'unsupported image encoding {encoding!r} (supported: {", ".join(ENCODINGS)})'
        )
    height, width, step = int(height), int(width), int(step)
    if height <= 0 or width <= 0:
        raise ImageConversionError(f'{encoding} image has zero size ({width}x{height})')
    itemsize = np.dtype(info.dtype).itemsize
    row_bytes = width * info.channels * itemsize
    if step < row_bytes:
        raise ImageConversionError(
            f'{encoding} image {width}x{height}: step {step} < width * bytes per pixel '
            f'= {row_bytes}'
        )
    data = np.frombuffer(data, dtype=np.uint8)
    if data.size < step * height:
        raise ImageConversionError(
            f'{encoding} image {width}x{height}: data has {data.size} bytes, expected '
            f'step * height = {step * height}'
        )
    rows = data[: step * height].reshape(height, step)[:, :row_bytes]
    if itemsize == 1:
        pixels = rows
    else:
        order = '>' if is_bigendian else '<'
        pixels = np.ascontiguousarray(rows).view(np.dtype(info.dtype).newbyteorder(order))
        pixels = pixels.astype(info.dtype, copy=False)  # native order
    if info.channels == 1:
        return pixels.reshape(height, width)
    return pixels.reshape(height, width, info.channels)


def significant_bits(pixels: np.ndarray) -> int:
    """Bits a 16-bit image uses: those of its largest value, at least 8 (0 when empty)."""
    if pixels.size == 0:
        return 0
    return max(8, int(pixels.max()).bit_length())


def to_8bit(pixels: np.ndarray, bits: int = 0) -> np.ndarray:
    """A uint16 image whose values use ``bits`` bits, as uint8 (``bits - 8`` low bits dropped).

    Args:
        pixels: uint16 array, any shape.
        bits: significant bits, 8 to 16 (values above ``2**bits - 1`` saturate); 0 = this
            image's own :func:`significant_bits`.
    """
    bits = bits or significant_bits(pixels)
    shift = min(max(int(bits), 8), 16) - 8
    top = (1 << (shift + 8)) - 1
    if top < 0xFFFF:
        pixels = np.minimum(pixels, top)
    return (pixels >> shift).astype(np.uint8)


def to_cv(pixels: np.ndarray, encoding: str, bit_depth: int = 0) -> np.ndarray:
    """:func:`decode_raw` output in ``encoding`` -> (H, W) uint8 grey or (H, W, 3) uint8 BGR.

    Colour and Bayer encodings become BGR; 16-bit images are scaled by :func:`to_8bit` with
    ``bit_depth`` significant bits (0 = this image's own :func:`significant_bits`).

    Raises:
        ImageConversionError: when the colour conversion fails.
    """
    if pixels.dtype == np.uint16:
        return to_8bit(pixels, bit_depth)
    info = ENCODINGS[encoding]
    if info.to_bgr is not None:
        try:
            return cv2.cvtColor(np.ascontiguousarray(pixels), info.to_bgr)
        except cv2.error as exc:
            raise ImageConversionError(
                f'{encoding} image {pixels.shape[1]}x{pixels.shape[0]}: cannot convert to BGR: '
                f'{exc}'
            ) from exc
    return pixels


# ---------------------------------------------------------------------------- grey and BGR
def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image from grey uint8/uint16 or (H, W, 3|4) BGR(A) uint8.

    16-bit grey keeps its high byte (``>> 8``).

    Raises:
        ImageConversionError: for any other shape or type, or an empty image.
    """
    img = np.asarray(image)
    if img.size == 0 or img.ndim not in (2, 3):
        raise ImageConversionError(f'expected a non-empty 2-D or 3-D image, got {img.shape}')
    if img.ndim == 3:
        if img.dtype != np.uint8 or img.shape[2] not in (1, 3, 4):
            raise ImageConversionError(
                f'colour images must be (H, W, 3 or 4) uint8, got {img.shape} {img.dtype}'
            )
        if img.shape[2] == 1:
            img = img[:, :, 0]
        else:
            code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
            return cv2.cvtColor(img, code)
    if img.dtype == np.uint16:
        return (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise ImageConversionError(f'grey images must be uint8 or uint16, got {img.dtype}')
    return np.ascontiguousarray(img)


def to_bgr(image: np.ndarray, *, copy: bool = False) -> np.ndarray:
    """(H, W, 3) uint8 BGR from grey, BGR or BGRA, uint8 or uint16 (high byte kept).

    Args:
        image: (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), uint8 or uint16.
        copy: return a copy even when ``image`` already is uint8 BGR (to draw on it).

    Raises:
        ImageConversionError: any other type or shape.
    """
    img = np.asarray(image)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise ImageConversionError(f'expected a uint8 or uint16 image, got {img.dtype}')
    if img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 1):
        return cv2.cvtColor(img.reshape(img.shape[:2]), cv2.COLOR_GRAY2BGR)
    if img.ndim == 3 and img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img.ndim == 3 and img.shape[2] == 3:
        return img.copy() if copy else img
    raise ImageConversionError(f'expected (H, W), (H, W, 3) or (H, W, 4) image, got {img.shape}')


# ------------------------------------------------------------------------- compressed images
#: Largest compressed image decoded, pixels (its header is read first: no decompression bomb).
MAX_DECODED_PIXELS = 1 << 26
_PNG_MAGIC = b'\x89PNG\r\n\x1a\n'
_JPEG_MAGIC = b'\xff\xd8'


def decode_compressed(
    data: bytes | bytearray | memoryview | np.ndarray,
    fmt: str = '',
) -> np.ndarray:
    """Decode JPEG or PNG bytes (a ``sensor_msgs/CompressedImage``) with ``cv2.imdecode``.

    The size in the header is checked before decoding (no decompression bomb).

    Args:
        data: the compressed bytes.
        fmt: the message's ``format`` field (``compressedDepth`` is refused).

    Returns:
        (H, W) grey or (H, W, 3) BGR, uint8, or uint16 for 16-bit PNGs (alpha dropped).

    Raises:
        ImageConversionError: empty data, not JPEG/PNG (``compressedDepth`` included), larger
            than :data:`MAX_DECODED_PIXELS`, or corrupt.
    """
    fmt = str(fmt)
    data = np.frombuffer(data, dtype=np.uint8)
    what = f'compressed image (format {fmt!r}, {data.size} bytes)'
    if 'compresseddepth' in fmt.lower().replace(' ', ''):
        raise ImageConversionError(f'{what}: compressedDepth is a depth image, not a camera image')
    head = bytes(data[:64])
    if head.startswith(_PNG_MAGIC):
        size = _png_size(head)
    elif head.startswith(_JPEG_MAGIC):
        size = _jpeg_size(data)
    else:
        raise ImageConversionError(f'{what}: not JPEG or PNG data')
    if size is None:
        raise ImageConversionError(f'{what}: corrupt header')
    width, height = size
    if width * height > MAX_DECODED_PIXELS or width == 0 or height == 0:
        raise ImageConversionError(
            f'{what}: {width}x{height} is outside 1..{MAX_DECODED_PIXELS} pixels'
        )
    try:
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        raise ImageConversionError(f'{what}: cannot decode: {exc}') from exc
    if image is None or image.size == 0:
        raise ImageConversionError(f'{what}: cannot decode (corrupt data?)')
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.dtype not in (np.uint8, np.uint16) or image.ndim not in (2, 3):
        raise ImageConversionError(f'{what}: decoded to unsupported {image.dtype} {image.shape}')
    return np.ascontiguousarray(image)


def encode_compressed(
    pixels: np.ndarray,
    fmt: str = 'jpeg',
    quality: int = 95,
) -> tuple[bytes, str]:
    """Encode (H, W) grey or (H, W, 3) BGR pixels (uint8; uint16 for PNG) as JPEG or PNG.

    Returns:
        The bytes and the image_transport ``format``, e.g. ``'bgr8; jpeg compressed bgr8'``.

    Raises:
        ImageConversionError: unknown ``fmt`` or pixels OpenCV cannot encode that way.
    """
    pixels = np.asarray(pixels)
    if fmt not in ('jpeg', 'png'):
        raise ImageConversionError(f"compressed format must be 'jpeg' or 'png', got {fmt!r}")
    depth = 16 if pixels.dtype == np.uint16 else 8
    encoding = f'{"mono" if pixels.ndim == 2 else "bgr"}{depth}'
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if fmt == 'jpeg' else []
    try:
        ok, buffer = cv2.imencode(f'.{"jpg" if fmt == "jpeg" else "png"}', pixels, params)
    except cv2.error as exc:
        raise ImageConversionError(f'cannot encode {encoding} as {fmt}: {exc}') from exc
    if not ok:
        raise ImageConversionError(f'cannot encode {encoding} as {fmt}')
    return buffer.tobytes(), f'{encoding}; {fmt} compressed {encoding}'


def _png_size(head: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR chunk, or None."""
    if len(head) < 24 or head[12:16] != b'IHDR':
        return None
    return int.from_bytes(head[16:20], 'big'), int.from_bytes(head[20:24], 'big')


def _jpeg_size(data: np.ndarray) -> tuple[int, int] | None:
    """(width, height) from a JPEG's first start-of-frame marker, or None."""
    buf = memoryview(np.ascontiguousarray(data))
    i = 2
    while i + 9 <= len(buf):
        if buf[i] != 0xFF:
            return None
        marker = buf[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a length
            i += 2
            continue
        length = int.from_bytes(buf[i + 2 : i + 4], 'big')
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height = int.from_bytes(buf[i + 5 : i + 7], 'big')
            width = int.from_bytes(buf[i + 7 : i + 9], 'big')
            return width, height
        if length < 2:
            return None
        i += 2 + length
    return None


__all__ = [
    'ENCODINGS',
    'MAX_DECODED_PIXELS',
    'EncodingInfo',
    'decode_compressed',
    'decode_raw',
    'encode_compressed',
    'significant_bits',
    'to_8bit',
    'to_bgr',
    'to_cv',
    'to_gray',
]
