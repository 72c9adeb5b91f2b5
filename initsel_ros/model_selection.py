"""Choosing among F, E and H estimates of one pair by geometric evidence.

Each candidate's matrix is scored on the same correspondences:

- **GRIC** (Torr 1998, the geometric robust information criterion), lower is better:
  ``GRIC = sum_i min(e_i^2 / sigma^2, lambda3 (r - d)) + lambda1 d n + lambda2 k`` with
  ``r = 4`` (two 2-D observations per correspondence), ``d`` the dimension of the model's
  manifold (3 for F and E, 2 for H), ``k`` its parameters (F 7, E 5, H 8),
  ``lambda1 = log r``, ``lambda2 = log(r n)``, ``lambda3 = 2``, and ``e_i`` the Sampson
  (first-order geometric) error, and sigma the noise estimated from the most general
  model's residuals (Torr's practice; a fixed 1 px hides a scene's depth when the tracks are
  much better than a pixel). A plane fits H as well as F, and H's lower dimension then
  wins; with depth variation H's residuals grow and F or E win. E is scored as the
  fundamental matrix ``K^-T E K^-1`` at its maximum-likelihood fit on its inliers (OpenCV's
  5-point RANSAC returns a minimal-sample E; F and H come refitted on their inliers), so a
  wrong K costs E residuals and F wins, and a right K makes E's two parameters fewer win.
- **ORB-SLAM's ratio** ``R_H = S_H / (S_H + S_F)`` on symmetric transfer and epipolar errors
  (chi-square cut-offs 5.991 and 3.841, sigma 1 px; :func:`initsel_ros.orb_slam.matrix_scores`),
  reported for comparison.

The winner is the candidate with the lowest GRIC among those whose pose passed the pose check
(enough triangulated points and parallax).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from initsel_ros.geometry import (
    CHI2_1_MEDIAN,
    Method,
    PoseEstimate,
    fundamental_from_essential,
    homogeneous,
    sampson_fundamental,
    skew,
)
from initsel_ros.orb_slam import matrix_scores
from initsel_ros.refine import refine_essential

#: Manifold dimension d and parameter count k of each model (Torr's GRIC).
MODEL_DIMENSION = {'F': 3, 'E': 3, 'H': 2}
MODEL_PARAMETERS = {'F': 7, 'E': 5, 'H': 8}


def sampson_homography(H: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """(N,) squared Sampson errors of ``x1 ~ H x0`` (first-order geometric error), pixels^2.

    The two algebraic residuals ``eps = A h`` of the DLT and their 2x4 Jacobian ``J`` with
    respect to ``(x0, y0, x1, y1)`` give ``eps^T (J J^T)^-1 eps``.
    """
    x0 = homogeneous(p0)
    p1 = np.asarray(p1, dtype=np.float64)
    Hx = x0 @ H.T  # (N, 3): rows of H times x0
    u, v = p1[:, 0], p1[:, 1]
    # eps1 = v * (h3 x) - (h2 x);  eps2 = (h1 x) - u * (h3 x)
    e1 = v * Hx[:, 2] - Hx[:, 1]
    e2 = Hx[:, 0] - u * Hx[:, 2]
    # derivatives with respect to x0, y0 (through Hx) and u, v
    d1 = np.stack(
        [v * H[2, 0] - H[1, 0], v * H[2, 1] - H[1, 1], np.zeros_like(u), Hx[:, 2]], axis=1
    )
    d2 = np.stack(
        [H[0, 0] - u * H[2, 0], H[0, 1] - u * H[2, 1], -Hx[:, 2], np.zeros_like(u)], axis=1
    )
    a = np.einsum('ij,ij->i', d1, d1)
    b = np.einsum('ij,ij->i', d1, d2)
    c = np.einsum('ij,ij->i', d2, d2)
    det = np.maximum(a * c - b * b, 1e-300)
    return (c * e1 * e1 - 2 * b * e1 * e2 + a * e2 * e2) / det


def gric(errors_sq: np.ndarray, method: str, sigma_px: float = 1.0) -> float:
    """Torr's GRIC of one model on (N,) squared errors (pixels^2); lower is better."""
    n = int(errors_sq.shape[0])
    if n == 0:
        return math.inf
    r, d, k = 4, MODEL_DIMENSION[method], MODEL_PARAMETERS[method]
    rho = np.minimum(np.nan_to_num(errors_sq / sigma_px**2, nan=np.inf), 2.0 * (r - d))
    return float(rho.sum() + math.log(r) * d * n + math.log(r * n) * k)


@dataclass(frozen=True)
class CandidateScore:
    """One method's evidence on a pair.

    Attributes:
        method: F, E or H.
        ok: its pose passed the pose check.
        problem: why not ('' when ok).
        gric: GRIC of its matrix on all correspondences (inf without a matrix).
        n_points: triangulated points kept.
        parallax_deg: median parallax, degrees.
        inlier_ratio: RANSAC inliers / correspondences.
    """

    method: Method
    ok: bool
    problem: str
    gric: float
    n_points: int
    parallax_deg: float
    inlier_ratio: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready fields (GRIC None when infinite)."""
        return {
            'method': self.method.value,
            'ok': self.ok,
            'problem': self.problem,
            'gric': round(self.gric, 1) if math.isfinite(self.gric) else None,
            'points': self.n_points,
            'parallax_deg': round(self.parallax_deg, 3),
            'inlier_ratio': round(self.inlier_ratio, 3),
        }


@dataclass(frozen=True)
class Selection:
    """Which candidate won and why.

    Attributes:
        winner: the chosen method (None when no candidate passed).
        scores: every candidate tried, in the order tried.
        orb_ratio: ORB-SLAM's ``R_H = S_H / (S_H + S_F)`` (NaN when H or F/E is missing).
        why: one sentence for the status and the log.
        sigma_px: the noise level GRIC used, pixels.
    """

    winner: Method | None
    scores: tuple[CandidateScore, ...]
    orb_ratio: float
    why: str
    sigma_px: float = 1.0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready fields."""
        return {
            'winner': None if self.winner is None else self.winner.value,
            'candidates': [s.to_dict() for s in self.scores],
            'orb_ratio': None if not math.isfinite(self.orb_ratio) else round(self.orb_ratio, 3),
            'noise_px': round(self.sigma_px, 3),
            'why': self.why,
        }

    def summary(self) -> str:
        """Compact text: ``H* gric=812 n=231 | E gric=990 n=240 | F failed (...)``."""
        parts = []
        for s in self.scores:
            mark = '*' if s.method is self.winner else ''
            if s.ok:
                parts.append(
                    f'{s.method.value}{mark} GRIC {s.gric:.0f}, {s.n_points} pts, '
                    f'{s.parallax_deg:.1f} deg'
                )
            else:
                parts.append(f'{s.method.value} failed ({s.problem})')
        return '; '.join(parts)


def _refined_essential(
    est: PoseEstimate, p0: np.ndarray, p1: np.ndarray, K: np.ndarray
) -> np.ndarray:
    """E at its maximum-likelihood fit on its inliers (OpenCV returns a minimal-sample E)."""
    if not est.ok or np.count_nonzero(est.inliers) < 6:
        return np.asarray(est.matrix, dtype=np.float64)
    R, t = refine_essential(est.R, est.t, p0[est.inliers], p1[est.inliers], K)
    return skew(t) @ R


#: Bounds of the noise estimated from the data, pixels (KLT on sharp frames reaches about
#: 0.1 px; beyond 2 px the tracks are not worth initializing on).
MIN_SIGMA_PX = 0.1
MAX_SIGMA_PX = 2.0


def estimate_noise_px(errors_sq: np.ndarray) -> float:
    """Robust noise level from an epipolar model's squared Sampson errors (pixels^2)."""
    finite = errors_sq[np.isfinite(errors_sq)]
    if finite.size < 8:
        return 1.0
    sigma = math.sqrt(float(np.median(finite)) / CHI2_1_MEDIAN)
    return float(min(max(sigma, MIN_SIGMA_PX), MAX_SIGMA_PX))


def select_method(
    estimates: Sequence[PoseEstimate],
    problems: Sequence[str],
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    sigma_px: float | None = None,
) -> Selection:
    """Score every estimate on the same correspondences and pick the lowest GRIC.

    Args:
        estimates: one :class:`PoseEstimate` per method tried.
        problems: per estimate, '' when it passed the pose check, else why not.
        p0: (N, 2) reference pixels (undistorted), the correspondences all were fit to.
        p1: (N, 2) current pixels.
        K: (3, 3) camera matrix.
        sigma_px: measurement noise for GRIC, pixels; None estimates it from the most
            general model's residuals (F, else E), as Torr does (:func:`estimate_noise_px`).
            ORB-SLAM's ratio always uses its own 1 px.
    """
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    n = max(len(p0), 1)
    errors: dict[str, np.ndarray] = {}
    fundamentals: dict[str, np.ndarray] = {}
    for est in estimates:
        matrix = np.asarray(est.matrix, dtype=np.float64)
        if not np.any(matrix):
            continue
        if est.method is Method.H:
            errors['H'] = sampson_homography(matrix, p0, p1)
            continue
        if est.method is Method.E:
            matrix = _refined_essential(est, p0, p1, K)
        F = matrix if est.method is Method.F else fundamental_from_essential(matrix, K)
        fundamentals[est.method.value] = F
        errors[est.method.value] = sampson_fundamental(F, p0, p1)
    if sigma_px is None:
        general = errors.get('F', errors.get('E'))
        sigma_px = 1.0 if general is None else estimate_noise_px(general)
    scores = []
    for est, problem in zip(estimates, problems, strict=True):
        e = errors.get(est.method.value)
        value = math.inf if e is None else gric(e, est.method.value, sigma_px)
        scores.append(
            CandidateScore(
                est.method,
                not problem,
                problem,
                value,
                est.n_points,
                est.parallax_deg,
                float(np.count_nonzero(est.inliers)) / n,
            )
        )
    H = next(
        (np.asarray(e.matrix) for e in estimates if e.method is Method.H and np.any(e.matrix)),
        None,
    )
    F = fundamentals.get('F', fundamentals.get('E'))
    orb_ratio = math.nan
    if H is not None and F is not None:
        s_h, s_f = matrix_scores(H, F, p0, p1, 1.0)
        orb_ratio = s_h / (s_h + s_f) if s_h + s_f > 0 else math.nan
    passed = [s for s in scores if s.ok]
    if not passed:
        return Selection(
            None, tuple(scores), orb_ratio, 'no candidate passed the pose check', sigma_px
        )
    best = min(passed, key=lambda s: s.gric)
    others = [s for s in passed if s is not best]
    if others:
        runner = min(others, key=lambda s: s.gric)
        why = (
            f'{best.method.value} has the lowest GRIC ({best.gric:.0f} vs '
            f'{runner.method.value} {runner.gric:.0f}, noise {sigma_px:.2f} px)'
        )
    else:
        failed = [s.method.value for s in scores if not s.ok]
        why = f'{best.method.value} is the only candidate that passed the pose check' + (
            f' ({", ".join(failed)} failed)' if failed else ''
        )
    return Selection(best.method, tuple(scores), orb_ratio, why, sigma_px)
