"""Two-view bundle adjustment of a seed map: rotation, unit translation and the points.

The reference camera stays at ``[I | 0]``; the current camera's rotation (3 parameters, a
rotation vector applied to the initial R) and translation direction (2 parameters on the
tangent plane of the unit sphere: monocular scale is not observable, so ``|t| = 1`` is kept)
are optimized together with every point (3 parameters each) to minimise the reprojection
error in both images, with a robust loss (``soft_l1``, the smooth pseudo-Huber: quadratic
below ``huber_px``, linear above; scipy's plain ``huber`` stalled here from perturbed
starts). ``scipy.optimize.least_squares`` with an analytic sparse Jacobian (each point
touches only its own 4 residuals) keeps it to a few milliseconds for a few hundred points.
Points whose final reprojection error exceeds ``max_reprojection_px`` in either image, or
that end behind a camera, are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import fundamental_from_essential, sampson_fundamental, skew


@dataclass(frozen=True)
class Refinement:
    """Result of :func:`refine_two_view`.

    Attributes:
        R: (3, 3) refined rotation, reference to current.
        t: (3,) refined translation, unit norm.
        points: (M, 3) refined points that were kept, reference camera frame, at the scale
            ``|t| = 1``.
        kept: (N,) bool over the input points: kept after refinement.
        rms_before_px: RMS reprojection error (both images) before, pixels.
        rms_after_px: RMS reprojection error of the kept points after, pixels.
        iterations: function evaluations of the optimizer.
        converged: the optimizer reported convergence.
    """

    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    kept: np.ndarray
    rms_before_px: float
    rms_after_px: float
    iterations: int
    converged: bool


def _tangent_basis(t: np.ndarray) -> np.ndarray:
    """(3, 2) orthonormal basis of the plane orthogonal to the unit vector t."""
    helper = np.eye(3)[int(np.argmin(np.abs(t)))]
    b1 = np.cross(t, helper)
    b1 /= np.linalg.norm(b1)
    return np.stack([b1, np.cross(t, b1)], axis=1)


def _rotation(rvec: np.ndarray) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))[0]


def _project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    uvw = X @ K.T
    return uvw[:, :2] / uvw[:, 2:3]


def _projection_jacobian(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(N, 2, 3) derivative of the pixel ``(K X)[:2] / (K X)[2]`` with respect to X."""
    uvw = X @ K.T
    z = np.where(np.abs(uvw[:, 2]) < 1e-9, 1e-9, uvw[:, 2])
    uv = uvw[:, :2] / z[:, None]
    return (K[None, :2, :] - uv[:, :, None] * K[None, 2:3, :]) / z[:, None, None]


def reprojection_errors(
    R: np.ndarray,
    t: np.ndarray,
    points: np.ndarray,
    K: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-point reprojection error in the reference and the current image, pixels.

    Returns ``(e0, e1)``, each (N,); infinity for points behind that camera.
    """
    Xc = points @ np.asarray(R).T + np.asarray(t).reshape(3)
    with np.errstate(divide='ignore', invalid='ignore'):
        e0 = np.linalg.norm(_project(K, points) - p0, axis=1)
        e1 = np.linalg.norm(_project(K, Xc) - p1, axis=1)
    e0 = np.where(points[:, 2] > 0, np.nan_to_num(e0, nan=np.inf), np.inf)
    e1 = np.where(Xc[:, 2] > 0, np.nan_to_num(e1, nan=np.inf), np.inf)
    return e0, e1


def _rms(e0: np.ndarray, e1: np.ndarray) -> float:
    both = np.concatenate([e0, e1])
    both = both[np.isfinite(both)]
    return float(np.sqrt(np.mean(both**2))) if both.size else float('nan')


def refine_essential(
    R: np.ndarray,
    t: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    max_evaluations: int = 60,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine an essential-matrix pose by its Sampson errors on its inliers (5 parameters).

    OpenCV's 5-point RANSAC returns the best minimal-sample model; model selection must
    compare it at its maximum-likelihood fit, as F (refitted on its inliers) and H (refined
    by OpenCV) are. Rotation vector and translation direction are optimized by
    Levenberg-Marquardt on the Sampson errors of ``K^-T [t]x R K^-1``.

    Returns:
        ``(R, t)``, t of unit norm.
    """
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    if len(p0) < 6:
        return R, t
    basis = _tangent_basis(t)

    def pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tk = t + basis @ x[3:5]
        return _rotation(x[:3]) @ R, tk / np.linalg.norm(tk)

    def residuals(x: np.ndarray) -> np.ndarray:
        Rk, tk = pose(x)
        F = fundamental_from_essential(skew(tk) @ Rk, K)
        return np.sqrt(sampson_fundamental(F, p0, p1))

    solution = least_squares(residuals, np.zeros(5), method='lm', max_nfev=max_evaluations)
    return pose(solution.x)


def refine_two_view(
    R: np.ndarray,
    t: np.ndarray,
    points: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    *,
    huber_px: float = 1.0,
    max_reprojection_px: float = 2.0,
    max_evaluations: int = 30,
) -> Refinement:
    """Bundle-adjust a two-view seed map (see the module docstring).

    Args:
        R: (3, 3) initial rotation, reference to current (``x_cur = R x_ref + t``).
        t: (3,) initial translation (any non-zero norm; the result has unit norm).
        points: (N, 3) initial points, reference camera frame, at the scale of ``t``.
        p0: (N, 2) their pixels in the reference image (undistorted).
        p1: (N, 2) their pixels in the current image (undistorted).
        K: (3, 3) camera matrix.
        huber_px: robust loss scale, pixels (residuals beyond it count about linearly).
        max_reprojection_px: points reprojecting worse than this afterwards are dropped.
        max_evaluations: cap on the optimizer's function evaluations.

    Raises:
        GeometryError: inconsistent shapes or a zero translation.
    """
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    X0 = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p0 = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    K = np.asarray(K, dtype=np.float64)
    n = X0.shape[0]
    if p0.shape[0] != n or p1.shape[0] != n:
        raise GeometryError(f'{n} points but {p0.shape[0]} and {p1.shape[0]} pixels')
    norm = float(np.linalg.norm(t))
    if not np.isfinite(norm) or norm < 1e-12:
        raise GeometryError('refinement needs a non-zero translation')
    t_unit = t / norm
    X0 = X0 / norm  # the map at the scale |t| = 1
    e0, e1 = reprojection_errors(R, t_unit, X0, K, p0, p1)
    rms_before = _rms(e0, e1)
    if n < 6:
        kept = (e0 <= max_reprojection_px) & (e1 <= max_reprojection_px)
        return Refinement(
            R, t_unit, X0[kept], kept, rms_before, _rms(e0[kept], e1[kept]), 0, False
        )
    basis = _tangent_basis(t_unit)

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        Rk = _rotation(x[:3]) @ R
        tk = t_unit + basis @ x[3:5]
        tk = tk / np.linalg.norm(tk)
        return Rk, tk, x[5:].reshape(n, 3)

    def residuals(x: np.ndarray) -> np.ndarray:
        Rk, tk, X = unpack(x)
        Xc = X @ Rk.T + tk
        # Guard the division: a point crossing a camera plane gets a large residual.
        z0 = np.where(np.abs(X[:, 2:3]) < 1e-9, 1e-9, X[:, 2:3])
        z1 = np.where(np.abs(Xc[:, 2:3]) < 1e-9, 1e-9, Xc[:, 2:3])
        u0 = (X @ K.T)[:, :2] / z0 - p0
        u1 = (Xc @ K.T)[:, :2] / z1 - p1
        return np.hstack([u0, u1]).ravel()

    rows = np.arange(4 * n).reshape(n, 4)
    # Sparse Jacobian layout: each point's 4 residual rows touch the 5 pose columns (zero for
    # the reference image's rows) and the point's own 3 columns.
    jac_rows = np.repeat(rows, 8, axis=1).ravel()
    point_cols = 5 + 3 * np.arange(n)[:, None] + np.arange(3)[None, :]
    cols_per_row = np.hstack([np.broadcast_to(np.arange(5), (n, 5)), point_cols])  # (n, 8)
    jac_cols = np.repeat(cols_per_row[:, None, :], 4, axis=1).ravel()

    def jacobian(x: np.ndarray) -> csr_matrix:
        Rk, tk, X = unpack(x)
        raw = t_unit + basis @ x[3:5]
        Y = X @ Rk.T
        Xc = Y + tk
        d_proj0 = _projection_jacobian(K, X)  # (n, 2, 3)
        d_proj1 = _projection_jacobian(K, Xc)
        # d(exp(w) R X)/dw = -[R X]_x for small w (the corrections stay small)
        cross = np.zeros((n, 3, 3))
        cross[:, 0, 1], cross[:, 0, 2] = Y[:, 2], -Y[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = -Y[:, 2], Y[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = Y[:, 1], -Y[:, 0]
        d_t = (np.eye(3) - np.outer(tk, tk)) @ basis / np.linalg.norm(raw)  # (3, 2)
        block = np.zeros((n, 4, 8))
        block[:, 0:2, 5:8] = d_proj0
        block[:, 2:4, 0:3] = d_proj1 @ cross
        block[:, 2:4, 3:5] = d_proj1 @ d_t
        block[:, 2:4, 5:8] = d_proj1 @ Rk
        return csr_matrix((block.ravel(), (jac_rows, jac_cols)), shape=(4 * n, 5 + 3 * n))

    x0 = np.concatenate([np.zeros(5), X0.ravel()])
    solution = least_squares(
        residuals,
        x0,
        jac=jacobian,
        method='trf',
        loss='soft_l1',
        f_scale=huber_px,
        x_scale='jac',
        max_nfev=max_evaluations,
        tr_solver='lsmr',
        ftol=1e-4,
        xtol=1e-5,
    )
    Rk, tk, X = unpack(solution.x)
    e0, e1 = reprojection_errors(Rk, tk, X, K, p0, p1)
    kept = (e0 <= max_reprojection_px) & (e1 <= max_reprojection_px)
    return Refinement(
        R=Rk,
        t=tk,
        points=X[kept],
        kept=kept,
        rms_before_px=rms_before,
        rms_after_px=_rms(e0[kept], e1[kept]),
        iterations=int(solution.nfev),
        converged=bool(solution.success),
    )
