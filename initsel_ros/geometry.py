"""Two-view geometry: pose recovery with F, E or H, triangulation, the rotation-only fit.

Conventions: pixel arrays are (N, 2); poses follow OpenCV, ``x_cur = R @ x_ref + t``, with
the reference camera at ``[I | 0]``. Monocular translation has no scale: estimates return
``t`` with ``|t| = 1`` and points triangulated at that scale, in the reference camera frame.
A failed or degenerate estimate is a value (``PoseEstimate.ok`` is False, ``reason`` says
why), not an exception; malformed arguments raise :class:`GeometryError`. Evaluation metrics
against ground truth (E_t, E_R, rotation error) are in :mod:`initsel_ros.metrics`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from initsel_ros.errors import GeometryError
from initsel_ros.names import Method  # re-exported: the pose methods are defined there

#: Minimum correspondences each method needs before it is attempted.
MIN_CORRESPONDENCES = {'F': 8, 'E': 5, 'H': 4}
_EPS = 1e-12


@dataclass(frozen=True)
class PoseEstimate:
    """Result of :func:`estimate_pose`.

    Attributes:
        method: the method used.
        ok: True when a pose was found with at least ``min_points`` triangulated points.
        reason: why not, when ``ok`` is False ('' otherwise).
        R: (3, 3) rotation, reference to current camera.
        t: (3,) translation with unit norm (zeros when none was found).
        points: (M, 3) triangulated points, reference camera frame, scale |t| = 1.
        indices: (M,) indices of those points' correspondences in the input arrays.
        inliers: (N,) bool, the robust estimator's inliers.
        parallax_deg: median parallax angle, degrees, over inliers in front of both cameras.
        matrix: (3, 3) the estimated H, F or E (zeros when none was found); model selection
            scores the correspondences against it.
        alternative: for H whose two best decompositions are close (the planar two-fold
            ambiguity, ``keep_ambiguous``), the runner-up as an estimate of its own (same
            matrix and inliers); the frames after it decide (``verify.py``). None otherwise.
        ambiguous: an H refused because its decompositions are too close to call and the
            runner-up fails the pose check (``initialize._resolve_ambiguity``); its pose is
            the winner's, for a caller that can tell them apart otherwise.
    """

    method: Method
    ok: bool
    reason: str
    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    indices: np.ndarray
    inliers: np.ndarray
    parallax_deg: float
    matrix: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    alternative: PoseEstimate | None = None
    ambiguous: bool = False

    @property
    def n_points(self) -> int:
        """Number of triangulated points kept."""
        return int(self.points.shape[0])


def _opencv_failure(function: str, exc: Exception) -> str:
    """The reason of an estimate OpenCV raised on: the function and its assertion."""
    detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
    return f'OpenCV {function} failed: {detail[-160:]}'


def _failure(
    method: Method,
    n: int,
    reason: str,
    inliers: np.ndarray | None = None,
    matrix: np.ndarray | None = None,
) -> PoseEstimate:
    return PoseEstimate(
        method=method,
        ok=False,
        reason=reason,
        R=np.eye(3),
        t=np.zeros(3),
        points=np.zeros((0, 3)),
        indices=np.zeros(0, dtype=np.int64),
        inliers=np.zeros(n, dtype=bool) if inliers is None else inliers,
        parallax_deg=0.0,
        matrix=np.zeros((3, 3)) if matrix is None else np.asarray(matrix, dtype=np.float64),
    )


def _check_pair(p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    if a.shape != b.shape:
        raise GeometryError(f'p0 and p1 differ in shape: {a.shape} vs {b.shape}')
    return a, b


def _check_camera_matrix(K: np.ndarray) -> np.ndarray:
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise GeometryError(f'K must be a finite (3, 3) camera matrix, got {K!r}')
    return K


@dataclass(frozen=True)
class Triangulation:
    """Points of one candidate pose and their per-point quality.

    Attributes:
        points: (N, 3) reference-frame points (NaN where the rays are parallel).
        in_front: (N,) bool, positive depth in both cameras.
        parallax_deg: (N,) angle between the two viewing rays, degrees.
        reprojection_px: (N,) larger of the two reprojection errors, pixels.
    """

    points: np.ndarray
    in_front: np.ndarray
    parallax_deg: np.ndarray
    reprojection_px: np.ndarray


def ray_parallax_rad(points: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N,) angle between the rays from the two camera centres to each point, radians: the
    reference's at the origin, the current's at ``-R^T t`` (``x_cur = R x_ref + t``); NaN
    for a point at either centre."""
    centre = -np.asarray(R, dtype=np.float64).T @ np.asarray(t, dtype=np.float64).reshape(3)
    a = np.asarray(points, dtype=np.float64)
    b = a - centre
    with np.errstate(divide='ignore', invalid='ignore'):
        cos = np.einsum('ij,ij->i', a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.arccos(np.clip(cos, -1.0, 1.0))


def triangulate_pair(
    R: np.ndarray, t: np.ndarray, K: np.ndarray, p0: np.ndarray, p1: np.ndarray
) -> Triangulation:
    """Triangulate correspondences for the pose ``(R, t)`` and measure each point.

    Args:
        R: (3, 3) rotation, reference to current.
        t: (3,) translation, reference to current.
        K: (3, 3) camera matrix shared by both views.
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
    """
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    P0 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    P1 = K @ np.hstack([R, t[:, None]])
    n = p0.shape[0]
    if n == 0:
        empty = np.zeros(0)
        return Triangulation(np.zeros((0, 3)), empty.astype(bool), empty, empty)
    X4 = cv2.triangulatePoints(P0, P1, p0.T.astype(np.float64), p1.T.astype(np.float64))
    w = X4[3]
    with np.errstate(divide='ignore', invalid='ignore'):
        X = (X4[:3] / np.where(np.abs(w) > _EPS, w, np.nan)).T
    Xc = X @ R.T + t
    finite = np.all(np.isfinite(X), axis=1)
    in_front = finite & (X[:, 2] > 0) & (Xc[:, 2] > 0)
    # 0 where undefined (a point at infinity or at a camera centre): never enough parallax
    parallax = np.degrees(np.nan_to_num(ray_parallax_rad(X, R, t), nan=0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        u0 = X @ K.T
        u1 = Xc @ K.T
        e0 = np.linalg.norm(u0[:, :2] / u0[:, 2:3] - p0, axis=1)
        e1 = np.linalg.norm(u1[:, :2] / u1[:, 2:3] - p1, axis=1)
    reproj = np.nan_to_num(np.maximum(e0, e1), nan=np.inf)
    return Triangulation(X, in_front, parallax, reproj)


#: H decomposition: the best solution must triangulate this many times more good points than
#: the runner-up (ORB-SLAM's rule: the second best keeps fewer than 75 % of the best's points).
HOMOGRAPHY_AMBIGUITY_RATIO = 0.75
#: A decomposition whose plane leaves more than this share of the homography's inliers behind
#: the reference or the current camera is not their plane: every inlier lies on it, so the
#: ray of each must meet it in front of both cameras. (The right decomposition left none
#: behind on 2,280 planar and desk pairs; the mirrored one of a plane seen from a sideways
#: move has its horizon through the image and leaves 20-80 % behind, yet triangulates enough
#: points in front to pass the ambiguity ratio.)
HOMOGRAPHY_MAX_BEHIND_SHARE = 0.1


@dataclass(frozen=True)
class HomographyChoice:
    """The chosen decomposition of a homography, or why none was chosen.

    Attributes:
        R: (3, 3) rotation of the chosen solution (identity when none).
        t: (3,) unit translation of the chosen solution (zeros when none).
        good: good points (in front of both cameras, small reprojection error, parallax) of
            each solution tried, best first.
        reason: '' when a solution was chosen, else why not.
        runner_up: when the choice is ambiguous, the ``(R, t)`` of the closest rival (the
            chosen one is then the one with the most good points, and ``reason`` says
            ambiguous).
    """

    R: np.ndarray
    t: np.ndarray
    good: tuple[int, ...]
    reason: str
    runner_up: tuple[np.ndarray, np.ndarray] | None = None


def choose_homography_decomposition(
    H: np.ndarray,
    K: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    inliers: np.ndarray,
    max_reprojection_px: float,
    min_baseline_ratio: float,
    plane_visibility_share: float | None = None,
) -> HomographyChoice:
    """Choose among the decompositions of H by triangulating its inliers (as ORB-SLAM does).

    Every solution of ``cv2.decomposeHomographyMat`` (up to four) triangulates the inliers;
    a point is good when it lies in front of both cameras and reprojects within
    ``max_reprojection_px`` (the caller filters by parallax afterwards). The solution with the
    most good points wins only when it is clearly ahead: the runner-up keeps fewer than
    :data:`HOMOGRAPHY_AMBIGUITY_RATIO` of its points. Otherwise the pair is ambiguous (planar
    two-fold ambiguity at small baselines) and nothing is chosen.
    Solutions whose translation (baseline over plane distance) is below
    ``min_baseline_ratio`` are rotations and are skipped.

    Where the inliers are at least ``plane_visibility_share`` of the correspondences (the
    plane is the scene), so are solutions whose plane leaves more than
    :data:`HOMOGRAPHY_MAX_BEHIND_SHARE` of the inliers' rays behind it in either view: the
    mirror of the planar two-fold ambiguity, whose horizon crosses the image when the camera
    moves sideways. On a smaller share the inliers may be a plane-like part of a scene with
    depth, whose decompositions all miss (their closeness is then what refuses them), and the
    rest of the scene gives E and F the parallax to decide; None turns the test off.
    """
    count, rotations, translations, normals = cv2.decomposeHomographyMat(H, K)
    a, b = p0[inliers], p1[inliers]
    scored = []
    behind_plane = 0
    visibility = plane_visibility_share is not None and len(a) >= plane_visibility_share * len(p0)
    if visibility:
        to_rays = np.linalg.inv(K).T
        rays0, rays1 = homogeneous(a) @ to_rays, homogeneous(b) @ to_rays
    for i in range(count):
        R = np.asarray(rotations[i], dtype=np.float64)
        t = np.asarray(translations[i], dtype=np.float64).reshape(3)
        norm = float(np.linalg.norm(t))
        if norm < min_baseline_ratio:
            continue
        if visibility:
            normal = np.asarray(normals[i], dtype=np.float64).reshape(3)
            behind = ((rays0 @ normal) <= 0.0) | ((rays1 @ (R @ normal)) <= 0.0)
            if np.count_nonzero(behind) > HOMOGRAPHY_MAX_BEHIND_SHARE * len(a):
                behind_plane += 1
                continue
        tri = triangulate_pair(R, t / norm, K, a, b)
        # Cheirality and reprojection only: a parallax cut would favour the mirrored solution,
        # whose points come out nearer and so with more parallax (seen on forward motion).
        good = tri.in_front & (tri.reprojection_px <= max_reprojection_px)
        scored.append((int(good.sum()), i, R, t / norm))
    none = HomographyChoice(np.eye(3), np.zeros(3), (), '')
    if not scored and behind_plane:
        return replace(
            none,
            reason='every decomposition of the homography leaves some of its points behind '
            'its plane (the tracks are no plane)',
        )
    if not scored:
        return replace(none, reason='homography has no decomposition with translation (rotation?)')
    scored.sort(key=lambda item: -item[0])
    good = tuple(item[0] for item in scored)
    best = scored[0]
    if best[0] == 0:
        return replace(
            none, good=good, reason='no decomposition puts points in front of both cameras'
        )
    # Solutions that are the same motion up to numerical noise do not compete.
    rivals = [
        item
        for item in scored[1:]
        if rotation_angle_deg(item[2].T @ best[2]) > 0.5 or item[3] @ best[3] < 0.999
    ]
    second = rivals[0][0] if rivals else 0
    if second >= HOMOGRAPHY_AMBIGUITY_RATIO * best[0]:
        return HomographyChoice(
            best[2],
            best[3],
            good,
            f'homography decomposition ambiguous: {best[0]} vs {second} good points',
            (rivals[0][2], rivals[0][3]),
        )
    return HomographyChoice(best[2], best[3], good, '')


def estimate_pose(
    method: Method | str,
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    *,
    ransac_threshold_px: float = 1.0,
    confidence: float = 0.999,
    max_iterations: int = 2000,
    max_reprojection_px: float = 2.5,
    min_point_parallax_deg: float = 0.36,
    min_points: int = 8,
    min_homography_baseline_ratio: float = 0.01,
    keep_ambiguous: bool = False,
    plane_visibility_share: float | None = None,
) -> PoseEstimate:
    """Recover the relative pose with one method and triangulate the map points.

    E is robustly estimated with OpenCV's USAC (``cv2.USAC_ACCURATE``, local optimization)
    over Nister's 5-point solver; F with USAC where the points of its pose show the depth off a
    dominant plane, with RANSAC's 8-point fit otherwise (:func:`plane_and_parallax_fundamental`);
    H with RANSAC (4-point DLT, Faugeras-Lustman decomposition). All three are deterministic:
    the same tracks give the same estimate. F and E poses are the ``recoverPose`` candidate
    with the most points in front of both cameras; H's is chosen by
    :func:`choose_homography_decomposition` (and refused when ambiguous).
    Kept points are inliers in front of both cameras, reprojecting within
    ``max_reprojection_px`` and seen with at least ``min_point_parallax_deg`` of parallax.

    Args:
        method: ``'F'``, ``'E'`` or ``'H'``.
        p0: (N, 2) reference pixels (undistorted).
        p1: (N, 2) current pixels (undistorted).
        K: (3, 3) camera matrix.
        ransac_threshold_px: inlier threshold of the robust fits, pixels.
        confidence: their confidence.
        max_iterations: their iteration cap (F and H; E keeps OpenCV's 1,000).
        max_reprojection_px: largest reprojection error of a kept point, pixels.
        min_point_parallax_deg: smallest parallax of a kept point, degrees.
        min_points: fewer kept points than this makes the estimate not ``ok``.
        min_homography_baseline_ratio: H decompositions with baseline / plane distance
            below this are treated as pure rotation.
        keep_ambiguous: when H's two best decompositions are close, return the one with
            the most good points (or the one that is ``ok``) with the other as its
            ``alternative`` (both triangulated and checked alike) instead of refusing the
            pair; the caller decides (``initialize.py`` keeps both only when both pass its
            pose check).
        plane_visibility_share: H's decompositions whose plane leaves its inliers behind a
            camera are dropped when the inliers are at least this share of the
            correspondences (:func:`choose_homography_decomposition`); None: never.

    Returns:
        A :class:`PoseEstimate`; ``ok`` False with a ``reason`` for degenerate input
        (too few correspondences, no model found, pure rotation, ...).
    """
    method = Method(method)
    a, b = _check_pair(p0, p1)
    K = _check_camera_matrix(K)
    n = a.shape[0]
    finite = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(b), axis=1)
    if not finite.all():
        raise GeometryError('correspondences contain NaN or infinity')
    needed = MIN_CORRESPONDENCES[method.value]
    if n < needed:
        return _failure(method, n, f'{n} correspondences, {method.value} needs {needed}')
    f0 = a.reshape(-1, 1, 2)
    f1 = b.reshape(-1, 1, 2)
    kept = dict(
        max_reprojection_px=max_reprojection_px,
        min_point_parallax_deg=min_point_parallax_deg,
        min_points=min_points,
    )
    if method is Method.F:
        return _fundamental_estimate(
            a, b, K, ransac_threshold_px, confidence, max_iterations, **kept
        )
    if method is Method.E:
        try:
            E, mask = cv2.findEssentialMat(
                f0, f1, K, cv2.USAC_ACCURATE, confidence, ransac_threshold_px
            )
        except cv2.error as exc:  # e.g. OpenCV 5.1's solvePoly assertion on a degenerate
            return _failure(method, n, _opencv_failure('findEssentialMat', exc))  # sample
        if E is None or E.shape[0] < 3 or mask is None:
            return _failure(method, n, 'no essential matrix found')
        return _epipolar_estimate(method, E[:3], mask, a, b, K, **kept)
    try:
        H, mask = cv2.findHomography(
            f0,
            f1,
            cv2.RANSAC,
            ransac_threshold_px,
            maxIters=max_iterations,
            confidence=confidence,
        )
    except cv2.error as exc:
        return _failure(method, n, _opencv_failure('findHomography', exc))
    if H is None or mask is None:
        return _failure(method, n, 'no homography found')
    inliers = mask.ravel().astype(bool)
    matrix = np.asarray(H, dtype=np.float64)
    choice = choose_homography_decomposition(
        matrix,
        K,
        a,
        b,
        inliers,
        max_reprojection_px,
        min_homography_baseline_ratio,
        plane_visibility_share,
    )
    if choice.reason and not (keep_ambiguous and choice.runner_up is not None):
        return _failure(method, n, choice.reason, inliers, matrix)
    if choice.runner_up is not None:
        first = _triangulated(method, choice.R, choice.t, K, a, b, inliers, matrix, **kept)
        second = _triangulated(method, *choice.runner_up, K, a, b, inliers, matrix, **kept)
        if not first.ok and second.ok:
            return replace(second, alternative=first)
        return replace(first, alternative=second)
    if np.linalg.norm(choice.t) < 0.5:
        return _failure(method, n, 'no translation recovered (pure rotation?)', inliers, matrix)
    return _triangulated(method, choice.R, choice.t, K, a, b, inliers, matrix, **kept)


def _fundamental_estimate(
    a: np.ndarray,
    b: np.ndarray,
    K: np.ndarray,
    ransac_threshold_px: float,
    confidence: float,
    max_iterations: int,
    **kept: Any,
) -> PoseEstimate:
    """F's pose: USAC's where its triangulated points show the depth off a dominant plane
    (:func:`plane_and_parallax_fundamental`), RANSAC's 8-point fit otherwise."""
    n = a.shape[0]
    try:
        candidate = plane_and_parallax_fundamental(
            a, b, K, ransac_threshold_px, confidence, max_iterations
        )
        if candidate is not None:
            F, mask, off_plane = candidate
            estimate = _epipolar_estimate(Method.F, F, mask, a, b, K, **kept)
            if np.count_nonzero(off_plane[estimate.indices]) >= USAC_F_MIN_OFF_PLANE_SHARE * n:
                return estimate
        found = fundamental_matrix(
            a, b, cv2.FM_RANSAC, ransac_threshold_px, confidence, max_iterations
        )
    except cv2.error as exc:
        return _failure(Method.F, n, _opencv_failure('findFundamentalMat', exc))
    if found is None:
        return _failure(Method.F, n, 'no fundamental matrix found')
    return _epipolar_estimate(Method.F, *found, a, b, K, **kept)


def fundamental_matrix(
    a: np.ndarray,
    b: np.ndarray,
    method: int,
    threshold_px: float,
    confidence: float,
    max_iterations: int,
) -> tuple[np.ndarray, np.ndarray] | None:
    """``cv2.findFundamentalMat`` on (N, 2) pixel tracks with a robust ``method``
    (``cv2.FM_RANSAC``, ``cv2.USAC_ACCURATE``, ...): F (3, 3) float64 and its (N, 1) inlier
    mask, or None when OpenCV finds none (no F, several, or no mask).

    Raises:
        cv2.error: from OpenCV on degenerate input.
    """
    F, mask = cv2.findFundamentalMat(
        a.reshape(-1, 1, 2),
        b.reshape(-1, 1, 2),
        method,
        threshold_px,
        confidence,
        max_iterations,
    )
    if F is None or F.shape != (3, 3) or mask is None:
        return None
    return np.asarray(F, dtype=np.float64), mask


def _epipolar_estimate(
    method: Method,
    matrix: np.ndarray,
    mask: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    K: np.ndarray,
    **kept: Any,
) -> PoseEstimate:
    """The pose and points of an F or E ``matrix`` (pixel F, or E) with its inlier ``mask``:
    ``recoverPose``'s candidate, then :func:`_triangulated` (``kept``: its point checks)."""
    n = a.shape[0]
    matrix = np.asarray(matrix, dtype=np.float64)
    E = K.T @ matrix @ K if method is Method.F else matrix
    inliers = mask.ravel().astype(bool)
    needed = MIN_CORRESPONDENCES[method.value]
    if inliers.sum() < needed:
        return _failure(method, n, f'only {int(inliers.sum())} RANSAC inliers', inliers, matrix)
    f0, f1 = a.reshape(-1, 1, 2), b.reshape(-1, 1, 2)
    _, R, t, _ = cv2.recoverPose(E, f0, f1, K, mask=mask.copy())
    t = t.reshape(3)
    t = t / max(np.linalg.norm(t), _EPS)
    if np.linalg.norm(t) < 0.5:
        return _failure(method, n, 'no translation recovered (pure rotation?)', inliers, matrix)
    return _triangulated(method, R, t, K, a, b, inliers, matrix, **kept)


#: A track lies off a plane when it is farther than this from where the plane's homography
#: puts it, pixels ...
OFF_PLANE_MIN_PX = 2.5
#: ... and than this many times the tracking noise per coordinate: the distance from where
#: H puts a track, with noise in both images, stays under about 5 sigma (the Rayleigh 99.9 %
#: point of sqrt(2) sigma per coordinate); with 1-2 px of noise, 2.5 px counted a fifth of a
#: plane's own points as off it.
OFF_PLANE_NOISE_FACTOR = 5.0
#: USAC's F is kept when the points it triangulates include at least this share of the
#: tracks off the dominant plane (the share off H's plane that makes E or F
#: well-posed for the fire path: 1 - ``PolicyConfig.min_homography_plane_share``).
USAC_F_MIN_OFF_PLANE_SHARE = 0.2


def plane_and_parallax_fundamental(
    a: np.ndarray,
    b: np.ndarray,
    K: np.ndarray,
    ransac_threshold_px: float = 1.0,
    confidence: float = 0.999,
    max_iterations: int = 2000,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """USAC's F of (N, 2) pixel tracks where a plane may dominate them, with its inlier mask
    and which tracks lie off the plane; None where too few do for any F to show depth.

    Where a plane holds most of the tracks, RANSAC's 8-point fit is degenerate: a sample of
    seven plane points and one off it gives an F that fits the plane and misses the rest (a
    far-style desk: pose good on half the pairs). USAC's DEGENSAC test fits the plane plus the
    parallax of the rest, but on a plane alone (noise, blur, rolling shutter) it takes
    tracking errors along the epipolar lines for relief. So :func:`estimate_pose` keeps this F
    only where at least :data:`USAC_F_MIN_OFF_PLANE_SHARE` of the tracks are points its pose
    triangulates that lie off the plane of :func:`dominant_homography`: farther from where it puts
    them than :data:`OFF_PLANE_MIN_PX` and :data:`OFF_PLANE_NOISE_FACTOR` times the noise (the
    smaller of what the two fits leave on all tracks, as :func:`tracking_noise_px`), the
    fire path's rule for E's depth off a plane. That bound is never under
    :data:`OFF_PLANE_MIN_PX`, so where fewer tracks than the share lie that far from the
    homography (a pan, a plane alone) USAC is not run.

    Returns:
        ``(F, mask, off_plane)``: F (3, 3), its (N, 1) uint8 inlier mask and (N,) bool, or
        None (no homography, too few tracks off it, or no F found).

    Raises:
        cv2.error: from OpenCV on degenerate input.
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    H = dominant_homography(a, b)
    if H is None:
        return None
    transfer = transfer_px(H, a, b)  # (NaN: never off the plane)
    if np.count_nonzero(transfer > OFF_PLANE_MIN_PX) < USAC_F_MIN_OFF_PLANE_SHARE * len(a):
        return None
    found = fundamental_matrix(
        a, b, cv2.USAC_ACCURATE, ransac_threshold_px, confidence, max_iterations
    )
    if found is None:
        return None
    F, mask = found
    noise = min(fundamental_noise_px(F, a, b), homography_noise_px(H, a, b))
    bound = max(OFF_PLANE_MIN_PX, OFF_PLANE_NOISE_FACTOR * noise)
    return F, mask, transfer > bound


def _triangulated(
    method: Method,
    R: np.ndarray,
    t: np.ndarray,
    K: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    inliers: np.ndarray,
    matrix: np.ndarray,
    *,
    max_reprojection_px: float,
    min_point_parallax_deg: float,
    min_points: int,
) -> PoseEstimate:
    """The estimate of one pose: its inliers triangulated, filtered and counted."""
    tri = triangulate_pair(R, t, K, a, b)
    valid = inliers & tri.in_front
    parallax = float(np.median(tri.parallax_deg[valid])) if valid.any() else 0.0
    keep = (
        valid
        & (tri.reprojection_px <= max_reprojection_px)
        & (tri.parallax_deg >= min_point_parallax_deg)
    )
    indices = np.flatnonzero(keep)
    ok = indices.size >= min_points
    reason = (
        ''
        if ok
        else (
            f'{indices.size} points triangulated with parallax >= {min_point_parallax_deg} deg '
            f'(median parallax {parallax:.2f} deg)'
        )
    )
    return PoseEstimate(
        method=method,
        ok=ok,
        reason=reason,
        R=np.asarray(R, dtype=np.float64),
        t=t,
        points=tri.points[indices],
        indices=indices,
        inliers=inliers,
        parallax_deg=parallax,
        matrix=matrix,
    )


def skew(v: np.ndarray) -> np.ndarray:
    """(3, 3) cross-product matrix ``[v]_x`` of a (3,) vector (``[v]_x w = v x w``)."""
    x, y, z = np.asarray(v, dtype=np.float64).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def homogeneous(p: np.ndarray) -> np.ndarray:
    """(N, 2) pixels -> (N, 3) homogeneous coordinates, float64."""
    return np.hstack([np.asarray(p, dtype=np.float64), np.ones((len(p), 1))])


def transfer_px(homography: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """(N,) distances |p1 - H(p0)|, pixels, of the (N, 2) pixels under the pixel homography
    ``p1 ~ H p0`` (inf or NaN where H maps a point to infinity)."""
    with np.errstate(divide='ignore', invalid='ignore'):
        q = homogeneous(p0) @ np.asarray(homography, dtype=np.float64).T
        return np.hypot(q[:, 0] / q[:, 2] - p1[:, 0], q[:, 1] / q[:, 2] - p1[:, 1])


def fundamental_from_essential(E: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``F = K^-T E K^-1``: the pixel-space epipolar constraint of an essential matrix."""
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))
    return K_inv.T @ np.asarray(E, dtype=np.float64) @ K_inv


def sampson_fundamental(F: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """(N,) squared Sampson errors of ``x1^T F x0 = 0``, pixels^2."""
    x0, x1 = homogeneous(p0), homogeneous(p1)
    Fx0 = x0 @ F.T
    Ftx1 = x1 @ F
    num = np.einsum('ij,ij->i', x1, Fx0) ** 2
    den = Fx0[:, 0] ** 2 + Fx0[:, 1] ** 2 + Ftx1[:, 0] ** 2 + Ftx1[:, 1] ** 2
    return num / np.maximum(den, 1e-300)


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle of a rotation matrix, degrees."""
    c = (np.trace(np.asarray(R, dtype=np.float64)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _kabsch(b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Rotations ``R`` with ``b1 ~ R b0`` (least squares), batched over leading axes.

    Args:
        b0: (..., N, 3) unit bearings in the first view.
        b1: (..., N, 3) the same bearings in the second view.
    """
    U, _, Vt = np.linalg.svd(np.swapaxes(b1, -1, -2) @ b0)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


#: Minimal samples (two bearing pairs each) of the robust rotation fit.
ROTATION_HYPOTHESES = 128
#: Hypotheses are scored on at most this many points (an even, deterministic subset).
ROTATION_SCORING_POINTS = 300


#: Focal-length scales the rotation test tries: a rotation seen through a camera whose focal
#: length is off by up to 15 % is still a rotation (a wrong calibration turns a pan into a
#: homography that no rotation under the nominal K explains: a 10 % error and a 10 degree pan
#: leave 3 times the noise). Wider is not free: a slide in front of a fronto-parallel plane,
#: turned back to keep it centred, is close to a rotation under another focal length (20 cm
#: at 3.5 m: 3.0 times the noise with +-15 %, 1.9 with +-25 %, 5.5 with the nominal K alone).
ROTATION_FOCAL_SCALES = tuple(float(s) for s in np.geomspace(0.87, 1.15, 9))
#: Radial distortion terms the rotation test also tries, where the focal scales alone leave
#: parallax: lambda of the one-parameter division model, ``x_u = x_d / (1 + lambda r_d^2)`` in
#: the nominal camera's normalized coordinates (barrel distortion is negative). A lens whose
#: distortion the camera_info leaves out (an uncalibrated driver's D = 0) bends a pan out of
#: any rotation: a 74-degree lens with k1 = -0.25 and k2 = 0.05 left 2.9-11.8 times the noise
#: over 5-30 frames of a pan, and E was published on a zero baseline; under the best term
#: 0.45-1.5. Only least-squares fits, refitted :data:`RADIAL_REFITS` times on the tracks at or
#: under the quantile, are tried under these terms, and only with the
#: :data:`RADIAL_FOCAL_SCALES` focal scales nearest 1 (no random samples: about 1 ms on 300
#: tracks, where all nine scales took 2.5): translating cameras keep their parallax (planes
#: from sideways arcs and slides, and a slide through that lens, moved by 0.1 at most), and a
#: distorted pan with objects moving on their own stays parallax. The bound is a prior on
#: how strong an unstated distortion may be: a uniform flow (a slide along a fronto-parallel
#: wall, not turning) is also a pan through a barrel lens of about -0.3 at the TUM camera's
#: field of view; down to -0.3 such a slide 3 m from a wall published H 7 frames later than
#: without the terms, down to -0.25 2 frames later, and down to -0.2 the k1 = -0.25 pan
#: published E again.
ROTATION_RADIAL_TERMS = (-0.25, -0.15, -0.05, 0.1)
RADIAL_REFITS = 3
RADIAL_FOCAL_SCALES = 3
#: The rotation test's residual is this quantile of the per-track residuals (least quantile
#: of squares): a rotation must explain a third of the tracks, so textured boards moving on
#: their own may hold up to two thirds of them (they attract many corners: with the median,
#: pans and a still camera with two boards initialized on the boards; with 0.4, a still
#: camera whose two boards held 62 % did, F fitting one board and the background as one
#: scene). A translating camera whose scene lies at infinity on a third of its tracks waits
#: for more baseline.
ROTATION_QUANTILE = 0.33
#: Median of chi-square with one degree of freedom: an epipolar Sampson error of pure noise
#: is about sigma^2 chi2(1).
CHI2_1_MEDIAN = 0.4549
#: ROTATION_QUANTILE of a transfer residual of pure noise, in units of the noise per
#: coordinate (its squared length is 2 sigma^2 chi2(2): the noise of both views).
_TRANSFER_QUANTILE_PER_SIGMA = float(np.sqrt(2.0 * -2.0 * np.log(1.0 - ROTATION_QUANTILE)))
#: Median length of a transfer residual of pure noise, in units of the noise per coordinate.
_TRANSFER_MEDIAN_PER_SIGMA = float(np.sqrt(2.0 * 2.0 * np.log(2.0)))


def _lower_quantile(values: np.ndarray, quantile: float, axis: int = -1) -> np.ndarray:
    """``np.quantile(values, quantile, axis, method='lower')`` by one partial sort (inf-safe;
    a tenth of the time on the rotation test's arrays)."""
    k = int(np.floor(quantile * (values.shape[axis] - 1)))
    return np.take(np.partition(values, k, axis=axis), k, axis=axis)


def _scaled_squared_residuals(
    R: np.ndarray,
    b0: np.ndarray,
    pixels: np.ndarray,
    Ks: np.ndarray,
    dtype: type[np.floating] = np.float64,
) -> np.ndarray:
    """Squared pixel distances between ``pixels`` (N, 2), or (S, N, 2) for pixels of their
    own per scale, and bearings rotated and projected, for S focal scales at once: (S, H, 3,
    3) rotations, (S, N, 3) bearings and (S, 3, 3) camera matrices -> (S, N, H) squared pixel
    residuals (inf behind the camera). Squared: quantiles and the best hypothesis are the
    same without the square roots, which only the returned residual needs."""
    M = (Ks[:, None] @ R).transpose(0, 2, 3, 1).astype(dtype)  # (S, row, j, H)
    b0, pixels = b0.astype(dtype, copy=False), pixels.astype(dtype, copy=False)
    # one product per scale and image row: (N, 3) bearings against the H rows, contiguous
    x, y, z = (b0 @ M[:, i] for i in range(3))  # each (S, N, H)
    with np.errstate(divide='ignore', invalid='ignore'):
        w = 1.0 / z
        x *= w
        x -= pixels[..., :1]
        y *= w
        y -= pixels[..., 1:]
        x *= x
        y *= y
        x += y
    x[~(z > 0)] = np.inf
    return x


def _two_point_rotations(b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """:func:`_kabsch` of minimal samples, (..., 2, 3) unit bearings each, in closed form.

    For two unit vectors the sum and the difference are orthogonal, so the cross-covariance
    ``sum b1 b0^T`` has them (normalized) as its singular vectors: the least-squares rotation
    takes the frame (sum, difference, their cross product) of the first view onto that of the
    second, with no SVD (NaN where the two bearings coincide).
    """

    def frame(b: np.ndarray) -> np.ndarray:
        m = b[..., 0, :] + b[..., 1, :]
        d = b[..., 0, :] - b[..., 1, :]
        with np.errstate(divide='ignore', invalid='ignore'):
            m = m / np.linalg.norm(m, axis=-1, keepdims=True)
            d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return np.stack([m, d, np.cross(m, d)], axis=-1)  # columns

    return frame(b1) @ np.swapaxes(frame(b0), -1, -2)


def _focal_scaled(K: np.ndarray, scales: Sequence[float]) -> np.ndarray:
    """(S, 3, 3): ``K`` with fx and fy times each of ``scales``."""
    Ks = np.repeat(K[None], len(scales), axis=0)
    Ks[:, 0, 0] *= np.asarray(scales)
    Ks[:, 1, 1] *= np.asarray(scales)
    return Ks


def _unit_bearings(pixels: np.ndarray, Ks: np.ndarray) -> np.ndarray:
    """(S, N, 3) unit bearings of (N, 2) ``pixels`` (or (S, N, 2), one set per camera) under
    each of the (S, 3, 3) camera matrices ``Ks``."""
    pixels = np.asarray(pixels, dtype=np.float64)
    rays = np.concatenate([pixels, np.ones((*pixels.shape[:-1], 1))], axis=-1)
    bearings = rays @ np.linalg.inv(Ks).transpose(0, 2, 1)
    bearings /= np.linalg.norm(bearings, axis=-1, keepdims=True)
    return bearings


def _rotation_quantile_over_scales(
    a: np.ndarray,
    b: np.ndarray,
    K: np.ndarray,
    scales: list[float],
    quantile: float,
    stop_px: float | None,
) -> tuple[float, float]:
    """The least-quantile rotation residual under each focal scale (``scales`` in the order
    they are preferred), all scales in one set of array operations; returns (lowest residual
    in pixels, its scale).

    Each scale runs the same steps: the least-squares (Kabsch) fit on all tracks, rotations
    from :data:`ROTATION_HYPOTHESES` random pairs of tracks (the minimal sample; fixed seed)
    scored by the ``quantile`` of their residuals on an even subset of at most
    :data:`ROTATION_SCORING_POINTS` tracks, and the best refitted on the tracks it explains
    at least that well; the lowest quantile of the three fits is the residual. (The tests
    check it against a one-scale-at-a-time reference implementation.)
    When ``stop_px`` is given and a scale's least-squares fit leaves less, the first such
    scale is returned at once, as a sequential search stopping there would (a plain pan).
    """
    n, count = a.shape[0], len(scales)
    Ks = _focal_scaled(K, scales)
    b0, b1 = _unit_bearings(a, Ks), _unit_bearings(b, Ks)  # (S, N, 3)

    def quantile_of(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S, 3, 3) rotations -> their squared residuals (S, N) and quantile (S,)."""
        squared = _scaled_squared_residuals(R[:, None], b0, b, Ks)[:, :, 0]
        return squared, _lower_quantile(squared, quantile)

    least_squares = _kabsch(b0, b1)  # (S, 3, 3)
    best = quantile_of(least_squares)[1]
    if stop_px is not None and (best < stop_px * stop_px).any():
        i = int(np.flatnonzero(best < stop_px * stop_px)[0])
        return float(np.sqrt(best[i])), float(scales[i])
    rng = np.random.default_rng(0)  # the same samples for every scale
    first = rng.integers(0, n, ROTATION_HYPOTHESES)
    second = (first + rng.integers(1, n, ROTATION_HYPOTHESES)) % n
    pairs = np.stack([first, second], axis=1)
    samples = _two_point_rotations(b0[:, pairs], b1[:, pairs])  # (S, H, 3, 3)
    samples = np.where(np.isfinite(samples), samples, least_squares[:, None])
    rotations = np.concatenate([least_squares[:, None], samples], axis=1)  # (S, H + 1, 3, 3)
    subset = np.linspace(0, n - 1, min(n, ROTATION_SCORING_POINTS)).astype(np.int64)
    # the hypotheses are only ranked here: in float32 (half the memory traffic), the chosen
    # one's residuals in float64 below
    scores = _lower_quantile(
        _scaled_squared_residuals(rotations, b0[:, subset], b[subset], Ks, np.float32),
        quantile,
        axis=1,
    )  # (S, H + 1)
    err, at = quantile_of(rotations[np.arange(count), np.argmin(scores, axis=1)])
    best = np.minimum(best, at)
    better = (err <= at[:, None]).astype(np.float64)  # each scale's better part, as weights
    refit = quantile_of(_kabsch(b0 * better[..., None], b1))[1]
    best = np.where(better.sum(axis=1) >= 3, np.minimum(best, refit), best)
    i = int(np.argmin(best))
    return float(np.sqrt(best[i])), float(scales[i])


def _radial_rotation_quantile(
    a: np.ndarray,
    b: np.ndarray,
    K: np.ndarray,
    scales: list[float],
    radial_terms: tuple[float, ...],
    quantile: float,
) -> tuple[float, float, float]:
    """The least-squares rotation's ``quantile`` residual under each radial term and focal
    scale at once (the tracks undistorted by the division model of each term, in pixels of
    the nominal K; :data:`RADIAL_REFITS` refits on the tracks at or under that quantile);
    returns (lowest residual in pixels, its focal scale, its radial term)."""
    f = np.array([K[0, 0], K[1, 1]])
    c = np.array([K[0, 2], K[1, 2]])
    lam = np.asarray(radial_terms, dtype=np.float64)[:, None, None]  # (L, 1, 1)

    def undistorted(p: np.ndarray) -> np.ndarray:  # (L * S, N, 2) pixels, term-major
        x = (p - c) / f
        # (the model folds beyond 1 + lambda r^2 = 0, past 115 degrees across for -0.3: held
        # off there, those tracks only grow the residual)
        scale_r = np.maximum(1.0 + lam * (x * x).sum(axis=1, keepdims=True), 0.25)
        return np.repeat(x / scale_r * f + c, len(scales), axis=0)

    ua, ub = undistorted(a), undistorted(b)
    Ks = np.tile(_focal_scaled(K, scales), (len(radial_terms), 1, 1))  # (L * S, 3, 3)
    b0, b1 = _unit_bearings(ua, Ks), _unit_bearings(ub, Ks)

    def squared(R: np.ndarray) -> np.ndarray:  # (L * S, 3, 3) -> (L * S, N)
        return _scaled_squared_residuals(R[:, None], b0, ub, Ks)[:, :, 0]

    err = squared(_kabsch(b0, b1))
    best = _lower_quantile(err, quantile)  # (L * S,)
    for _ in range(RADIAL_REFITS):
        better = err <= best[..., None]
        err = squared(_kabsch(b0 * better[..., None], b1))
        refit = _lower_quantile(err, quantile)
        best = np.where(np.count_nonzero(better, axis=-1) >= 3, np.minimum(best, refit), best)
    best = best.reshape(len(radial_terms), len(scales))
    i, j = np.unravel_index(int(np.argmin(best)), best.shape)
    return float(np.sqrt(best[i, j])), float(scales[j]), float(radial_terms[i])


@dataclass(frozen=True)
class RotationTest:
    """Does one rotation explain the flow, judged against the noise of the same tracks?

    Attributes:
        residual_px: :data:`ROTATION_QUANTILE` quantile of the transfer residuals of the best
            rotation, pixels (over the focal scales tried).
        noise_px: tracking noise per coordinate, pixels, from the same tracks
            (:func:`tracking_noise_px`: a RANSAC homography's or fundamental matrix's
            residuals, whichever is smaller).
        statistic: ``residual_px`` in units of that noise: the noise per coordinate a
            rotation would imply, over ``noise_px`` (about 1 for a rotation, large when a
            baseline leaves parallax).
        focal_scale: the focal scale of the best rotation (1: the nominal K).
        radial_term: the radial distortion term of the best rotation (0: none; see
            :data:`ROTATION_RADIAL_TERMS`).
    """

    residual_px: float
    noise_px: float
    statistic: float
    focal_scale: float
    radial_term: float = 0.0

    def to_dict(self) -> dict[str, float | None]:
        """JSON-ready fields (None for NaN)."""
        return {
            k: (round(v, 3) if np.isfinite(v) else None)
            for k, v in (
                ('residual_px', self.residual_px),
                ('noise_px', self.noise_px),
                ('statistic', self.statistic),
                ('focal_scale', self.focal_scale),
                ('radial_term', self.radial_term),
            )
        }


#: RANSAC draws of the homography whose residuals measure the tracking noise (OpenCV's
#: USAC_FAST: local optimization and early rejection; 0.1 ms on 283 tracks where its plain
#: RANSAC takes 0.35-0.46 ms). Its median is the noise only where H holds most of the tracks
#: (a plane, a pan), where 4-point samples are often all inliers (30 draws miss a share of
#: 0.7 with probability 3e-4, of 0.6 with 0.016); with depth no H holds most of them, F's
#: estimate is taken, and unbounded draws of the plain RANSAC took 30 ms.
NOISE_HOMOGRAPHY_MAX_ITERS = 30


def _fundamental_noise_px(a: np.ndarray, b: np.ndarray) -> float:
    """Noise per coordinate from a RANSAC fundamental matrix's Sampson errors on all tracks
    (their median is about ``0.455 sigma^2``); inf when none is found."""
    found = fundamental_matrix(a, b, cv2.FM_RANSAC, 1.0, 0.999, 500)
    if found is None:
        return math.inf
    return fundamental_noise_px(found[0], a, b)


def fundamental_noise_px(F: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Noise per coordinate that the fundamental matrix ``F`` leaves on all tracks: the
    median Sampson error is about ``0.455 sigma^2``."""
    errors = sampson_fundamental(np.asarray(F, dtype=np.float64), a, b)
    return float(np.sqrt(np.median(errors) / CHI2_1_MEDIAN))


def _homography_noise_px(a: np.ndarray, b: np.ndarray) -> float:
    """Noise per coordinate from a RANSAC homography's transfer residuals on all tracks
    (their median length is ``sqrt(4 ln 2) sigma``: both views' noise); inf when none is
    found."""
    H = dominant_homography(a, b)
    if H is None:
        return math.inf
    return homography_noise_px(H, a, b)


def dominant_homography(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The homography of the plane (or pan) that holds most of the (N, 2) tracks, by
    :data:`NOISE_HOMOGRAPHY_MAX_ITERS` draws of OpenCV's USAC_FAST at 1 px, or None: cheap
    where one holds most of them, and bounded where none does."""
    H, _ = cv2.findHomography(
        a.reshape(-1, 1, 2),
        b.reshape(-1, 1, 2),
        cv2.USAC_FAST,
        1.0,
        maxIters=NOISE_HOMOGRAPHY_MAX_ITERS,
        confidence=0.995,
    )
    if H is None or H.shape != (3, 3):
        return None
    return np.asarray(H, dtype=np.float64)


def homography_noise_px(H: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Noise per coordinate that the homography ``H`` leaves on all tracks (their median
    transfer distance is ``sqrt(4 ln 2) sigma``: both views' noise); inf with fewer than 8
    finite distances."""
    transfer = transfer_px(np.asarray(H, dtype=np.float64), a, b)
    transfer = transfer[np.isfinite(transfer)]
    if transfer.shape[0] < 8:
        return math.inf
    return float(np.median(transfer)) / _TRANSFER_MEDIAN_PER_SIGMA


def tracking_noise_px(a: np.ndarray, b: np.ndarray, min_noise_px: float = 0.1) -> float:
    """The tracking noise per coordinate of correspondences ``a`` -> ``b``, pixels: the
    smaller of what a RANSAC homography and a RANSAC fundamental matrix leave on all of them
    (median residuals, as noise), floored at ``min_noise_px``; NaN when neither is found.

    Either model fits the flow it can explain to the noise, and a median over all tracks
    only grows where it cannot (depth, for H). F fits every rigid flow, but a plane and a pan,
    the two flows the rotation test must tell apart, are degenerate for it: many F fit them,
    and RANSAC's choice wobbles from frame to frame (on KLT tracks of a clean poster, 0.10 to
    0.39 px between consecutive frames). H fits both without degeneracy. H is fitted only
    when F leaves more than the floor (the floor is the answer otherwise, whatever H leaves).
    Fewer than 8 correspondences measure nothing (NaN).
    """
    if len(a) < 8:
        return math.nan
    noise = _fundamental_noise_px(a, b)
    if not noise <= min_noise_px:
        noise = min(noise, _homography_noise_px(a, b))
    return max(noise, min_noise_px) if math.isfinite(noise) else math.nan


def rotation_test(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    focal_scales: tuple[float, ...] = ROTATION_FOCAL_SCALES,
    min_noise_px: float = 0.1,
    enough_below: float | None = None,
    noise_px: float | None = None,
    radial_terms: tuple[float, ...] = (),
) -> RotationTest:
    """Fit the best rotation (3 dof, ``x1 ~ K R K^-1 x0``) and weigh its residual by the noise.

    The rotation is a least-quantile fit (robust to independently moving objects on up to
    two thirds of the tracks: :data:`ROTATION_QUANTILE`), tried under each focal scale
    (``K`` with fx and fy scaled, :data:`ROTATION_FOCAL_SCALES`; a miscalibrated pan is
    still a rotation) and, where that leaves ``enough_below`` or more, with least-squares
    fits under each of ``radial_terms`` as well (:data:`ROTATION_RADIAL_TERMS`; a pan
    through a lens whose distortion was left out is still a rotation); the noise is that of
    the same tracks (:func:`tracking_noise_px`: the
    smaller of what a RANSAC homography and a RANSAC fundamental matrix leave), floored at
    ``min_noise_px`` (KLT on sharp frames reaches about 0.1 px; exact synthetic shifts would
    otherwise make any flow parallax, as GRIC's noise is bounded in ``model_selection``).
    Their ratio is the statistic:
    a plane's perspective change at ten times the noise gives about 10, a pan about 1.

    Args:
        p0: (N, 2) pixels in the first view; rows with a non-finite value are ignored.
        p1: (N, 2) the same points in the second view.
        K: (3, 3) camera matrix.
        focal_scales: the focal scales tried (nearest 1 first).
        min_noise_px: floor of the noise estimate, pixels.
        enough_below: a caller comparing the statistic with this threshold passes it: the
            search stops at the first scale (and least-squares fit) below it, since more
            fits can only lower the statistic (a plain pan costs one fit, not nine).
        noise_px: the noise, when already measured on a larger set of the same tracks (a
            subset's own estimate would be that of its own tracks: no model is fitted for
            it then; still floored at ``min_noise_px``).
        radial_terms: the radial terms tried where the focal scales leave parallax (none by
            default; the fire path passes :data:`ROTATION_RADIAL_TERMS` for a camera that
            states no distortion).

    Returns:
        A :class:`RotationTest`; NaN fields for fewer than 8 finite correspondences.
    """
    a, b = _check_pair(p0, p1)
    K = _check_camera_matrix(K)
    finite = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[finite], b[finite]
    nan = float('nan')
    if a.shape[0] < 8:
        return RotationTest(nan, nan, nan, nan, nan)
    if noise_px is None:
        noise = tracking_noise_px(a, b, min_noise_px)
    else:
        noise = max(float(noise_px), min_noise_px) if np.isfinite(noise_px) else nan
    per_sigma = _TRANSFER_QUANTILE_PER_SIGMA
    stop_px = None
    if enough_below is not None and np.isfinite(noise):
        stop_px = enough_below * per_sigma * noise
    order = sorted(focal_scales, key=lambda v: abs(np.log(v)))
    best, scale = _rotation_quantile_over_scales(a, b, K, order, ROTATION_QUANTILE, stop_px)
    radial = 0.0
    if radial_terms and not (stop_px is not None and best < stop_px):
        bent, bent_scale, term = _radial_rotation_quantile(
            a, b, K, order[:RADIAL_FOCAL_SCALES], tuple(radial_terms), ROTATION_QUANTILE
        )
        if bent < best:
            best, scale, radial = bent, bent_scale, term
    statistic = float(best / per_sigma / noise) if np.isfinite(noise) else nan
    return RotationTest(float(best), noise, statistic, scale, radial)


#: The least noise :func:`plane_perspective_test` takes from a homography's residual, pixels
#: per coordinate (an exact synthetic plane leaves none).
MIN_PLANE_NOISE_PX = 0.005


def plane_perspective_test(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    homography: np.ndarray,
    inliers: np.ndarray,
    enough_below: float | None = None,
) -> RotationTest:
    """Does a homography explain its own tracks better than one rotation does?

    :func:`rotation_test` on the tracks the homography holds, with the noise taken from the
    homography's own transfer residual on them (the same quantile, so the statistic is the
    rotation's residual over the homography's). On a plane seen with a baseline the
    homography takes out the perspective change a rotation leaves, and the statistic is that
    change over the noise; where a homography is fitted, at a short baseline, to tracks of a
    scene with depth, its residual is their relief, as large as what the rotation leaves, and
    the statistic stays near 1 (its decomposition is then no pose: on a desk 1.5-2.4 cm from
    its reference, 67-81 % of the tracks in the band, 1.0-1.5, every decomposition wrong; on
    planes from sideways arcs at 2-3 x the noise, 3.3 and more).

    Args:
        p0: (N, 2) pixels in the first view.
        p1: (N, 2) the same points in the second view.
        K: (3, 3) camera matrix.
        homography: (3, 3) pixel homography, ``p1 ~ H p0``.
        inliers: (N,) bool, the tracks it holds.
        enough_below: as in :func:`rotation_test` (the search stops below it).

    Returns:
        A :class:`RotationTest` whose ``noise_px`` is the homography's residual as noise per
        coordinate; NaN fields for fewer than 8 finite inliers.
    """
    a, b = _check_pair(p0, p1)
    inliers = np.asarray(inliers, dtype=bool)
    if inliers.shape != (a.shape[0],):
        raise GeometryError(f'inliers must be ({a.shape[0]},), got {inliers.shape}')
    a, b = a[inliers], b[inliers]
    nan = float('nan')
    transfer = transfer_px(homography, a, b)
    transfer = transfer[np.isfinite(transfer)]
    if transfer.shape[0] < 8:
        return RotationTest(nan, nan, nan, nan, nan)
    noise = float(np.quantile(transfer, ROTATION_QUANTILE)) / _TRANSFER_QUANTILE_PER_SIGMA
    return rotation_test(
        a, b, K, min_noise_px=MIN_PLANE_NOISE_PX, enough_below=enough_below, noise_px=noise
    )
