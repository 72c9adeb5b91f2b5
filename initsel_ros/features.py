"""The 23 summary features of a correspondence set (Troutman & Tuceryan 2021).

Feature order (``FEATURE_NAMES``): count; mean and population standard deviation of the
disparity |p1 - p0|; min and max of x0, y0, x1, y1; range of x0, y0, x1, y1; the
8-bin histogram of motion directions. Directions are measured with image y pointing up,
i.e. the angle of ``(x1 - x0, -(y1 - y0))``, and bin k is centred on ``45 * k`` degrees
(each bin spans +-22.5 degrees); a correspondence that did not move has angle 0 (bin 0).

Two scalings map the raw values into the models' input:

* ``Scaling.PAPER`` (the authors' code, tied to 640x480): count / 300, disparities / 800,
  x / 640, y / 480.
* ``Scaling.RESOLUTION_FREE``: count / 300, x / width, y / height, disparities / image
  diagonal; identical to ``PAPER`` for 640x480 images and meaningful at any resolution.

In both, the 8 direction counts are divided by their Euclidean norm (zeros stay zeros).

Beyond the paper, :func:`extra_features` computes seven optional, resolution-free features
(``EXTRA_FEATURE_NAMES``) that a model file may ask for by name: disparity percentiles, grid
occupancy and entropy of the reference points, and the residuals of affine and homography fits.
The pair table (``initsel dataset``) stores the same values, computed the same way.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from enum import Enum
from functools import lru_cache

import cv2
import numpy as np

from initsel_ros.errors import GeometryError

FEATURE_NAMES: tuple[str, ...] = (
    'count',
    'disparity_mean',
    'disparity_std',
    'x0_min',
    'x0_max',
    'y0_min',
    'y0_max',
    'x1_min',
    'x1_max',
    'y1_min',
    'y1_max',
    'x0_range',
    'y0_range',
    'x1_range',
    'y1_range',
    *(f'direction_{45 * k}' for k in range(8)),
)
N_FEATURES = len(FEATURE_NAMES)

#: Optional features beyond the paper's 23, all resolution-free (see :func:`extra_features`).
EXTRA_FEATURE_NAMES: tuple[str, ...] = (
    'x_disp_p10',  # 10th percentile of disparity / image diagonal
    'x_disp_p50',  # median disparity / image diagonal
    'x_disp_p90',  # 90th percentile of disparity / image diagonal
    'x_grid_occupancy',  # fraction of the 16 cells of a 4x4 grid holding a reference point
    'x_grid_entropy',  # entropy of the reference points over the 4x4 grid / log(16)
    'x_affine_residual',  # RMS residual of a least-squares affine fit p0 -> p1 / diagonal
    'x_homography_residual',  # RMS residual of a least-squares homography p0 -> p1 / diagonal
)
#: Every feature name a model may read: the paper's 23, then the extra ones.
ALL_FEATURE_NAMES: tuple[str, ...] = FEATURE_NAMES + EXTRA_FEATURE_NAMES

COUNT_SCALE = 300.0
_PAPER_WIDTH, _PAPER_HEIGHT, _PAPER_DISPARITY = 640.0, 480.0, 800.0
# Index groups into the feature vector.
_DISPARITY = [1, 2]
_X = [3, 4, 7, 8, 11, 13]
_Y = [5, 6, 9, 10, 12, 14]
_BINS = slice(15, 23)


class Scaling(str, Enum):
    """How raw feature values are normalized before the models see them."""

    PAPER = 'paper'
    RESOLUTION_FREE = 'resolution_free'


def _as_points(p: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(p)
    if arr.size == 0:
        return arr.reshape(0, 2)
    if arr.ndim == 3 and arr.shape[1] == 1:
        arr = arr[:, 0, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise GeometryError(f'{name} must be (N, 2) pixel coordinates, got shape {arr.shape}')
    return arr


def direction_bins(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Counts of motion directions in the 8 bins centred on 0, 45, ..., 315 degrees.

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.

    Returns:
        (8,) float64 counts; image y points down, so the angle uses ``-(y1 - y0)``.
    """
    d = _as_points(p1, 'p1') - _as_points(p0, 'p0')
    angle = np.arctan2(-d[:, 1], d[:, 0])
    bins = np.rint(angle / (np.pi / 4)).astype(np.int64) % 8
    return np.bincount(bins, minlength=8).astype(np.float64)


def raw_features(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Unscaled features of one correspondence set.

    Args:
        p0: (N, 2) reference pixel coordinates (x right, y down).
        p1: (N, 2) current pixel coordinates, row i matching row i of ``p0``.

    Returns:
        (23,) float64 in pixels (count as a number, direction bins as counts).
        An empty set gives all zeros.
    """
    p0 = _as_points(p0, 'p0')
    p1 = _as_points(p1, 'p1')
    if p0.shape != p1.shape:
        raise GeometryError(f'p0 and p1 differ in shape: {p0.shape} vs {p1.shape}')
    out = np.zeros(N_FEATURES)
    n = p0.shape[0]
    if n == 0:
        return out
    # Few, whole-array numpy calls on contiguous rows: this runs once per camera frame.
    rows = np.empty((4, n))  # x0, y0, x1, y1
    rows[:2] = p0.T
    rows[2:] = p1.T
    d = rows[2:] - rows[:2]
    disparity = np.hypot(d[0], d[1])
    lo, hi = rows.min(axis=1), rows.max(axis=1)
    out[0] = n
    mean = disparity.sum() / n
    out[1] = mean
    out[2] = np.sqrt(max(np.dot(disparity, disparity) / n - mean * mean, 0.0))
    out[3:11:2] = lo  # x0min, y0min, x1min, y1min
    out[4:11:2] = hi
    out[11:15] = hi - lo
    angle = np.arctan2(-d[1], d[0])
    bins = np.rint(angle * (4 / np.pi)).astype(np.int64) & 7
    out[_BINS] = np.bincount(bins, minlength=8)
    return out


def feature_divisors(
    width: int = 640, height: int = 480, scaling: Scaling | str = Scaling.RESOLUTION_FREE
) -> np.ndarray:
    """(23,) divisors that scale raw features (the direction bins' are 1: see scale_features)."""
    return _divisors(int(width), int(height), Scaling(scaling))


@lru_cache(maxsize=32)
def _divisors(width: int, height: int, scaling: Scaling) -> np.ndarray:
    if scaling is Scaling.PAPER:
        sx, sy, sd = _PAPER_WIDTH, _PAPER_HEIGHT, _PAPER_DISPARITY
    else:
        if width <= 0 or height <= 0:
            raise GeometryError(f'image size must be positive, got {width}x{height}')
        sx, sy, sd = float(width), float(height), float(np.hypot(width, height))
    div = np.ones(N_FEATURES)
    div[0] = COUNT_SCALE
    div[_DISPARITY] = sd
    div[_X] = sx
    div[_Y] = sy
    div.flags.writeable = False
    return div


def scale_features(
    raw: np.ndarray,
    width: int = 640,
    height: int = 480,
    scaling: Scaling | str = Scaling.RESOLUTION_FREE,
) -> np.ndarray:
    """Scale raw features (see module docstring) for the models.

    Args:
        raw: (..., 23) raw features.
        width: image width, pixels.
        height: image height, pixels.
        scaling: ``Scaling.PAPER`` or ``Scaling.RESOLUTION_FREE``.

    Returns:
        (..., 23) float64 scaled features.
    """
    raw = np.asarray(raw, dtype=np.float64)
    if raw.shape[-1] != N_FEATURES:
        raise GeometryError(f'expected {N_FEATURES} features, got shape {raw.shape}')
    x = raw / feature_divisors(width, height, scaling)
    bins = x[..., _BINS]
    if x.ndim == 1:  # one frame's vector: scalar arithmetic is cheaper than array calls
        bins /= max(float(np.sqrt(bins @ bins)), 1.0)
        return x
    norm = np.sqrt((bins * bins).sum(axis=-1, keepdims=True))
    x[..., _BINS] = bins / np.maximum(norm, 1.0)  # counts: a non-zero norm is at least 1
    return x


def pair_features(
    p0: np.ndarray,
    p1: np.ndarray,
    width: int = 640,
    height: int = 480,
    scaling: Scaling | str = Scaling.RESOLUTION_FREE,
) -> np.ndarray:
    """The 23 scaled features of one (reference, current) correspondence set.

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        width: image width, pixels.
        height: image height, pixels.
        scaling: which normalization to apply.

    Returns:
        (23,) float64.

    Examples:
        >>> p0 = np.array([[100.0, 100.0], [200.0, 300.0]])
        >>> f = pair_features(p0, p0 + [10.0, 0.0], 640, 480)
        >>> float(f[1] * 800), float(f[15])  # mean disparity in pixels, bin 0 (rightwards)
        (10.0, 1.0)
    """
    return scale_features(raw_features(p0, p1), width, height, scaling)


def batch_features(
    pairs: Iterable[tuple[np.ndarray, np.ndarray]],
    width: int = 640,
    height: int = 480,
    scaling: Scaling | str = Scaling.RESOLUTION_FREE,
) -> np.ndarray:
    """Scaled features of many correspondence sets.

    Args:
        pairs: iterable of (p0, p1), each (N_i, 2) pixels.
        width: image width, pixels.
        height: image height, pixels.
        scaling: which normalization to apply.

    Returns:
        (M, 23) float64, one row per pair.
    """
    raw = [raw_features(p0, p1) for p0, p1 in pairs]
    if not raw:
        return np.zeros((0, N_FEATURES))
    return scale_features(np.stack(raw), width, height, scaling)


def mean_disparity(p0: np.ndarray, p1: np.ndarray) -> float:
    """Mean of |p1 - p0| in pixels (0 for an empty set)."""
    d = _as_points(p1, 'p1') - _as_points(p0, 'p0')
    return float(np.hypot(d[:, 0], d[:, 1]).mean()) if len(d) else 0.0


_DISPARITY_PERCENTILES = ('x_disp_p10', 'x_disp_p50', 'x_disp_p90')
_GRID = ('x_grid_occupancy', 'x_grid_entropy')
_GRID_CELLS = 4  # per side


def extra_features(
    p0: np.ndarray,
    p1: np.ndarray,
    width: int,
    height: int,
    names: tuple[str, ...] = EXTRA_FEATURE_NAMES,
) -> np.ndarray:
    """The extra features ``names`` of one correspondence set (only those are computed).

    Values (all resolution-free; ``diag`` is the image diagonal in pixels):

    * ``x_disp_p10/p50/p90``: percentiles of the disparity |p1 - p0| / diag;
    * ``x_grid_occupancy``: fraction of the 16 cells of a 4x4 image grid holding a reference
      point; ``x_grid_entropy``: entropy of the reference points over those cells / log 16;
    * ``x_affine_residual``: RMS residual of the least-squares affine map p0 -> p1 / diag
      (NaN below 3 points);
    * ``x_homography_residual``: RMS residual of the least-squares homography p0 -> p1
      (``cv2.findHomography``, method 0) / diag; near 0 for pure rotation and planes (NaN
      below 4 points or when the fit fails).

    The pair table stores exactly these values (the same operations in the same order).

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        width: image width, pixels.
        height: image height, pixels.
        names: which features, any subset of ``EXTRA_FEATURE_NAMES`` in any order.

    Returns:
        (len(names),) float64 in the order of ``names``; all NaN for an empty set.

    Raises:
        GeometryError: an unknown name, or mismatched point arrays.
    """
    unknown = [n for n in names if n not in EXTRA_FEATURE_NAMES]
    if unknown:
        raise GeometryError(f'unknown extra features {unknown}; known: {EXTRA_FEATURE_NAMES}')
    p0 = np.asarray(_as_points(p0, 'p0'), dtype=np.float64)
    p1 = np.asarray(_as_points(p1, 'p1'), dtype=np.float64)
    if p0.shape != p1.shape:
        raise GeometryError(f'p0 and p1 differ in shape: {p0.shape} vs {p1.shape}')
    values: dict[str, float] = {}
    n = len(p0)
    wanted = set(names)
    if n:
        diag = math.hypot(width, height)
        if wanted.intersection(_DISPARITY_PERCENTILES):
            d = np.hypot(*(p1 - p0).T)
            pct = np.percentile(d, (10, 50, 90)) / diag
            values.update(zip(_DISPARITY_PERCENTILES, pct.tolist(), strict=True))
        if wanted.intersection(_GRID):
            values.update(zip(_GRID, _grid_features(p0, width, height), strict=True))
        if 'x_affine_residual' in wanted and n >= 3:
            q0, q1 = p0 / diag, p1 / diag
            A = np.column_stack((q0, np.ones(n)))
            sol, *_ = np.linalg.lstsq(A, q1, rcond=None)
            values['x_affine_residual'] = math.sqrt(
                float(np.mean(np.sum((q1 - A @ sol) ** 2, axis=1)))
            )
        if 'x_homography_residual' in wanted and n >= 4:
            values['x_homography_residual'] = _homography_residual(p0, p1) / diag
    return np.array([values.get(name, math.nan) for name in names], dtype=np.float64)


def _grid_features(p0: np.ndarray, width: int, height: int) -> tuple[float, float]:
    cells = _GRID_CELLS
    gx = np.clip((p0[:, 0] * (cells / width)).astype(np.int64), 0, cells - 1)
    gy = np.clip((p0[:, 1] * (cells / height)).astype(np.int64), 0, cells - 1)
    counts = np.bincount(gy * cells + gx, minlength=cells * cells)
    occupancy = np.count_nonzero(counts) / float(cells * cells)
    prob = counts[counts > 0] / len(p0)
    entropy = float(-(prob * np.log(prob)).sum() / math.log(cells * cells))
    return occupancy, entropy


def _homography_residual(p0: np.ndarray, p1: np.ndarray) -> float:
    """RMS transfer residual of the least-squares homography, pixels (NaN on failure)."""
    H, _ = cv2.findHomography(p0.reshape(-1, 1, 2), p1.reshape(-1, 1, 2), 0)
    if H is None:
        return math.nan
    proj = cv2.perspectiveTransform(p0.reshape(-1, 1, 2), H).reshape(-1, 2)
    err = np.sum((proj - p1) ** 2, axis=1)
    if not np.all(np.isfinite(err)):
        return math.nan
    return math.sqrt(float(np.mean(err)))
