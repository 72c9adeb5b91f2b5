"""Images without ROS: decode by encoding, to grey, to BGR, 16-bit scaling, JPEG/PNG.

The one home of image decoding and normalization: the node (:func:`raw_to_cv`,
:func:`compressed_to_cv`), its message conversions (:mod:`initsel_ros.ros.conversions`), the
bag reader, the selector (:func:`to_gray`, :class:`BitDepth`) and the overlay (:func:`to_bgr`)
use it. Raw images are read with ``np.frombuffer`` honouring ``step`` (row padding) and the
byte order; compressed ones are decoded with ``cv2.imdecode`` after their size has been read
from the JPEG/PNG header (no decompression bomb). ``cv2.imdecode`` cannot report libjpeg's
"Corrupt JPEG data" warnings: a JPEG whose entropy-coded data is damaged decodes to a partly
grey image without any error. Every failure is an
:class:`~initsel_ros.errors.ImageConversionError`.

16-bit pixels have one scaling rule (:func:`significant_bits`, :func:`to_8bit`): the fewest
bits, at least 8, that hold all but :data:`HOT_PIXEL_FRACTION` of a frame's pixels, the
``bits - 8`` low bits dropped. A stream keeps one depth across frames (:class:`BitDepth`).
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
    '8UC1': EncodingInfo(1, 'uint8', None),
    'mono16': EncodingInfo(1, 'uint16', None),
    '16UC1': EncodingInfo(1, 'uint16', None),
    'rgb8': EncodingInfo(3, 'uint8', cv2.COLOR_RGB2BGR),
    'bgr8': EncodingInfo(3, 'uint8', None),
    '8UC3': EncodingInfo(3, 'uint8', None),  # channel order unknown: taken as BGR
    'rgba8': EncodingInfo(4, 'uint8', cv2.COLOR_RGBA2BGR),
    'bgra8': EncodingInfo(4, 'uint8', cv2.COLOR_BGRA2BGR),
    # OpenCV names Bayer patterns after the second row, so RGGB is its BayerBG (as cv_bridge).
    'bayer_rggb8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerBG2BGR),
    'bayer_bggr8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerRG2BGR),
    'bayer_gbrg8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerGR2BGR),
    'bayer_grbg8': EncodingInfo(1, 'uint8', cv2.COLOR_BayerGB2BGR),
    # 4:2:2 YUV, two bytes a pixel (USB cameras): yuv422 and uyvy are U Y V Y, yuv422_yuy2 and
    # yuyv Y U Y V (the ROS names of the same two layouts).
    'yuv422': EncodingInfo(2, 'uint8', cv2.COLOR_YUV2BGR_UYVY),
    'uyvy': EncodingInfo(2, 'uint8', cv2.COLOR_YUV2BGR_UYVY),
    'yuv422_yuy2': EncodingInfo(2, 'uint8', cv2.COLOR_YUV2BGR_YUY2),
    'yuyv': EncodingInfo(2, 'uint8', cv2.COLOR_YUV2BGR_YUY2),
}

#: Depth encodings, read only where asked (``decode_raw(..., depth=True)``: the bag reader).
DEPTH_ENCODINGS: dict[str, EncodingInfo] = {
    '32FC1': EncodingInfo(1, 'float32', None),
    '16UC1': EncodingInfo(1, 'uint16', None),
}
_BY_LOWER = {name.lower(): name for name in ENCODINGS}
_DEPTH_BY_LOWER = {name.lower(): name for name in DEPTH_ENCODINGS}

#: Largest compressed image decoded, pixels (its header is read first: no decompression bomb).
MAX_DECODED_PIXELS = 1 << 26
#: Share of a frame's pixels that may lie above its significant bits (hot pixels, glints).
HOT_PIXEL_FRACTION = 1e-3
#: Frames in a row that must need more bits before a stream's automatic depth rises.
BIT_DEPTH_FRAMES = 3
_PNG_MAGIC = b'\x89PNG\r\n\x1a\n'
_JPEG_MAGIC = b'\xff\xd8'


def encoding_info(encoding: str, *, depth: bool = False) -> tuple[str, EncodingInfo]:
    """The canonical name and layout of ``encoding`` (case-insensitive).

    Args:
        encoding: a ``sensor_msgs/image_encodings.hpp`` name.
        depth: also accept :data:`DEPTH_ENCODINGS`.

    Raises:
        ImageConversionError: unknown encoding.
    """
    name = _BY_LOWER.get(str(encoding).lower())
    if name is not None:
        return name, ENCODINGS[name]
    name = _DEPTH_BY_LOWER.get(str(encoding).lower()) if depth else None
    if name is not None:
        return name, DEPTH_ENCODINGS[name]
    supported = ', '.join(dict.fromkeys([*ENCODINGS, *(DEPTH_ENCODINGS if depth else ())]))
    hint = ''
    if str(encoding).lower() in _DEPTH_BY_LOWER:  # a depth image on the image topic
        hint = (
            f'; {encoding} is what depth cameras publish depth in (REP 118): remap the image '
            'topic to the intensity or colour image'
        )
    raise ImageConversionError(
        f'unsupported image encoding {encoding!r} (supported: {supported}){hint}'
    )


# ---------------------------------------------------------------------------- raw images
def decode_raw(
    data: bytes | bytearray | memoryview | np.ndarray,
    encoding: str,
    width: int,
    height: int,
    step: int,
    is_bigendian: bool = False,
    *,
    depth: bool = False,
) -> np.ndarray:
    """Raw image bytes (a ``sensor_msgs/Image``'s fields) as an array in their channel order.

    Args:
        data: the pixel bytes, ``step * height`` at least.
        encoding: one of :data:`ENCODINGS` (``sensor_msgs/image_encodings.hpp`` names, any
            case).
        width: pixels per row.
        height: rows.
        step: bytes per row, padding included.
        is_bigendian: byte order of multi-byte encodings.
        depth: also accept :data:`DEPTH_ENCODINGS` (32FC1 is returned as float32).

    Returns:
        (H, W) for mono and Bayer encodings (raw mosaic), (H, W, C) otherwise; uint8, or
        uint16 (native byte order) for mono16. A view on ``data`` when no copy is needed.

    Raises:
        ImageConversionError: unknown encoding, zero size, ``step`` shorter than a row, or
            ``data`` shorter than ``step * height``.
    """
    encoding, info = encoding_info(encoding, depth=depth)
    height, width, step = int(height), int(width), int(step)
    if height <= 0 or width <= 0:
        raise ImageConversionError(f'{encoding} image has zero size ({width}x{height})')
    if info.channels == 2 and width % 2:  # (4:2:2 YUV: a U and a V for two pixels)
        raise ImageConversionError(f'{encoding} image {width}x{height}: 4:2:2 needs an even width')
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


def significant_bits(pixels: np.ndarray, fraction: float = HOT_PIXEL_FRACTION) -> int:
    """Bits a 16-bit image uses: the fewest, at least 8, that hold all its pixels but a few.

    Up to ``fraction`` of the pixels (rounded down: none in a tiny image) may lie above, so one
    hot pixel or a small glint does not decide the scaling. 0 when ``pixels`` is empty.
    """
    if pixels.size == 0:
        return 0
    allowed = int(fraction * pixels.size)
    bits = max(8, int(pixels.max()).bit_length())
    # Drop the top bit while only ``allowed`` pixels need it (usually not once: one pass).
    while bits > 8 and np.count_nonzero(pixels >= (1 << (bits - 1))) <= allowed:
        bits -= 1
    return bits


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


class BitDepth:
    """How one stream's 16-bit frames become 8-bit: fixed significant bits, or automatic.

    Automatic (``bits=0``): the first 16-bit frame's :func:`significant_bits` (a hot pixel does
    not count), raised only when :data:`BIT_DEPTH_FRAMES` frames in a row need more (then to
    the fewest bits all of them need). It never falls while the stream lasts (the contrast
    would jump); :meth:`reset` forgets it. uint8 frames pass through untouched.
    """

    def __init__(self, bits: int = 0, frames: int = BIT_DEPTH_FRAMES) -> None:
        bits = int(bits)
        if bits != 0 and not 8 <= bits <= 16:
            raise ImageConversionError(f'bit depth must be 0 or 8 to 16, got {bits}')
        self.fixed = bits
        self.frames = max(1, int(frames))
        self._auto = 0
        self._higher: list[int] = []  # bits of the latest frames that needed more

    @property
    def bits(self) -> int:
        """The bits in use: the fixed ones, else the automatic ones (0 before a 16-bit frame)."""
        return self.fixed or self._auto

    def reset(self) -> None:
        """Forget the automatic depth (the next 16-bit frame sets it again)."""
        self._auto = 0
        self._higher = []

    def update(self, pixels: np.ndarray) -> int:
        """Take a 16-bit frame into account; the bits to scale it by."""
        if self.fixed:
            return self.fixed
        bits = significant_bits(pixels)
        if not self._auto:
            self._auto = bits
        elif bits > self._auto:
            self._higher.append(bits)
            if len(self._higher) >= self.frames:
                self._auto = min(self._higher)
                self._higher = []
        else:
            self._higher = []
        return self._auto

    def scale(self, image: np.ndarray) -> np.ndarray:
        """``image`` as uint8: 16-bit ones scaled by :meth:`update`, others unchanged."""
        if image.dtype != np.uint16:
            return image
        return to_8bit(image, self.update(image))


def to_cv(pixels: np.ndarray, encoding: str, bit_depth: int | BitDepth = 0) -> np.ndarray:
    """:func:`decode_raw` output in ``encoding`` -> (H, W) uint8 grey or (H, W, 3) uint8 BGR.

    Colour and Bayer encodings become BGR; 16-bit images are scaled by :func:`to_8bit` with
    ``bit_depth`` significant bits (0 = this image's own :func:`significant_bits`; a
    :class:`BitDepth` = the stream's).

    Raises:
        ImageConversionError: unknown encoding, or the colour conversion fails.
    """
    if pixels.dtype == np.uint16:
        if isinstance(bit_depth, BitDepth):
            return bit_depth.scale(pixels)
        return to_8bit(pixels, bit_depth)
    encoding, info = encoding_info(encoding)
    if info.to_bgr is not None:
        try:
            return cv2.cvtColor(np.ascontiguousarray(pixels), info.to_bgr)
        except cv2.error as exc:
            raise ImageConversionError(
                f'{encoding} image {pixels.shape[1]}x{pixels.shape[0]}: cannot convert to BGR: '
                f'{exc}'
            ) from exc
    return pixels


def raw_to_cv(
    data: bytes | bytearray | memoryview | np.ndarray,
    encoding: str,
    width: int,
    height: int,
    step: int,
    is_bigendian: bool = False,
    bit_depth: int | BitDepth = 0,
    *,
    max_pixels: int = MAX_DECODED_PIXELS,
) -> np.ndarray:
    """A raw frame (a ``sensor_msgs/Image``'s fields) as the selector's input: uint8 grey or BGR.

    :func:`decode_raw`, then :func:`to_cv`; a frame of more than ``max_pixels`` pixels is
    refused before anything is read.

    Raises:
        ImageConversionError: as :func:`decode_raw` and :func:`to_cv`, or too large.
    """
    check_size(int(width), int(height), max_pixels, f'{encoding} image')
    return to_cv(
        decode_raw(data, encoding, width, height, step, is_bigendian), encoding, bit_depth
    )


def check_size(
    width: int, height: int, max_pixels: int = MAX_DECODED_PIXELS, what: str = 'image'
) -> None:
    """Refuse a ``width`` x ``height`` frame larger than ``max_pixels`` (before decoding it).

    Raises:
        ImageConversionError: naming the size and the limit.
    """
    if width * height > max_pixels:
        raise ImageConversionError(
            f'{what} of {width}x{height} = {width * height} pixels is larger than the '
            f'{max_pixels} pixels allowed (max_image_pixels): not decoded'
        )


# ---------------------------------------------------------------------------- grey and BGR
def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image from grey uint8/uint16 or (H, W, 3|4) BGR(A) uint8.

    16-bit grey is scaled by its own :func:`significant_bits` (:func:`to_8bit`).

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
        return to_8bit(img)
    if img.dtype != np.uint8:
        raise ImageConversionError(f'grey images must be uint8 or uint16, got {img.dtype}')
    return np.ascontiguousarray(img)


def to_bgr(image: np.ndarray, *, copy: bool = False) -> np.ndarray:
    """(H, W, 3) uint8 BGR from grey, BGR or BGRA, uint8 or uint16 (scaled by :func:`to_8bit`).

    Args:
        image: (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), uint8 or uint16.
        copy: return a copy even when ``image`` already is uint8 BGR (to draw on it).

    Raises:
        ImageConversionError: any other type or shape.
    """
    img = np.asarray(image)
    if img.dtype == np.uint16:
        img = to_8bit(img)
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


def compressed_size(data: bytes | bytearray | memoryview | np.ndarray) -> tuple[int, int]:
    """(width, height) of JPEG or PNG bytes, read from the header without decoding.

    Raises:
        ImageConversionError: neither JPEG nor PNG, or no readable size in the header.
    """
    data = np.frombuffer(data, dtype=np.uint8)
    head = bytes(data[:64])
    if head.startswith(_PNG_MAGIC):
        size = _png_size(head)
    elif head.startswith(_JPEG_MAGIC):
        size = _jpeg_size(data)
    else:
        raise ImageConversionError('not JPEG or PNG data')
    if size is None:
        raise ImageConversionError('corrupt header (no image size)')
    return size


def decode_compressed(
    data: bytes | bytearray | memoryview | np.ndarray,
    fmt: str = '',
    *,
    max_pixels: int = MAX_DECODED_PIXELS,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """Decode JPEG or PNG bytes (a ``sensor_msgs/CompressedImage``) with ``cv2.imdecode``.

    The size in the header (:func:`compressed_size`) is checked before decoding: no
    decompression bomb, and nothing decoded that would be refused afterwards. Corrupt
    entropy-coded JPEG data is not detected (``cv2.imdecode`` does not report libjpeg's
    warnings).

    Args:
        data: the compressed bytes.
        fmt: the message's ``format`` field (``compressedDepth`` is refused).
        max_pixels: largest width * height decoded (at most :data:`MAX_DECODED_PIXELS`).
        size: the (width, height) the frame must have (the camera_info's), or None.

    Returns:
        (H, W) grey or (H, W, 3) BGR, uint8, or uint16 for 16-bit PNGs (alpha dropped).

    Raises:
        ImageConversionError: empty data, not JPEG/PNG (``compressedDepth`` included), larger
            than ``max_pixels``, of another size than ``size``, or corrupt.
    """
    fmt = str(fmt)
    data = np.frombuffer(data, dtype=np.uint8)
    what = f'compressed image (format {fmt!r}, {data.size} bytes)'
    if 'compresseddepth' in fmt.lower().replace(' ', ''):
        raise ImageConversionError(f'{what}: compressedDepth is a depth image, not a camera image')
    try:
        width, height = compressed_size(data)
    except ImageConversionError as exc:
        raise ImageConversionError(f'{what}: {exc}') from exc
    if width == 0 or height == 0:
        raise ImageConversionError(f'{what}: its header says {width}x{height}: not decoded')
    check_size(width, height, min(int(max_pixels), MAX_DECODED_PIXELS), f'{what}: a frame')
    if size is not None and (width, height) != tuple(size):
        raise ImageConversionError(
            f'{what}: its header says {width}x{height} but camera_info is for '
            f'{size[0]}x{size[1]}: not decoded'
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


def compressed_to_cv(
    data: bytes | bytearray | memoryview | np.ndarray,
    fmt: str = '',
    bit_depth: int | BitDepth = 0,
    *,
    max_pixels: int = MAX_DECODED_PIXELS,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """A compressed frame as the selector's input: uint8 grey or BGR (16-bit PNG scaled).

    :func:`decode_compressed`, then 16-bit pixels scaled as :func:`to_cv` does.

    Raises:
        ImageConversionError: as :func:`decode_compressed`.
    """
    pixels = decode_compressed(data, fmt, max_pixels=max_pixels, size=size)
    return to_cv(pixels, 'mono16', bit_depth) if pixels.dtype == np.uint16 else pixels


def encode_compressed(
    pixels: np.ndarray,
    fmt: str = 'jpeg',
    quality: int = 95,
) -> tuple[bytes, str]:
    """Encode (H, W) grey or (H, W, 3) BGR pixels (uint8 or uint16) as JPEG or PNG, as
    compressed_image_transport does: the one encoder of the node's tools and the bag writers.

    JPEG holds 8 bits only, so 16-bit pixels are always PNG (the ``format`` says so); PNG is
    written at compression level 1 (fast; lossless either way).

    Returns:
        The bytes and the image_transport ``format``, e.g. ``'bgr8; jpeg compressed bgr8'``.

    Raises:
        ImageConversionError: unknown ``fmt``, a quality outside 0-100, or pixels OpenCV
            cannot encode that way.
    """
    pixels = np.asarray(pixels)
    if fmt not in ('jpeg', 'png'):
        raise ImageConversionError(f"compressed format must be 'jpeg' or 'png', got {fmt!r}")
    if not 0 <= int(quality) <= 100:
        raise ImageConversionError(f'jpeg quality must be in 0-100, got {quality}')
    depth = 16 if pixels.dtype == np.uint16 else 8
    if depth == 16:
        fmt = 'png'
    encoding = f'{"mono" if pixels.ndim == 2 else "bgr"}{depth}'
    if fmt == 'jpeg':
        extension, params = '.jpg', [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    else:
        extension, params = '.png', [cv2.IMWRITE_PNG_COMPRESSION, 1]
    try:
        ok, buffer = cv2.imencode(extension, pixels, params)
    except cv2.error as exc:
        raise ImageConversionError(f'cannot encode {encoding} as {fmt}: {exc}') from exc
    if not ok:
        raise ImageConversionError(f'cannot encode {encoding} as {fmt}')
    return buffer.tobytes(), f'{encoding}; {fmt} compressed {encoding}'


def tracking_factor(width: int, max_width: int) -> int:
    """The smallest whole factor (1, 2, 3, ...) that brings an image ``width`` pixels wide
    within ``max_width`` (0 or less: 1, no limit)."""
    if max_width <= 0 or width <= max_width:
        return 1
    return -(-width // max_width)


def downscaled(image: np.ndarray, factor: int) -> np.ndarray:
    """``image`` (grey, colour or 16-bit) shrunk by a whole ``factor``: each block of factor x
    factor pixels averaged into one, the last columns and rows that fill no block left out
    (floor(width / factor) x floor(height / factor)); the image itself for a factor of 1.
    Its camera is :meth:`~initsel_ros.camera.Intrinsics.binned`, and its pixels map back to
    ``image``'s by :func:`unbinned_pixels`."""
    if factor <= 1:
        return image
    h, w = image.shape[:2]
    size = (max(w // factor, 1), max(h // factor, 1))
    whole = image[: size[1] * factor, : size[0] * factor]
    return cv2.resize(whole, size, interpolation=cv2.INTER_AREA)


def unbinned_pixels(pixels: np.ndarray, factor: int) -> np.ndarray:
    """Pixel coordinates (..., 2) of an image :func:`downscaled` by ``factor``, in the
    original image's (pixel centres at whole numbers in both: x -> factor x + (factor -
    1) / 2); float64."""
    pixels = np.asarray(pixels, dtype=np.float64)
    return pixels if factor <= 1 else pixels * factor + 0.5 * (factor - 1)


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
    'BIT_DEPTH_FRAMES',
    'DEPTH_ENCODINGS',
    'ENCODINGS',
    'HOT_PIXEL_FRACTION',
    'MAX_DECODED_PIXELS',
    'BitDepth',
    'EncodingInfo',
    'check_size',
    'compressed_size',
    'compressed_to_cv',
    'decode_compressed',
    'decode_raw',
    'downscaled',
    'encode_compressed',
    'encoding_info',
    'raw_to_cv',
    'significant_bits',
    'to_8bit',
    'to_bgr',
    'to_cv',
    'to_gray',
    'tracking_factor',
    'unbinned_pixels',
]
