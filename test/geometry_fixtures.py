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
