"""Property-based fuzzing (hypothesis) of image conversion and the node's image path.

Three properties, shared by ``test/test_fuzz.py`` (a few hundred examples in CI) and
``initsel bench --fuzz N`` (any number):

* :func:`check_conversion`: ``image_to_numpy`` / ``image_to_cv`` either return an array of the
  documented shape and type or raise :class:`ImageConversionError`, for any encoding, size
  (0 and 1 pixel included), step, byte length and endianness.
* :func:`check_node_callbacks`: the ``selector`` node, sent a random CameraInfo (NaN or zero
  intrinsics, zero size, a principal point outside the image) and a random Image on its
  topics, never reports an internal error and processes the next good frame; after an
  implausible CameraInfo the intrinsics in ``~/status`` are still the previous ones.
* :func:`check_compressed_callbacks`: a node taking ``image_transport: compressed``, sent a
  random CompressedImage (JPEG or PNG, truncated, with flipped bytes, a header claiming
  another or a huge size, a foreign format, garbage), never reports an internal error,
  refuses before decoding every frame whose header gives another size than camera_info's
  or more than ``max_image_pixels``, and processes the next good frame.

The node is driven only through its public interfaces (:class:`NodeProbe`: topics and the
``~/reset`` service of a :class:`~initsel_ros.ros.harness.NodeHarness`, its ``~/status``
read back), never through its private methods or state. hypothesis is imported inside the
functions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from rclpy.logging import LoggingSeverity
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from initsel_ros.benchmarks.live import configure_ros_environment, textured_frames
from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ImageConversionError
from initsel_ros.image import encode_compressed, encoding_info
from initsel_ros.names import Mode
from initsel_ros.policy import Reason
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.conversions import ENCODINGS
from initsel_ros.ros.harness import NodeHarness
from initsel_ros.status import FrameStatus

#: Encodings tried besides the supported ones (unknown, odd, empty).
FOREIGN_ENCODINGS = ('', '8UC3', 'rgb16', 'nv12', '32FC1', 'MONO8', 'bgr8 ', 'jpeg\x00')
#: The one reason the node must never report for a fuzzed frame.
INTERNAL_ERROR_REASON = Reason.INTERNAL_ERROR.value
#: Largest side of fuzzed images, pixels (kept small so thousands of cases run quickly).
MAX_SIDE = 48
UINT32_MAX = 2**32 - 1
#: Size of the probe's good frames (and of the compressed node's camera_info).
GOOD_SIZE = (160, 120)


@dataclass(frozen=True)
class ImageCase:
    """The fields of one fuzzed ``sensor_msgs/Image``."""

    encoding: str
    height: int
    width: int
    step: int
    n_bytes: int
    is_bigendian: bool
    seed: int

    def message(self) -> Image:
        """The Image message (data: ``n_bytes`` seeded random bytes)."""
        msg = Image()
        msg.encoding = self.encoding
        msg.height, msg.width, msg.step = self.height, self.width, self.step
        msg.is_bigendian = int(self.is_bigendian)
        msg.data = (
            np.random.default_rng(self.seed)
            .integers(0, 256, self.n_bytes, dtype=np.uint8)
            .tobytes()
        )
        return msg


def _bytes_per_pixel(encoding: str) -> int:
    try:
        _, info = encoding_info(encoding)
    except ImageConversionError:
        return 1
    return info.channels * np.dtype(info.dtype).itemsize


def image_cases() -> Any:
    """hypothesis strategy of :class:`ImageCase` (mostly plausible, sometimes absurd)."""
    from hypothesis import strategies as st

    side = st.one_of(
        st.integers(0, 2),
        st.integers(0, MAX_SIDE),
        st.sampled_from([0, 1, 2**16, 2**31, UINT32_MAX]),
    )

    def case(draw: Callable[[Any], Any], *layout: Any) -> ImageCase:
        """The case of ``layout`` (encoding, height, width, step, bytes), its byte order and
        data seed drawn."""
        return ImageCase(*layout, draw(st.booleans()), draw(st.integers(0, 2**32 - 1)))

    @st.composite
    def anything(draw: Callable[[Any], Any]) -> ImageCase:
        encoding = draw(
            st.one_of(
                st.sampled_from(sorted(ENCODINGS)),
                st.sampled_from(FOREIGN_ENCODINGS),
                st.text(max_size=8),
            )
        )
        height, width = draw(side), draw(side)
        row = width * _bytes_per_pixel(encoding)
        step = draw(
            st.one_of(
                st.just(row),
                st.integers(row, row + 9),
                st.integers(0, max(row, 1) * 2),
                st.sampled_from([0, 1, UINT32_MAX]),
            ).filter(lambda s: 0 <= s <= UINT32_MAX)
        )
        full = min(step * height, 4 * MAX_SIDE * MAX_SIDE * 4)
        n_bytes = draw(
            st.one_of(
                st.just(full),
                st.integers(0, full + 16),
                st.integers(max(0, full - 8), full),
                st.integers(0, 64),
            )
        )
        return case(draw, encoding, height, width, step, n_bytes)

    @st.composite
    def plausible(draw: Callable[[Any], Any]) -> ImageCase:
        """A supported encoding, 1..MAX_SIDE pixels a side, maybe padded rows or extra bytes."""
        encoding = draw(st.sampled_from(sorted(ENCODINGS)))
        height, width = draw(st.integers(1, MAX_SIDE)), draw(st.integers(1, MAX_SIDE))
        step = width * _bytes_per_pixel(encoding) + draw(st.sampled_from([0, 0, 1, 3, 8]))
        n_bytes = step * height + draw(st.sampled_from([0, 0, 0, 1, 100]))
        return case(draw, encoding, height, width, step, n_bytes)

    return st.one_of(plausible(), anything())


def check_conversion(case: ImageCase) -> str:
    """Convert one fuzzed message; returns 'ok' or 'rejected' and asserts the contract."""
    msg = case.message()
    try:
        raw = conv.image_to_numpy(msg)
    except ImageConversionError:
        raw = None
    try:
        cv = conv.image_to_cv(msg)
    except ImageConversionError:
        assert raw is None, f'image_to_cv rejected what image_to_numpy accepted: {case}'
        return 'rejected'
    assert raw is not None, f'image_to_numpy rejected what image_to_cv accepted: {case}'
    _, info = encoding_info(case.encoding)
    assert raw.shape[:2] == (case.height, case.width), (raw.shape, case)
    assert raw.dtype == np.dtype(info.dtype), (raw.dtype, case)
    assert cv.dtype == np.uint8, (cv.dtype, case)
    assert cv.shape[:2] == (case.height, case.width), (cv.shape, case)
    assert cv.ndim == 2 or (cv.ndim == 3 and cv.shape[2] == 3), (cv.shape, case)
    return 'ok'


@dataclass(frozen=True)
class InfoCase:
    """A fuzzed CameraInfo: K entries, size and distortion (None = send none)."""

    k: tuple[float, ...]
    width: int
    height: int
    distortion: tuple[float, ...]
    model: str


def info_cases(extreme: bool = False) -> Any:
    """hypothesis strategy of :class:`InfoCase` or None.

    Args:
        extreme: also draw any finite float (1e306, 5e-324, ...), not only NaN, infinities,
            zero, negatives and plausible values.
    """
    from hypothesis import strategies as st

    plain = st.sampled_from(
        [
            float('nan'),
            float('inf'),
            float('-inf'),
            0.0,
            -0.0,
            -1.0,
            1.0,
            320.0,
            240.0,
            525.0,
            1e6,
            -5e5,
        ]
    )
    number = st.one_of(plain, st.floats(allow_nan=True, allow_infinity=True)) if extreme else plain
    case = st.builds(
        InfoCase,
        k=st.tuples(*[number] * 9),
        width=st.sampled_from([0, 1, 64, 640, UINT32_MAX]),
        height=st.sampled_from([0, 1, 48, 480, UINT32_MAX]),
        distortion=st.one_of(st.just(()), st.tuples(*[number] * 5)),
        model=st.sampled_from(['plumb_bob', 'rational_polynomial', 'equidistant', '']),
    )
    return st.one_of(st.none(), case)


class NodeProbe:
    """The ``selector`` node in a private context, driven through its topics only.

    Each example restores the default intrinsics (a camera_info of the TUM fr3 camera the
    node's parameters describe) and a fresh reference (``~/reset``), so examples are
    independent; then the node gets the fuzzed camera_info and image on its topics, and its
    ``~/status`` says what it made of them.
    """

    def __init__(
        self, model_path: str, good_size: tuple[int, int] = GOOD_SIZE, compressed: bool = False
    ) -> None:
        configure_ros_environment()
        self.compressed = compressed
        self.harness = NodeHarness(
            {
                'model_file': model_path,
                'mode': Mode.CONTINUOUS.value,
                'image_transport': 'compressed' if compressed else 'raw',
            },
            namespace='/initsel_fuzz_compressed' if compressed else '/initsel_fuzz',
            client_name='initsel_fuzz_client',
        )
        # Every example resets and sends a camera_info: keep the node's log to its warnings.
        self.harness.node.get_logger().set_level(LoggingSeverity.WARN)
        frames = textured_frames(good_size[0], good_size[1], 4)
        self._good: list[Image | CompressedImage] = [
            conv.numpy_to_compressed(f, 'jpeg') if compressed else conv.numpy_to_image(f, 'bgr8')
            for f in frames
        ]
        #: The intrinsics each example starts from: the TUM fr3 camera (for compressed frames
        #: at the good frames' size: camera_info's size is the one they must have).
        self.default_intrinsics = (
            Intrinsics.tum_fr3().scaled(*good_size) if compressed else Intrinsics.tum_fr3()
        )
        #: What ``~/status`` must say for a good frame while the default intrinsics hold.
        self.good_intrinsics = self.default_intrinsics.scaled(*good_size).to_dict()
        self._default_info = conv.intrinsics_to_camera_info(self.default_intrinsics)
        self._stamp = 1.0

    @property
    def node(self) -> Any:
        """The node under test (for tests that inject a fault; the probe never touches it)."""
        return self.harness.node

    def _next_stamp(self) -> Any:
        self._stamp += 0.033
        return conv.seconds_to_stamp(self._stamp)

    def restart(self, info: CameraInfo | None = None) -> None:
        """Default intrinsics (then ``info``, if any) and no reference for the next image.

        The camera_info messages go out first; the reset's round trip lets them arrive, and
        the node applies both before it processes the next image.
        """
        self.harness.publish_camera_info(self._default_info)
        if info is not None:
            self.harness.publish_camera_info(info)
        self.harness.reset()

    def feed(self, image: Image | CompressedImage, info: InfoCase | None) -> FrameStatus:
        """Camera info (optional) then the image, on the node's topics; the frame's status."""
        self.restart(None if info is None else info_message(info))
        image.header.stamp = self._next_stamp()
        return self.harness.send(image)

    def feed_good(self) -> FrameStatus:
        """A good textured frame; its status."""
        msg = self._good[int(self._stamp * 100) % len(self._good)]
        msg.header.stamp = self._next_stamp()
        return self.harness.send(msg)

    def close(self) -> None:
        """Destroy the node and its context."""
        self.harness.close()


def info_message(info: InfoCase) -> CameraInfo:
    """The CameraInfo message of a fuzzed case."""
    msg = CameraInfo()
    msg.k = [float(v) for v in info.k]
    msg.width, msg.height = info.width, info.height
    msg.d = [float(v) for v in info.distortion]
    msg.distortion_model = info.model
    return msg


def implausible(info: InfoCase) -> bool:
    """A CameraInfo no camera has, by the rules alone (independent of the node's code).

    Non-finite K or D, K not of the form [fx 0 cx; 0 fy cy; 0 0 1], a focal length <= 0, a
    zero size, or a principal point outside the image.
    """
    k = np.asarray(info.k, dtype=float)
    if not np.all(np.isfinite(k)) or not all(np.isfinite(d) for d in info.distortion):
        return True
    fx, skew, cx, zero_a, fy, cy, zero_b, zero_c, one = k
    return bool(
        skew != 0
        or zero_a != 0
        or zero_b != 0
        or zero_c != 0
        or one != 1
        or fx <= 0
        or fy <= 0
        or info.width <= 0
        or info.height <= 0
        or not 0 <= cx <= info.width
        or not 0 <= cy <= info.height
    )


def check_node_callbacks(probe: NodeProbe, image: ImageCase, info: InfoCase | None) -> str:
    """One fuzzed camera_info + image, then a good frame; asserts the node's contract."""
    status = probe.feed(image.message(), info)
    assert status.reason is not Reason.INTERNAL_ERROR, (
        f'internal error on {image} / {info}: {status.detail}'
    )
    good = probe.feed_good()
    assert good.reason not in (Reason.INTERNAL_ERROR, Reason.SKIPPED_IMAGE), (
        f'the good frame after {image} / {info} was not processed: {good.reason.value}: '
        f'{good.detail}'
    )
    if info is not None and implausible(info):
        assert good.intrinsics == probe.good_intrinsics, (
            f'an implausible camera_info {info} changed the intrinsics in ~/status to '
            f'{good.intrinsics}'
        )
        return 'refused camera_info'
    return 'skipped' if status.reason is Reason.SKIPPED_IMAGE else 'processed'


#: Mutations of a fuzzed compressed frame.
MUTATIONS = ('none', 'truncate', 'flip', 'claim', 'format', 'garbage')


@dataclass(frozen=True)
class CompressedCase:
    """A fuzzed ``sensor_msgs/CompressedImage``: an encoded random picture, then a mutation.

    Attributes:
        codec: 'jpeg' or 'png'.
        width, height: the picture's size.
        colour: BGR, else grey.
        sixteen: 16-bit grey (PNG only).
        mutation: one of :data:`MUTATIONS`.
        claim: (width, height) the header claims after a 'claim' mutation.
        cut: bytes kept ('truncate'), or bytes flipped ('flip').
        fmt: the ``format`` field ('' = image_transport's for the codec).
        seed: pixels and mutation positions.
    """

    codec: str
    width: int
    height: int
    colour: bool
    sixteen: bool
    mutation: str
    claim: tuple[int, int]
    cut: int
    fmt: str
    seed: int

    def message(self) -> CompressedImage:
        """The CompressedImage of this case."""
        rng = np.random.default_rng(self.seed)
        shape = (self.height, self.width, 3) if self.colour else (self.height, self.width)
        sixteen = self.sixteen and self.codec == 'png' and not self.colour
        top = 4096 if sixteen else 256
        pixels = rng.integers(0, top, shape).astype(np.uint16 if sixteen else np.uint8)
        data, fmt = encode_compressed(pixels, self.codec)
        data = bytearray(data)
        if self.mutation == 'truncate':
            data = data[: self.cut % max(len(data), 1)]
        elif self.mutation == 'flip':
            for position in rng.integers(0, len(data), max(1, self.cut % 16)):
                data[int(position)] ^= int(rng.integers(1, 256))
        elif self.mutation == 'claim':
            w, h = self.claim
            if self.codec == 'png':
                data[16:24] = w.to_bytes(4, 'big') + h.to_bytes(4, 'big')
            else:
                sof = data.find(b'\xff\xc0')
                data[sof + 5 : sof + 9] = h.to_bytes(2, 'big') + w.to_bytes(2, 'big')
        elif self.mutation == 'garbage':
            head = data[:4] if self.cut % 2 else b''
            data = bytearray(head) + bytearray(rng.integers(0, 256, self.cut % 4096, np.uint8))
        msg = CompressedImage()
        msg.format = self.fmt if self.mutation == 'format' else fmt
        msg.data = bytes(data)
        return msg

    @property
    def header_size(self) -> tuple[int, int] | None:
        """The size its header gives, where the case knows it for sure (None otherwise)."""
        if self.mutation == 'none' or (
            self.mutation == 'format' and 'depth' not in self.fmt.lower()
        ):
            return (self.width, self.height)
        if self.mutation == 'claim':
            return self.claim
        return None


def compressed_cases() -> Any:
    """hypothesis strategy of :class:`CompressedCase` (mostly at the camera's size)."""
    from hypothesis import strategies as st

    side = st.one_of(st.just(GOOD_SIZE), st.tuples(st.integers(1, 48), st.integers(1, 48)))
    claims = st.one_of(
        st.sampled_from([GOOD_SIZE, (0, 0), (1, 1), (8000, 8000), (4097, 2160), (65535, 65535)]),
        st.tuples(st.integers(0, 65535), st.integers(0, 65535)),
    )

    @st.composite
    def case(draw: Callable[[Any], Any]) -> CompressedCase:
        width, height = draw(side)
        return CompressedCase(
            codec=draw(st.sampled_from(['jpeg', 'png'])),
            width=width,
            height=height,
            colour=draw(st.booleans()),
            sixteen=draw(st.booleans()),
            mutation=draw(st.sampled_from(MUTATIONS)),
            claim=draw(claims),
            cut=draw(st.integers(0, 20_000)),
            fmt=draw(
                st.one_of(
                    st.sampled_from(['', 'jpeg', 'png', 'tiff', '16UC1; compressedDepth png']),
                    st.text(max_size=12),
                )
            ),
            seed=draw(st.integers(0, 2**32 - 1)),
        )

    return case()


def check_compressed_callbacks(probe: NodeProbe, case: CompressedCase) -> str:
    """One fuzzed compressed frame, then a good one; asserts the compressed node's contract."""
    status = probe.feed(case.message(), None)
    assert status.reason is not Reason.INTERNAL_ERROR, f'internal error on {case}: {status.detail}'
    size = case.header_size
    camera = (probe.default_intrinsics.width, probe.default_intrinsics.height)
    if size is not None and size != camera:
        assert status.reason is Reason.SKIPPED_IMAGE and 'not decoded' in status.detail, (
            f'a frame whose header says {size[0]}x{size[1]} was not refused before decoding '
            f'(camera_info is for {camera[0]}x{camera[1]}): {case}: {status.reason.value}'
        )
    elif case.mutation == 'none':
        assert status.reason is not Reason.SKIPPED_IMAGE, (
            f'a valid frame was skipped: {case}: {status.detail}'
        )
    good = probe.feed_good()
    assert good.reason not in (Reason.INTERNAL_ERROR, Reason.SKIPPED_IMAGE), (
        f'the good frame after {case} was not processed: {good.reason.value}: {good.detail}'
    )
    return 'skipped' if status.reason is Reason.SKIPPED_IMAGE else 'processed'


def _settings(max_examples: int, seed: int | None) -> Any:
    """The hypothesis settings of a fuzz run: no deadline, no example database, every health
    check off, derandomized when ``seed`` is given."""
    from hypothesis import HealthCheck, settings

    return settings(
        max_examples=max_examples,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
        derandomize=seed is not None,
    )


def run_conversion_fuzz(max_examples: int, seed: int | None = None) -> dict[str, int]:
    """Run :func:`check_conversion` on ``max_examples`` cases; counts of outcomes."""
    from hypothesis import given

    counts: dict[str, int] = {}

    @_settings(max_examples, seed)
    @given(image_cases())
    def prop(case: ImageCase) -> None:
        outcome = check_conversion(case)
        counts[outcome] = counts.get(outcome, 0) + 1

    prop()
    return counts


def run_compressed_fuzz(
    model_path: str, max_examples: int, seed: int | None = None
) -> dict[str, int]:
    """Run :func:`check_compressed_callbacks` on ``max_examples`` cases; counts of outcomes."""
    from hypothesis import given

    counts: dict[str, int] = {}
    probe = NodeProbe(model_path, compressed=True)
    try:

        @_settings(max_examples, seed)
        @given(compressed_cases())
        def prop(case: CompressedCase) -> None:
            outcome = check_compressed_callbacks(probe, case)
            key = f'{case.mutation} {outcome}'
            counts[key] = counts.get(key, 0) + 1

        prop()
    finally:
        probe.close()
    return dict(sorted(counts.items()))


def run_node_fuzz(
    model_path: str, max_examples: int, seed: int | None = None, extreme: bool = False
) -> dict[str, int]:
    """Run :func:`check_node_callbacks` on ``max_examples`` cases; counts of outcomes."""
    from hypothesis import given

    counts: dict[str, int] = {}
    probe = NodeProbe(model_path)
    try:

        @_settings(max_examples, seed)
        @given(image_cases(), info_cases(extreme))
        def prop(case: ImageCase, info: InfoCase | None) -> None:
            outcome = check_node_callbacks(probe, case, info)
            counts[outcome] = counts.get(outcome, 0) + 1

        prop()
    finally:
        probe.close()
    return counts


__all__ = [
    'FOREIGN_ENCODINGS',
    'GOOD_SIZE',
    'MUTATIONS',
    'CompressedCase',
    'ImageCase',
    'InfoCase',
    'NodeProbe',
    'check_compressed_callbacks',
    'check_conversion',
    'check_node_callbacks',
    'compressed_cases',
    'image_cases',
    'implausible',
    'info_cases',
    'info_message',
    'run_compressed_fuzz',
    'run_conversion_fuzz',
    'run_node_fuzz',
]
