"""Tests for ``initsel demo`` (the README's main job) on a rendered sequence."""

from __future__ import annotations

import pytest
from ros_helpers import configure_this_process

from initsel_ros.cli import main


@pytest.mark.parametrize('mode', ['--offline', '--live'])
def test_demo_initializes_on_the_near_sequence_and_judges_it_good(near_sequence, capsys, mode):
    if mode == '--live':
        pytest.importorskip('rclpy')
        configure_this_process()
    args = ['demo', '--source', str(near_sequence), '--frames', '60', '--mode', 'once']
    if mode == '--offline':
        args.append('--offline')
    assert main(args) == 0
    out = capsys.readouterr().out
    assert 'live (ROS 2 node)' in out if mode == '--live' else 'offline' in out
    assert '1/1 initializations good' in out
    assert 'first initialization at frame' in out
    if mode == '--live':  # the node's count of frames, not of the statuses that came back
        assert '     60  (frames received)' in out


def test_demo_fails_loudly_when_nothing_initializes(static_sequence, capsys):
    assert main(['demo', '--source', str(static_sequence), '--offline']) == 1
    captured = capsys.readouterr()
    assert 'never initialized' in captured.err
    assert 'no initialization' in captured.out
