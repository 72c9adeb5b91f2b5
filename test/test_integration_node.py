"""The selector node in one process: node and test publisher/subscribers on one executor.

No launch, no subprocesses: a private rclpy context on a private DDS domain. Frames are fed
one at a time and each waits for its ``~/status``, so nothing is dropped and every frame is
accounted for.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

from diagnostic_msgs.msg import DiagnosticStatus
from image_fixtures import shifted, texture
from node_harness import (
    TIMEOUT_S,
    as_sequence,
    double_model_file,
    harnesses,
    hold_selector,
    play,
    ros_context,
)
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers import DOMAIN_ID
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from initsel_ros.backlog import BacklogWatch
from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError, ModelFileError
from initsel_ros.metrics import relative_pose, translation_chordal_error
from initsel_ros.policy import Reason
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.node import SelectorNode


@pytest.fixture(scope='module')
def context():
    yield from ros_context()


@pytest.fixture
def harness_factory(context):
    yield from harnesses(context)


# ------------------------------------------------------------------------------ with a model
def test_node_initializes_on_a_near_sequence_with_the_true_baseline_direction(
    harness_factory, near_sequence
):
    sequence = as_sequence(near_sequence)
    h = harness_factory()
    statuses = play(h, sequence)
    assert len(statuses) == len(sequence)  # one status per frame, none dropped
    assert all(s.dropped_frames == 0 for s in statuses)
    h.wait_until(lambda: h.methods and h.poses and h.clouds, what='init/method, pose, points')
    assert h.methods == [next(s.method for s in statuses if s.method)]
    assert h.methods[0] in ('F', 'E', 'H')
    assert statuses[-1].initialized

    pose, cloud = h.poses[0], h.clouds[0]
    assert pose.header.frame_id == cloud.header.frame_id == 'initsel_reference_optical'
    stamps = sequence.stamps
    cur = int(np.argmin(np.abs(stamps - conv.stamp_to_seconds(pose.header.stamp))))
    ref = int(np.argmin(np.abs(stamps - conv.stamp_to_seconds(cloud.header.stamp))))
    assert ref < cur
    q = pose.pose.orientation
    R_est = conv.quaternion_to_rotation([q.x, q.y, q.z, q.w]).T
    p = pose.pose.position
    t_est = -R_est @ np.array([p.x, p.y, p.z])
    _, t_gt = relative_pose(sequence.frames[ref].pose, sequence.frames[cur].pose)
    assert translation_chordal_error(t_gt, t_est) < 0.8

    points = conv.point_cloud_to_array(cloud)
    assert points.size >= 50
    z = points['z']
    assert np.mean(z > 0) > 0.95
    assert np.median(z) == pytest.approx(1.0, rel=0.01)  # scale convention: median depth 1
    assert np.all((points['u0'] >= 0) & (points['u0'] < sequence.intrinsics.width))
    assert len(h.diagnostics) >= len(sequence) - 1


@pytest.mark.parametrize('fixture_name', ['rotation_sequence', 'static_sequence'])
def test_node_never_initializes_on_rotation_or_a_static_camera(
    harness_factory, request, fixture_name
):
    sequence = as_sequence(request.getfixturevalue(fixture_name))
    h = harness_factory()
    statuses = play(h, sequence)
    assert len(statuses) == len(sequence)
    assert not any(s.method for s in statuses)
    assert not statuses[-1].initialized
    for _ in range(10):
        h.executor.spin_once(timeout_sec=0.02)
    assert h.methods == [] and h.poses == [] and h.clouds == []


# ----------------------------------------------------------------- behaviour without a model
def test_status_reports_reasons_probabilities_and_diagnostics(harness_factory, tmp_path):
    h = harness_factory(model_file=double_model_file(tmp_path))
    h.send_camera_info(Intrinsics.tum_fr3())  # the camera of the frames: nothing guessed
    img = texture(1)
    first = h.send_array(img, 100.0)
    second = h.send_array(shifted(img, 2.0, 1.0), 100.033)
    assert first.reason == 'new reference' and first.new_reference
    assert second.reason == 'no model fired' and second.level == 'OK'
    assert second.probabilities['E'] == pytest.approx(0.01)
    assert second.tracks > 100
    assert second.mean_disparity_px == pytest.approx(math.hypot(2.0, 1.0), abs=0.2)
    assert second.frames_since_reference == 1
    h.wait_until(lambda: len(h.diagnostics) >= 2, what='diagnostics')
    diag = h.diagnostics[-1]
    assert diag.level == DiagnosticStatus.OK and diag.message == 'no model fired'
    keys = {kv.key for kv in diag.values}
    assert {
        'p_F',
        'p_E',
        'p_H',
        'p_R',
        'tracks',
        'mean_disparity_px',
        'frames_since_reference',
        'dropped_frames',
        'reason',
    } <= keys


def test_reset_service_makes_the_next_frame_the_reference(harness_factory, tmp_path):
    h = harness_factory(model_file=double_model_file(tmp_path))
    img = texture(2)
    for k in range(3):
        status = h.send_array(shifted(img, k, 0.0), 10.0 + k / 30)
    assert status.frames_since_reference == 2 and not status.new_reference
    assert h.reset_client.wait_for_service(timeout_sec=TIMEOUT_S)
    future = h.reset_client.call_async(Trigger.Request())
    h.wait_until(future.done, what='the reset response')
    assert future.result().success
    status = h.send_array(shifted(img, 3.0, 0.0), 10.1)
    assert status.new_reference and status.reason == 'new reference'
    status = h.send_array(shifted(img, 4.0, 0.0), 10.13)
    assert status.frames_since_reference == 1


def _bad_images() -> list[Image]:
    good = conv.numpy_to_image(texture(3), 'mono8', stamp=conv.seconds_to_stamp(5.0))
    unknown = conv.numpy_to_image(texture(3), 'mono8')
    unknown.encoding = '32FC1'
    short_step = conv.numpy_to_image(texture(3), 'mono8')
    short_step.step = short_step.width - 1
    truncated = conv.numpy_to_image(np.zeros((480, 640, 3), np.uint8), 'rgb8')
    truncated.data = bytes(truncated.data)[: 3 * 640 * 100]
    empty = Image(encoding='bgr8')
    return [unknown, short_step, truncated, empty, good]


def test_bad_images_are_skipped_with_a_warning_and_the_node_keeps_going(harness_factory, tmp_path):
    h = harness_factory(model_file=double_model_file(tmp_path))
    *bad, good = _bad_images()
    for msg in bad:
        status = h.send(msg)
        assert status.reason is Reason.SKIPPED_IMAGE and status.level == 'WARN'
        assert status.frame_index is None
    assert 'unsupported image encoding' in h.statuses[0].detail
    assert 'step' in h.statuses[1].detail and 'data has' in h.statuses[2].detail
    status = h.send(good)
    assert status.reason == 'new reference' and status.frame_index == 0
    assert status.skipped_frames == len(bad)


def test_images_of_another_size_than_the_intrinsics_are_still_processed(harness_factory, tmp_path):
    h = harness_factory(model_file=double_model_file(tmp_path), use_camera_info=False)
    small = texture(4, shape=(240, 320))
    assert h.send_array(small, 1.0).reason == 'new reference'
    status = h.send_array(shifted(small, 1.0, 0.0), 1.033)
    assert status.reason == 'no model fired'
    assert h.node._selector.intrinsics == Intrinsics.tum_fr3().scaled(320, 240)


def test_invalid_camera_info_is_ignored_and_a_valid_one_is_used(harness_factory, tmp_path):
    h = harness_factory(model_file=double_model_file(tmp_path))
    bad = conv.intrinsics_to_camera_info(Intrinsics.tum_fr3())
    bad.k = [math.nan] * 9
    h.info_pub.publish(bad)
    h.send_array(texture(5), 1.0)
    assert h.node._selector.intrinsics == Intrinsics.tum_fr3()
    other = Intrinsics(600.0, 600.0, 319.5, 239.5, 640, 480)
    h.send_camera_info(other)
    h.send_array(texture(5), 1.033)
    assert h.node._selector.intrinsics == other


def test_only_the_newest_frame_waits_and_overwritten_ones_count_as_dropped(
    harness_factory, tmp_path
):
    h = harness_factory(model_file=double_model_file(tmp_path))
    entered, release = hold_selector(h)
    frames = [
        conv.numpy_to_image(texture(6), 'mono8', stamp=conv.seconds_to_stamp(1.0 + k))
        for k in range(4)
    ]
    h.node._on_image(frames[0])
    assert entered.wait(10.0)  # the worker is busy with frame 1 ...
    for msg in frames[1:]:  # ... while three more arrive
        h.node._on_image(msg)
    release.set()
    h.wait_until(lambda: len(h.statuses) >= 2, what='two statuses')
    for _ in range(10):
        h.executor.spin_once(timeout_sec=0.02)
    assert [s.stamp for s in h.statuses] == [pytest.approx(1.0), pytest.approx(4.0)]
    assert h.statuses[-1].dropped_frames == 2 and h.statuses[-1].received_frames == 4


def test_a_node_slower_than_its_camera_says_so_in_its_log(harness_factory, tmp_path, capfd):
    # a 720p camera at 30 Hz on a busy machine dropped a fifth of its frames with nothing in
    # the log (only ~/status counted them)
    h = harness_factory(model_file=double_model_file(tmp_path))
    h.node._backlog = BacklogWatch(window=4, warn_share=0.25)
    h.send_array(texture(6), 0.5)  # the first processed frame starts the first window
    entered, release = hold_selector(h)
    frames = [
        conv.numpy_to_image(texture(6), 'mono8', stamp=conv.seconds_to_stamp(1.0 + k))
        for k in range(4)
    ]
    h.node._on_image(frames[0])
    assert entered.wait(10.0)  # the worker is busy with this frame while three more arrive
    for msg in frames[1:]:
        h.node._on_image(msg)
    release.set()
    h.wait_until(lambda: len(h.statuses) >= 3, what='three statuses')
    for _ in range(10):
        h.executor.spin_once(timeout_sec=0.02)
    err = capfd.readouterr().err
    assert 'dropped 2 of the last 4 frames (they arrived every' in err, err
    # (which cause it names depends on this machine's timing: test_backlog.py holds both)
    assert 'processing is slower than the camera' in err or 'arrive in bursts' in err


def test_missing_or_malformed_model_file_stops_the_node_with_one_error(context, tmp_path):
    broken = tmp_path / 'broken.json'
    broken.write_text('{"format": "something else"')
    for path in (tmp_path / 'missing.json', broken):
        with pytest.raises(ModelFileError, match=str(path.name)):
            SelectorNode(
                context=context,
                namespace='/broken',
                parameter_overrides=[Parameter('model_file', value=str(path))],
            )


def test_main_returns_1_on_a_bad_model_file(tmp_path, monkeypatch):
    from initsel_ros.ros.node import main

    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    code = main(['selector', '--ros-args', '-p', f'model_file:={tmp_path / "none.json"}'])
    assert code == 1


def test_parameter_of_the_wrong_type_is_a_config_error(context):
    with pytest.raises(ConfigError, match='parameter max_features'):
        SelectorNode(
            context=context,
            namespace='/badparam',
            parameter_overrides=[Parameter('max_features', value='many')],
        )


def test_empty_r_veto_from_a_params_file_disables_the_veto(context, tmp_path):
    params = tmp_path / 'no_veto.yaml'
    params.write_text(
        f'/**/selector:\n  ros__parameters:\n    r_veto: []\n'
        f'    model_file: {double_model_file(tmp_path)}\n'
    )
    node = SelectorNode(
        context=context, namespace='/noveto', cli_args=['--ros-args', '--params-file', str(params)]
    )
    try:
        assert node._selector.config.policy.r_veto == frozenset()
    finally:
        node.destroy_node()


def test_debug_image_is_drawn_only_while_someone_subscribes(harness_factory, near_sequence):
    sequence = as_sequence(near_sequence)
    h = harness_factory()
    images: list[Image] = []
    h.send_array(sequence.image(0), sequence.frames[0].stamp)
    h.send_array(sequence.image(1), sequence.frames[1].stamp)
    assert not images  # nobody listened: nothing drawn
    h.client.create_subscription(
        Image,
        'selector/debug_image',
        images.append,
        QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT),
    )
    h.wait_until(
        lambda: h.node.count_subscribers(f'{h.namespace}/selector/debug_image') > 0,
        what='debug image subscriber',
    )
    raw = sequence.image(2)
    h.send_array(raw, sequence.frames[2].stamp)
    h.wait_until(lambda: images, what='a debug image')
    debug = conv.image_to_cv(images[-1])
    assert images[-1].encoding == 'bgr8'
    assert debug.shape == raw.shape
    changed = np.any(debug != raw, axis=2).mean()
    assert 0.01 < changed < 0.9  # tracks, bars and text drawn over the frame, not a blank
    assert conv.stamp_to_seconds(images[-1].header.stamp) == pytest.approx(
        sequence.frames[2].stamp, abs=1e-6
    )
