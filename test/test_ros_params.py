"""Selector node parameters: the YAML file, the declared defaults and their validation."""

from __future__ import annotations

from pathlib import Path

import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.ros.params import (
    PARAMETERS,
    Mode,
    NodeSettings,
    default_params_file,
    load_params_file,
)

CONFIG = Path(__file__).resolve().parent.parent / 'config' / 'selector.yaml'


def test_selector_yaml_lists_every_parameter_with_its_declared_default():
    values = load_params_file(CONFIG)
    defaults = {spec.name: spec.default for spec in PARAMETERS}
    assert values == defaults


def test_default_params_file_is_found_without_ament_prefix(monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    assert default_params_file().read_text() == CONFIG.read_text()


def test_defaults_give_the_tum_camera_and_the_model_file_thresholds():
    settings = NodeSettings.from_values({})
    assert settings.intrinsics == Intrinsics.tum_fr3()
    assert settings.thresholds == {}
    assert settings.r_veto == frozenset({'F', 'E'})
    assert settings.mode is Mode.ONCE


def test_settings_build_the_selector_config():
    settings = NodeSettings.from_values({
        'thresholds.E': 0.7, 'max_features': 200, 'min_points': 30, 'mode': 'continuous',
        'r_veto': ['F', 'E', 'H'], 'camera.distortion': [0.1, 0.0, 0.0, 0.0, 0.0],
    })
    config = settings.selector_config()
    assert config.tracker.max_features == 200
    assert dict(config.policy.thresholds) == {'E': 0.7}
    assert config.policy.r_veto == frozenset({'F', 'E', 'H'})
    assert config.policy.min_points == 30
    assert config.mode == 'continuous'
    assert settings.intrinsics.distortion == (0.1, 0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ('values', 'match'),
    [
        ({'mode': 'twice'}, "mode must be 'once' or 'continuous'"),
        ({'thresholds.F': 1.5}, r'thresholds.F must be <= 1'),
        ({'r_veto': ['R']}, 'r_veto must name models among F, E, H'),
        ({'min_tracks': 0}, 'min_tracks must be >= 1'),
        ({'camera.fx': 0.0}, 'focal lengths must be positive'),
        ({'reference_frame_id': ''}, 'reference_frame_id must not be empty'),
        ({'no_such_thing': 1}, 'unknown selector parameters: no_such_thing'),
    ],
)
def test_invalid_settings_raise_config_error(values, match):
    with pytest.raises(ConfigError, match=match):
        NodeSettings.from_values(values)


def test_params_file_without_selector_section_is_rejected(tmp_path):
    path = tmp_path / 'other.yaml'
    path.write_text('other_node:\n  ros__parameters:\n    a: 1\n')
    with pytest.raises(ConfigError, match='no "selector: ros__parameters:" section'):
        load_params_file(path)
