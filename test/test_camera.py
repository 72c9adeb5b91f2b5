"""Tests for initsel_ros.camera: undistorting pixels, the standard and the fisheye lens."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from initsel_ros.camera import Intrinsics, lens_from_camera_info
from initsel_ros.errors import ConfigError


def test_undistort_pixels_inverts_the_opencv_distortion_model():
    camera = Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480, (-0.15, 0.05, 5e-4, -5e-4))
    rng = np.random.default_rng(0)
    ideal = rng.uniform([40, 40], [600, 440], (100, 2))
    rays = np.hstack([ideal, np.ones((100, 1))]) @ np.linalg.inv(camera.K).T
    distorted, _ = cv2.projectPoints(
        rays, np.zeros(3), np.zeros(3), camera.K, np.array(camera.distortion)
    )
    out = camera.undistort_pixels(distorted.reshape(-1, 2))
    assert out.dtype == np.float32 and out.shape == (100, 2)
    assert np.max(np.abs(out - ideal)) < 0.05
    plain = Intrinsics.tum_fr3()
    assert np.array_equal(plain.undistort_pixels(ideal), ideal.astype(np.float32))
    assert camera.undistort_pixels(np.zeros((0, 2))).shape == (0, 2)


def _fisheye(distortion=(0.05, -0.01, 0.004, -0.001)) -> Intrinsics:
    """A 640x480 fisheye whose image corners see 60 degrees off the axis (f-theta)."""
    f = 400.0 / math.radians(60.0)
    return Intrinsics(f, f, 320.0, 240.0, 640, 480, distortion, fisheye=True)


def test_undistort_pixels_inverts_the_fisheye_model():
    camera = _fisheye()
    rng = np.random.default_rng(1)
    rays = np.column_stack([rng.uniform(-1.2, 1.2, (200, 2)), np.ones(200)])
    distorted, _ = cv2.fisheye.projectPoints(
        rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, np.array(camera.distortion)
    )
    ideal = rays[:, :2] @ np.diag([camera.fx, camera.fy]) + [camera.cx, camera.cy]
    out = camera.undistort_pixels(distorted.reshape(-1, 2))
    assert out.dtype == np.float32 and out.shape == (200, 2)
    assert np.max(np.abs(out - ideal)) < 0.05
    # read as OpenCV's standard model, the same four numbers give other pixels
    standard = Intrinsics(*camera.pinhole, 640, 480, camera.distortion)
    assert np.max(np.abs(standard.undistort_pixels(distorted.reshape(-1, 2)) - ideal)) > 20


def test_a_fisheye_with_zero_coefficients_is_an_f_theta_lens_not_a_pinhole():
    camera = _fisheye(())
    assert camera.has_distortion and camera.distortion_model == 'equidistant'
    theta = math.radians(45.0)
    corner = np.array([[camera.cx + camera.fx * theta, camera.cy]])  # f-theta: r = f theta
    expected = camera.cx + camera.fx * math.tan(theta)  # pinhole: r = f tan(theta)
    assert abs(camera.undistort_pixels(corner)[0, 0] - expected) < 0.01


@pytest.mark.parametrize(
    ('model', 'd', 'expected'),
    [
        ('plumb_bob', [0.0] * 5, ((), False)),
        ('', [], ((), False)),
        ('plumb_bob', [0.1, 0.0, 0.0, 0.0, 0.0], ((0.1, 0.0, 0.0, 0.0, 0.0), False)),
        ('rational_polynomial', [0.1] * 8, ((0.1,) * 8, False)),
        ('equidistant', [0.1, 0.0, 0.0, 0.0], ((0.1, 0.0, 0.0, 0.0), True)),
        ('equidistant', [0.0] * 4, ((0.0,) * 4, True)),
        ('equidistant', [], ((0.0,) * 4, True)),
        ('fov', [0.0], ((), False)),  # no coefficients to misread
    ],
)
def test_lens_from_camera_info(model, d, expected):
    assert lens_from_camera_info(model, d) == expected


@pytest.mark.parametrize(
    ('model', 'd', 'match'),
    [
        ('fov', [0.9], "model 'fov' is not supported"),
        ('equidistant', [0.1, 0.0, 0.0, 0.0, 0.0], r'fisheye .equidistant. model takes 4'),
        ('plumb_bob', [0.1, 0.0, 0.0], 'OpenCV needs 4, 5, 8, 12, 14'),
        ('plumb_bob', [math.nan, 0, 0, 0], 'non-finite'),
    ],
)
def test_lens_from_camera_info_refuses_what_it_would_misread(model, d, match):
    with pytest.raises(ConfigError, match=match):
        lens_from_camera_info(model, d)


@pytest.mark.parametrize(
    'k',
    [
        [500.0, 3.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],  # skew: would be dropped
        [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 2.0],  # not normalized
        [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.1, 0.0, 1.0],
        [500.0, 0.0, math.nan, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],
        [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0],  # 8 values
    ],
)
def test_a_camera_info_k_that_is_not_a_pinhole_matrix_is_refused_not_misread(k):
    # the bag readers and the node read CameraInfo here: neither may drop a skew silently
    with pytest.raises(ConfigError, match='invalid K'):
        Intrinsics.from_camera_info(k, 640, 480, [], 'plumb_bob')
    good = [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]
    assert Intrinsics.from_camera_info(good, 640, 480, [], 'plumb_bob') == Intrinsics(
        500.0, 500.0, 320.0, 240.0, 640, 480
    )


def test_fisheye_intrinsics_round_trip_through_their_file_form(tmp_path):
    camera = _fisheye()
    camera.save_yaml(tmp_path / 'intrinsics.yaml')
    assert 'fisheye: true' in (tmp_path / 'intrinsics.yaml').read_text()
    assert Intrinsics.load_yaml(tmp_path / 'intrinsics.yaml') == camera
    assert 'fisheye' not in Intrinsics.tum_fr3().to_dict()  # older readers see no new key
    assert camera.scaled(320, 240).fisheye
    standard = Intrinsics(*camera.pinhole, 640, 480, camera.distortion)
    assert not camera.same_camera(standard) and camera.same_camera(camera.scaled(640, 480))
    with pytest.raises(ConfigError, match='fisheye must be true or false'):
        Intrinsics.from_dict({**camera.to_dict(), 'fisheye': 'yes'})
    with pytest.raises(ConfigError, match=r'fisheye .equidistant. model takes 4'):
        Intrinsics(*camera.pinhole, 640, 480, (0.1, 0.0, 0.0, 0.0, 0.0), fisheye=True)


def test_the_corner_field_angle_tells_a_lens_past_its_pinhole_horizon():
    assert Intrinsics.tum_fr3().corner_field_angle_deg == pytest.approx(37.0, abs=0.1)
    assert _fisheye(()).corner_field_angle_deg == pytest.approx(60.0, abs=0.01)
    wide = Intrinsics(200.0, 200.0, 320.0, 240.0, 640, 480, (), fisheye=True)  # 115 degrees
    assert wide.corner_field_angle_deg == 90.0
    barrel = Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480, (-0.15, 0.05, 5e-4, -5e-4))
    assert barrel.corner_field_angle_deg > Intrinsics.tum_fr3().corner_field_angle_deg


def test_the_field_mask_keeps_the_rays_within_80_degrees_of_the_axis():
    assert Intrinsics.tum_fr3().field_mask() is None
    assert _fisheye().field_mask() is None  # corners at 60 degrees: nothing to leave out
    wide = Intrinsics(200.0, 200.0, 320.0, 240.0, 640, 480, (), fisheye=True)  # f-theta
    mask = wide.field_mask()
    assert mask.shape == (480, 640) and mask[240, 320] and not mask[0, 0]
    assert wide.field_mask() is mask and not mask.flags.writeable  # made once, shared
    radius = 200.0 * math.radians(80.0)  # r = f theta
    assert mask[240, 320 + int(radius) - 2] and not mask[240, 320 + int(radius) + 2]


def test_an_intrinsics_file_s_errors_name_it_on_one_line(tmp_path):
    path = tmp_path / 'intrinsics.yaml'
    path.write_text('fx: .nan\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\n')
    with pytest.raises(ConfigError, match=f'^{path}: intrinsics must be finite'):
        Intrinsics.load_yaml(path)
    path.write_text('fx: [500\nfy: 500\n')
    with pytest.raises(ConfigError, match=f'^{path}: cannot read intrinsics') as info:
        Intrinsics.load_yaml(path)
    assert '\n' not in str(info.value)


def test_an_infinite_image_size_in_an_intrinsics_file_is_one_line_naming_it(tmp_path):
    path = tmp_path / 'intrinsics.yaml'
    path.write_text('fx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: .inf\nheight: 480\n')
    with pytest.raises(ConfigError, match=f'^{path}: intrinsics need'):  # was OverflowError
        Intrinsics.load_yaml(path)


@pytest.mark.parametrize('k1', [1e30, 1e6])
def test_a_distortion_that_folds_the_image_onto_a_sliver_is_refused(k1):
    # k1 = 1e30 used to be taken: every undistorted track sat on the principal point, and
    # the node said "the camera has hardly moved" on every frame of a moving camera
    with pytest.raises(ConfigError, match='folds the 640x480 image onto'):
        Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480, (k1, 0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize(
    'distortion, fisheye',
    [
        ((0.2624, -0.9531, -0.0054, 0.0026, 1.1633), False),  # TUM fr1
        ((-0.2834, 0.0740, 0.0002, 0.00002), False),  # EuRoC
        ((5.0, 0.0, 0.0, 0.0, 0.0), False),  # strong pincushion: 47 % of the width
        ((-0.01, 0.05, -0.05, 0.01), True),  # a fisheye past the pinhole's horizon
    ],
)
def test_real_and_strong_lenses_keep_their_distortion(distortion, fisheye):
    f = 285.0 if fisheye else 500.0
    Intrinsics(f, f, 320.0, 240.0, 640, 480, distortion, fisheye)
