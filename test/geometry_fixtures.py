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


def wall_with_objects(
    plane_share: float = 0.7, n: int = 300, noise_px: float = 0.5, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """two_view's wall (2 m ahead, tilted 20 degrees) holding ``plane_share`` of the tracks,
    the rest on objects standing 15-40 % nearer, the camera slid 15 cm sideways and turned
    back: a plane dominates, where an 8-point RANSAC F can fit the plane and miss the rest.
    Returns p0, p1 (``noise_px`` in both views) and the unit translation."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(20, 620, n)
    v = rng.uniform(20, 460, n)
    rays = np.linalg.inv(K) @ np.vstack([u, v, np.ones(n)])
    normal = np.array([np.sin(0.35), 0.0, -np.cos(0.35)])
    depth = -2.0 / (normal @ rays)
    off = rng.random(n) >= plane_share
    depth[off] *= rng.uniform(0.6, 0.85, int(off.sum()))
    X = (rays * depth).T
    t = np.array([-0.15, 0.01, 0.02])
    p0 = np.stack([u, v], axis=1) + rng.normal(0, noise_px, (n, 2))
    p1 = view_of(X, np.array([0.01, -0.06, 0.005]), t) + rng.normal(0, noise_px, (n, 2))
    return p0, p1, t / np.linalg.norm(t)


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


# ----------------------------------------------------------------- rotation fit, reference
def rotation_residuals_px(
    R: np.ndarray, b0: np.ndarray, pixels: np.ndarray, K: np.ndarray
) -> np.ndarray:
    """Pixel distances between ``pixels`` (N, 2) and bearings ``b0`` (N, 3) rotated by ``R``
    (3, 3) or by each of a stack (H, 3, 3): (N,) or (H, N); inf behind the camera."""
    stack = np.asarray(K @ R).reshape(-1, 3, 3)
    proj = np.einsum('hij,nj->hni', stack, b0)
    with np.errstate(divide='ignore', invalid='ignore'):
        err = np.hypot(
            proj[..., 0] / proj[..., 2] - pixels[:, 0], proj[..., 1] / proj[..., 2] - pixels[:, 1]
        )
    err = np.where(proj[..., 2] > 0, err, np.inf)
    return err[0] if np.ndim(R) == 2 else err


def least_quantile_rotation_px(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    quantile: float = 0.5,
    enough_below_px: float | None = None,
) -> float:
    """The robust rotation fit of ``geometry._rotation_quantile_over_scales`` under one K,
    written one step at a time (the reference the vectorized search is checked against):
    the ``quantile`` of the residuals of the best of the least-squares fit, 128 two-point
    samples (scored on an even subset of at most 300 tracks) and the best one's refit on the
    tracks it explains at least that well. With ``quantile`` 0.5 and the 3 px threshold this
    was the selector's rotation guard before issue 20 (``rotation_only_residual_px``).
    ``enough_below_px``: return the least-squares fit's value when it is already below.
    Rows with a non-finite value are ignored; NaN below 3 finite rows."""
    from initsel_ros.geometry import (
        ROTATION_HYPOTHESES,
        ROTATION_SCORING_POINTS,
        _kabsch,
        homogeneous,
    )

    a, b = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    finite = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[finite], b[finite]
    n = a.shape[0]
    if n < 3:
        return float('nan')

    def q(values: np.ndarray, axis: int | None = None) -> np.ndarray:
        return np.quantile(values, quantile, axis=axis, method='lower')  # inf-safe

    K_inv = np.linalg.inv(K)
    b0 = homogeneous(a) @ K_inv.T
    b1 = homogeneous(b) @ K_inv.T
    b0 /= np.linalg.norm(b0, axis=1, keepdims=True)
    b1 /= np.linalg.norm(b1, axis=1, keepdims=True)
    least_squares = _kabsch(b0, b1)
    best = float(q(rotation_residuals_px(least_squares, b0, b, K)))
    if enough_below_px is not None and best < enough_below_px:
        return best
    rng = np.random.default_rng(0)
    first = rng.integers(0, n, ROTATION_HYPOTHESES)
    second = (first + rng.integers(1, n, ROTATION_HYPOTHESES)) % n
    pairs = np.stack([first, second], axis=1)
    rotations = np.concatenate([least_squares[None], _kabsch(b0[pairs], b1[pairs])])
    subset = np.linspace(0, n - 1, min(n, ROTATION_SCORING_POINTS)).astype(np.int64)
    scores = q(rotation_residuals_px(rotations, b0[subset], b[subset], K), axis=1)
    err = rotation_residuals_px(rotations[int(np.argmin(scores))], b0, b, K)
    best = min(best, float(q(err)))
    better = err <= q(err)
    if better.sum() >= 3:
        refit = _kabsch(b0[better], b1[better])
        best = min(best, float(q(rotation_residuals_px(refit, b0, b, K))))
    return best
