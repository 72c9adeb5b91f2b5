"""``initsel demo --compressed``: the live demo over JPEG CompressedImages, and its warning
about frames too large for the shared-memory segment."""

from __future__ import annotations

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

from ros_helpers import configure_this_process

from initsel_ros.cli import main


def test_demo_over_compressed_images_initializes_and_judges_it_good(near_sequence, capsys):
    configure_this_process()
    args = ['demo', '--source', str(near_sequence), '--frames', '60', '--compressed']
    assert main(args) == 0
    out = capsys.readouterr().out
    assert 'live (ROS 2 node)' in out and 'compressed (JPEG)' in out
    assert '1/1 initializations good' in out
    assert 'shared-memory segment' not in out  # a JPEG frame fits easily


def test_demo_warns_when_a_frame_exceeds_the_shared_memory_segment(
    near_sequence, capsys, monkeypatch
):
    from initsel_ros.ros import transport

    configure_this_process()
    monkeypatch.setattr(
        transport,
        'shm_limit',
        lambda environ=None: transport.ShmLimit(256 * 1024, 'a small profile'),
    )
    assert main(['demo', '--source', str(near_sequence), '--frames', '8']) in (0, 1)
    out = capsys.readouterr().out
    assert out.count('does not fit the 0.25 MiB Fast DDS shared-memory segment') == 1
    assert '0.88 MiB' in out and 'a small profile' in out
