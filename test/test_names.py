"""The shared names: models, pose methods and modes are defined once and used everywhere."""

from __future__ import annotations

import pytest

from initsel_ros import geometry
from initsel_ros.errors import ConfigError
from initsel_ros.names import MODEL_NAMES, POSE_METHODS, ROTATION_MODEL, Method, Mode
from initsel_ros.ros.params import SPECS
from initsel_ros.selector import SelectorConfig


def test_the_models_are_the_pose_methods_plus_rotation():
    assert POSE_METHODS == ('F', 'E', 'H') == tuple(m.value for m in Method)
    assert MODEL_NAMES == ('F', 'E', 'H', 'R') and MODEL_NAMES[-1] == ROTATION_MODEL
    assert geometry.Method is Method


def test_the_selector_takes_a_mode_or_its_name():
    assert SelectorConfig().mode is Mode.ONCE
    assert SelectorConfig(mode='continuous').mode is Mode.CONTINUOUS
    assert SelectorConfig(mode=Mode.CONTINUOUS) == SelectorConfig(mode='continuous')
    with pytest.raises(ConfigError, match="mode must be 'once' or 'continuous', got 'twice'"):
        SelectorConfig(mode='twice')  # type: ignore[arg-type]


def test_the_node_parameters_use_the_shared_names():
    assert SPECS['mode'].check.values == tuple(m.value for m in Mode)
    assert SPECS['r_veto'].check.allowed == POSE_METHODS
    assert [name for name in SPECS if name.startswith('thresholds.')] == [
        f'thresholds.{m}' for m in MODEL_NAMES
    ]
