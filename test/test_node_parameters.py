"""Live parameters of the running node, through its ``/selector/set_parameters`` service (what
``ros2 param set`` calls), and the start-up checks (one line, exit code 1)."""

from __future__ import annotations

import math

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

from image_fixtures import shifted, texture
from node_harness import as_sequence, double_model_file, harnesses, play, ros_context
from rcl_interfaces.srv import DescribeParameters
from rclpy.parameter import Parameter
from ros_helpers import DOMAIN_ID

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.ros.params import PARAMETERS
from initsel_ros.selector import Selector

READ_ONLY = ('model_file', 'max_features', 'image_transport', 'use_camera_info')


@pytest.fixture(scope='module')
def context():
    yield from ros_context()


@pytest.fixture
def harness_factory(context):
    yield from harnesses(context)


@pytest.fixture
def node(harness_factory, tmp_path):
    """A running node whose test-double models give p = 0.01 (E), so nothing fires."""
    return harness_factory(model_file=double_model_file(tmp_path))


@pytest.mark.parametrize(
    ('name', 'value', 'reason'),
    [
        ('max_features', -5, 'read-only'),
        ('model_file', '/etc/passwd', 'read-only'),
        ('image_transport', 'compressed', 'read-only'),
        ('use_camera_info', False, 'read-only'),
        ('thresholds.E', 2.0, 'thresholds.E must be a finite number <= 1'),
        ('thresholds.E', math.nan, 'thresholds.E must be a finite number <= 1'),
        ('mode', 'sometimes', "mode must be one of 'once', 'continuous'"),
        ('r_veto', ['X'], 'r_veto must name models among F, E, H'),
        ('r_veto', ['F', 'F'], 'r_veto names F more than once'),
        (
            'max_tracking_width',
            100,
            'max_tracking_width must be 0 (full size) or an integer in [320',
        ),
        ('min_parallax_deg', math.nan, r'min_parallax_deg must be a finite number in [0, 90]'),
        ('min_tracks', 400, 'min_tracks (400) > max_features (300)'),
        ('camera.fx', -1.0, 'focal lengths must be positive'),
        ('camera.cx', -1e6, 'principal point cx=-1e+06 px is outside the 640x480 image'),
        ('camera.cy', 481.0, 'principal point cy=481 px is outside'),
        ('max_image_pixels', 0, 'max_image_pixels must be an integer in [1, '),
        ('restart_tolerance_s', math.inf, 'restart_tolerance_s must be a finite number'),
        ('camera.distortion', [0.01, 0.001, 0.0], 'camera.distortion: 3 distortion coefficients'),
        ('bit_depth', 3, 'bit_depth must be 0 (automatic) or an integer in [8, 16]'),
        ('min_parallax_deg', 2, 'Wrong parameter type'),  # an integer for a double
    ],
)
def test_invalid_or_read_only_values_are_refused_with_a_reason_and_nothing_changes(
    node, name, value, reason
):
    before = node.get_parameter(name)
    thresholds = dict(node.node._selector.thresholds)
    [result] = node.set_parameters({name: value})
    assert not result.successful
    assert reason in result.reason
    after = node.get_parameter(name)
    assert after == before or (
        isinstance(before, float) and math.isnan(before) and math.isnan(after)
    )
    status = node.send_array(texture(20), 1.0)
    assert status.reason == 'new reference'
    assert node.node._selector.thresholds == thresholds


def test_restart_parameters_are_declared_read_only_and_all_carry_constraints(node):
    names = [spec.name for spec in PARAMETERS]
    response = node.call(
        node.describe_client, DescribeParameters.Request(names=names), 'describe_parameters'
    )
    described = {d.name: d for d in response.descriptors}
    assert {n for n, d in described.items() if d.read_only} == set(READ_ONLY)
    assert all(d.additional_constraints and d.description for d in described.values())
    assert '[1, 10000]' in described['max_features'].additional_constraints


def test_every_live_parameter_of_the_table_can_be_set_while_running(node):
    """Generic over the table: a parameter added to it later is live without more code."""
    live = {spec.name: spec.default for spec in PARAMETERS if spec.live}
    results = node.set_parameters(live)
    assert [r.reason for r in results if not r.successful] == []
    status = node.send_array(texture(21), 1.0)
    assert status.reason == 'new reference'


def test_parameters_of_rclpy_itself_stay_settable(node):
    [result] = node.set_parameters({'use_sim_time': False})
    assert result.successful, result.reason


def test_an_unknown_parameter_is_refused_and_named_with_a_guess(node, capfd):
    [result] = node.set_parameters({'min_parralax_deg': 2.0})
    assert not result.successful
    err = capfd.readouterr().err
    assert 'no such parameter: min_parralax_deg (min_parallax_deg?)' in err


def test_valid_changes_apply_to_the_running_selector_from_the_next_frame(node):
    img = texture(22)
    assert node.send_array(img, 1.0).reason == 'new reference'
    assert node.send_array(shifted(img, 1, 0), 1.033).reason == 'no model fired'
    # Thresholds: the test double says p_E = 0.01; below that, E fires.
    [result] = node.set_parameters({'thresholds.E': 0.005})
    assert result.successful
    assert node.get_parameter('thresholds.E') == 0.005
    status = node.send_array(shifted(img, 2, 0), 1.066)
    assert 'E' in status.fired and status.reason != 'no model fired'
    assert node.node._selector.thresholds['E'] == 0.005
    # min_tracks above what is tracked: too few tracks, a new reference.
    assert all(r.successful for r in node.set_parameters({'min_tracks': 300, 'min_points': 300}))
    status = node.send_array(shifted(img, 3, 0), 1.1)
    assert status.reason == 'too few tracks' and status.new_reference
    assert node.node._selector.config.policy.min_points == 300
    # Several at once, including the mode and the R veto.
    results = node.set_parameters(
        {
            'mode': 'continuous',
            'r_veto': ['F', 'E', 'H'],
            'min_parallax_deg': 2.5,
            'max_frames_since_reference': 2,
            'min_tracks': 50,
            'bit_depth': 12,
        }
    )
    assert all(r.successful for r in results), [r.reason for r in results]
    node.send_array(shifted(img, 4, 0), 1.133)
    config = node.node._selector.config
    assert config.mode == 'continuous' and config.max_frames_since_reference == 2
    assert config.policy.r_veto == frozenset('FEH') and config.policy.min_parallax_deg == 2.5
    assert node.node._settings.bit_depth == 12


def test_publishing_settings_are_live(harness_factory, near_sequence):
    h = harness_factory()
    assert h.set_parameters({'reference_frame_id': 'slam_map_optical'})[0].successful
    statuses = play(h, as_sequence(near_sequence), until_initialized=True)
    assert statuses[-1].method
    h.wait_until(lambda: h.poses and h.clouds, what='init/pose')
    assert h.poses[0].header.frame_id == h.clouds[0].header.frame_id == 'slam_map_optical'
    [result] = h.set_parameters({'reference_frame_id': ''})
    assert not result.successful and 'reference_frame_id must not be empty' in result.reason


def test_camera_parameters_are_live_until_a_camera_info_arrives(node):
    img = texture(23)
    node.send_array(img, 1.0)
    assert node.send_array(shifted(img, 1, 0), 1.033).frames_since_reference == 1
    results = node.set_parameters({'camera.fx': 500.0, 'camera.fy': 500.0})
    assert all(r.successful for r in results)
    status = node.send_array(shifted(img, 2, 0), 1.066)
    assert status.new_reference  # other intrinsics: a new reference
    assert (node.node._selector.intrinsics.fx, node.node._selector.intrinsics.fy) == (500, 500)
    camera = Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480)
    node.send_camera_info(camera)
    node.send_array(shifted(img, 3, 0), 1.1)
    [result] = node.set_parameters({'camera.fx': 450.0})
    assert not result.successful and 'camera_info' in result.reason
    assert node.get_parameter('camera.fx') == 500.0
    assert node.node._selector.intrinsics == camera


# ------------------------------------------------------------------------------- start-up
@pytest.mark.parametrize(
    ('override', 'match'),
    [
        ('min_parallax_deg:=.nan', r'min_parallax_deg must be a finite number in \[0, 90\]'),
        ('thresholds.E:=.nan', 'thresholds.E must be a finite number <= 1'),
        ('max_features:=1000000000000', r'max_features must be an integer in \[1, 10000\]'),
        ('camera.distortion:=[0.01, 0.001, 0.0]', 'camera.distortion: 3 distortion'),
        ('bit_depth:=20', 'bit_depth must be 0'),
        ('camera.cx:=-5.0', 'principal point cx=-5 px is outside the 640x480 image'),
        ('camera.cy:=1000000.0', 'principal point cy=1e\\+06 px is outside'),
        ('restart_tolerance_s:=-1.0', 'restart_tolerance_s must be a finite number'),
    ],
)
def test_bad_start_up_values_are_refused(context, tmp_path, override, match):
    from initsel_ros.ros.node import SelectorNode

    with pytest.raises(ConfigError, match=match):
        SelectorNode(
            context=context,
            namespace='/badstart',
            cli_args=[
                '--ros-args',
                '-p',
                override,
                '-p',
                f'model_file:={double_model_file(tmp_path)}',
            ],
        )


def _main_error(argv: list[str], monkeypatch, capfd) -> tuple[int, str]:
    from initsel_ros.ros.node import main

    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    code = main(['selector', *argv])
    return code, capfd.readouterr().err


def test_a_yaml_syntax_error_in_the_params_file_is_one_line_and_exit_1(
    tmp_path, monkeypatch, capfd
):
    params = tmp_path / 'broken.yaml'
    params.write_text('/**/selector:\n  ros__parameters:\n    mode: [once\n    min_tracks: 5\n')
    code, err = _main_error(['--ros-args', '--params-file', str(params)], monkeypatch, capfd)
    assert code == 1
    assert 'Traceback' not in err
    lines = [line for line in err.splitlines() if 'cannot start' in line]
    assert len(lines) == 1 and 'broken.yaml: YAML syntax error at line' in lines[0]


def test_a_nan_in_the_params_file_is_one_line_and_exit_1(tmp_path, monkeypatch, capfd):
    params = tmp_path / 'nan.yaml'
    params.write_text(
        f'/**/selector:\n  ros__parameters:\n    min_parallax_deg: .nan\n'
        f'    model_file: {double_model_file(tmp_path)}\n'
    )
    code, err = _main_error(['--ros-args', '--params-file', str(params)], monkeypatch, capfd)
    assert code == 1 and 'Traceback' not in err
    assert 'cannot start: min_parallax_deg must be a finite number in [0, 90], got nan' in err


def test_params_files_are_found_in_every_ros_args_section():
    from initsel_ros.ros.node import params_files

    argv = [
        'selector',
        '--params-file',
        'not_ros.yaml',
        '--ros-args',
        '--params-file',
        'a.yaml',
        '-p',
        'x:=1',
        '--',
        '--ros-args',
        '--params-file',
        'b.yaml',
    ]
    assert params_files(argv) == ['a.yaml', 'b.yaml']


def test_selector_update_config_rebuilds_the_tracker_only_when_its_settings_change():
    import dataclasses

    from model_fixtures import constant_models

    from initsel_ros.selector import SelectorConfig

    selector = Selector(constant_models(), Intrinsics.tum_fr3())
    img = texture(24)
    selector.process(img, 0)
    tracker = selector.tracker
    config = dataclasses.replace(
        selector.config, policy=dataclasses.replace(selector.config.policy, thresholds={'E': 0.2})
    )
    selector.update_config(config)
    assert selector.tracker is tracker and selector.thresholds['E'] == 0.2
    assert not selector.process(shifted(img, 1, 0), 1).new_reference
    selector.update_config(
        dataclasses.replace(config, tracker=dataclasses.replace(config.tracker, max_features=100))
    )
    assert selector.tracker is not tracker
    assert selector.process(shifted(img, 2, 0), 2).new_reference
    assert isinstance(selector.config, SelectorConfig)


def test_selector_set_intrinsics_resets_the_reference_only_for_another_camera():
    from model_fixtures import constant_models

    tum = Intrinsics.tum_fr3()
    selector = Selector(constant_models(), tum)
    img = texture(25)
    selector.process(img, 0)
    assert not selector.set_intrinsics(Intrinsics(**{**tum.to_dict(), 'distortion': (0.0,) * 5}))
    assert not selector.process(shifted(img, 1, 0), 1).new_reference
    assert selector.set_intrinsics(Intrinsics(540.0, 539.2, 320.1, 247.6, 640, 480))
    assert selector.process(shifted(img, 2, 0), 2).new_reference


def test_parameter_overrides_of_wrong_types_stay_a_config_error(context):
    from initsel_ros.ros.node import SelectorNode

    with pytest.raises(ConfigError, match='parameter bit_depth'):
        SelectorNode(
            context=context,
            namespace='/badtype',
            parameter_overrides=[Parameter('bit_depth', value='auto')],
        )


def test_parameters_the_selector_does_not_have_are_named_with_what_was_meant(
    context, tmp_path, capfd
):
    # before: a typo in a params file or a -p override set nothing, without a word
    from initsel_ros.ros.node import SelectorNode

    node = SelectorNode(
        context=context,
        namespace='/typos',
        cli_args=[
            '--ros-args',
            '-p',
            'min_parralax_deg:=5.0',
            '-p',
            'thresholds.e:=0.5',
            '-p',
            f'model_file:={double_model_file(tmp_path)}',
        ],
    )
    try:
        err = capfd.readouterr().err
        assert (
            'ignoring parameters the selector does not have: min_parralax_deg '
            '(min_parallax_deg?), thresholds.e (thresholds.E?)'
        ) in err
        assert node.get_parameter('min_parallax_deg').value != 5.0
    finally:
        node.destroy_node()


def test_a_params_file_with_no_section_for_the_node_is_said(context, tmp_path, capfd):
    from initsel_ros.ros.node import (
        SelectorNode,
        _check_ros_arguments,
        _warn_of_unused_params_files,
    )

    files = {
        'typo.yaml': '/**/selectr:\n  ros__parameters:\n    min_tracks: 5\n',
        'other_ns.yaml': '/robot/selector:\n  ros__parameters:\n    min_tracks: 5\n',
        'bare.yaml': 'selector:\n  ros__parameters:\n    min_tracks: 5\n',
        'nested.yaml': 'sections:\n  selector:\n    ros__parameters:\n      min_tracks: 5\n',
        'wildcard.yaml': '/*/selector:\n  ros__parameters:\n    min_tracks: 5\n',
        'any.yaml': '/**:\n  ros__parameters:\n    min_tracks: 5\n',
    }
    argv = ['selector', '--ros-args']
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        argv += ['--params-file', str(tmp_path / name)]
    node = SelectorNode(
        context=context,
        namespace='/sections',
        parameter_overrides=[Parameter('model_file', value=str(double_model_file(tmp_path)))],
    )
    try:
        capfd.readouterr()
        _warn_of_unused_params_files(_check_ros_arguments(argv), node)
        err = capfd.readouterr().err
        # as rcl matches them (checked against rclpy): a section for another name or another
        # namespace sets nothing; the nested form and the wildcards set this node's
        said = {name for name in files if f'{name}: no section for node /sections/selector' in err}
        assert said == {'typo.yaml', 'other_ns.yaml', 'bare.yaml'}
        assert 'typo.yaml: no section for node /sections/selector (sections: /**/selectr)' in err
    finally:
        node.destroy_node()
