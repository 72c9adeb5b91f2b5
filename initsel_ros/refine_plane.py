"""Refinement of a homography's seed map under its own model: the tracks are one plane.

:func:`refine.refine_two_view` frees every point's depth. On a plane seen over a short
baseline that is the wrong model: the points' depths and the translation's direction trade
against each other along a nearly flat valley, and the bundle adjustment drifts along it (a
poster 1.2 m away, 2 cm of baseline: the homography's own pose at E_t 0.02, the bundle
adjustment's at 0.13-0.34, with a standard deviation of the direction of 2.1-2.4 degrees that
did not shrink as the baseline doubled). A homography says more: every point lies on one
plane, ``n . X = d``, so the current view is ``x_cur ~ (R + t p^T) x_ref`` with ``p = n / d``
at ``|t| = 1``, eight unknowns for all the tracks.

:func:`refine_homography` fits those eight (a rotation vector, the translation's direction on
its tangent plane and ``p``) by the same Levenberg-Marquardt and robust loss as the bundle
adjustment, on the transfer error in the current image (which carries the tracking noise of
both images), with the analytic Jacobian. The standard deviation of the direction of motion
is read from the same fit (:func:`plane_translation_sigma_deg`), and the points are
triangulated from the refined pose, each at its own depth: :mod:`initsel_ros.plane` places
those the two views cannot tell from the plane onto it when the map is published, and keeps
relief.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import fdtri

from initsel_ros.geometry import triangulate_pair
from initsel_ros.plane import fit_plane
from initsel_ros.refine import (
    Refinement,
    State,
    TwoViewProblem,
    _levenberg_marquardt,
    _pixels_and_jacobian,
    _pose_step,
    _tangent_basis,
    damped_solve,
    reprojection_errors,
    soft_l1,
    solve_two_view,
    two_view_problem,
)

#: Unknowns of the planar model: rotation vector (3), translation direction (2), ``p`` (3).
PLANE_UNKNOWNS = 8
#: Fewer points than this leave no plane worth fitting: the free bundle adjustment refines.
MIN_PLANE_POINTS = 12
#: The share of planes whose :func:`relief_statistic` exceeds :func:`relief_threshold` by
#: chance: they are refined with free depths, as every seed map was before.
RELIEF_FALSE_ALARM = 0.01


@dataclass(frozen=True)
class _PlaneLinearization:
    """Robust cost of the transfer residuals, IRLS ``J^T W J`` (8, 8) and ``J^T W r`` (8,),
    and the residuals themselves (2, N)."""

    cost: float
    JtJ: np.ndarray
    Jtr: np.ndarray
    residuals: np.ndarray


def _linearize_plane(
    R: np.ndarray,
    t: np.ndarray,
    p: np.ndarray,
    rays: np.ndarray,
    K: np.ndarray,
    q1: np.ndarray,
    scale: float,
) -> _PlaneLinearization:
    """Transfer residuals ``K (R + t p^T) m - q1`` of the reference rays ``m`` (3, N) and
    their Jacobian by ``(w, d, dp)``: ``d Y / d w = -[R m]_x`` (``R <- exp(w) R``),
    ``d Y / d d = (p . m) basis`` (``t <- normalize(t + basis d)``), ``d Y / d p = t m^T``."""
    Rm = R @ rays
    depth_inv = p @ rays  # (N,) p . m: the inverse depth of the plane along each ray
    Y = Rm + np.outer(t, depth_inv)
    uv, D = _pixels_and_jacobian(K, Y)  # (2, N), (2, 3, N)
    r = uv - q1
    cost, w = soft_l1(r, scale)
    n = rays.shape[1]
    dY = np.empty((3, PLANE_UNKNOWNS, n))
    dY[0, 0], dY[0, 1], dY[0, 2] = 0.0, Rm[2], -Rm[1]
    dY[1, 0], dY[1, 1], dY[1, 2] = -Rm[2], 0.0, Rm[0]
    dY[2, 0], dY[2, 1], dY[2, 2] = Rm[1], -Rm[0], 0.0
    dY[:, 3:5] = _tangent_basis(t)[:, :, None] * depth_inv
    dY[:, 5:8] = t[:, None, None] * rays[None]
    J = np.einsum('kin,ijn->kjn', D, dY)  # (2, 8, N)
    Jf = J.transpose(1, 0, 2).reshape(PLANE_UNKNOWNS, -1)  # (8, 2N)
    wf = w.ravel()
    return _PlaneLinearization(
        cost=cost if np.isfinite(cost) else np.inf,
        JtJ=(Jf * wf) @ Jf.T,
        Jtr=(Jf * wf) @ r.ravel(),
        residuals=r,
    )


def plane_translation_sigma_deg(lin: _PlaneLinearization) -> float:
    """First-order standard deviation of the translation direction along its least certain
    axis, degrees, under the planar model: the direction's block of ``(J^T J)^-1`` times the
    variance of a residual coordinate, ``sum r^2 / (2 N - 8)`` (each residual holds both
    images' noise). NaN when the system is singular or too small."""
    r = lin.residuals
    dof = r.size - PLANE_UNKNOWNS
    if dof <= 0:
        return math.nan
    variance = float(np.sum(r * r)) / dof
    try:
        covariance = np.linalg.inv(lin.JtJ)
    except np.linalg.LinAlgError:
        return math.nan
    largest = float(np.linalg.eigvalsh(covariance[3:5, 3:5])[-1])
    if not (math.isfinite(largest) and largest >= 0.0 and math.isfinite(variance)):
        return math.nan
    return math.degrees(math.sqrt(largest * variance))


def refine_homography(
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
    """Refine a homography's seed map as one plane (see the module docstring).

    The arguments and the result are those of :func:`refine.refine_two_view`: ``points``
    (N, 3) start the plane, ``p0``/``p1`` (N, 2) are their undistorted pixels. The result's
    points are triangulated from the refined pose; those reprojecting worse than
    ``max_reprojection_px`` in either image, or behind a camera, are dropped. With fewer than
    :data:`MIN_PLANE_POINTS` usable points, or no plane through them, the free bundle
    adjustment refines instead.

    Raises:
        GeometryError: inconsistent shapes or a zero translation.
    """
    problem = two_view_problem(R, t, points, p0, p1, K)
    refinement, final = _refine_plane(problem, huber_px, max_reprojection_px, max_evaluations)
    if final is None:
        return solve_two_view(problem, huber_px, max_reprojection_px, max_evaluations)
    return refinement


def _refine_plane(
    problem: TwoViewProblem, huber_px: float, max_reprojection_px: float, max_evaluations: int
) -> tuple[Refinement, _PlaneLinearization] | tuple[None, None]:
    """:func:`refine_homography` on a checked problem, with the final linearization (its
    transfer residuals); ``(None, None)`` without a plane to fit."""
    plane = fit_plane(problem.points, MIN_PLANE_POINTS)
    if plane is None:
        return None, None
    K = problem.K
    rays = np.linalg.solve(K, np.vstack([problem.p0.T, np.ones(len(problem.p0))]))
    q1 = problem.p1.T

    def linearize(state: State) -> _PlaneLinearization:
        return _linearize_plane(*state, rays, K, q1, huber_px)

    def propose(
        state: State, lin: _PlaneLinearization, damping: float
    ) -> tuple[State, float] | None:
        step = damped_solve(lin.JtJ, lin.Jtr, damping)
        if step is None:
            return None
        Rk, tk, pk = state
        size = float(np.sqrt(step[:5] @ step[:5] + step[5:] @ step[5:] / max(pk @ pk, 1e-300)))
        return (*_pose_step(Rk, tk, step[:5]), pk + step[5:]), size

    (Rk, tk, _), evaluations, converged, final = _levenberg_marquardt(
        (problem.R, problem.t, plane), linearize, propose, max_evaluations
    )
    X = triangulate_pair(Rk, tk, K, problem.p0, problem.p1).points
    refinement = problem.refinement(Rk, tk, X, evaluations, converged, max_reprojection_px)
    sigma = plane_translation_sigma_deg(final)
    return replace(refinement, translation_sigma_deg=sigma, as_plane=True), final


def relief_statistic(
    free: Refinement, transfer: np.ndarray, p0: np.ndarray, p1: np.ndarray, K: np.ndarray
) -> float:
    """How much better free depths explain the tracks than one plane does, over the noise:
    ``F = ((SSE_plane - SSE_free) / (N - 3)) / (SSE_free / (N - 5))``.

    ``SSE_free`` is the bundle adjustment's sum of squared reprojection errors in both images
    (``N - 5`` degrees of freedom: 4 coordinates a point, 3 unknowns a point, 5 for the pose);
    ``SSE_plane`` is half the planar fit's squared transfer errors (for the near-identity
    homographies of a first baseline the best correction splits a transfer error evenly
    between the two images; ``2 N - 8`` degrees of freedom: 2 unknowns a point on the plane,
    8 for the plane and the pose). Where the tracks are one plane, the difference is noise,
    ``chi^2`` with ``N - 3`` degrees of freedom, and ``F`` follows Fisher's distribution about
    1; relief that the baseline shows makes it larger. Over the points both fits kept.

    Args:
        free: :func:`refine.refine_two_view`'s result on ``p0``/``p1`` (N, 2).
        transfer: (2, N) the planar fit's transfer residuals, pixels.
        K: (3, 3) camera matrix.

    Returns:
        ``F``, NaN with fewer than :data:`MIN_PLANE_POINTS` common points or no noise.
    """
    kept = np.flatnonzero(free.kept)
    e0, e1 = reprojection_errors(free.R, free.t, free.points, K, p0[kept], p1[kept])
    common = np.isfinite(e0) & np.isfinite(e1) & np.all(np.isfinite(transfer[:, kept]), axis=0)
    n = int(np.count_nonzero(common))
    if n < MIN_PLANE_POINTS:
        return math.nan
    sse_free = float(np.sum(e0[common] ** 2 + e1[common] ** 2))
    sse_plane = 0.5 * float(np.sum(transfer[:, kept[common]] ** 2))
    if not sse_free > 0.0:
        return math.nan
    return ((sse_plane - sse_free) / (n - 3)) / (sse_free / (n - 5))


def relief_threshold(n_points: int) -> float:
    """The :func:`relief_statistic` a plane exceeds with probability
    :data:`RELIEF_FALSE_ALARM` (Fisher's distribution with ``N - 3`` and ``N - 5`` degrees
    of freedom)."""
    return float(fdtri(n_points - 3, n_points - 5, 1.0 - RELIEF_FALSE_ALARM))


def refine_as_plane(
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
    """A homography's seed map refined as one plane where the tracks are one (see the
    module docstring), by the bundle adjustment with free depths where they are not.

    Both are fitted; the planar one is kept unless free depths explain the tracks better than
    the noise allows (:func:`relief_statistic` above :func:`relief_threshold`): then the
    scene has relief that the baseline shows, the plane's pose is biased by it, and the free
    one is the estimate (on a desk whose papers lie on the floor before a bent poster, three
    pairs measured F 3-6; published with the planar pose two of them had E_t 0.088 and 0.342,
    with the free one 0.019 and 0.142). Arguments and result as
    :func:`refine.refine_two_view`.

    Raises:
        GeometryError: inconsistent shapes or a zero translation.
    """
    problem = two_view_problem(R, t, points, p0, p1, K)
    free = solve_two_view(problem, huber_px, max_reprojection_px, max_evaluations)
    planar, final = _refine_plane(problem, huber_px, max_reprojection_px, max_evaluations)
    if final is None:
        return free
    statistic = relief_statistic(free, final.residuals, problem.p0, problem.p1, problem.K)
    n = int(np.count_nonzero(free.kept))
    if math.isfinite(statistic) and statistic <= relief_threshold(n):
        return planar
    return free
