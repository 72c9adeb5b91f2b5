"""Property-based fuzzing of image conversion and the selector node's image path.

CI runs the ``initsel-ci`` hypothesis profile (200 examples per property, derandomized).
``INITSEL_FUZZ_PROFILE=initsel-long`` runs 10,000 per property; so does
``initsel bench --fuzz 10000``.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

pytest.importorskip('sensor_msgs.msg')

from initsel_ros.ros.fuzz import (
    GOOD_SIZE,
    INTERNAL_ERROR_REASON,
    CompressedCase,
    ImageCase,
    InfoCase,
    check_compressed_callbacks,
    check_conversion,
    check_node_callbacks,
    compressed_cases,
    image_cases,
    info_cases,
)

_COMMON = {
    'deadline': None,
    'database': None,
    'suppress_health_check': [
        HealthCheck.too_slow,
        HealthCheck.data_too_large,
        HealthCheck.filter_too_much,
    ],
}
settings.register_profile('initsel-ci', max_examples=200, derandomize=True, **_COMMON)
settings.register_profile('initsel-long', max_examples=10_000, **_COMMON)
PROFILE = settings.get_profile(os.environ.get('INITSEL_FUZZ_PROFILE', 'initsel-ci'))


@PROFILE
@given(image_cases())
@example(ImageCase('mono8', 0, 0, 0, 0, False, 0))
@example(ImageCase('mono8', 1, 1, 1, 1, False, 0))
@example(ImageCase('rgb8', 1, 1, 3, 2, False, 0))  # one byte short
@example(ImageCase('bgra8', 2, 2, 7, 14, False, 0))  # step shorter than a row
@example(ImageCase('mono16', 1, 1, 2, 2, True, 0))
@example(ImageCase('bayer_rggb8', 1, 1, 1, 1, False, 0))  # a 1-pixel mosaic
@example(ImageCase('rgb8', 2**31, 2**31, 2**32 - 1, 16, False, 0))
@example(ImageCase('16UC1', 4, 4, 8, 32, False, 0))
@example(ImageCase('MONO8', 1, 1, 1, 1, False, 0))  # encoding names in any case
@example(ImageCase('32FC1', 2, 2, 8, 16, False, 0))  # a depth encoding: refused
def test_image_conversion_returns_the_documented_array_or_raises_image_conversion_error(
    case: ImageCase,
):
    check_conversion(case)


def test_conversion_check_catches_a_wrong_shape(monkeypatch):
    """The property itself can fail: a converter returning the wrong shape is caught."""
    import numpy as np

    from initsel_ros.ros import conversions

    monkeypatch.setattr(conversions, 'image_to_cv', lambda msg: np.zeros((1, 1), np.uint8))
    with pytest.raises(AssertionError):
        check_conversion(ImageCase('mono8', 4, 4, 4, 16, False, 0))


@pytest.fixture(scope='module')
def fuzz_models(tmp_path_factory):
    pytest.importorskip('rclpy')
    from ros_helpers import configure_this_process

    from initsel_ros.benchmarks.common import random_models

    configure_this_process()
    os.environ['ROS_DOMAIN_ID'] = str(os.getpid() % 50 + 150)
    path = tmp_path_factory.mktemp('fuzz_models') / 'models.json'
    random_models().save(path)
    return str(path)


@pytest.fixture(scope='module')
def probe(fuzz_models):
    from initsel_ros.ros.fuzz import NodeProbe

    p = NodeProbe(fuzz_models)
    yield p
    p.close()


@pytest.fixture(scope='module')
def compressed_probe(fuzz_models):
    from initsel_ros.ros.fuzz import NodeProbe

    p = NodeProbe(fuzz_models, compressed=True)
    yield p
    p.close()


NAN = float('nan')
PLAUSIBLE_K = (525.0, 0.0, 320.0, 0.0, 525.0, 240.0, 0.0, 0.0, 1.0)


@PROFILE
@given(case=image_cases(), info=info_cases())
@example(case=ImageCase('mono8', 0, 0, 0, 0, False, 0), info=None)
@example(
    case=ImageCase('mono8', 1, 1, 1, 1, False, 0),
    info=InfoCase((NAN,) * 9, 640, 480, (), 'plumb_bob'),
)
@example(
    case=ImageCase('rgb8', 1, 1, 3, 3, False, 0),
    info=InfoCase((0.0,) * 9, 640, 480, (), 'plumb_bob'),
)
@example(case=ImageCase('bgr8', 3, 2, 6, 18, False, 0), info=InfoCase(PLAUSIBLE_K, 0, 0, (), ''))
@example(
    case=ImageCase('mono16', 5, 7, 14, 70, True, 1),
    info=InfoCase(PLAUSIBLE_K, 640, 480, (NAN, 0, 0, 0, 0), 'plumb_bob'),
)
@example(  # issue 22: a principal point far outside a 640x480 image
    case=ImageCase('mono8', 4, 4, 4, 16, False, 0),
    info=InfoCase((525.0, 0.0, 1e6, 0.0, 525.0, -5e5, 0.0, 0.0, 1.0), 640, 480, (), 'plumb_bob'),
)
def test_node_survives_any_image_and_camera_info_and_processes_the_next_good_frame(
    probe,
    case: ImageCase,
    info: InfoCase | None,
):
    check_node_callbacks(probe, case, info)


def test_node_check_catches_an_internal_error(probe, monkeypatch):
    """The property itself can fail: a selector that raises shows up as an internal error."""

    def broken(*args, **kwargs):
        raise RuntimeError('boom')

    monkeypatch.setattr(probe.node._selector, 'process', broken)
    with pytest.raises(AssertionError, match=INTERNAL_ERROR_REASON):
        check_node_callbacks(probe, ImageCase('mono8', 8, 8, 8, 64, False, 0), None)


@pytest.mark.parametrize(
    'info',
    [
        InfoCase((1e307, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0), 1, 1, (), 'plumb_bob'),
        InfoCase((1.0, 0.0, 0.0, 0.0, 5e-324, 0.0, 0.0, 0.0, 1.0), 1, 48, (), 'plumb_bob'),
    ],
)
def test_node_survives_camera_info_with_absurd_finite_focal_lengths(probe, info):
    check_node_callbacks(probe, ImageCase('mono8', 1, 1, 1, 1, False, 0), info)


def test_node_check_catches_intrinsics_taken_from_an_implausible_camera_info(probe, monkeypatch):
    """The property itself can fail: a node that takes any camera_info is caught."""
    from initsel_ros.camera import Intrinsics
    from initsel_ros.ros import node as node_module

    monkeypatch.setattr(
        node_module.conv,
        'camera_info_to_intrinsics',
        lambda msg: Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480),
    )
    bad = InfoCase((525.0, 0.0, 1e6, 0.0, 525.0, -5e5, 0.0, 0.0, 1.0), 640, 480, (), '')
    with pytest.raises(AssertionError, match='implausible camera_info'):
        check_node_callbacks(probe, ImageCase('mono8', 8, 8, 8, 64, False, 0), bad)


def _compressed(mutation: str, claim=(0, 0), size=GOOD_SIZE, fmt='', codec='jpeg'):
    return CompressedCase(codec, *size, True, False, mutation, claim, 300, fmt, 7)


@PROFILE
@given(case=compressed_cases())
@example(case=_compressed('none'))
@example(case=_compressed('none', size=(32, 24)))  # another size than camera_info's
@example(case=_compressed('claim', (8000, 8000)))  # the 64 KB JPEG that decoded to 192 MB
@example(case=_compressed('claim', (0, 0), codec='png'))
@example(case=_compressed('truncate'))
@example(case=_compressed('flip'))  # corrupt entropy-coded data
@example(case=_compressed('format', fmt='16UC1; compressedDepth png', codec='png'))
@example(case=_compressed('garbage'))
def test_compressed_node_refuses_mis_sized_frames_before_decoding_and_survives_any_frame(
    compressed_probe, case: CompressedCase
):
    check_compressed_callbacks(compressed_probe, case)


def test_compressed_check_catches_a_frame_decoded_despite_its_size(compressed_probe, monkeypatch):
    """The property itself can fail: a node that decodes a mis-sized frame is caught."""
    import initsel_ros.image as image_module
    from initsel_ros.ros import conversions

    def decode_anything(msg, bit_depth=0, *, max_pixels=0, size=None):
        return image_module.compressed_to_cv(msg.data, str(msg.format), bit_depth)

    monkeypatch.setattr(conversions, 'compressed_to_cv', decode_anything)
    with pytest.raises(AssertionError, match='not refused before decoding'):
        check_compressed_callbacks(compressed_probe, _compressed('none', size=(32, 24)))


def _encoded_samples() -> list[bytes]:
    import cv2
    import numpy as np

    rng = np.random.default_rng(0)
    gray = rng.integers(0, 256, (24, 32), dtype=np.uint8)
    colour = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    deep = rng.integers(0, 4096, (24, 32), dtype=np.uint16)
    return [
        cv2.imencode(ext, img)[1].tobytes()
        for ext, img in (('.jpg', gray), ('.jpg', colour), ('.png', colour), ('.png', deep))
    ]


ENCODED = _encoded_samples()


@PROFILE
@given(
    sample=st.integers(0, len(ENCODED) - 1),
    cut=st.integers(0, 4000),
    flips=st.lists(st.tuples(st.integers(0, 4000), st.integers(0, 255)), max_size=6),
    fmt=st.sampled_from(['jpeg', 'png', 'bgr8; jpeg compressed bgr8', '', 'tiff']),
)
@example(sample=0, cut=0, flips=[], fmt='jpeg')
@example(sample=1, cut=20, flips=[], fmt='jpeg')  # header only
@example(sample=3, cut=4000, flips=[(18, 255), (19, 255)], fmt='png')  # huge declared width
def test_compressed_decoding_returns_the_selector_input_or_raises_image_conversion_error(
    sample, cut, flips, fmt
):
    import numpy as np
    from sensor_msgs.msg import CompressedImage

    from initsel_ros.errors import ImageConversionError
    from initsel_ros.ros.conversions import compressed_to_cv

    data = bytearray(ENCODED[sample][:cut])
    for position, value in flips:
        if position < len(data):
            data[position] = value
    try:
        image = compressed_to_cv(CompressedImage(format=fmt, data=bytes(data)))
    except ImageConversionError:
        return
    assert image.dtype == np.uint8 and image.ndim in (2, 3) and image.size > 0
