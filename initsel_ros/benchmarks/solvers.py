"""Yardsticks for the two-view bundle adjustment of :mod:`initsel_ros.refine`, for the bench.

The same problem (a :class:`~initsel_ros.refine.TwoViewProblem`: reference camera at
``[I | 0]``, the current camera's rotation and unit translation, every point; reprojection
errors in both images under the ``soft_l1`` loss at ``huber_px``) solved by two general
solvers, so that the bench times them side by side with the solver of
:func:`initsel_ros.refine.refine_two_view` (:func:`schur_two_view`) on the same pairs:

- :func:`scipy_two_view`: ``scipy.optimize.least_squares`` (trust region reflective, sparse
  Jacobian, ``lsmr``), the solver ``refine_two_view`` used before its Schur-complement
  Levenberg-Marquardt;
- :func:`ceres_two_view`: Ceres through ``pyceres`` (Levenberg-Marquardt, dense Schur
  complement), with one Python cost function per point; None when pyceres is not installed.

Each takes the problem and returns a :class:`~initsel_ros.refine.Refinement`, the points
dropped by the same rule.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

# the record and the problem's pieces of refine_two_view, for the same problem and the same
# points kept
from initsel_ros.refine import (
    Refinement,
    TwoViewProblem,
    _pixels_and_jacobian,
    _tangent_basis,
    solve_two_view,
)

#: As refine_two_view: robust loss scale, reprojection cut-off, evaluation cap.
HUBER_PX = 1.0
MAX_REPROJECTION_PX = 2.0
MAX_EVALUATIONS = 30


def schur_two_view(problem: TwoViewProblem) -> Refinement:
    """:func:`initsel_ros.refine.refine_two_view`'s own solver on ``problem``, at the settings
    above."""
    return solve_two_view(problem, HUBER_PX, MAX_REPROJECTION_PX, MAX_EVALUATIONS)


def scipy_two_view(problem: TwoViewProblem) -> Refinement:
    """The two-view bundle adjustment by ``scipy.optimize.least_squares`` (trf, lsmr).

    On ``problem`` as :func:`initsel_ros.refine.refine_two_view` builds it.
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    R, t_unit, X0 = problem.R, problem.t, problem.points
    p0, p1, K = problem.p0, problem.p1, problem.K
    n = X0.shape[0]
    basis = _tangent_basis(t_unit)

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tk = t_unit + basis @ x[3:5]
        return cv2.Rodrigues(x[:3].reshape(3, 1))[0] @ R, tk / np.linalg.norm(tk), x[5:]

    def residuals(x: np.ndarray) -> np.ndarray:
        Rk, tk, flat = unpack(x)
        X = flat.reshape(n, 3)
        Xc = X @ Rk.T + tk
        z0 = np.where(np.abs(X[:, 2:3]) < 1e-9, 1e-9, X[:, 2:3])
        z1 = np.where(np.abs(Xc[:, 2:3]) < 1e-9, 1e-9, Xc[:, 2:3])
        u0 = (X @ K.T)[:, :2] / z0 - p0
        u1 = (Xc @ K.T)[:, :2] / z1 - p1
        return np.hstack([u0, u1]).ravel()

    rows = np.arange(4 * n).reshape(n, 4)
    jac_rows = np.repeat(rows, 8, axis=1).ravel()
    point_cols = 5 + 3 * np.arange(n)[:, None] + np.arange(3)[None, :]
    cols_per_row = np.hstack([np.broadcast_to(np.arange(5), (n, 5)), point_cols])
    jac_cols = np.repeat(cols_per_row[:, None, :], 4, axis=1).ravel()

    def jacobian(x: np.ndarray) -> csr_matrix:
        Rk, tk, flat = unpack(x)
        X = flat.reshape(n, 3)
        raw = t_unit + basis @ x[3:5]
        Y = X @ Rk.T
        d_proj0 = _pixels_and_jacobian(K, X.T)[1].transpose(2, 0, 1)  # (n, 2, 3)
        d_proj1 = _pixels_and_jacobian(K, (Y + tk).T)[1].transpose(2, 0, 1)
        cross = np.zeros((n, 3, 3))
        cross[:, 0, 1], cross[:, 0, 2] = Y[:, 2], -Y[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = -Y[:, 2], Y[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = Y[:, 1], -Y[:, 0]
        d_t = (np.eye(3) - np.outer(tk, tk)) @ basis / np.linalg.norm(raw)
        block = np.zeros((n, 4, 8))
        block[:, 0:2, 5:8] = d_proj0
        block[:, 2:4, 0:3] = d_proj1 @ cross
        block[:, 2:4, 3:5] = d_proj1 @ d_t
        block[:, 2:4, 5:8] = d_proj1 @ Rk
        return csr_matrix((block.ravel(), (jac_rows, jac_cols)), shape=(4 * n, 5 + 3 * n))

    solution = least_squares(
        residuals,
        np.concatenate([np.zeros(5), X0.ravel()]),
        jac=jacobian,
        method='trf',
        loss='soft_l1',
        f_scale=HUBER_PX,
        x_scale='jac',
        max_nfev=MAX_EVALUATIONS,
        tr_solver='lsmr',
        ftol=1e-4,
        xtol=1e-5,
    )
    Rk, tk, flat = unpack(solution.x)
    return problem.refinement(
        Rk, tk, flat.reshape(n, 3), int(solution.nfev), bool(solution.success), MAX_REPROJECTION_PX
    )


def ceres_available() -> bool:
    """True when pyceres can be imported."""
    try:
        import pyceres  # noqa: F401
    except ImportError:
        return False
    return True


def _ceres_point_cost(pyceres: Any, K: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> Any:
    """Residual block of one point: 4 residuals (both images) over (rvec, t, X)."""

    class PointCost(pyceres.CostFunction):
        def __init__(self) -> None:
            pyceres.CostFunction.__init__(self)
            self.set_num_residuals(4)
            self.set_parameter_block_sizes([3, 3, 3])

        def Evaluate(self, parameters: Any, residuals: Any, jacobians: Any) -> bool:  # noqa: N802
            rvec, t, X = parameters
            R, dR = cv2.Rodrigues(np.asarray(rvec).reshape(3, 1))
            Xc = R @ X + t
            u0, u1 = K @ X, K @ Xc
            if u0[2] <= 1e-9 or u1[2] <= 1e-9:
                return False
            residuals[0:2] = u0[:2] / u0[2] - q0
            residuals[2:4] = u1[:2] / u1[2] - q1
            if jacobians is not None:
                A0 = (K[:2] - np.outer(u0[:2] / u0[2], K[2])) / u0[2]
                D1 = (K[:2] - np.outer(u1[:2] / u1[2], K[2])) / u1[2]
                d_rot = D1 @ (dR.reshape(3, 3, 3) @ X).T  # (2, 3): d(R X)/d rvec_k
                j_rot = np.zeros((4, 3))
                j_rot[2:] = d_rot
                j_t = np.zeros((4, 3))
                j_t[2:] = D1
                j_x = np.vstack([A0, D1 @ R])
                jacobians[0][:] = j_rot.ravel()
                jacobians[1][:] = j_t.ravel()
                jacobians[2][:] = j_x.ravel()
            return True

    return PointCost()


def ceres_two_view(problem: TwoViewProblem) -> Refinement | None:
    """The two-view bundle adjustment by Ceres (pyceres): LM, dense Schur, soft_l1.

    The rotation is a rotation vector, the translation lives on the unit sphere (Ceres's
    ``SphereManifold``); one Python cost function per point. None without pyceres.
    On ``problem`` as :func:`initsel_ros.refine.refine_two_view` builds it.
    """
    try:
        import pyceres
    except ImportError:
        return None
    rvec = cv2.Rodrigues(problem.R)[0].ravel().copy()
    t_param = problem.t.copy()
    X = [x.copy() for x in problem.points]
    ceres_problem = pyceres.Problem()
    loss = pyceres.SoftLOneLoss(HUBER_PX)
    costs = []  # kept alive while the problem is solved
    for i in range(len(X)):
        cost = _ceres_point_cost(pyceres, problem.K, problem.p0[i], problem.p1[i])
        costs.append(cost)
        ceres_problem.add_residual_block(cost, loss, [rvec, t_param, X[i]])
    ceres_problem.set_manifold(t_param, pyceres.SphereManifold(3))
    options = pyceres.SolverOptions()
    options.linear_solver_type = pyceres.LinearSolverType.DENSE_SCHUR
    options.minimizer_progress_to_stdout = False
    options.max_num_iterations = MAX_EVALUATIONS
    options.function_tolerance = 1e-4
    options.parameter_tolerance = 1e-5
    options.num_threads = 1
    summary = pyceres.SolverSummary()
    pyceres.solve(options, ceres_problem, summary)
    Rk = cv2.Rodrigues(rvec.reshape(3, 1))[0]
    tk = t_param / np.linalg.norm(t_param)
    converged = summary.termination_type == pyceres.TerminationType.CONVERGENCE
    evaluations = int(summary.num_successful_steps + summary.num_unsuccessful_steps)
    return problem.refinement(Rk, tk, np.array(X), evaluations, converged, MAX_REPROJECTION_PX)


__all__ = ['ceres_available', 'ceres_two_view', 'schur_two_view', 'scipy_two_view']
