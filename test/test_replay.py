"""Frame selection, timing and publishing order of ``initsel replay`` (no DDS)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from initsel_ros.cli.replay import add_arguments
from initsel_ros.errors import ConfigError
from initsel_ros.ros.replay import plan_replay


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


def test_replay_and_demo_share_one_shm_limit():
    from initsel_ros.ros import replay

    assert not hasattr(replay, 'shm_segment_limit') and not hasattr(replay, 'ShmLimit')
    assert 'OversizeMonitor' in replay.run.__code__.co_names


def test_segment_limit_of_a_profile_without_shm_or_unreadable_is_the_default(tmp_path):
    from initsel_ros.ros.transport import DEFAULT_SEGMENT_BYTES, shm_limit

    udp_only = tmp_path / 'udp.xml'
    udp_only.write_text(
        '<dds><profiles><transport_descriptors><transport_descriptor>'
        '<transport_id>u</transport_id><type>UDPv4</type>'
        '</transport_descriptor></transport_descriptors></profiles></dds>'
    )
    limit = shm_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': str(udp_only)})
    assert limit.segment_bytes == DEFAULT_SEGMENT_BYTES and 'sets no SHM size' in limit.source
    broken = tmp_path / 'broken.xml'
    broken.write_text('<dds><profiles>')
    assert shm_limit({'FASTDDS_DEFAULT_PROFILES_FILE': str(broken)}).segment_bytes == (
        DEFAULT_SEGMENT_BYTES
    )


def test_oversized_frames_are_reported_once(caplog):
    from initsel_ros.ros.transport import OversizeMonitor, ShmLimit

    monitor = OversizeMonitor(ShmLimit(16 * 2**20, 'config/fastdds_shm.xml'))
    assert monitor.check(1920 * 1080 * 3, 'image_raw')  # 5.9 MiB fits
    with caplog.at_level('WARNING'):
        assert not monitor.check(4096 * 3072 * 3, 'image_raw')  # 36 MiB
        assert not monitor.check(4096 * 3072 * 3, 'image_raw')
    warnings = [r for r in caplog.records if 'shared-memory segment' in r.getMessage()]
    assert len(warnings) == 1
    assert '36.00 MiB' in warnings[0].getMessage() and '16.00 MiB' in warnings[0].getMessage()


# ------------------------------------------------------------------------- --intrinsics
def _replay_options(argv: list[str]):
    from initsel_ros.cli.options import options_from
    from initsel_ros.ros.replay import ReplayOptions

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return options_from(parser.parse_args(argv), ReplayOptions)


def test_intrinsics_given_to_replay_replace_the_folders_own(static_sequence, tmp_path):
    from initsel_ros.camera import Intrinsics
    from initsel_ros.ros.replay import open_source

    camera = Intrinsics(500.0, 505.0, 321.0, 239.0, 640, 480)
    camera.save_yaml(tmp_path / 'camera.yaml')
    assert open_source(_replay_options([str(static_sequence)])).intrinsics != camera
    options = _replay_options(
        [str(static_sequence), '--intrinsics', str(tmp_path / 'camera.yaml')]
    )
    assert open_source(options).intrinsics == camera


def test_an_unreadable_intrinsics_file_is_one_line(static_sequence, tmp_path):
    from initsel_ros.ros.replay import open_source

    (tmp_path / 'bad.yaml').write_text('fx: [1, 2\n')
    options = _replay_options([str(static_sequence), '--intrinsics', str(tmp_path / 'bad.yaml')])
    with pytest.raises(ConfigError, match=r'bad.yaml: cannot read intrinsics: \S.*'):
        open_source(options)


def test_each_frames_camera_info_is_published_before_the_frame(static_sequence, monkeypatch):
    # a node that gets the frame first processes it with the intrinsics it had: the replay
    # publishes the calibration first, each frame (before: replays differed run to run)
    pytest.importorskip('rclpy')
    import rclpy

    from initsel_ros.ros import replay

    calls: list[tuple[str, int]] = []

    class Recorder:
        def __init__(self, kind: str, topic: str) -> None:
            self.kind, self.topic_name = kind, topic

        def publish(self, message) -> None:
            stamp = message.header.stamp
            calls.append((self.kind, stamp.sec * 10**9 + stamp.nanosec))

    class FakeNode:
        def create_publisher(self, msgtype, topic, qos):
            return Recorder(msgtype.__name__, topic)

        def destroy_node(self) -> None:
            pass

    monkeypatch.setattr(rclpy, 'init', lambda args=None: None)
    monkeypatch.setattr(rclpy, 'ok', lambda: True)
    monkeypatch.setattr(rclpy, 'try_shutdown', lambda: None)
    monkeypatch.setattr(rclpy, 'create_node', lambda name: FakeNode())
    monkeypatch.setattr(replay, 'LINGER_S', 0.0)
    options = _replay_options(
        [str(static_sequence), '--rate', '100', '--duration', '0.2', '--wait-for-subscriber', '0']
    )
    assert replay.run(options) == 0
    kinds = [kind for kind, _ in calls]
    assert len(calls) >= 4 and kinds == ['CameraInfo', 'Image'] * (len(calls) // 2)
    assert all(a[1] == b[1] for a, b in zip(calls[::2], calls[1::2], strict=True))
