"""Ground-truth labels of a correspondence set: per-method pose errors and the R label.

For each method (F 8-point, E 5-point, H DLT) the pose is estimated from the correspondences
by the fire path's estimators (:func:`initsel_ros.initialize.initialize_pair`, estimates only:
no rotation test, selection or refinement) and compared with ground truth
(:mod:`initsel_ros.metrics`):

- ``E_t``: chordal distance between the unit ground-truth and estimated translation directions;
- ``E_R``: median distance between ground-truth 3D points (the reference pixels back-projected
  with the reference depth) and the triangulated points after a scale alignment, computed with
  both scale rules (``first_two``: the paper's, from the first two points; ``median``: the
  median over points of |P_g,i| / |P_e,i|, distances from the reference camera centre, robust).
  Both are computed on the points the estimator kept (in front of both cameras, reprojection
  and parallax checks: see ``estimate_pose``); labels use ``median`` unless told otherwise.

Label(method) = ``E_t < et_max`` and ``E_R < er_max`` (0.8 and 1 in the paper);
R label = ground-truth baseline <= 0.05 m. A failed estimate (including one that keeps fewer
than 8 points) is label 0 with NaN errors and a reason. Raw errors are kept so
:func:`relabel` can apply other thresholds later.

Without depth (EuRoC, KITTI, TUM folders without depth.txt) there are no ground-truth points,
so E_R is NaN and label(method) = ``E_t < et_max`` and ``rotation error < rotation_error_max_deg``
(the angle of ``R_gt^T R_est``); the row's ``scale_rule`` is ``no_depth``. The rotation check
takes E_R's place of rejecting a wrong decomposition whose translation direction happens to
be close (docs/learning.md gives the threshold's measurement).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import Enum

import cv2
import numpy as np

from initsel_ros import geometry
from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError, GeometryError, InitselError
from initsel_ros.geometry import OFF_PLANE_MIN_PX
from initsel_ros.initialize import ESTIMATES_ONLY, initialize_pair
from initsel_ros.metrics import (
    reconstruction_error,
    relative_pose,
    rotation_error_deg,
    translation_chordal_error,
)
from initsel_ros.names import POSE_METHODS  # the methods that get a pose label, in table order
from initsel_ros.policy import PolicyConfig

LOG = logging.getLogger(__name__)

#: Without depth, the largest rotation error (degrees) of a good pose; see docs/learning.md.
ROTATION_ERROR_MAX_DEG = 5.0

#: ``scale_rule`` of rows labelled without depth (E_R undefined; E_t and rotation error only).
NO_DEPTH = 'no_depth'


class ScaleRule(str, Enum):
    """How E_R removes the monocular scale."""

    FIRST_TWO = 'first_two'
    MEDIAN = 'median'


@dataclass(frozen=True)
class LabelConfig:
    """Label thresholds.

    Attributes:
        et_max: (float)
            A pose is good when E_t is below this (chordal distance, 0..2).
        er_max: (float)
            ... and E_R is below this (metres).
        rotation_baseline_m: (float)
            R label = 1 when the ground-truth baseline is at most this (metres; the paper's
            rule, ``rotation_label='baseline'``).
        rotation_label: (str)
            ``baseline`` (the paper's) or ``parallax``: R label = 1 when the median
            ground-truth parallax angle of the pair's points is under ``rotation_parallax_deg``
            (no usable baseline for *this* scene: 5 cm is a baseline at 1 m and none at 10 m);
            rows without depth (no parallax) keep the baseline rule.
            ``flow``: R label = 1 when the true flow of at least ``dominant_share`` of the
            tracks is the rotation's (``gt_rotation_share``: within the plane tolerance of
            where the rotation alone puts them), so that no usable depth shows in the image,
            whatever the scene's distance; rows without depth keep the baseline rule.
            ``test``: R label = 1 where the node's own rotation test, run on the pair's
            tracks by ``initsel dataset --fire-path``, leaves under ``rotation_test_bar``
            times the noise (``fire_rotation_statistic``): R then stands in for the test
            the fire path runs; not ground truth (the test's errors become R's targets), and
            rows without the column keep the baseline rule.
        rotation_parallax_deg: (float)
            The parallax threshold of ``rotation_label='parallax'``, degrees.
        scale_rule: (ScaleRule)
            Which E_R feeds the labels (both are stored).
        ransac_threshold_px: (float)
            RANSAC threshold given to ``estimate_pose`` (pixels).
        rotation_error_max_deg: (float)
            Without depth: a pose is good when E_t is below ``et_max`` and its rotation error
            (degrees) below this.
        method_label: (str)
            ``good`` (the paper's): a method is labelled 1 when its own pose is good, whatever
            the others do; ``best``: when its pose is good and its E_t is within
            ``best_margin`` of the lowest E_t of the pair's good poses, that is, when it is a
            method the pair should be initialized with (docs/learning.md, section 7: on
            planes a degenerate E still lands within the margin of H about half the time);
            ``determined``: when its pose is good and the scene's geometry determines that
            method's model: for E and F, less than ``dominant_share`` of the tracks lie on
            one homography's flow (``gt_plane_share``: a plane, where the 5-point fit has
            two exact solutions and the 8-point fit a family of them, or a baseline too
            short to show depth, where the translation is not observed: a good pose there is
            luck), for H at least that share. ``dominant_share`` is the fire path's policy
            share, not a bound of the geometry: a fifth of the tracks off the plane already
            fix E. Pairs whose share is unknown (no depth, too few points ahead) keep the
            ``good`` label (:func:`relabel` counts them).
        best_margin: (float)
            The E_t margin of ``method_label='best'`` (the seed map's "chosen method best"
            criterion uses the same 0.05).
        dominant_share: (float)
            The share of the tracks that makes one homography (a plane, or the rotation) the
            scene, for ``method_label='determined'`` and ``rotation_label='flow'``: the
            node's default ``min_homography_plane_share`` (the share H's plane must hold for
            the fire path to take the plane for the scene).
    """

    et_max: float = 0.8
    er_max: float = 1.0
    rotation_baseline_m: float = 0.05
    scale_rule: ScaleRule = ScaleRule.MEDIAN
    ransac_threshold_px: float = 1.0
    rotation_error_max_deg: float = ROTATION_ERROR_MAX_DEG
    rotation_label: str = 'baseline'
    rotation_parallax_deg: float = 1.0
    method_label: str = 'good'
    best_margin: float = 0.05
    dominant_share: float = PolicyConfig().min_homography_plane_share
    rotation_test_bar: float = PolicyConfig().min_rotation_residual_sigma

    def __post_init__(self) -> None:
        if self.rotation_label not in ROTATION_LABELS:
            raise ConfigError(
                f'rotation_label must be one of {", ".join(ROTATION_LABELS)}, '
                f'got {self.rotation_label!r}'
            )
        if self.method_label not in METHOD_LABELS:
            raise ConfigError(
                f'method_label must be one of {", ".join(METHOD_LABELS)}, '
                f'got {self.method_label!r}'
            )
        if not (math.isfinite(self.best_margin) and self.best_margin >= 0.0):
            raise ConfigError(f'best_margin must be a finite number >= 0, got {self.best_margin}')
        if not 0.0 < self.dominant_share <= 1.0:
            raise ConfigError(f'dominant_share must be in (0, 1], got {self.dominant_share}')

    def method_labels(
        self,
        good: Mapping[str, np.ndarray],
        et: Mapping[str, np.ndarray],
        plane_share: np.ndarray | float = math.nan,
    ) -> dict[str, np.ndarray]:
        """The F, E, H labels by ``method_label`` from each method's own verdict ``good``,
        its E_t and the pair's ``gt_plane_share`` (arrays of one length, or scalars), as
        int64 arrays."""
        good = {m: np.asarray(v).astype(bool) for m, v in good.items()}
        if self.method_label == 'good':
            return {m: v.astype(np.int64) for m, v in good.items()}
        if self.method_label == 'determined':
            share = np.asarray(plane_share, dtype=float)
            known = np.isfinite(share)
            with np.errstate(invalid='ignore'):
                planar = known & (share >= self.dominant_share)
            off_plane = known & ~planar
            determined = {m: ~known | (planar if m == 'H' else off_plane) for m in good}
            return {m: (v & determined[m]).astype(np.int64) for m, v in good.items()}
        et = {m: np.asarray(v, dtype=float) for m, v in et.items()}
        # the lowest E_t among the pair's good poses (inf where none is good)
        lowest = np.min(np.stack([np.where(good[m], et[m], np.inf) for m in good]), axis=0)
        with np.errstate(invalid='ignore'):
            return {
                m: (good[m] & (et[m] <= lowest + self.best_margin)).astype(np.int64) for m in good
            }

    def rotation_labels(
        self,
        baseline_m: np.ndarray,
        parallax_deg: np.ndarray,
        rotation_share: np.ndarray | float = math.nan,
        test_statistic: np.ndarray | float = math.nan,
    ) -> np.ndarray:
        """(N,) int64 R labels from the ground-truth baselines, median parallax angles and
        rotation shares (:func:`ground_truth_rotation_share`), or the rotation test's
        statistics (``rotation_label='test'``)."""
        baseline_m = np.asarray(baseline_m, dtype=float)
        by_baseline = baseline_m <= self.rotation_baseline_m
        if self.rotation_label == 'baseline':
            return by_baseline.astype(np.int64)
        if self.rotation_label == 'test':
            statistic = np.asarray(test_statistic, dtype=float)
            with np.errstate(invalid='ignore'):
                by_test = statistic < self.rotation_test_bar
            return np.where(np.isfinite(statistic), by_test, by_baseline).astype(np.int64)
        if self.rotation_label == 'flow':
            share = np.asarray(rotation_share, dtype=float)
            with np.errstate(invalid='ignore'):
                by_flow = share >= self.dominant_share
            return np.where(np.isfinite(share), by_flow, by_baseline).astype(np.int64)
        parallax_deg = np.asarray(parallax_deg, dtype=float)
        with np.errstate(invalid='ignore'):
            by_parallax = parallax_deg < self.rotation_parallax_deg
        return np.where(np.isfinite(parallax_deg), by_parallax, by_baseline).astype(np.int64)


#: The R label rules of :class:`LabelConfig` (``rotation_label``).
ROTATION_LABELS = ('baseline', 'parallax', 'flow', 'test')
#: The F, E, H label rules of :class:`LabelConfig` (``method_label``).
METHOD_LABELS = ('good', 'best', 'determined')


@dataclass(frozen=True)
class MethodOutcome:
    """One method's estimate against ground truth (errors NaN when the estimate failed)."""

    ok: bool
    reason: str
    et: float = math.nan
    er_first_two: float = math.nan
    er_median: float = math.nan
    n_points: int = 0
    n_gt_points: int = 0
    parallax_deg: float = math.nan
    t: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    rotation_error_deg: float = math.nan

    def er(self, rule: ScaleRule) -> float:
        """E_R under ``rule``."""
        return self.er_first_two if rule is ScaleRule.FIRST_TWO else self.er_median

    def label(self, config: LabelConfig) -> int:
        """1 when both errors are below the thresholds (NaN compares false)."""
        er = self.er(config.scale_rule)
        return int(self.ok and self.et < config.et_max and er < config.er_max)

    def label_without_depth(self, config: LabelConfig) -> int:
        """1 when E_t and the rotation error are below their thresholds (no E_R)."""
        return int(
            self.ok
            and self.et < config.et_max
            and self.rotation_error_deg < config.rotation_error_max_deg
        )


@dataclass(frozen=True)
class PairLabels:
    """Ground truth of one pair: baseline, rotation, parallax, R label and per-method
    outcomes (``parallax_deg``: the median angle between the two cameras' rays to the pair's
    ground-truth points, degrees; ``static_share``: :func:`ground_truth_static_share`;
    ``plane_share``: :func:`ground_truth_plane_share`; ``rotation_share``:
    :func:`ground_truth_rotation_share`; all four NaN without depth)."""

    baseline_m: float
    rotation_deg: float
    R_gt: np.ndarray
    t_gt: np.ndarray
    outcomes: dict[str, MethodOutcome]
    config: LabelConfig
    has_depth: bool = True
    parallax_deg: float = math.nan
    static_share: float = math.nan
    plane_share: float = math.nan
    rotation_share: float = math.nan

    @property
    def r_label(self) -> int:
        """The R label by ``config.rotation_label`` (:meth:`LabelConfig.rotation_labels`)."""
        return int(
            self.config.rotation_labels(self.baseline_m, self.parallax_deg, self.rotation_share)
        )

    @property
    def scale_rule(self) -> str:
        """The table's ``scale_rule``: the config's E_R rule, or ``no_depth``."""
        return self.config.scale_rule.value if self.has_depth else NO_DEPTH

    def label(self, method: str) -> int:
        """Label of ``method`` ('F', 'E' or 'H'), by ``config.method_label``."""
        if self.config.method_label == 'good':
            return self._good(method)
        good = {m: self._good(m) for m in self.outcomes}
        et = {m: o.et for m, o in self.outcomes.items()}
        return int(self.config.method_labels(good, et, self.plane_share)[method])

    def _good(self, method: str) -> int:
        outcome = self.outcomes[method]
        if self.has_depth:
            return outcome.label(self.config)
        return outcome.label_without_depth(self.config)


def backproject(pixels: np.ndarray, depth: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, ...]:
    """Back-project pixels with a depth image.

    Args:
        pixels: ((N, 2) array)
            Pixel coordinates (x right, y down); depth is read at the nearest pixel.
        depth: ((H, W) float32)
            Metres, 0 (or non-finite) = no data.
        K: ((3, 3) array)
            Camera matrix of the depth-registered image.

    Returns:
        points: ((N, 3) float64)
            Points in the camera frame, metres (NaN where there is no depth).
        valid: ((N,) bool)
            Where the depth was available.
    """
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    h, w = depth.shape[:2]
    u = np.rint(pixels[:, 0]).astype(np.int64)
    v = np.rint(pixels[:, 1]).astype(np.int64)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    z = np.zeros(len(pixels))
    z[inside] = depth[v[inside], u[inside]]
    valid = inside & np.isfinite(z) & (z > 0)
    z = np.where(valid, z, np.nan)
    x = (pixels[:, 0] - K[0, 2]) / K[0, 0] * z
    y = (pixels[:, 1] - K[1, 2]) / K[1, 1] * z
    return np.column_stack((x, y, z)), valid


def _reconstruction_errors(gt: np.ndarray, est: np.ndarray) -> tuple[float, float]:
    """(first_two, median) E_R for matched (M, 3) arrays; NaN where undefined."""
    out = []
    for rule in (ScaleRule.FIRST_TWO, ScaleRule.MEDIAN):
        try:
            value = float(reconstruction_error(gt, est, scale=rule.value))
        except (GeometryError, ValueError, ZeroDivisionError, FloatingPointError):
            value = math.nan
        out.append(value if math.isfinite(value) else math.nan)
    return out[0], out[1]


def method_outcome(
    est: geometry.PoseEstimate,
    gt_points: np.ndarray,
    gt_valid: np.ndarray,
    t_gt: np.ndarray,
    R_gt: np.ndarray | None = None,
) -> MethodOutcome:
    """Compare one method's estimate with ground truth (see module docstring).

    Args:
        est: the method's estimate on the pair.
        gt_points: (N, 3) ground-truth points of the reference pixels, metres.
        gt_valid: (N,) where ``gt_points`` is known.
        t_gt: (3,) ground-truth translation, reference to current.
        R_gt: (3, 3) ground-truth rotation, reference to current; the rotation error is NaN
            without it.
    """
    if not est.ok:
        return MethodOutcome(False, est.reason or 'failed')
    n_points = len(est.points)
    t_norm = float(np.linalg.norm(t_gt))
    et = float(translation_chordal_error(t_gt, est.t)) if t_norm > 1e-9 else math.nan
    idx = np.asarray(est.indices, dtype=np.int64)
    keep = gt_valid[idx]
    n_gt = int(keep.sum())
    if n_gt >= 2:
        er_first, er_median = _reconstruction_errors(gt_points[idx[keep]], est.points[keep])
    else:
        er_first = er_median = math.nan
    rot_err = rotation_error_deg(R_gt, est.R) if R_gt is not None else math.nan
    return MethodOutcome(
        True,
        est.reason or 'ok',
        et,
        er_first,
        er_median,
        n_points,
        n_gt,
        float(est.parallax_deg),
        np.asarray(est.t, dtype=float).reshape(3),
        float(rot_err),
    )


def estimate_outcomes(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    gt_points: np.ndarray,
    gt_valid: np.ndarray,
    t_gt: np.ndarray,
    config: LabelConfig,
    R_gt: np.ndarray | None = None,
) -> dict[str, MethodOutcome]:
    """Every labelled method estimated on the pair (the fire path's estimators) and judged."""
    fire_config = replace(ESTIMATES_ONLY, ransac_threshold_px=config.ransac_threshold_px)
    try:
        fire = initialize_pair(p0, p1, K, POSE_METHODS, fire_config)
    except InitselError as exc:
        return {m: MethodOutcome(False, f'error: {exc}') for m in POSE_METHODS}
    return {
        e.method.value: method_outcome(e, gt_points, gt_valid, t_gt, R_gt) for e in fire.estimates
    }


def ground_truth_points(
    p0: np.ndarray,
    K: np.ndarray,
    depth_ref: np.ndarray | None,
    depth_pixels: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth 3D points of the reference pixels (the depth half of :func:`label_pair`).

    Args:
        p0: ((N, 2) array)
            Reference pixels (undistorted).
        K: ((3, 3) array)
            Camera matrix.
        depth_ref: ((H, W) float32 or None)
            Reference depth, metres; None gives NaN points, none valid.
        depth_pixels: ((N, 2) array or None)
            Where to read the depth when it is on another pixel grid than ``p0``; default p0.

    Returns:
        points: ((N, 3) float64)
            Reference-frame points, NaN where there is no depth.
        valid: ((N,) bool)
            Where the depth was available.
    """
    if depth_ref is None:
        return np.full((len(p0), 3), np.nan), np.zeros(len(p0), dtype=bool)
    lookup = p0 if depth_pixels is None else depth_pixels
    gt_points, gt_valid = backproject(lookup, depth_ref, K)
    if depth_pixels is not None:  # the ray through the undistorted pixel, at that depth
        rays = np.column_stack(
            ((np.asarray(p0, float) - K[:2, 2]) / np.diag(K)[:2], np.ones(len(p0)))
        )
        gt_points = rays * gt_points[:, 2:3]
    return gt_points, gt_valid


def true_depths(
    pixels: np.ndarray, intrinsics: Intrinsics, depth: np.ndarray | None
) -> np.ndarray:
    """(N,) true depths, metres (NaN where unknown), of the undistorted reference pixels
    ``pixels`` of a camera with lens ``intrinsics``: read on the depth map's own (distorted)
    grid, where the lens puts each pixel's ray (:func:`ground_truth_points`)."""
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    lookup = None
    if intrinsics.has_distortion and len(pixels):
        f, c = np.array([intrinsics.fx, intrinsics.fy]), np.array([intrinsics.cx, intrinsics.cy])
        lookup = intrinsics.project(np.column_stack(((pixels - c) / f, np.ones(len(pixels)))))
    return ground_truth_points(pixels, intrinsics.K, depth, lookup)[0][:, 2]


def label_pair_points(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    gt_points: np.ndarray,
    gt_valid: np.ndarray,
    T_w_ref: np.ndarray,
    T_w_cur: np.ndarray,
    config: LabelConfig | None = None,
    has_depth: bool = True,
) -> PairLabels:
    """Label one pair from precomputed ground-truth points (:func:`ground_truth_points`).

    The same result as :func:`label_pair`; the dataset builder computes the points where the
    depth map is loaded and labels the pairs elsewhere (a worker, a cluster).
    """
    config = config or LabelConfig()
    R_gt, t_gt = relative_pose(np.asarray(T_w_ref), np.asarray(T_w_cur))
    t_gt = np.asarray(t_gt, dtype=float).reshape(3)
    baseline = float(np.linalg.norm(t_gt))
    rotation = float(geometry.rotation_angle_deg(R_gt))
    outcomes = estimate_outcomes(p0, p1, K, gt_points, gt_valid, t_gt, config, R_gt)
    parallax = ground_truth_parallax_deg(gt_points, gt_valid, np.asarray(R_gt), t_gt)
    static = ground_truth_static_share(p1, K, gt_points, gt_valid, np.asarray(R_gt), t_gt)
    plane = ground_truth_plane_share(p0, K, gt_points, gt_valid, np.asarray(R_gt), t_gt)
    rotation_share = ground_truth_rotation_share(
        p0, K, gt_points, gt_valid, np.asarray(R_gt), t_gt
    )
    return PairLabels(
        baseline,
        rotation,
        np.asarray(R_gt),
        t_gt,
        outcomes,
        config,
        has_depth=has_depth,
        parallax_deg=parallax,
        static_share=static,
        plane_share=plane,
        rotation_share=rotation_share,
    )


#: A track agrees with a static scene when its reference point, moved with the camera by the
#: ground truth, projects within this many pixels of where it was tracked (up to one
#: homography, see :func:`ground_truth_static_share`). Measured on rendered training
#: sequences: on the desk at baselines up to 5 cm, 99 % of the tracks land within 1.6-3.3 px
#: (KLT's drift and noise); the tracks on a board or object that moves on its own are off by
#: 30-350 px.
STATIC_TOLERANCE_PX = 5.0


def ground_truth_static_share(
    p1: np.ndarray,
    K: np.ndarray,
    points: np.ndarray,
    valid: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    tolerance_px: float = STATIC_TOLERANCE_PX,
) -> float:
    """Share of a pair's tracks that the ground truth explains as one static scene.

    Each track's ground-truth point (reference depth, camera motion) is projected into the
    current frame; a homography fitted robustly (RANSAC) from those projections to the tracks
    takes up what moves every track together (a focal length off by 10 %, a residual lens
    error), so what is left out is what moves on its own: tracks on an independently moving
    object, slipped tracks.

    Args:
        p1: (N, 2) current pixels of the tracks (undistorted).
        K: (3, 3) camera matrix.
        points: (N, 3) the tracks' reference points in the reference camera frame, metres.
        valid: (N,) where ``points`` is known.
        R, t: the current camera's pose, ``x_cur = R x_ref + t`` (metres).
        tolerance_px: how far from its track a point may land and still count.

    Returns:
        Of the tracks with a finite ground-truth point, the share that projects in front of
        the current camera and, through the homography, within ``tolerance_px`` of the track:
        1 for a static scene; NaN with fewer than 4 such points or no homography.
    """
    known, kept, projected = _moved_projections(K, points, valid, R, t)
    if projected is None:
        return math.nan
    return _homography_share(projected, _tracks(p1, kept), tolerance_px, known)


def _moved_projections(
    K: np.ndarray, points: np.ndarray, valid: np.ndarray, R: np.ndarray, t: np.ndarray
) -> tuple[int, np.ndarray, np.ndarray | None]:
    """Ground-truth points moved with the camera and projected into the current frame.

    Returns how many points are known and finite, ``kept`` (N,) the tracks whose point is
    known, finite and in front of the current camera, and their (M, 1, 2) float32
    projections; None with fewer than 4 kept.
    """
    use = np.asarray(valid, dtype=bool) & np.isfinite(np.asarray(points, dtype=float)).all(axis=1)
    X = np.asarray(points, dtype=float)[use] @ np.asarray(R, dtype=float).T
    X += np.asarray(t, dtype=float).reshape(1, 3)
    kept = use.copy()
    kept[use] = X[:, 2] > 1e-9
    if kept.sum() < 4:
        return int(use.sum()), kept, None
    x = X[kept[use]] @ np.asarray(K, dtype=float).T
    return int(use.sum()), kept, (x[:, :2] / x[:, 2:3]).astype(np.float32).reshape(-1, 1, 2)


def _tracks(pixels: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """The (M, 1, 2) float32 pixels of the ``kept`` tracks."""
    return np.asarray(pixels, dtype=np.float32)[kept].reshape(-1, 1, 2)


def _homography_share(src: np.ndarray, dst: np.ndarray, tolerance_px: float, total: int) -> float:
    """Of ``total`` tracks, the share a homography fitted by RANSAC from ``src`` to ``dst``
    ((M, 1, 2) float32) maps within ``tolerance_px``; NaN when no homography is found."""
    H, inliers = cv2.findHomography(src, dst, cv2.RANSAC, tolerance_px)
    if H is None or inliers is None:
        return math.nan
    return _share_within(src, dst, H, tolerance_px, total)


def _share_within(
    src: np.ndarray, dst: np.ndarray, H: np.ndarray, tolerance_px: float, total: int
) -> float:
    """Of ``total`` tracks, the share the homography ``H`` maps from ``src`` to within
    ``tolerance_px`` of ``dst`` ((M, 1, 2) arrays)."""
    mapped = cv2.perspectiveTransform(src.astype(np.float64), H).reshape(-1, 2)
    error = np.hypot(*(mapped - dst.reshape(-1, 2)).T)
    return float(np.sum(error <= tolerance_px) / total)


#: A track lies on the scene's plane when the homography of the ground-truth flow puts it
#: within this many pixels of where the ground truth does: the fire path's bound for a track
#: off H's plane (:data:`initsel_ros.geometry.OFF_PLANE_MIN_PX`).
FLOW_TOLERANCE_PX = OFF_PLANE_MIN_PX


def ground_truth_plane_share(
    p0: np.ndarray,
    K: np.ndarray,
    points: np.ndarray,
    valid: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    tolerance_px: float = FLOW_TOLERANCE_PX,
) -> float:
    """Share of a pair's tracks whose true flow one homography explains: the largest plane.

    Each track's ground-truth point is moved with the camera and projected into the current
    frame (noise-free flow); a homography fitted robustly (RANSAC) from the reference pixels
    to those projections finds the largest set one plane (or a pure rotation, or a baseline
    too short to show depth) accounts for. 1 for a plane, a pure rotation and a still camera;
    lower as more of the scene shows depth off that plane.

    Args:
        p0: (N, 2) reference pixels of the tracks (undistorted), where ``points`` were read.
        K: (3, 3) camera matrix.
        points: (N, 3) the tracks' reference points in the reference camera frame, metres.
        valid: (N,) where ``points`` is known.
        R, t: the current camera's pose, ``x_cur = R x_ref + t`` (metres).
        tolerance_px: how far from its true projection the homography may put a track.

    Returns:
        Of the tracks whose ground-truth point is known and in front of the current camera,
        the share the homography puts within ``tolerance_px``; NaN with fewer than 4 such
        points or no homography.
    """
    _, kept, projected = _moved_projections(K, points, valid, R, t)
    if projected is None:
        return math.nan
    return _homography_share(_tracks(p0, kept), projected, tolerance_px, len(projected))


def ground_truth_rotation_share(
    p0: np.ndarray,
    K: np.ndarray,
    points: np.ndarray,
    valid: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    tolerance_px: float = FLOW_TOLERANCE_PX,
) -> float:
    """Share of a pair's tracks whose true flow the camera's rotation alone explains.

    Each track's ground-truth point is moved with the camera and projected into the current
    frame; a track counts when the rotation alone (the homography ``K R K^-1``) maps its
    reference pixel within ``tolerance_px`` of that projection, so the translation shows no
    depth there: 1 for a pure rotation and a still camera, lower as the baseline shows
    against the scene's distance.

    Args and the NaN cases as in :func:`ground_truth_plane_share`.
    """
    _, kept, projected = _moved_projections(K, points, valid, R, t)
    if projected is None:
        return math.nan
    K = np.asarray(K, dtype=float)
    rotation = K @ np.asarray(R, dtype=float) @ np.linalg.inv(K)
    return _share_within(_tracks(p0, kept), projected, rotation, tolerance_px, len(projected))


def ground_truth_parallax_deg(
    points: np.ndarray, valid: np.ndarray, R: np.ndarray, t: np.ndarray
) -> float:
    """Median parallax angle, degrees, of ground-truth points seen from two cameras.

    Args:
        points: (N, 3) points in the reference camera frame, metres.
        valid: (N,) where ``points`` is known.
        R, t: the current camera's pose, ``x_cur = R x_ref + t`` (metres).

    Returns:
        The median over the valid points of the angle between the rays from the two camera
        centres (the reference's at the origin, the current's at ``-R^T t``); NaN without any.
    """
    X = np.asarray(points, dtype=float)[np.asarray(valid, dtype=bool)]
    X = X[np.isfinite(X).all(axis=1)]
    if len(X) == 0:
        return math.nan
    return float(np.degrees(np.median(geometry.ray_parallax_rad(X, R, t))))


def label_pair(
    p0: np.ndarray,
    p1: np.ndarray,
    K: np.ndarray,
    depth_ref: np.ndarray | None,
    T_w_ref: np.ndarray,
    T_w_cur: np.ndarray,
    config: LabelConfig | None = None,
    depth_pixels: np.ndarray | None = None,
) -> PairLabels:
    """Label one pair.

    Args:
        p0, p1: ((N, 2) float32)
            Reference and current pixels of the correspondences (undistorted).
        K: ((3, 3) array)
            Camera matrix.
        depth_ref: ((H, W) float32 or None)
            Reference frame depth, metres (0 = no data); None labels without depth (E_R NaN,
            labels from E_t and the rotation error).
        T_w_ref, T_w_cur: ((4, 4) array)
            Ground-truth camera-to-world poses of the two frames.
        depth_pixels: ((N, 2) array or None)
            Where to read ``depth_ref`` for each correspondence, when the depth map is on another
            pixel grid than ``p0`` (the distorted image, when ``p0`` is undistorted); default p0.
    """
    gt_points, gt_valid = ground_truth_points(p0, K, depth_ref, depth_pixels)
    return label_pair_points(
        p0, p1, K, gt_points, gt_valid, T_w_ref, T_w_cur, config, has_depth=depth_ref is not None
    )


def relabel(columns: dict[str, np.ndarray], config: LabelConfig) -> dict[str, np.ndarray]:
    """Recompute ``m_er``, ``m_label``, ``R_label`` and ``scale_rule`` from the raw columns.

    ``columns`` is a table's column mapping; a new mapping is returned (input untouched).
    Rows labelled without depth (``scale_rule == 'no_depth'``) keep that rule and get
    ``ok and E_t < et_max and m_rot_err_deg < rotation_error_max_deg``; a table without the
    ``m_rot_err_deg`` column keeps their stored label as the rotation verdict, so only
    ``et_max`` is re-applied to them (logged once). With ``method_label='best'`` a good pose
    keeps its label only where it is among the pair's best, with ``'determined'`` only where
    ``gt_plane_share`` says the scene fixes the method (:meth:`LabelConfig.method_labels`);
    ``rotation_label='flow'`` reads ``gt_rotation_share``. Rows with depth whose share is
    unknown keep the older rule (logged with their count).
    """
    out = dict(columns)
    rule = ScaleRule(config.scale_rule)
    baseline = np.asarray(columns['gt_baseline_m'], dtype=float)
    stored_rule = np.asarray(
        columns.get('scale_rule', np.full(len(baseline), rule.value)), dtype=object
    ).astype(str)
    no_depth = stored_rule == NO_DEPTH
    warned = False
    good, et_of = {}, {}
    for m in POSE_METHODS:
        er = np.asarray(columns[f'{m}_er_{rule.value}'], dtype=float)
        et = np.asarray(columns[f'{m}_et'], dtype=float)
        ok = np.asarray(columns[f'{m}_ok']).astype(bool)
        with np.errstate(invalid='ignore'):
            label = ok & (et < config.et_max) & (er < config.er_max)
            if np.any(no_depth):
                if f'{m}_rot_err_deg' in columns:
                    rot = np.asarray(columns[f'{m}_rot_err_deg'], dtype=float)
                    rotation_ok = rot < config.rotation_error_max_deg
                else:
                    rotation_ok = np.asarray(columns[f'{m}_label']).astype(bool)
                    if not warned:
                        LOG.warning(
                            'relabel: %d rows labelled without depth and no '
                            'rotation-error column; their stored labels stand as the '
                            'rotation verdict',
                            int(no_depth.sum()),
                        )
                        warned = True
                label = np.where(no_depth, ok & (et < config.et_max) & rotation_ok, label)
        out[f'{m}_er'] = er
        good[m], et_of[m] = label, et
    plane_share = _column_or_nan(columns, 'gt_plane_share', len(baseline))
    rotation_share = _column_or_nan(columns, 'gt_rotation_share', len(baseline))
    statistic = _column_or_nan(columns, 'fire_rotation_statistic', len(baseline))
    for rule_in_use, column, share, older_rule in (
        (config.method_label == 'determined', 'gt_plane_share', plane_share, "the paper's"),
        (config.rotation_label == 'flow', 'gt_rotation_share', rotation_share, 'the 5 cm'),
    ):
        unknown = int(np.sum(np.isnan(share[~no_depth])))
        if rule_in_use and unknown:
            LOG.warning(
                'relabel: %d of the %d rows with depth have no %s (a table written before '
                'the column, or under 4 ground-truth points ahead): they keep %s labels',
                unknown,
                int(np.sum(~no_depth)),
                column,
                older_rule,
            )
    unknown = int(np.sum(np.isnan(statistic)))
    if config.rotation_label == 'test' and unknown:
        LOG.warning(
            'relabel: %d of the %d rows have no fire_rotation_statistic (a table made without '
            'initsel dataset --fire-path, or under 8 tracks): they keep the 5 cm R label',
            unknown,
            len(statistic),
        )
    for m, label in config.method_labels(good, et_of, plane_share).items():
        out[f'{m}_label'] = label
    parallax = _column_or_nan(columns, 'gt_parallax_deg', len(baseline))
    out['R_label'] = config.rotation_labels(baseline, parallax, rotation_share, statistic)
    out['scale_rule'] = np.where(no_depth, NO_DEPTH, rule.value).astype(object)
    return out


def _column_or_nan(columns: Mapping[str, np.ndarray], name: str, n: int) -> np.ndarray:
    """A table's float column ``name``, or ``n`` NaNs for a table written before it."""
    return np.asarray(columns.get(name, np.full(n, np.nan)), dtype=float)


__all__ = [
    'FLOW_TOLERANCE_PX',
    'METHOD_LABELS',
    'NO_DEPTH',
    'POSE_METHODS',
    'ROTATION_ERROR_MAX_DEG',
    'ROTATION_LABELS',
    'STATIC_TOLERANCE_PX',
    'LabelConfig',
    'MethodOutcome',
    'PairLabels',
    'ScaleRule',
    'backproject',
    'estimate_outcomes',
    'ground_truth_parallax_deg',
    'ground_truth_plane_share',
    'ground_truth_points',
    'ground_truth_rotation_share',
    'ground_truth_static_share',
    'label_pair',
    'label_pair_points',
    'method_outcome',
    'relabel',
    'true_depths',
]
