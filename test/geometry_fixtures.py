"""Synthetic two-view scenes with exact ground truth, shared by the geometry tests."""

from __future__ import annotations

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics

K = Intrinsics.tum_fr3().K


def two_view(
    planar: bool,
    n: int = 250,
    baseline: float = 0.15,
    noise_px: float = 0.3,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points seen by ``[I|0]`` and a camera moved sideways and turned back toward them.

    Returns:
        ``(p0 (n, 2), p1 (n, 2), R (3, 3), t (3,) unit, X (n, 3))`` with ``x1 = R x0 + t``
        (t at the scale of X divided by its norm; X in the reference camera frame).
    """
    rng = np.random.default_rng(seed)
    u = rng.uniform(20, 620, n)
    v = rng.uniform(20, 460, n)
    rays = np.linalg.inv(K) @ np.vstack([u, v, np.ones(n)])
    if planar:  # a wall 2 m ahead, tilted 20 degrees about the vertical
        normal = np.array([np.sin(0.35), 0.0, -np.cos(0.35)])
        depth = -2.0 / (normal @ rays)
    else:  # depths from 1 m to 4 m
        depth = rng.uniform(1.0, 4.0, n)
    X = (rays * depth).T
    R = cv2.Rodrigues(np.array([0.01, -0.06, 0.005]))[0]
    t = np.array([-baseline, 0.01, 0.02])
    Xc = X @ R.T + t
    p0 = np.stack([u, v], axis=1) + rng.normal(0, noise_px, (n, 2))
    proj = Xc @ K.T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, (n, 2))
    return p0, p1, R, t / np.linalg.norm(t), X / np.linalg.norm(t)


def pan(
    n: int = 200, seed: int = 3, noise_px: float = 0.2, both_views: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Correspondences of a camera turning 2 degrees on the spot (any depths), with
    ``noise_px`` of tracking noise in the second view (in both with ``both_views``)."""
    rng = np.random.default_rng(seed)
    p0 = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    R = cv2.Rodrigues(np.array([0.0, np.radians(2.0), 0.0]))[0]
    rays = np.column_stack([p0, np.ones(n)]) @ np.linalg.inv(K).T
    proj = rays @ (K @ R).T
    p1 = proj[:, :2] / proj[:, 2:3]
    if both_views:
        p0 = p0 + rng.normal(0, noise_px, (n, 2))
    return p0, p1 + rng.normal(0, noise_px, (n, 2))


def poster_off_centre(
    baseline: float = 0.02, n: int = 300, noise_px: float = 0.15, seed: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A poster 1.2 m away seen from below and to its left (its tracks mostly right of the
    principal point), the camera slid ``baseline`` m sideways and turned back toward it: H's
    mirrored decomposition triangulates most tracks in front too. Returns p0, p1 and the unit
    translation."""
    rng = np.random.default_rng(seed)
    p0 = rng.uniform([240, 20], [620, 460], (n, 2))
    rays = np.c_[p0, np.ones(n)] @ np.linalg.inv(K).T
    normal = np.array([0.0, -np.sin(np.radians(33)), np.cos(np.radians(33))])
    X = rays * (1.2 / (rays @ normal))[:, None]
    R = cv2.Rodrigues(np.array([0.0, -np.arctan2(baseline, 1.2), 0.0]))[0]
    t = -R @ np.array([baseline, 0.0, 0.0])
    proj = (X @ R.T + t) @ K.T
    p1 = proj[:, :2] / proj[:, 2:3] + rng.normal(0, noise_px, (n, 2))
    return p0 + rng.normal(0, noise_px, (n, 2)), p1, t / np.linalg.norm(t)


#: The turn of :func:`toward_a_wall`'s camera (a rotation vector, radians).
TOWARD_A_WALL_TURN = np.array([0.01, -0.03, 0.005])


def view_of(X: np.ndarray, rvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points ``X`` (reference frame) seen by the camera ``x = R X + t``."""
    proj = (X @ cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))[0].T + t) @ K.T
    return proj[:, :2] / proj[:, 2:3]


def toward_a_wall(
    baseline: float = 0.1, n: int = 250, noise_px: float = 0.3, seed: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """two_view's wall (2 m ahead, tilted 20 degrees), the camera moving mostly toward it
    (forward, a little right and down) by ``baseline`` m and turning by
    :data:`TOWARD_A_WALL_TURN`: both of H's decompositions put the whole wall in front of
    both cameras (the mirrored plane's normal is near the motion, its horizon outside the
    image), the genuine two-fold ambiguity.

    Returns:
        ``(p0, p1, R, t unit, X)`` as :func:`two_view`.
    """
    rng = np.random.default_rng(seed)
    u = rng.uniform(20, 620, n)
    v = rng.uniform(20, 460, n)
    rays = np.linalg.inv(K) @ np.vstack([u, v, np.ones(n)])
    normal = np.array([np.sin(0.35), 0.0, -np.cos(0.35)])
    X = (rays * (-2.0 / (normal @ rays))).T
    direction = np.array([0.3, 0.05, 1.0]) / np.linalg.norm([0.3, 0.05, 1.0])
    t = baseline * direction
    p0 = np.stack([u, v], axis=1) + rng.normal(0, noise_px, (n, 2))
    p1 = view_of(X, TOWARD_A_WALL_TURN, t) + rng.normal(0, noise_px, (n, 2))
    R = cv2.Rodrigues(TOWARD_A_WALL_TURN)[0]
    return p0, p1, R, direction, X / baseline
