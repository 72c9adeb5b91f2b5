"""Selector node parameters: the YAML file, the declared defaults and their validation."""

from __future__ import annotations

from pathlib import Path

import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.names import POSE_METHODS, Mode
from initsel_ros.policy import PolicyConfig
from initsel_ros.ros.params import (
    PARAMETERS,
    NodeSettings,
    default_params_file,
    load_params_file,
    read_params_yaml,
)
from initsel_ros.selector import SelectorConfig
from initsel_ros.tracking import TrackerConfig
from initsel_ros.verify import VerifyConfig

CONFIG = Path(__file__).resolve().parent.parent / 'config' / 'selector.yaml'


@pytest.mark.parametrize('doc', ['README.md', 'docs/node.md'])
def test_the_parameter_tables_of_the_docs_list_every_parameter_with_its_default(doc):
    """Each parameter has a row; a number's row states its declared default (rows may
    group ``camera.*`` and ``thresholds.*`` names)."""
    import re

    text = (CONFIG.parent.parent / doc).read_text()
    rows = {}
    for line in text.splitlines():
        match = re.match(r'\| `([\w.]+)`[^|]* \| `([^`]*)`', line)
        if match:
            rows.setdefault(match.group(1), match.group(2))
    for spec in PARAMETERS:
        group = spec.name.split('.')[0]
        if group in ('camera', 'thresholds'):
            assert any(name.startswith(group + '.') for name in rows), (doc, spec.name)
            continue
        assert spec.name in rows, (doc, spec.name)
        if isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool):
            assert float(rows[spec.name]) == pytest.approx(spec.default), (doc, spec.name)


def test_selector_yaml_lists_every_parameter_with_its_declared_default():
    values = load_params_file(CONFIG)
    defaults = {spec.name: spec.default for spec in PARAMETERS}
    assert values == defaults


#: Parameters that configure the core -> their default in the core's dataclasses.
CORE_DEFAULTS = {
    'max_features': TrackerConfig().max_features,
    'min_tracks': PolicyConfig().min_tracks,
    'min_points': PolicyConfig().min_points,
    'min_parallax_deg': PolicyConfig().min_parallax_deg,
    'max_frames_since_reference': SelectorConfig().max_frames_since_reference,
    'rotation_rereference_share': SelectorConfig().rotation_rereference_share,
    'mode': SelectorConfig().mode.value,
    'r_veto': [m for m in POSE_METHODS if m in PolicyConfig().r_veto],
    'refine': SelectorConfig().refine,
    'verify_frames': VerifyConfig().frames,
    'verify_min_fraction': VerifyConfig().min_fraction,
    'verify_max_rms_px': VerifyConfig().max_rms_px,
    **{
        f'camera.{k}': getattr(Intrinsics.tum_fr3(), k)
        for k in ('fx', 'fy', 'cx', 'cy', 'width', 'height')
    },
}


@pytest.mark.parametrize('name', sorted(CORE_DEFAULTS))
def test_yaml_table_and_core_defaults_agree_in_value_and_type(name):
    yaml_value = load_params_file(CONFIG)[name]
    table_value = {spec.name: spec.default for spec in PARAMETERS}[name]
    core_value = CORE_DEFAULTS[name]
    assert yaml_value == table_value == core_value
    # ROS types a parameter by its default: 1 and 1.0 are different parameters.
    assert type(yaml_value) is type(table_value) is type(core_value)


def test_the_default_parameters_configure_the_selector_with_the_core_defaults():
    assert NodeSettings.from_values({}).selector_config() == SelectorConfig()
    assert NodeSettings.from_values({}).intrinsics == Intrinsics.tum_fr3()


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
    settings = NodeSettings.from_values(
        {
            'thresholds.E': 0.7,
            'max_features': 200,
            'min_points': 30,
            'mode': 'continuous',
            'r_veto': ['F', 'E', 'H'],
            'camera.distortion': [0.1, 0.0, 0.0, 0.0, 0.0],
        }
    )
    config = settings.selector_config()
    assert config.tracker.max_features == 200
    assert dict(config.policy.thresholds) == {'E': 0.7}
    assert config.policy.r_veto == frozenset({'F', 'E', 'H'})
    assert config.policy.min_points == 30
    assert config.mode == 'continuous'
    assert settings.intrinsics.distortion == (0.1, 0.0, 0.0, 0.0, 0.0)


NAN = float('nan')


@pytest.mark.parametrize(
    ('values', 'match'),
    [
        ({'mode': 'twice'}, "mode must be one of 'once', 'continuous', got 'twice'"),
        ({'mode': 'sometimes'}, "mode must be one of 'once', 'continuous'"),
        ({'thresholds.F': 1.5}, r'thresholds.F must be a finite number <= 1'),
        ({'thresholds.E': 2.0}, r'thresholds.E must be a finite number <= 1'),
        ({'thresholds.E': NAN}, r'thresholds.E must be a finite number <= 1 .*got nan'),
        ({'r_veto': ['R']}, 'r_veto must name models among F, E, H'),
        ({'r_veto': ['X']}, r"r_veto must name models among F, E, H, got \['X'\]"),
        ({'r_veto': 'F'}, 'r_veto must be a list'),
        ({'r_veto': ['E', 'E']}, r"r_veto names E more than once: \['E', 'E'\]"),
        ({'min_tracks': 0}, r'min_tracks must be an integer in \[1, 10000\], got 0'),
        ({'max_features': -5}, r'max_features must be an integer in \[1, 10000\], got -5'),
        ({'max_features': 1_000_000_000_000}, r'max_features must be an integer in \[1, 10000\]'),
        ({'max_features': True}, 'max_features must be an integer'),
        ({'max_features': 40}, r'min_tracks \(50\) > max_features \(40\)'),
        ({'min_parallax_deg': NAN}, r'min_parallax_deg must be a finite number in \[0, 90\]'),
        ({'min_parallax_deg': -1.0}, 'min_parallax_deg must be a finite number'),
        ({'max_frames_since_reference': 0}, 'max_frames_since_reference must be an integer'),
        ({'camera.fx': 0.0}, 'focal lengths must be positive'),
        ({'camera.fx': -1.0}, 'focal lengths must be positive'),
        ({'camera.cx': NAN}, 'camera.cx must be a finite number'),
        ({'camera.width': 0}, r'camera.width must be an integer in \[1, 100000\]'),
        (
            {'camera.distortion': [0.01, 0.001, 0.0]},
            'camera.distortion: 3 distortion coefficients .* OpenCV needs 4, 5, 8, 12, 14',
        ),
        ({'camera.distortion': [0.1] * 6}, 'camera.distortion: 6 distortion coefficients'),
        ({'camera.distortion': [0.1, NAN, 0.0, 0.0]}, 'camera.distortion must be finite'),
        ({'image_transport': 'theora'}, "image_transport must be one of 'raw', 'compressed'"),
        ({'bit_depth': 4}, r'bit_depth must be 0 \(automatic\) or an integer in \[8, 16\]'),
        ({'bit_depth': 17}, 'bit_depth must be 0'),
        ({'publish_tf': 1}, 'publish_tf must be true or false'),
        ({'reference_frame_id': ''}, 'reference_frame_id must not be empty'),
        ({'reference_frame_id': '/map'}, "reference_frame_id must not start with '/'"),
        ({'camera_frame_id': '/camera'}, "camera_frame_id must not start with '/'"),
        ({'camera_frame_id': 'my camera'}, 'camera_frame_id must not contain white space'),
        (
            {'camera_frame_id': 'initsel_reference_optical'},
            'camera_frame_id is reference_frame_id .* a frame to itself',
        ),
        ({'model_file': 3}, 'model_file must be a string'),
        ({'no_such_thing': 1}, 'unknown selector parameters: no_such_thing'),
    ],
)
def test_invalid_settings_raise_one_line_config_error(values, match):
    with pytest.raises(ConfigError, match=match) as info:
        NodeSettings.from_values(values)
    assert '\n' not in str(info.value)


def test_valid_distortion_lengths_and_all_zero_vectors_are_accepted():
    for n in (4, 5, 8, 12, 14):
        coefficients = [0.01] + [0.0] * (n - 1)
        assert NodeSettings.from_values(
            {'camera.distortion': coefficients}
        ).intrinsics.distortion == tuple(coefficients)
    for zeros in ([], [0.0] * 3, [0.0] * 5):
        assert NodeSettings.from_values({'camera.distortion': zeros}).intrinsics.distortion == ()


def test_every_parameter_is_either_live_or_read_only_with_its_constraints():
    read_only = {spec.name for spec in PARAMETERS if not spec.live}
    assert read_only == {'model_file', 'max_features', 'image_transport', 'use_camera_info'}
    for spec in PARAMETERS:
        assert spec.constraints, spec.name
        spec.check(spec.name, spec.default)  # raises ConfigError if a default were invalid


def test_default_intrinsics_are_recognized_until_camera_parameters_change():
    assert NodeSettings.from_values({}).default_intrinsics
    assert NodeSettings.from_values({'camera.fx': 535.4}).default_intrinsics
    assert not NodeSettings.from_values({'camera.fx': 500.0}).default_intrinsics


def test_yaml_syntax_error_is_one_line_with_its_position(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('selector:\n  ros__parameters:\n    mode: [once\n    min_tracks: 5\n')
    with pytest.raises(
        ConfigError, match=r'broken.yaml: YAML syntax error at line \d+, column'
    ) as info:
        read_params_yaml(path)
    assert '\n' not in str(info.value)
    with pytest.raises(ConfigError, match='YAML syntax error'):
        load_params_file(path)


def test_params_file_without_selector_section_is_rejected(tmp_path):
    path = tmp_path / 'other.yaml'
    path.write_text('other_node:\n  ros__parameters:\n    a: 1\n')
    with pytest.raises(ConfigError, match='no "selector: ros__parameters:" section'):
        load_params_file(path)
