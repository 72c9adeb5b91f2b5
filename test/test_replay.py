"""Frame selection and timing of ``initsel replay`` (no DDS)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from initsel_ros.errors import ConfigError
from initsel_ros.ros.replay import add_arguments, plan_replay


def test_plan_keeps_recorded_timing_scaled_by_rate():
    stamps = 100.0 + np.arange(10) / 30.0
    plan = plan_replay(stamps, rate=2.0)
    np.testing.assert_array_equal(plan.indices, np.arange(10))
    np.testing.assert_allclose(plan.offsets, np.arange(10) / 60.0)
    assert plan.period == pytest.approx(10 / 60.0)


def test_plan_window_selects_start_and_duration():
    stamps = 50.0 + np.arange(100) * 0.1
    plan = plan_replay(stamps, start=2.0, duration=1.0)
    np.testing.assert_array_equal(plan.indices, np.arange(20, 30))
    assert plan.offsets[0] == 0.0


@pytest.mark.parametrize(
    ('kwargs', 'match'),
    [
        ({'rate': 0.0}, '--rate must be positive'),
        ({'start': -1.0}, '--start must be >= 0'),
        ({'start': 100.0}, 'no frame between'),
        ({'duration': 0.0}, '--duration > 0'),
    ],
)
def test_bad_windows_raise_config_error(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        plan_replay(np.arange(10) * 0.1, **kwargs)


def test_options_default_to_the_node_topics():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(['some/folder'])
    assert (args.image_topic, args.camera_info_topic) == ('image_raw', 'camera_info')
    assert (args.rate, args.loop, args.encoding) == (1.0, False, 'rgb8')


# --------------------------------------------------------------- shared-memory frame limit
ROOT = __import__('pathlib').Path(__file__).resolve().parent.parent


def test_segment_limit_comes_from_the_profile_in_use():
    from initsel_ros.ros.replay import FASTDDS_DEFAULT_SEGMENT, shm_segment_limit

    profile = str(ROOT / 'config' / 'fastdds_shm.xml')
    assert shm_segment_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': profile}) == (16 * 2**20,
                                                                              profile)
    assert shm_segment_limit({'FASTDDS_DEFAULT_PROFILES_FILE': profile})[0] == 16 * 2**20
    size, source = shm_segment_limit({})
    assert size == FASTDDS_DEFAULT_SEGMENT == 512 * 1024 and 'no profile' in source


def test_segment_limit_of_a_profile_without_shm_or_unreadable_is_the_default(tmp_path, caplog):
    from initsel_ros.ros.replay import FASTDDS_DEFAULT_SEGMENT, shm_segment_limit

    udp_only = tmp_path / 'udp.xml'
    udp_only.write_text('<dds><profiles><transport_descriptors><transport_descriptor>'
                        '<transport_id>u</transport_id><type>UDPv4</type>'
                        '</transport_descriptor></transport_descriptors></profiles></dds>')
    size, source = shm_segment_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': str(udp_only)})
    assert size == FASTDDS_DEFAULT_SEGMENT and 'no SHM segment_size' in source
    broken = tmp_path / 'broken.xml'
    broken.write_text('<dds><profiles>')
    size, _ = shm_segment_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': str(broken)})
    assert size == FASTDDS_DEFAULT_SEGMENT
    assert 'cannot read the Fast DDS profile' in caplog.text


def test_oversized_frames_are_reported_once(caplog):
    from initsel_ros.ros.replay import ShmLimit

    limit = ShmLimit(16 * 2**20, 'config/fastdds_shm.xml')
    assert limit.check(1920 * 1080 * 3, 'image_raw')  # 5.9 MiB fits
    with caplog.at_level('WARNING'):
        assert not limit.check(4096 * 3072 * 3, 'image_raw')  # 36 MiB
        assert not limit.check(4096 * 3072 * 3, 'image_raw')
    warnings = [r for r in caplog.records if 'shared-memory segment' in r.getMessage()]
    assert len(warnings) == 1
    assert '36.00 MiB' in warnings[0].getMessage() and '16.00 MiB' in warnings[0].getMessage()


def test_frame_pixels_give_each_encoding_its_layout(static_sequence):
    from initsel_ros.datasets import open_sequence
    from initsel_ros.ros.replay import frame_pixels

    seq = open_sequence(static_sequence)
    bgr = seq.image(0)
    rgb, name = frame_pixels(seq, 0, 'rgb8')
    assert name == 'rgb8' and np.array_equal(rgb, bgr[..., ::-1])
    assert frame_pixels(seq, 0, 'bgr8')[1] == 'bgr8'
    mono, name = frame_pixels(seq, 0, 'mono8')
    assert name == 'mono8' and mono.shape == bgr.shape[:2]
    native, name = frame_pixels(seq, 0, 'native')  # rendered TUM frames: colour PNGs
    assert name == 'bgr8' and np.array_equal(native, bgr)


def test_new_options_parse():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(['root', '--sequence', '03', '--compressed', '--jpeg-quality', '80',
                              '--encoding', 'native', '--bag-image-topic', '/cam/compressed'])
    assert (args.sequence, args.compressed, args.compressed_format) == ('03', True, 'jpeg')
    assert (args.jpeg_quality, args.encoding, args.bag_image_topic) == (80, 'native',
                                                                        '/cam/compressed')
