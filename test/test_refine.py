"""Tests for initsel_ros.refine: two-view bundle adjustment and the E refit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from geometry_fixtures import K, two_view

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import (
    estimate_pose,
    fundamental_from_essential,
    rotation_angle_deg,
    sampson_fundamental,
    skew,
    triangulate_pair,
)
from initsel_ros.metrics import translation_chordal_error
from initsel_ros.refine import refine_essential, refine_two_view, reprojection_errors


def _perturbed(R, t, seed=1):
    rng = np.random.default_rng(seed)
    dR = cv2.Rodrigues(rng.normal(0, 0.01, 3))[0]  # about 1 degree
    dt = t + rng.normal(0, 0.08, 3)
    return dR @ R, dt / np.linalg.norm(dt)


@pytest.mark.parametrize('planar', [False, True])
def test_bundle_adjustment_recovers_the_pose_from_a_perturbed_start(planar):
    p0, p1, R, t, _ = two_view(planar=planar, noise_px=0.3)
    R0, t0 = _perturbed(R, t)
    X0 = triangulate_pair(R0, t0, K, p0, p1).points
    before = (translation_chordal_error(t, t0), rotation_angle_deg(R0.T @ R))
    result = refine_two_view(R0, t0, X0, p0, p1, K)
    after = (translation_chordal_error(t, result.t), rotation_angle_deg(result.R.T @ R))
    assert after[0] < 0.3 * before[0] and after[0] < 0.03
    assert after[1] < 0.3 * before[1] and after[1] < 0.1
    assert np.linalg.norm(result.t) == pytest.approx(1.0)
    assert result.rms_after_px < result.rms_before_px
    assert result.rms_after_px < 0.5  # the noise level (0.3 px per coordinate)
    assert result.kept.sum() >= 0.95 * len(p0)


def test_bundle_adjustment_drops_outliers_and_resists_them():
    p0, p1, R, t, _ = two_view(planar=False, noise_px=0.2, seed=3)
    p1 = p1.copy()
    p1[:20] += np.random.default_rng(4).uniform(-15, 15, (20, 2))  # 8 % gross outliers
    estimate = estimate_pose('E', p0, p1, K)
    X = triangulate_pair(estimate.R, estimate.t, K, p0, p1).points
    result = refine_two_view(estimate.R, estimate.t, X, p0, p1, K, max_reprojection_px=2.0)
    # Two views cannot see an error along the epipolar line, and the adjustment splits an
    # error across it between both images: the outliers that must go are those off their
    # true epipolar line by more than twice the threshold.
    F = fundamental_from_essential(skew(t) @ R, K)
    off_line = np.sqrt(sampson_fundamental(F, p0[:20], p1[:20]) * 2) > 5.0
    assert off_line.sum() >= 8 and not result.kept[:20][off_line].any()
    assert result.kept[20:].mean() > 0.95
    assert translation_chordal_error(t, result.t) < 0.03
    e0, e1 = reprojection_errors(
        result.R, result.t, result.points, K, p0[result.kept], p1[result.kept]
    )
    assert np.all(e0 <= 2.0) and np.all(e1 <= 2.0)


def test_refinement_rejects_inconsistent_input():
    p0, p1, R, t, X = two_view(planar=False)
    with pytest.raises(GeometryError):
        refine_two_view(R, np.zeros(3), X, p0, p1, K)
    with pytest.raises(GeometryError):
        refine_two_view(R, t, X[:10], p0, p1, K)


def test_essential_refit_lowers_the_error_of_the_minimal_sample_solution():
    p0, p1, R, t, _ = two_view(planar=False, noise_px=0.5, seed=5)
    R0, t0 = _perturbed(R, t, seed=6)
    R1, t1 = refine_essential(R0, t0, p0, p1, K)
    assert translation_chordal_error(t, t1) < translation_chordal_error(t, t0)
    assert rotation_angle_deg(R1.T @ R) < rotation_angle_deg(R0.T @ R)


def _problem(n=40, seed=7):
    """A small two-view problem at a perturbed state: (R, t, Q, K, q0, q1)."""
    from initsel_ros.refine import _rotation

    p0, p1, R, t, X = two_view(planar=False, n=n, noise_px=0.5, seed=seed)
    rng = np.random.default_rng(seed)
    p1 = p1.copy()
    p1[:4] += rng.uniform(-8, 8, (4, 2))  # a few outliers: weights below 1
    R0 = _rotation(rng.normal(0, 0.01, 3)) @ R
    t0 = t + rng.normal(0, 0.05, 3)
    t0 /= np.linalg.norm(t0)
    X0 = X * rng.uniform(0.9, 1.1, (n, 1))
    Q = np.vstack([X0[:, 0] / X0[:, 2], X0[:, 1] / X0[:, 2], 1 / X0[:, 2]])
    return R0, t0, Q, K, p0.T.copy(), p1.T.copy()


def _robust_cost(R, t, Q, K, q0, q1):
    from initsel_ros.refine import _linearize, _tangent_basis

    return _linearize(R, t, _tangent_basis(t), Q, K, q0, q1, 1.0).cost


def test_two_view_gradient_is_the_robust_costs_by_finite_differences():
    from initsel_ros.refine import _linearize, _pose_step, _tangent_basis

    R, t, Q, K_, q0, q1 = _problem()
    lin = _linearize(R, t, _tangent_basis(t), Q, K_, q0, q1, 1.0)
    h = 1e-6
    for k in range(5):
        step = np.zeros(5)
        step[k] = h
        up = _robust_cost(*_pose_step(R, t, step), Q, K_, q0, q1)
        down = _robust_cost(*_pose_step(R, t, -step), Q, K_, q0, q1)
        assert (up - down) / (2 * h) == pytest.approx(lin.g_pose[k], rel=1e-4, abs=1e-6)
    for i, j in [(0, 0), (1, 5), (2, 9), (2, 1)]:  # point parameters, outliers included
        dQ = np.zeros_like(Q)
        dQ[i, j] = h
        up = _robust_cost(R, t, Q + dQ, K_, q0, q1)
        down = _robust_cost(R, t, Q - dQ, K_, q0, q1)
        assert (up - down) / (2 * h) == pytest.approx(lin.g_points[i, j], rel=1e-4, abs=1e-6)


def test_schur_step_solves_the_full_damped_normal_equations():
    from initsel_ros.refine import _damped_step, _inverse_3x3, _linearize, _tangent_basis

    R, t, Q, K_, q0, q1 = _problem(n=12)
    lin = _linearize(R, t, _tangent_basis(t), Q, K_, q0, q1, 1.0)
    n = Q.shape[1]
    H = np.zeros((5 + 3 * n, 5 + 3 * n))
    H[:5, :5] = lin.U
    for j in range(n):
        block = slice(5 + 3 * j, 8 + 3 * j)
        H[block, block] = lin.V[:, :, j]
        H[:5, block] = lin.W[:, :, j]
        H[block, :5] = lin.W[:, :, j].T
    g = np.concatenate([lin.g_pose, lin.g_points.T.ravel()])
    damping = 1e-2
    dense = np.linalg.solve(H + damping * np.diag(np.diag(H)), -g)
    dp, dq = _damped_step(lin, damping)
    np.testing.assert_allclose(dp, dense[:5], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(dq.T.ravel(), dense[5:], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(
        np.moveaxis(_inverse_3x3(lin.V), -1, 0),
        np.linalg.inv(np.moveaxis(lin.V, -1, 0)),
        rtol=1e-9,
    )


def test_bundle_adjustment_reaches_the_robust_minimum_a_general_solver_finds():
    from scipy.optimize import least_squares

    from initsel_ros.refine import _rotation, _tangent_basis

    p0, p1, R, t, _ = two_view(planar=False, n=30, noise_px=0.5, seed=11)
    p1 = p1.copy()
    p1[:3] += np.random.default_rng(12).uniform(-10, 10, (3, 2))
    R0, t0 = _perturbed(R, t, seed=13)
    X0 = triangulate_pair(R0, t0, K, p0, p1).points
    ours = refine_two_view(R0, t0, X0, p0, p1, K, max_reprojection_px=np.inf)
    assert ours.converged and ours.iterations <= 15 and ours.kept.all()
    basis = _tangent_basis(t0)

    def unpack(x):
        tk = t0 + basis @ x[3:5]
        return _rotation(x[:3]) @ R0, tk / np.linalg.norm(tk), x[5:].reshape(-1, 3)

    def residuals(x):
        u0, u1 = pixels(*unpack(x))
        return np.concatenate([(u0 - p0).ravel(), (u1 - p1).ravel()])

    # the same robust cost, minimized by scipy's trust-region solver to tight tolerances
    reference = least_squares(
        residuals,
        np.concatenate([np.zeros(5), X0.ravel()]),
        loss='soft_l1',
        f_scale=1.0,
        x_scale='jac',
        ftol=1e-12,
        xtol=1e-12,
        max_nfev=500,
    )
    R_ref, t_ref, X_ref = unpack(reference.x)

    def cost(R_, t_, X_):
        u0, u1 = pixels(R_, t_, X_)
        e = np.concatenate([(u0 - p0).ravel(), (u1 - p1).ravel()])
        return float(np.sum(np.sqrt(1 + e**2) - 1))

    assert translation_chordal_error(t_ref, ours.t) < 2e-3
    assert rotation_angle_deg(R_ref.T @ ours.R) < 5e-3
    # it stops once a step gains less than 1e-4 of the cost: within a few such steps
    assert cost(ours.R, ours.t, ours.points) <= cost(R_ref, t_ref, X_ref) * (1 + 1e-3)


def pixels(R_, t_, X):
    """Pixels of points X (N, 3) in the reference and in the current image."""
    u0 = X @ K.T
    u1 = (X @ R_.T + t_) @ K.T
    return u0[:, :2] / u0[:, 2:], u1[:, :2] / u1[:, 2:]


def test_essential_jacobian_matches_finite_differences():
    from initsel_ros.geometry import homogeneous
    from initsel_ros.refine import _pose_step, _sampson_residuals, essential_jacobian

    p0, p1, R, t, _ = two_view(planar=False, n=50, noise_px=0.5, seed=5)
    R0, t0 = _perturbed(R, t, seed=6)
    x0, x1, K_inv = homogeneous(p0), homogeneous(p1), np.linalg.inv(K)
    r, J = essential_jacobian(R0, t0, x0, x1, K_inv)
    h = 1e-7
    for k in range(5):
        step = np.zeros(5)
        step[k] = h
        up = _sampson_residuals(*_pose_step(R0, t0, step), x0, x1, K_inv)[0]
        down = _sampson_residuals(*_pose_step(R0, t0, -step), x0, x1, K_inv)[0]
        np.testing.assert_allclose((up - down) / (2 * h), J[:, k], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(
        r**2, sampson_fundamental(fundamental_from_essential(skew(t0) @ R0, K), p0, p1), rtol=1e-9
    )


@pytest.mark.parametrize('baseline', [0.08, 0.4])
def test_translation_sigma_predicts_the_spread_of_the_direction_and_shrinks_with_baseline(
    baseline,
):
    # The first-order standard deviation against the actual errors of 16 noisy draws of the
    # same geometry: their RMS angle (two axes) is about 1-2 times the largest axis' sigma.
    errors, sigmas = [], []
    for seed in range(16):
        p0, p1, R, t, X = two_view(planar=False, baseline=baseline, noise_px=0.3, seed=seed)
        result = refine_two_view(R, t, X, p0, p1, K)
        errors.append(np.degrees(2 * np.arcsin(translation_chordal_error(t, result.t) / 2)))
        sigmas.append(result.translation_sigma_deg)
    rms_error, sigma = float(np.sqrt(np.mean(np.square(errors)))), float(np.median(sigmas))
    assert 0.7 * sigma < rms_error < 2.0 * sigma, (rms_error, sigma)  # 1.2 here


def test_translation_sigma_grows_as_the_baseline_shrinks():
    sigmas = []
    for baseline in (0.4, 0.15, 0.05):
        p0, p1, R, t, X = two_view(planar=False, baseline=baseline, noise_px=0.3, seed=2)
        sigmas.append(refine_two_view(R, t, X, p0, p1, K).translation_sigma_deg)
    assert sigmas[0] < sigmas[1] < sigmas[2], sigmas
    assert sigmas[2] > 5 * sigmas[0]


def test_the_damped_step_is_none_when_singular_or_not_finite():
    from initsel_ros.refine import damped_solve

    JtJ = np.diag([4.0, 1.0, 0.0])  # a flat direction is damped by the floored diagonal
    step = damped_solve(JtJ, np.array([4.0, 1.0, 0.0]), 1.0)
    assert step is not None and np.allclose(step, [-0.5, -0.5, 0.0])
    assert damped_solve(JtJ, np.array([np.nan, 1.0, 0.0]), 1.0) is None  # before: a NaN step
    assert damped_solve(np.zeros((2, 2)), np.ones(2), 0.0) is None  # singular
