"""Quaternion/matrix conversions and trajectory interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.datasets.poses import interpolate_poses
from initsel_ros.errors import GeometryError
from initsel_ros.transforms import (
    matrix_to_pose,
    matrix_to_quaternion,
    pose_matrix,
    quaternion_to_matrix,
    slerp,
)


def _random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, 3:4] < 0, -q, q)


def test_quaternion_matrix_round_trip_is_identity_and_rotations_are_orthonormal():
    rng = np.random.default_rng(0)
    q = _random_quaternions(rng, 500)
    R = quaternion_to_matrix(q)
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(matrix_to_quaternion(R), q, atol=1e-10)


def test_quaternion_convention_is_xyzw():
    # 90 degrees about z: (x, y, z, w) = (0, 0, sin 45, cos 45)
    s = np.sqrt(0.5)
    R = quaternion_to_matrix(np.array([0.0, 0.0, s, s]))
    assert np.allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def test_pose_matrix_places_translation_and_inverts():
    rng = np.random.default_rng(1)
    q = _random_quaternions(rng, 1)[0]
    t = np.array([1.0, -2.0, 0.5])
    T = pose_matrix(t, q)
    assert T.shape == (4, 4)
    assert np.allclose(T[:3, 3], t) and np.allclose(T[3], [0, 0, 0, 1])
    t2, q2 = matrix_to_pose(T)
    assert np.allclose(t2, t) and np.allclose(q2, q)


def test_zero_quaternion_raises():
    with pytest.raises(GeometryError, match='zero norm'):
        quaternion_to_matrix(np.zeros(4))


def test_slerp_halfway_is_half_the_angle():
    q0 = np.array([[0.0, 0.0, 0.0, 1.0]])
    angle = np.deg2rad(80)
    q1 = np.array([[0.0, np.sin(angle / 2), 0.0, np.cos(angle / 2)]])
    half = slerp(q0, q1, np.array([0.5]))
    assert np.allclose(half, [[0.0, np.sin(angle / 4), 0.0, np.cos(angle / 4)]])


def test_interpolation_is_linear_inside_and_nan_outside_or_across_gaps():
    stamps = np.array([0.0, 1.0, 2.0, 5.0])
    positions = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [5, 0, 0]], dtype=float)
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (4, 1))
    t, q = interpolate_poses([0.25, 1.0, 3.0, -0.5, 6.0], stamps, positions, quats, max_gap=1.5)
    assert np.allclose(t[0], [0.25, 0, 0]) and np.allclose(t[1], [1, 0, 0])
    assert np.all(np.isnan(t[2:])) and np.all(np.isnan(q[2:]))


def test_nearest_tolerance_fills_queries_just_outside_the_trajectory():
    stamps = np.array([1.0, 1.01])
    positions = np.array([[0, 0, 0], [1, 1, 1]], dtype=float)
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))
    t, _ = interpolate_poses([0.89, 0.5], stamps, positions, quats, nearest_tolerance=0.15)
    assert np.allclose(t[0], [0, 0, 0])
    assert np.isnan(t[1, 0])


def test_a_trajectory_is_checked_sorted_and_its_exact_repeats_dropped(caplog):
    import logging

    from initsel_ros.datasets.poses import check_trajectory
    from initsel_ros.errors import DatasetError

    stamps = np.array([2.0, 1.0, 1.0, 3.0])
    positions = np.array([[2.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]])
    quaternions = np.array([[0, 0, 0, 1.0], [0, 0, 0, 1.0], [0, 0, 0, -1.0], [0, 0, 0, 1.0]])
    t, p, q = check_trajectory(stamps, positions, quaternions, 'gt.txt')
    assert len(q) == 3
    assert t.tolist() == [1.0, 2.0, 3.0] and p[:, 0].tolist() == [1.0, 2.0, 3.0]  # q = -q
    # one time, two poses: before, interpolation blended them silently
    conflicting = positions.copy()
    conflicting[2, 0] = 2.0
    with pytest.raises(DatasetError, match=r'gt.txt: time 1.0 has two different poses'):
        check_trajectory(stamps, conflicting, quaternions, 'gt.txt')
    broken = positions.copy()
    broken[3, 1] = np.nan  # before: a bag's NaN position went through as a missing x
    with pytest.raises(DatasetError, match=r'bag /pose: sample 3 \(time 3.0\) has a non-finite'):
        check_trajectory(stamps, broken, quaternions, 'bag /pose')
    with pytest.raises(DatasetError, match='zero quaternion'):
        check_trajectory(stamps, positions, quaternions * [1, 1, 1, 0], 'bag /pose')
    with caplog.at_level(logging.WARNING):
        check_trajectory(stamps, positions, quaternions * 3.0, 'gt.txt')
    assert '4 of 4 quaternions are not of unit norm' in caplog.text
