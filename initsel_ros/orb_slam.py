"""ORB-SLAM's H/F model scores: the one implementation of its chi-square scoring.

ORB-SLAM (Mur-Artal et al. 2015; ORB-SLAM3 keeps it) runs H and F RANSAC on the same random
8-point sets and scores each hypothesis by symmetric transfer (H) or epipolar (F) errors: a
correspondence adds ``5.991 - chi2`` in each direction where its ``chi2 = e^2 / sigma^2`` is
within the cut-off (5.991 for H, 2 degrees of freedom at 95 %; 3.841 for F, 1 degree, scored
against 5.991 all the same). It chooses H when ``S_H / (S_H + S_F)`` exceeds 0.40 (ORB-SLAM2)
or 0.50 (ORB-SLAM3).

:func:`orbslam_scores` is that RANSAC, the baseline of the evaluation and the yardstick of the
decision's cost (``initsel bench``); :func:`matrix_scores` scores given matrices with the same
helpers (the selector reports ORB-SLAM's ratio for its own F/E and H estimates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: ORB-SLAM's chi-square cut-offs (95 %, 2 and 1 degrees of freedom) and its score offset.
CHI2_H = 5.991
CHI2_F = 3.841


@dataclass(frozen=True)
class OrbSlamScores:
    """ORB-SLAM's model scores for one correspondence set.

    Attributes:
        s_h: best homography score (higher is better).
        s_f: best fundamental-matrix score (higher is better).
        ratio: ``s_h / (s_h + s_f)``; NaN when both are 0 or there are fewer than 8
            correspondences.
        H: (3, 3) float64 best homography, reference -> current pixels (NaN when not
            computed).
        F: (3, 3) float64 best fundamental matrix, ``x_cur^T F x_ref = 0`` (NaN when not
            computed).
        inliers_h: (N,) bool inliers of the best homography.
        inliers_f: (N,) bool inliers of the best fundamental matrix.
    """

    s_h: float
    s_f: float
    ratio: float
    H: np.ndarray
    F: np.ndarray
    inliers_h: np.ndarray
    inliers_f: np.ndarray


def _normalize(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ORB-SLAM's normalization: zero mean, unit mean absolute deviation per axis."""
    mean = points.mean(axis=0)
    dev = np.abs(points - mean).mean(axis=0)
    dev = np.where(dev > 0, dev, 1.0)
    T = np.array(
        [[1 / dev[0], 0, -mean[0] / dev[0]], [0, 1 / dev[1], -mean[1] / dev[1]], [0, 0, 1.0]]
    )
    return (points - mean) / dev, T


def _null_vectors(A: np.ndarray) -> np.ndarray:
    """(B, M, 9) design matrices -> (B, 3, 3) least-squares null vectors.

    Solves with the last entry fixed to 1 (batched 8x8 solves, fast); falls back to the
    smallest eigenvector of A^T A when a system is singular.
    """
    try:
        if A.shape[1] == 8:
            x = np.linalg.solve(A[:, :, :8], -A[:, :, 8:])
        else:
            M = A.transpose(0, 2, 1) @ A
            x = np.linalg.solve(M[:, :8, :8], -M[:, :8, 8:])
        v = np.concatenate((x[..., 0], np.ones((len(A), 1))), axis=1)
        if not np.all(np.isfinite(v)):
            raise np.linalg.LinAlgError('non-finite solution')
    except np.linalg.LinAlgError:
        _, vecs = np.linalg.eigh(A.transpose(0, 2, 1) @ A)
        v = vecs[:, :, 0]
    return v.reshape(-1, 3, 3)


def _homographies(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """DLT homographies for B sets: x1, x2 (B, 8, 2) -> (B, 3, 3) mapping x1 to x2."""
    u1, v1 = x1[..., 0], x1[..., 1]
    u2, v2 = x2[..., 0], x2[..., 1]
    zero, one = np.zeros_like(u1), np.ones_like(u1)
    row1 = np.stack([zero, zero, zero, -u1, -v1, -one, v2 * u1, v2 * v1, v2], axis=-1)
    row2 = np.stack([u1, v1, one, zero, zero, zero, -u2 * u1, -u2 * v1, -u2], axis=-1)
    A = np.concatenate([row1, row2], axis=1)
    return _null_vectors(A)


def _fundamentals(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Rank-2 8-point fundamental matrices for B sets: (B, 8, 2) -> (B, 3, 3), x2^T F x1 = 0."""
    u1, v1 = x1[..., 0], x1[..., 1]
    u2, v2 = x2[..., 0], x2[..., 1]
    A = np.stack([u2 * u1, u2 * v1, u2, v2 * u1, v2 * v1, v2, u1, v1, np.ones_like(u1)], axis=-1)
    F = _null_vectors(A)
    u, s, vt = np.linalg.svd(F)
    s[:, 2] = 0.0
    return u @ (s[:, :, None] * vt)


def _apply(M: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
    """(B, 3, 3) matrices times the homogeneous points (x, y, 1), x and y (N,) -> 3 x (B, N).

    The three results are views of one fresh array (the callers work on them in place).
    """
    out = M @ np.vstack((x, y, np.ones_like(x)))
    return out[:, 0], out[:, 1], out[:, 2]


def _chi2_transfer(
    M: np.ndarray, src: np.ndarray, dst: np.ndarray, inv_sigma2: float
) -> np.ndarray:
    """Squared transfer error of src through homographies M against dst, over sigma^2: (B, N).

    NaN where a point maps to infinity (it fails every ``chi2 <= cut-off`` test). Computed in
    place: (B, N) temporaries were a good part of the ORB-SLAM baseline's time.
    """
    a, b, c = _apply(M, src[:, 0], src[:, 1])
    with np.errstate(divide='ignore', invalid='ignore'):
        inv_c = np.divide(1.0, c, out=c)
        a *= inv_c
        a -= dst[:, 0]
        a *= a
        b *= inv_c
        b -= dst[:, 1]
        b *= b
        a += b
        if inv_sigma2 != 1.0:
            a *= inv_sigma2
    return a


def _chi2_epipolar(
    lines_from: np.ndarray, src: np.ndarray, dst: np.ndarray, inv_sigma2: float
) -> np.ndarray:
    """Squared distance of dst to the epipolar lines M @ src, over sigma^2: (B, N).

    NaN for a degenerate line (fails every cut-off test); computed in place.
    """
    a, b, c = _apply(lines_from, src[:, 0], src[:, 1])
    with np.errstate(divide='ignore', invalid='ignore'):
        num = a * dst[:, 0]
        num += b * dst[:, 1]
        num += c
        num *= num
        a *= a
        b *= b
        a += b
        num /= a
        if inv_sigma2 != 1.0:
            num *= inv_sigma2
    return num


def _score(chi_a: np.ndarray, chi_b: np.ndarray, reject: float) -> tuple[np.ndarray, np.ndarray]:
    """ORB-SLAM's score: sum of (5.991 - chi2) over both directions where chi2 <= ``reject``.

    ``chi_a`` and ``chi_b`` are overwritten.
    """
    ok_a, ok_b = chi_a <= reject, chi_b <= reject  # NaN: False
    score = np.zeros(len(chi_a))
    for chi, ok in ((chi_a, ok_a), (chi_b, ok_b)):
        gain = np.subtract(CHI2_H, chi, out=chi)
        np.copyto(gain, 0.0, where=~ok)
        score += gain.sum(-1)
    return score, np.logical_and(ok_a, ok_b, out=ok_a)


def orbslam_scores(
    p0: np.ndarray,
    p1: np.ndarray,
    *,
    iterations: int = 200,
    sigma: float = 1.0,
    rng: np.random.Generator | None = None,
) -> OrbSlamScores:
    """ORB-SLAM's parallel H and F RANSAC with symmetric transfer scores.

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        iterations: RANSAC iterations (ORB-SLAM: 200); both models use the same 8-point sets.
        sigma: measurement noise, pixels (ORB-SLAM: 1).
        rng: numpy Generator, the source of the random sets (seeded for reproducibility;
            default seed 0).
    """
    p0 = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    n = len(p0)
    nan33 = np.full((3, 3), np.nan)
    if n < 8:
        empty = np.zeros(n, dtype=bool)
        return OrbSlamScores(0.0, 0.0, math.nan, nan33, nan33, empty, empty)
    rng = np.random.default_rng(0) if rng is None else rng
    # The 8 smallest of n random keys: a random 8-point set (kth 7 when n is exactly 8).
    sets = np.argpartition(rng.random((iterations, n)), min(8, n - 1), axis=1)[:, :8]
    n0, T0 = _normalize(p0)
    n1, T1 = _normalize(p1)
    x0, x1 = n0[sets], n1[sets]
    Hn = _homographies(x0, x1)
    H = np.linalg.inv(T1) @ Hn @ T0
    Fn = _fundamentals(x0, x1)
    F = T1.T @ Fn @ T0
    inv_sigma2 = 1.0 / (sigma * sigma)
    with np.errstate(all='ignore'):
        H_inv = np.linalg.inv(H)
    score_h, in_h = _score(
        _chi2_transfer(H, p0, p1, inv_sigma2), _chi2_transfer(H_inv, p1, p0, inv_sigma2), CHI2_H
    )
    # ORB-SLAM rejects F outliers with the 1-dof cut-off but scores against the 2-dof one.
    score_f, in_f = _score(
        _chi2_epipolar(F, p0, p1, inv_sigma2),
        _chi2_epipolar(F.transpose(0, 2, 1), p1, p0, inv_sigma2),
        CHI2_F,
    )
    bh, bf = int(np.argmax(score_h)), int(np.argmax(score_f))
    s_h, s_f = float(score_h[bh]), float(score_f[bf])
    total = s_h + s_f
    ratio = s_h / total if total > 0 else math.nan
    return OrbSlamScores(s_h, s_f, ratio, H[bh], F[bf], in_h[bh], in_f[bf])


def matrix_scores(
    H: np.ndarray | None,
    F: np.ndarray | None,
    p0: np.ndarray,
    p1: np.ndarray,
    sigma_px: float = 1.0,
) -> tuple[float, float]:
    """ORB-SLAM's ``(S_H, S_F)`` of a given homography and fundamental matrix (0 for None).

    Args:
        H: (3, 3) homography, reference -> current pixels, or None.
        F: (3, 3) fundamental matrix, ``x_cur^T F x_ref = 0``, or None.
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        sigma_px: measurement noise, pixels (ORB-SLAM: 1).
    """
    p0 = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    inv_sigma2 = 1.0 / (sigma_px * sigma_px)
    s_h = s_f = 0.0
    if H is not None and abs(np.linalg.det(H)) > 1e-12:
        Hs = np.asarray(H, dtype=np.float64)[None]
        chi = (
            _chi2_transfer(Hs, p0, p1, inv_sigma2),
            _chi2_transfer(np.linalg.inv(Hs), p1, p0, inv_sigma2),
        )
        s_h = float(_score(*chi, CHI2_H)[0][0])
    if F is not None:
        Fs = np.asarray(F, dtype=np.float64)[None]
        chi = (
            _chi2_epipolar(Fs, p0, p1, inv_sigma2),
            _chi2_epipolar(Fs.transpose(0, 2, 1), p1, p0, inv_sigma2),
        )
        s_f = float(_score(*chi, CHI2_F)[0][0])
    return s_h, s_f


__all__ = ['CHI2_F', 'CHI2_H', 'OrbSlamScores', 'matrix_scores', 'orbslam_scores']
