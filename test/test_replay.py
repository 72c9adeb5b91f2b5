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
