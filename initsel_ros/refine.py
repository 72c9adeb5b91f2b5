"""Two-view bundle adjustment of a seed map, and the essential-matrix refit of model selection.

The reference camera stays at ``[I | 0]``; the current camera's rotation (3 parameters, a
rotation vector applied to the current R) and translation direction (2 parameters on the
tangent plane of the unit sphere: monocular scale is not observable, so ``|t| = 1`` is kept)
are optimized together with every point (3 parameters each: inverse depth along its
reference ray, see :func:`_linearize`) to minimise the reprojection error in both images,
with a robust loss (``soft_l1``, the smooth pseudo-Huber: quadratic below ``huber_px``, linear
above).

The solver is a Levenberg-Marquardt in numpy that uses the problem's structure: each point
touches only its own 4 residuals and the 5 pose unknowns, so the damped normal equations are
reduced to the pose (the Schur complement of the points' 3x3 blocks, all inverted in one
vectorized step), solved as a 5x5 system, and the points' steps follow by back-substitution.
The robust loss enters as iteratively reweighted least squares: each residual is weighted by
the loss's derivative, which makes the step's gradient the robust cost's. On the bench's fire
pairs (about 250 points) it is 27x faster than scipy's ``least_squares`` with an analytic
sparse Jacobian, which it replaced, for the same median E_t (docs/performance.md). Points
whose final reprojection error exceeds ``max_reprojection_px`` in either image, or that end
behind a camera, are dropped.

:func:`refine_essential` refits an essential-matrix pose (5 unknowns) by the same small
Levenberg-Marquardt on its Sampson errors, with their analytic Jacobian.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import homogeneous, skew


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
        iterations: cost evaluations of the optimizer (one per step tried).
        converged: the optimizer stopped because the cost or the step became negligible
            (not at its evaluation cap).
        translation_sigma_deg: standard deviation of the translation's direction along its
            least certain axis, degrees (first-order, from the solution's normal equations
            and the noise its residuals imply; NaN when not computed): how well the pair
            fixes the direction the camera moved.
        as_plane: refined as one plane (:mod:`initsel_ros.refine_plane`), not with free depths.
    """

    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    kept: np.ndarray
    rms_before_px: float
    rms_after_px: float
    iterations: int
    converged: bool
    translation_sigma_deg: float = float('nan')
    as_plane: bool = False


def _tangent_basis(t: np.ndarray) -> np.ndarray:
    """(3, 2) orthonormal basis of the plane orthogonal to the unit vector t.

    ``b1 = t x e_k / |t x e_k|`` for the axis ``e_k`` least aligned with t, ``b2 = t x b1``;
    in plain floats (the solvers call it at every step, and numpy's overhead on a single
    vector is most of the cost).
    """
    x, y, z = (float(v) for v in t)
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax <= ay and ax <= az:  # t x e_x
        u = (0.0, z, -y)
    elif ay <= az:  # t x e_y
        u = (-z, 0.0, x)
    else:  # t x e_z
        u = (y, -x, 0.0)
    norm = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    u0, u1, u2 = u[0] / norm, u[1] / norm, u[2] / norm
    v0, v1, v2 = y * u2 - z * u1, z * u0 - x * u2, x * u1 - y * u0
    return np.array([[u0, v0], [u1, v1], [u2, v2]])


def _rotation(rvec: np.ndarray) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))[0]


def _project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    uvw = X @ K.T
    return uvw[:, :2] / uvw[:, 2:3]


def _pixels_and_jacobian(K: np.ndarray, Xt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of points and their derivative by the points, points along the last axis.

    Args:
        K: (3, 3) camera matrix.
        Xt: (3, N) points in the camera frame.

    Returns:
        ``(uv (2, N), D (2, 3, N))``: ``(K X)[:2] / (K X)[2]`` and ``D[k, i] = d uv[k] / d X[i]``.
        A depth within 1e-9 of zero is moved to 1e-9 (a point crossing a camera plane gets a
        large residual instead of a division by zero).
    """
    uvw = K @ Xt
    z = uvw[2]
    z = np.where(np.abs(z) < 1e-9, 1e-9, z)
    uv = uvw[:2] / z
    return uv, (K[:2, :, None] - uv[:, None, :] * K[2][None, :, None]) / z


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


@dataclass(frozen=True)
class TwoViewProblem:
    """A seed map as bundle adjustment starts from it: float64, at the scale ``|t| = 1``.

    :func:`two_view_problem` builds it from :func:`refine_two_view`'s arguments; the bench's
    yardstick solvers (:mod:`initsel_ros.benchmarks.solvers`) start from the same one.

    Attributes:
        R: (3, 3) rotation, reference to current.
        t: (3,) unit translation.
        points: (N, 3) points, reference camera frame, at the scale ``|t| = 1``.
        p0: (N, 2) their pixels in the reference image.
        p1: (N, 2) their pixels in the current image.
        K: (3, 3) camera matrix.
        rms_before_px: RMS reprojection error (both images) of the start, pixels.
    """

    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    K: np.ndarray
    rms_before_px: float

    def refinement(
        self,
        R: np.ndarray,
        t: np.ndarray,
        points: np.ndarray,
        iterations: int,
        converged: bool,
        max_reprojection_px: float,
    ) -> Refinement:
        """The record of a solution (``points`` (N, 3) at the unit scale, NaN where lost):
        the points reprojecting worse than ``max_reprojection_px`` in either image dropped."""
        e0, e1 = reprojection_errors(R, t, points, self.K, self.p0, self.p1)
        kept = (e0 <= max_reprojection_px) & (e1 <= max_reprojection_px)
        return Refinement(
            R=R,
            t=t,
            points=points[kept],
            kept=kept,
            rms_before_px=self.rms_before_px,
            rms_after_px=_rms(e0[kept], e1[kept]),
            iterations=iterations,
            converged=converged,
        )


def two_view_problem(
    R: np.ndarray, t: np.ndarray, points: np.ndarray, p0: np.ndarray, p1: np.ndarray, K: np.ndarray
) -> TwoViewProblem:
    """The arguments of :func:`refine_two_view` checked, as float64, at the scale ``|t| = 1``.

    Raises:
        GeometryError: inconsistent shapes or a zero translation.
    """
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    X = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p0 = np.asarray(p0, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=np.float64).reshape(-1, 2)
    K = np.asarray(K, dtype=np.float64)
    n = X.shape[0]
    if p0.shape[0] != n or p1.shape[0] != n:
        raise GeometryError(f'{n} points but {p0.shape[0]} and {p1.shape[0]} pixels')
    norm = float(np.linalg.norm(t))
    if not np.isfinite(norm) or norm < 1e-12:
        raise GeometryError('refinement needs a non-zero translation')
    t, X = t / norm, X / norm
    return TwoViewProblem(R, t, X, p0, p1, K, _rms(*reprojection_errors(R, t, X, K, p0, p1)))


def soft_l1(residuals: np.ndarray, scale: float) -> tuple[float, np.ndarray]:
    """The pseudo-Huber cost of residuals and its IRLS weights.

    ``rho(z) = 2 (sqrt(1 + z) - 1)`` of ``z = (r / scale)^2`` per residual (scipy's
    ``soft_l1``); the cost is ``0.5 scale^2 sum rho`` and the weights are ``rho'(z)``, with
    which the weighted least-squares gradient equals the robust cost's.

    Args:
        residuals: any shape, pixels.
        scale: where the loss turns from quadratic to linear, pixels.

    Returns:
        ``(cost, weights)``, the weights of the shape of ``residuals``.
    """
    root = np.sqrt(1.0 + (residuals / scale) ** 2)
    return float(scale**2 * np.sum(root - 1.0)), 1.0 / root


#: Levenberg-Marquardt: starting damping (relative to the normal matrix's diagonal), the
#: factors it shrinks by after a successful step and grows by after a failed one, the relative
#: cost decrease and relative step below which the solver stops (scipy's ftol and xtol as the
#: previous solver used them), and the smallest diagonal entry damping scales with.
LM_INITIAL_DAMPING = 1e-3
LM_SHRINK = 1.0 / 3.0
LM_GROW = 4.0
LM_FTOL = 1e-4
LM_XTOL = 1e-5
LM_MIN_DAMPING = 1e-9
LM_MAX_DAMPING = 1e8
_MIN_DIAGONAL = 1e-12

#: The unknowns the Levenberg-Marquardt loop carries: (R, t) or (R, t, points).
State = tuple[np.ndarray, ...]


@dataclass(frozen=True)
class _Linearization:
    """Cost and normal-equation pieces of the two-view problem at one state.

    Points run along the last axis: ``U`` (5, 5) pose block, ``V`` (3, 3, N) point blocks,
    ``W`` (5, 3, N) pose-point blocks, ``g_pose`` (5,) and ``g_points`` (3, N) gradients of
    the robust cost.
    """

    cost: float
    U: np.ndarray
    V: np.ndarray
    W: np.ndarray
    g_pose: np.ndarray
    g_points: np.ndarray


def _linearize(
    R: np.ndarray,
    t: np.ndarray,
    basis: np.ndarray,
    Q: np.ndarray,
    K: np.ndarray,
    q0: np.ndarray,
    q1: np.ndarray,
    scale: float,
) -> _Linearization:
    """IRLS normal equations of the robust two-view cost at ``(R, t, Q)``.

    Points are in inverse depth along the reference ray: ``Q`` (3, N) holds ``(u, v, rho)``
    with ``X = (u, v, 1) / rho``, so the reference image sees ``K (u, v, 1)`` (linear in the
    unknowns) and the current one ``K (R (u, v, 1) + rho t)`` (the same direction as
    ``K (R X + t)``): far points, whose depth the views hardly fix, no longer make the
    problem strongly nonlinear (with points as X the solver crept along their depths for 30
    evaluations on some pairs).

    Pose unknowns: a rotation vector ``w`` (``R <- exp(w) R``, so ``d(R m)/dw = -[R m]_x``)
    and the step ``d`` of ``t`` along ``basis`` (``d t / d d = basis`` at ``|t| = 1``).
    ``q0``, ``q1``: (2, N) observed pixels.
    """
    n = Q.shape[1]
    m = np.vstack([Q[:2], np.ones(n)])  # reference rays (3, N)
    rho = Q[2]
    Y = R @ m
    uv0, D0 = _pixels_and_jacobian(K, m)
    uv1, D1 = _pixels_and_jacobian(K, Y + rho * t[:, None])
    r0, r1 = uv0 - q0, uv1 - q1
    cost0, w0 = soft_l1(r0, scale)
    cost1, w1 = soft_l1(r1, scale)
    A0 = np.zeros((2, 3, n))  # (2, 3, N) reference residuals by (u, v, rho)
    A0[:, :2] = D0[:, :2]
    A1 = np.empty((2, 3, n))  # current residuals by (u, v, rho)
    A1[:, :2] = np.einsum('kin,ij->kjn', D1, R[:, :2])
    A1[:, 2] = np.tensordot(D1, t, axes=([1], [0]))
    # the pose columns: D1 @ -[Y]_x (rotation) and rho D1 @ basis (translation)
    P = np.empty((2, 5, n))
    P[:, 0] = D1[:, 2] * Y[1] - D1[:, 1] * Y[2]
    P[:, 1] = D1[:, 0] * Y[2] - D1[:, 2] * Y[0]
    P[:, 2] = D1[:, 1] * Y[0] - D1[:, 0] * Y[1]
    P[:, 3:] = np.einsum('kin,im->kmn', D1, basis) * rho
    wA0 = A0 * w0[:, None, :]
    wA1 = A1 * w1[:, None, :]
    wP = P * w1[:, None, :]
    V = (wA0[:, :, None] * A0[:, None]).sum(axis=0) + (wA1[:, :, None] * A1[:, None]).sum(axis=0)
    cost = cost0 + cost1
    return _Linearization(
        cost=cost if np.isfinite(cost) else np.inf,
        U=wP.transpose(1, 0, 2).reshape(5, -1) @ P.transpose(1, 0, 2).reshape(5, -1).T,
        V=V,
        W=(wP[:, :, None] * A1[:, None]).sum(axis=0),
        g_pose=(wP * r1[:, None]).sum(axis=(0, 2)),
        g_points=(wA0 * r0[:, None]).sum(axis=0) + (wA1 * r1[:, None]).sum(axis=0),
    )


def _inverse_3x3(V: np.ndarray) -> np.ndarray:
    """Inverses of symmetric 3x3 matrices stacked along the last axis ((3, 3, N)), by their
    cofactors in one vectorized step.

    Raises:
        np.linalg.LinAlgError: a matrix is singular (or not finite).
    """
    a, b, c = V[0, 0], V[0, 1], V[0, 2]
    d, e, f = V[1, 1], V[1, 2], V[2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * A + b * B + c * C
    if not np.all(np.abs(det) > 1e-300) or not np.all(np.isfinite(det)):
        raise np.linalg.LinAlgError('singular point block')
    return np.array([[A, B, C], [B, D, E], [C, E, F]]) / det


def _pose_schur(W: np.ndarray, V_inv: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``W V^-1`` (5, 3, N) and the pose's Schur complement ``U - sum W V^-1 W^T`` (5, 5)."""
    WV = (W[:, :, None] * V_inv[None]).sum(axis=1)
    return WV, U - WV.reshape(5, -1) @ W.reshape(5, -1).T


def _damped_step(lin: _Linearization, damping: float) -> tuple[np.ndarray, np.ndarray]:
    """Solve the damped normal equations through the pose's Schur complement.

    ``(H + damping diag(H)) [dp; dx] = -g`` with ``H = [[U, W], [W^T, V]]``: the points' 3x3
    blocks are inverted in one vectorized step, the 5x5 reduced system
    ``(U - sum W V^-1 W^T) dp = -g_p + sum W V^-1 g_x`` solved, and
    ``dx = -V^-1 (g_x + W^T dp)`` substituted back.

    Returns:
        ``(dp (5,), dx (3, N))``.

    Raises:
        np.linalg.LinAlgError: the damped system is singular.
    """
    U = lin.U + damping * np.diag(np.maximum(np.diag(lin.U), _MIN_DIAGONAL))
    V = lin.V.copy()
    for i in range(3):
        V[i, i] += damping * np.maximum(lin.V[i, i], _MIN_DIAGONAL)
    V_inv = _inverse_3x3(V)  # (3, 3, N)
    WV, S = _pose_schur(lin.W, V_inv, U)
    b = -lin.g_pose + WV.reshape(5, -1) @ lin.g_points.ravel()
    dp = np.linalg.solve(S, b)
    rhs = lin.g_points + np.tensordot(dp, lin.W, axes=1)  # (3, N)
    return dp, -(V_inv * rhs[None]).sum(axis=1)


def _pose_step(R: np.ndarray, t: np.ndarray, dp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R <- exp(dp[:3]) R``, ``t <- normalize(t + basis dp[3:])``."""
    t_new = t + _tangent_basis(t) @ dp[3:5]
    return _rotation(dp[:3]) @ R, t_new / np.linalg.norm(t_new)


def damped_solve(JtJ: np.ndarray, Jtr: np.ndarray, damping: float) -> np.ndarray | None:
    """The Levenberg-Marquardt step ``(JtJ + damping diag(JtJ)) step = -Jtr`` (the diagonal
    floored at a tiny value so that a flat direction is damped too); None when the system is
    singular or the step not finite."""
    A = JtJ + damping * np.diag(np.maximum(np.diag(JtJ), _MIN_DIAGONAL))
    try:
        step = np.linalg.solve(A, -Jtr)
    except np.linalg.LinAlgError:
        return None
    return step if np.all(np.isfinite(step)) else None


def _levenberg_marquardt(
    state: State,
    linearize: Callable[[State], Any],
    propose: Callable[[State, Any, float], tuple[State, float] | None],
    max_evaluations: int,
) -> tuple[State, int, bool, Any]:
    """The damping loop shared by both refinements.

    Each step tried is linearized at once (its cost decides whether it is kept; steps are
    rarely refused, so the Jacobian is seldom computed in vain).

    Args:
        state: the unknowns, as the callables take them.
        linearize: ``linearize(state)``: whatever ``propose`` needs, with the state's cost
            (inf when unusable) as its ``cost`` attribute.
        propose: ``propose(state, linearization, damping) -> (new state, step size relative
            to the state)``, None when the damped system could not be solved.
        max_evaluations: cap on evaluations of a step tried.

    Returns:
        ``(state, evaluations, converged, linearization)``, the last the state's own (what
        its covariance is read from).
    """
    lin = linearize(state)
    damping = LM_INITIAL_DAMPING
    evaluations = 0
    while evaluations < max_evaluations:
        proposal = propose(state, lin, damping)
        trial = None
        if proposal is not None:
            evaluations += 1
            trial = linearize(proposal[0])
        if trial is None or not trial.cost < lin.cost:
            damping *= LM_GROW
            if damping > LM_MAX_DAMPING:
                return state, evaluations, True, lin  # no step lowers the cost: at a minimum
            continue
        new_state, relative_step = proposal
        decrease = (lin.cost - trial.cost) / max(lin.cost, 1e-300)
        state, lin = new_state, trial
        damping = max(damping * LM_SHRINK, LM_MIN_DAMPING)
        if decrease < LM_FTOL or relative_step < LM_XTOL:
            return state, evaluations, True, lin
    return state, evaluations, False, lin


def _sampson_residuals(
    R: np.ndarray, t: np.ndarray, x0: np.ndarray, x1: np.ndarray, K_inv: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Signed Sampson residuals of ``F = K^-T [t]_x R K^-1`` and what their Jacobian needs.

    Args:
        x0, x1: (N, 3) homogeneous pixels.

    Returns:
        ``(r, algebraic, Fx0, Ftx1)``: (N,) residuals (their squares are
        :func:`~initsel_ros.geometry.sampson_fundamental`), (N,) ``x1^T F x0``, (N, 3)
        ``F x0`` and (N, 3) ``F^T x1``.
    """
    F = K_inv.T @ skew(t) @ R @ K_inv
    Fx0 = x0 @ F.T
    Ftx1 = x1 @ F
    algebraic = np.einsum('ij,ij->i', x1, Fx0)
    den = Fx0[:, 0] ** 2 + Fx0[:, 1] ** 2 + Ftx1[:, 0] ** 2 + Ftx1[:, 1] ** 2
    return algebraic / np.sqrt(np.maximum(den, 1e-300)), algebraic, Fx0, Ftx1


@dataclass(frozen=True)
class _EssentialLinearization:
    """Cost ``0.5 sum r^2`` of the Sampson residuals, ``J^T J`` (5, 5) and ``J^T r`` (5,)."""

    cost: float
    JtJ: np.ndarray
    Jtr: np.ndarray


#: [e_k]_x for the unit vectors e_k: d(exp(w) R)/dw_k = [e_k]_x R at w = 0.
_GENERATORS = np.array([skew(e) for e in np.eye(3)])


def essential_jacobian(
    R: np.ndarray, t: np.ndarray, x0: np.ndarray, x1: np.ndarray, K_inv: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Sampson residuals of ``(R, t)`` and their analytic Jacobian.

    The unknowns are a rotation vector ``w`` (``R <- exp(w) R``) and a step along
    ``_tangent_basis(t)`` (``t <- normalize(t + basis d)``), both at 0: ``d([t]_x R)`` is
    ``[t]_x [e_k]_x R`` for ``w_k`` and ``[b_k]_x R`` for ``d_k``. With ``a = x1^T F x0`` and
    ``s`` the sum of squares of the first two entries of ``F x0`` and ``F^T x1``,
    ``r = a / sqrt(s)`` and ``dr = da / sqrt(s) - a ds / (2 s^1.5)``.

    Args:
        R: (3, 3) rotation; t: (3,) unit translation.
        x0, x1: (N, 3) homogeneous pixels.
        K_inv: (3, 3) inverse camera matrix.

    Returns:
        ``(r (N,), J (N, 5))``.
    """
    r, algebraic, Fx0, Ftx1 = _sampson_residuals(R, t, x0, x1, K_inv)
    dE = np.concatenate(
        [skew(t) @ _GENERATORS @ R, np.array([skew(b) @ R for b in _tangent_basis(t).T])]
    )
    dF = K_inv.T @ dE @ K_inv  # (5, 3, 3)
    n = len(x0)
    dFx0 = (x0 @ dF.reshape(15, 3).T).reshape(n, 5, 3)  # dF_k x0
    dFtx1 = (x1 @ dF.transpose(1, 0, 2).reshape(3, 15)).reshape(n, 5, 3)  # dF_k^T x1
    d_algebraic = (dFx0 * x1[:, None, :]).sum(axis=2)
    den = np.maximum(Fx0[:, 0] ** 2 + Fx0[:, 1] ** 2 + Ftx1[:, 0] ** 2 + Ftx1[:, 1] ** 2, 1e-300)
    d_den = 2 * (
        (dFx0[:, :, :2] * Fx0[:, None, :2]).sum(axis=2)
        + (dFtx1[:, :, :2] * Ftx1[:, None, :2]).sum(axis=2)
    )
    J = d_algebraic / np.sqrt(den)[:, None] - 0.5 * (algebraic / den**1.5)[:, None] * d_den
    return r, J


def refine_essential(
    R: np.ndarray,
    t: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    max_evaluations: int = 30,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine an essential-matrix pose by its Sampson errors on its inliers (5 parameters).

    OpenCV's 5-point RANSAC returns the best minimal-sample model; model selection must
    compare it at its maximum-likelihood fit, as F (refitted on its inliers) and H (refined
    by OpenCV) are. Rotation vector and translation direction are optimized by
    Levenberg-Marquardt on the Sampson errors of ``K^-T [t]x R K^-1``, with their analytic
    Jacobian (``d[t]_x R`` is ``[t]_x [e_k]_x R`` for the rotation, ``[b_k]_x R`` for the
    translation's tangent directions ``b_k``).

    Returns:
        ``(R, t)``, t of unit norm.
    """
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    x0 = homogeneous(np.asarray(p0, dtype=np.float64))
    x1 = homogeneous(np.asarray(p1, dtype=np.float64))
    if len(x0) < 6:
        return R, t
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))

    def linearize(state: State) -> _EssentialLinearization:
        r, J = essential_jacobian(*state, x0, x1, K_inv)
        cost = 0.5 * float(r @ r)
        return _EssentialLinearization(cost if np.isfinite(cost) else np.inf, J.T @ J, J.T @ r)

    def propose(
        state: State, lin: _EssentialLinearization, damping: float
    ) -> tuple[State, float] | None:
        dp = damped_solve(lin.JtJ, lin.Jtr, damping)
        if dp is None:
            return None
        return _pose_step(*state, dp), float(np.linalg.norm(dp))

    (R, t), _, _, _ = _levenberg_marquardt((R, t), linearize, propose, max_evaluations)
    return R, t


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
        max_evaluations: cap on the steps the solver tries (each one evaluation of the cost
            and its Jacobian).

    Raises:
        GeometryError: inconsistent shapes or a zero translation.
    """
    problem = two_view_problem(R, t, points, p0, p1, K)
    return solve_two_view(problem, huber_px, max_reprojection_px, max_evaluations)


def solve_two_view(
    problem: TwoViewProblem, huber_px: float, max_reprojection_px: float, max_evaluations: int
) -> Refinement:
    """:func:`refine_two_view` on a checked :class:`TwoViewProblem` (the other arguments as
    there)."""
    X0, K = problem.points, problem.K
    # points behind (or on) the reference camera's plane have no inverse depth: they stay out
    # of the adjustment and are dropped (they would be dropped afterwards anyway)
    usable = np.isfinite(X0).all(axis=1) & (X0[:, 2] > 1e-9)
    if np.count_nonzero(usable) < 6:
        return problem.refinement(problem.R, problem.t, X0, 0, False, max_reprojection_px)
    scale = float(huber_px)
    Xu = X0[usable]
    q0, q1 = problem.p0[usable].T.copy(), problem.p1[usable].T.copy()

    def linearize(state: State) -> _Linearization:
        Rk, tk, Q = state
        return _linearize(Rk, tk, _tangent_basis(tk), Q, K, q0, q1, scale)

    def propose(state: State, lin: _Linearization, damping: float) -> tuple[State, float] | None:
        Rk, tk, Q = state
        try:
            dp, dq = _damped_step(lin, damping)
        except np.linalg.LinAlgError:
            return None
        if not (np.all(np.isfinite(dp)) and np.all(np.isfinite(dq))):
            return None
        # relative step, as scipy's xtol: pose unknowns against 1 (|t| = 1, radians)
        size = float(np.sqrt(dp @ dp + np.sum(dq * dq)))
        norm = float(np.sqrt(1.0 + np.sum(Q * Q)))
        return (*_pose_step(Rk, tk, dp), Q + dq), size / norm

    Q0 = np.vstack([Xu[:, 0] / Xu[:, 2], Xu[:, 1] / Xu[:, 2], 1.0 / Xu[:, 2]])
    (Rk, tk, Q), evaluations, converged, final = _levenberg_marquardt(
        (problem.R, problem.t, Q0), linearize, propose, max_evaluations
    )
    X = np.full_like(X0, np.nan)
    with np.errstate(divide='ignore', invalid='ignore'):  # inf/NaN where rho ended at 0
        X[usable] = np.column_stack([Q[0], Q[1], np.ones(Q.shape[1])]) / Q[2][:, None]
    refinement = problem.refinement(Rk, tk, X, evaluations, converged, max_reprojection_px)
    sigma_deg = translation_sigma_deg(final, refinement.rms_after_px)
    return replace(refinement, translation_sigma_deg=sigma_deg)


def translation_sigma_deg(lin: _Linearization, rms_px: float) -> float:
    """First-order standard deviation of the translation direction along its least certain
    axis, degrees: the pose block of the inverse normal equations (the points eliminated) at
    the solution, times the noise variance per coordinate. Each point gives 4 coordinates for
    its 3 unknowns, so N points leave N - 5 degrees of freedom to the 2N residual lengths
    whose RMS is ``rms_px``: ``sigma^2 = 2 N rms^2 / (N - 5)``. NaN when the system is
    singular or too small."""
    n = lin.V.shape[2]
    if n <= 5 or not math.isfinite(rms_px):
        return math.nan
    try:
        _, S = _pose_schur(lin.W, _inverse_3x3(lin.V), lin.U)
        largest = float(np.linalg.eigvalsh(np.linalg.inv(S)[3:, 3:])[-1])
    except np.linalg.LinAlgError:
        return math.nan
    if not (math.isfinite(largest) and largest >= 0.0):
        return math.nan
    return math.degrees(math.sqrt(largest * 2.0 * n * rms_px**2 / (n - 5)))
