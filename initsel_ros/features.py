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

Beyond the paper, :func:`extra_features` computes optional, resolution-free features
(``EXTRA_FEATURE_NAMES``) that a model file may ask for by name: disparity percentiles, grid
occupancy and entropy of the reference points, the residuals of affine and homography fits,
and moments of the flow and of the points (mean flow, its coherence and spread, the
divergence, curl and shear of the affine fit), most of them from one Gram matrix.
The pair table (``initsel dataset``) stores the same values, computed the same way.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Sequence
from enum import Enum
from functools import lru_cache

import cv2
import numpy as np

from initsel_ros.errors import GeometryError
from initsel_ros.geometry import ROTATION_FOCAL_SCALES

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
    # Moments of one Gram matrix over the points (see extra_features): no pass of their own.
    'x_flow_mean_x',  # mean flow x1 - x0 / diagonal
    'x_flow_mean_y',  # mean flow y1 - y0 / diagonal (image y down)
    'x_flow_coherence',  # |mean flow| / mean |flow|: 1 for a uniform shift, 0 for zoom or roll
    'x_flow_spread',  # RMS deviation of the flow vectors from their mean / diagonal
    'x_point_spread',  # RMS distance of the reference points from their centroid / diagonal
    'x_affine_divergence',  # affine fit p0 -> p1: half its trace - 1 (zoom, forward motion)
    'x_affine_curl',  # affine fit: rotation about the optical axis (radians, small angles)
    'x_affine_deformation',  # affine fit: shear and anisotropic scaling
    'x_homography_dlt_residual',  # RMS algebraic residual of the linear (DLT) homography / diag
    # Needs the camera (input_plan's ``camera``; NaN without it):
    'x_rotation_departure',  # how far the linear homography departs from a rotation K R K^-1
    'x_rotation_departure_focal',  # the same, least over the rotation test's focal scales
)
#: The extra features computed from the Gram matrix of the fit rows, in this order.
MOMENT_FEATURE_NAMES: tuple[str, ...] = EXTRA_FEATURE_NAMES[7:]
#: A pinhole camera as the features need it: (fx, fy, cx, cy), pixels.
Camera = tuple[float, float, float, float]
#: The extra features that need the camera's intrinsics (``input_plan(camera=...)``).
CAMERA_FEATURE_NAMES: tuple[str, ...] = ('x_rotation_departure', 'x_rotation_departure_focal')
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
    if type(p) is np.ndarray and p.ndim == 2 and p.shape[1] == 2:
        return p  # the per-frame case: nothing to check or convert
    arr = np.asarray(p)
    if arr.size == 0:
        return arr.reshape(0, 2)
    if arr.ndim == 3 and arr.shape[1] == 1:
        arr = arr[:, 0, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise GeometryError(f'{name} must be (N, 2) pixel coordinates, got shape {arr.shape}')
    return arr


def raw_features(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Unscaled features of one correspondence set.

    Args:
        p0: (N, 2) reference pixel coordinates (x right, y down).
        p1: (N, 2) current pixel coordinates, row i matching row i of ``p0``.

    Returns:
        (23,) float64 in pixels (count as a number, direction bins as counts).
        An empty set gives all zeros.
    """
    return np.array(MeasuredPair(p0, p1, _RAW_PLAN).features(_RAW_PLAN)[0])


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


def mean_disparity(p0: np.ndarray, p1: np.ndarray) -> float:
    """Mean of |p1 - p0| in pixels (0 for an empty set)."""
    d = _as_points(p1, 'p1') - _as_points(p0, 'p0')
    return float(np.hypot(d[:, 0], d[:, 1]).mean()) if len(d) else 0.0


# ----------------------------------------------------------------------------- one pass
# Every feature comes out of one pass over the points (:class:`MeasuredPair`), shaped for the
# per-frame budget: a few whole-array numpy calls on one (5, N) buffer, scalar arithmetic on
# their small results, and the constants of an image size and a feature list computed once
# (:func:`input_plan`).

_DISPARITY_PERCENTILES = (0.1, 0.5, 0.9)
_GRID_CELLS = 4  # per side
_LOG_GRID = math.log(_GRID_CELLS * _GRID_CELLS)
#: Sector edges of the angle atan2(y1 - y0, x1 - x0) (image y down), radians. The direction
#: with y up is its negation, so an angle at or above j of these edges lies in direction bin
#: (4 - j) mod 8: :data:`_SECTOR_BIN` (both ends, j = 0 and 8, are bin 4).
_DIRECTION_EDGES = (np.arange(8) - 3.5) * (math.pi / 4)
_EXTRA_INDEX = {name: i for i, name in enumerate(EXTRA_FEATURE_NAMES)}
_ROTATION_DEPARTURE = _EXTRA_INDEX['x_rotation_departure']
_FOCAL_DEPARTURE = _EXTRA_INDEX['x_rotation_departure_focal']
_CAMERA_FEATURES = frozenset({_ROTATION_DEPARTURE, _FOCAL_DEPARTURE})
_FOCAL_SCALES = np.array(ROTATION_FOCAL_SCALES)
_ONE = np.ones(1)
_row_minima = np.minimum.reduce  # (ndarray.min without its Python wrapper)
_EYE3 = np.eye(3).ravel()

# The fit rows (see _fit_buffer): X, Y, 1 (reference), u, v (current), |d| (the disparity),
# then rows 6, 7 hold -u (X, Y) and rows 8, 9 -v (X, Y); the DLT reads a = (X, Y, 1), u, v and
# those products. Their Gram matrix comes with a row of zeros first (see MeasuredPair: the fit
# rows shift by one).
_FIT_ROWS = 10
_A, _UA, _VA, _U, _V = (0, 1, 2), (6, 7, 3), (8, 9, 4), 3, 4


def _dlt_terms() -> tuple[np.ndarray, np.ndarray]:
    """Where the homography DLT's bordered normal equations lie in the Gram matrix of the
    fit rows: (81,) and (81,) indices into its flattened (11, 10) form with the zero row
    first (:class:`MeasuredPair`), whose two entries add up to each entry of the 9x9 matrix
    [[A, b], [b^T, y^T y]] (index 0, a zero, where an entry has fewer than two terms).

    With h33 = 1 each point gives ``[X, Y, 1, 0, 0, 0, -uX, -uY] h = u`` and
    ``[0, 0, 0, X, Y, 1, -vX, -vY] h = v`` (y stacks the u and v); the normal equations are
    sums of products of fit rows, i.e. entries of their Gram matrix, each one or a sum of two.
    The fit rows hold -uX ... -vY, so no term needs a sign. Two look-ups and an addition
    assemble it, from a table of 1.3 KB where a (81, 100) map took 65 KB of the cache.
    """
    terms: list[list[int]] = [[] for _ in range(81)]

    def put(r: int, c: int, i: int, j: int) -> None:
        terms[r * 9 + c].append((i + 1) * _FIT_ROWS + j)

    for i in range(3):
        for j in range(3):
            put(i, j, _A[i], _A[j])  # sum a a^T, in the u and the v equations
            put(3 + i, 3 + j, _A[i], _A[j])
        for k in range(2):  # -sum a (uX, uY), -sum a (vX, vY), both sides of the diagonal
            for r, w in ((i, _UA[k]), (3 + i, _VA[k])):
                put(r, 6 + k, _A[i], w)
                put(6 + k, r, _A[i], w)
        for r, w in ((i, _U), (3 + i, _V)):  # b: sum a u, sum a v
            put(r, 8, _A[i], w)
            put(8, r, _A[i], w)
    for k in range(2):
        for m in range(2):  # sum (uX, uY)(uX, uY)^T + (vX, vY)(vX, vY)^T
            put(6 + k, 6 + m, _UA[k], _UA[m])
            put(6 + k, 6 + m, _VA[k], _VA[m])
        for w, z in ((_UA[k], _U), (_VA[k], _V)):  # b: -sum u (uX, uY) - sum v (vX, vY)
            put(6 + k, 8, w, z)
            put(8, 6 + k, w, z)
    put(8, 8, _U, _U)  # y^T y
    put(8, 8, _V, _V)
    assert all(len(t) <= 2 for t in terms)  # (the layout above: one or two terms an entry)
    padded = [[*t, 0, 0][:2] for t in terms]
    return np.array([t[0] for t in padded]), np.array([t[1] for t in padded])


def _gauss_newton_map() -> np.ndarray:
    """(73, 81) map from the Gram matrix of the Jacobian rows to J^T J, J^T r and r^T r.

    The rows at a homography H (see :func:`_homography_residual`) are b = (X, Y, 1) / w, the
    residuals ru, rv, and pu (bX, bY), pv (bX, bY), where w is the third row of H (X, Y, 1)
    and (pu, pv) the transferred point: d(pu) / dh = [b, 0, 0, 0, -pu bX, -pu bY] and
    likewise for pv. Rows 0-63 of the map give J^T J, 64-71 J^T r, 72 r^T r.
    """
    ru, rv, pu, pv = 3, 4, (5, 6), (7, 8)
    out = np.zeros((73, 81))

    def put(r: int, c: int, i: int, j: int, sign: float) -> None:
        out[r * 8 + c, i * 9 + j] += sign

    for i in range(3):
        for j in range(3):
            put(i, j, i, j, 1.0)
            put(3 + i, 3 + j, i, j, 1.0)
        for k in range(2):
            for r, w in ((i, pu[k]), (3 + i, pv[k])):
                put(r, 6 + k, i, w, -1.0)
                put(6 + k, r, i, w, -1.0)
        out[64 + i, i * 9 + ru] = 1.0
        out[64 + 3 + i, i * 9 + rv] = 1.0
    for k in range(2):
        for m in range(2):
            put(6 + k, 6 + m, pu[k], pu[m], 1.0)
            put(6 + k, 6 + m, pv[k], pv[m], 1.0)
        out[64 + 6 + k, pu[k] * 9 + ru] = -1.0
        out[64 + 6 + k, pv[k] * 9 + rv] = -1.0
    out[72, ru * 9 + ru] = out[72, rv * 9 + rv] = 1.0
    return out


_DLT_FIRST, _DLT_SECOND = _dlt_terms()
_LAST_UNIT = np.eye(9)[:, 8:9].copy()  # (9, 1) e_9
_GAUSS_NEWTON_MAP = _gauss_newton_map()


class InputPlan:
    """Constants of the model inputs for one image size, scaling and list of extra features.

    Built once per (width, height, scaling, extra, directions, camera) by :func:`input_plan`;
    read-only.

    Attributes:
        width, height: image size, pixels.
        scaling: the scaling of the 23 features.
        extra: the extra features computed, in this order, after the 23.
        directions: whether the 8 direction bins are computed (else they read 0.0: a model
            set none of whose models reads them skips their pass).
        camera: (fx, fy, cx, cy) pixels, for the features of ``CAMERA_FEATURE_NAMES`` (None:
            they read NaN).
    """

    __slots__ = (
        '_camera_fit',
        '_diag',
        '_divisors',
        '_fit_rows',
        '_grid',
        '_grid_x',
        '_grid_y4',
        '_homography',
        '_percentiles',
        '_pick',
        '_take',
        '_to_fit',
        '_unit',
        'camera',
        'directions',
        'extra',
        'height',
        'scaling',
        'width',
    )

    def __init__(
        self,
        width: int,
        height: int,
        scaling: Scaling,
        extra: tuple[str, ...],
        directions: bool = True,
        camera: Camera | None = None,
    ):
        unknown = [n for n in extra if n not in _EXTRA_INDEX]
        if unknown:
            raise GeometryError(f'unknown extra features {unknown}; known: {EXTRA_FEATURE_NAMES}')
        self.width, self.height, self.scaling, self.extra = width, height, scaling, extra
        self.directions, self.camera = directions, camera
        self._divisors = _divisors(width, height, scaling).tolist()[:15] if width > 0 else []
        self._pick = [_EXTRA_INDEX[n] for n in extra]
        self._take = _taker(self._pick)
        wanted = set(self._pick)
        self._percentiles = bool(wanted & {0, 1, 2})
        self._grid = bool(wanted & {3, 4})
        self._homography = 6 in wanted
        # Rows of the Gram matrix: none; X, Y, 1, u, v and |d| (the affine fit, the moments);
        # with the products uX ... vY (the homographies).
        moments = bool(wanted & set(range(7, len(EXTRA_FEATURE_NAMES))))
        linear = {_EXTRA_INDEX['x_homography_dlt_residual'], *_CAMERA_FEATURES}
        products = self._homography or bool(wanted & linear)
        self._fit_rows = _FIT_ROWS if products else 6 if moments or 5 in wanted else 0
        # The fit's coordinates: pixels minus the image centre, times a power of two (scale);
        # _unit takes fit units back to pixels.
        scale = 2.0 ** -math.frexp(max(width, height, 1))[1]
        self._unit = 1.0 / scale
        self._to_fit = _to_fit_matrix(0.5 * width, 0.5 * height, scale)
        # The camera (fx, fy, cx, cy) in fit coordinates, when a model reads its features.
        self._camera_fit: tuple[float, float, float, float] | None = None
        if camera is not None and wanted & _CAMERA_FEATURES:
            fx, fy, cx, cy = camera  # (input_plan made it four floats)
            if not (math.isfinite(fx + fy + cx + cy) and fx > 0 and fy > 0):
                raise GeometryError(
                    f'a camera (fx, fy, cx, cy) needs finite values and positive focal '
                    f'lengths, got {camera}'
                )
            self._camera_fit = (
                scale * fx,
                scale * fy,
                scale * (cx - 0.5 * width),
                scale * (cy - 0.5 * height),
            )
        if extra and (width <= 0 or height <= 0):
            raise GeometryError(f'image size must be positive, got {width}x{height}')
        self._diag = math.hypot(width, height)
        self._grid_x = _grid_edges(width) if self._grid else None
        # The y edges repeated 4 times: counting the edges at or below y gives 4 * row.
        self._grid_y4 = np.repeat(_grid_edges(height), _GRID_CELLS) if self._grid else None


def _taker(index: list[int]) -> Callable[[list[float]], list[float]]:
    """A function picking ``index`` out of a list, as a list."""
    if not index:
        return lambda values: []
    if len(index) == 1:
        return lambda values: [values[index[0]]]
    pick = operator.itemgetter(*index)
    return lambda values: list(pick(values))


def _to_fit_matrix(cx: float, cy: float, s: float) -> np.ndarray:
    """(26, 5) map from x0, y0, 1, x1, y1 to the rows of :func:`_fit_buffer` it fills: x0, y0,
    x1, y1 and their negatives; -u, -u, -v, -v, dX, dY and X, Y, X, Y, dX, dY (the two factors
    of one product); 0, X, Y, 1, u, v."""
    x0, y0, one, x1, y1 = np.eye(5)
    X, Y = s * x0 - s * cx * one, s * y0 - s * cy * one
    u, v = s * x1 - s * cx * one, s * y1 - s * cy * one
    dX, dY = s * x1 - s * x0, s * y1 - s * y0
    extents = (x0, y0, x1, y1, -x0, -y0, -x1, -y1)
    factors = (-u, -u, -v, -v, dX, dY, X, Y, X, Y, dX, dY)
    return np.array((*extents, *factors, 0.0 * one, X, Y, one, u, v))


def input_plan(
    width: int,
    height: int,
    scaling: Scaling | str = Scaling.RESOLUTION_FREE,
    extra: tuple[str, ...] = (),
    directions: bool = True,
    camera: Camera | None = None,
) -> InputPlan:
    """The (cached) :class:`InputPlan` of an image size, a scaling and extra feature names;
    ``directions=False`` skips the direction bins (they read 0.0); ``camera`` (fx, fy, cx,
    cy) in pixels, any sequence of four numbers, lets ``CAMERA_FEATURE_NAMES`` be computed
    (else they read NaN).

    Raises:
        GeometryError: an unknown extra feature name, a non-positive image size, or a camera
            that is not four finite numbers with positive focal lengths (when a feature reads
            it).
    """
    if camera is not None:
        camera = as_camera(camera)
    return _cached_plan(
        int(width), int(height), Scaling(scaling), tuple(extra), bool(directions), camera
    )


def as_camera(camera: Sequence[float]) -> Camera:
    """(fx, fy, cx, cy) as a tuple of floats (hashable, for the plan caches).

    Raises:
        GeometryError: not four numbers.
    """
    try:
        fx, fy, cx, cy = (float(c) for c in camera)
    except (TypeError, ValueError) as exc:
        raise GeometryError(f'a camera is (fx, fy, cx, cy), got {camera!r}') from exc
    return (fx, fy, cx, cy)


@lru_cache(maxsize=64)
def _cached_plan(
    width: int,
    height: int,
    scaling: Scaling,
    extra: tuple[str, ...],
    directions: bool,
    camera: Camera | None,
) -> InputPlan:
    return InputPlan(width, height, scaling, extra, directions, camera)


_RAW_PLAN = InputPlan(0, 0, Scaling.PAPER, ())


def _grid_edges(size: int) -> np.ndarray:
    """(3,) the smallest coordinates in grid columns 1, 2, 3, exactly as ``x * (4 / size)``
    truncated to an integer decides them (so integer corner positions fall as they did)."""
    k = _GRID_CELLS / size
    edges = []
    for j in range(1, _GRID_CELLS):
        e = j * size / _GRID_CELLS
        while e * k >= j:
            e = float(np.nextafter(e, -np.inf))
        while not e * k >= j:
            e = float(np.nextafter(e, np.inf))
        edges.append(e)
    return np.array(edges)


def model_inputs(p0: np.ndarray, p1: np.ndarray, plan: InputPlan) -> tuple[list[float], float]:
    """The model input vector of one correspondence set, the per-frame path.

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        plan: image size, scaling and extra features (:func:`input_plan`).

    Returns:
        (values, mean_disparity): the 23 scaled features then ``plan.extra`` (NaN where one
        is undefined, e.g. a homography of fewer than 4 points), as floats; and the mean
        disparity, pixels.
    """
    return MeasuredPair(p0, p1, plan).inputs(plan)


def extra_features(
    p0: np.ndarray,
    p1: np.ndarray,
    width: int,
    height: int,
    names: tuple[str, ...] = EXTRA_FEATURE_NAMES,
    camera: Camera | None = None,
) -> np.ndarray:
    """The extra features ``names`` of one correspondence set (only those are computed).

    Values (all resolution-free; ``diag`` is the image diagonal in pixels):

    * ``x_disp_p10/p50/p90``: percentiles of the disparity |p1 - p0| / diag (linear
      interpolation, as ``np.percentile``);
    * ``x_grid_occupancy``: fraction of the 16 cells of a 4x4 image grid holding a reference
      point; ``x_grid_entropy``: entropy of the reference points over those cells / log 16;
    * ``x_affine_residual``: RMS residual of the least-squares affine map p0 -> p1 / diag
      (NaN below 3 points);
    * ``x_homography_residual``: RMS transfer residual of the least-squares homography p0 ->
      p1 (the minimum over H of the mean of |p1 - H(p0)|^2, square-rooted) / diag; near 0 for
      pure rotation and planes (NaN below 4 points or when the fit fails). See
      :func:`_fit_features` for how it is computed;
    * ``x_homography_dlt_residual``: the RMS algebraic residual of the same linear fit
      (h33 = 1, in the fit's normalized coordinates, which makes it a transfer residual
      weighted by each point's projective depth: equal to it for an affine map), in pixels /
      diag; it needs no pass over the points;
    * ``x_flow_mean_x/y``: the mean flow p1 - p0 / diag; ``x_flow_coherence``: |mean flow| /
      mean |flow| (1 for a uniform shift, near 0 for zoom or roll about the optical axis);
      ``x_flow_spread``: RMS deviation of the flow vectors from their mean / diag;
    * ``x_point_spread``: RMS distance of the reference points from their centroid / diag;
    * ``x_affine_divergence``, ``x_affine_curl``, ``x_affine_deformation``: of the linear part
      A of the least-squares affine map (unitless): tr(A) / 2 - 1 (zoom, forward motion),
      (a21 - a12) / 2 (roll) and the magnitude of its shear (NaN for collinear points);
    * ``x_rotation_departure`` (needs ``camera``): the linear homography in the camera's
      normalized coordinates, G = K^-1 H K scaled to det G = 1, against a rotation:
      ||G^T G - I||_F. Zero for any pure rotation (whatever the scene); about sqrt(2) |t| / d
      for a plane at distance d slid along it by t (its flow stays close to a rotation's, but
      not this) and 1.6 |t| / d moving toward it; unitless, and the same at any image size and
      field of view. NaN without a camera, below 4 points or when the fit fails;
    * ``x_rotation_departure_focal`` (needs ``camera``): the least of the same over the
      focal lengths the rotation test allows (``geometry.ROTATION_FOCAL_SCALES``, 0.87-1.15
      of the stated one): a 5-degree pan through a focal length 10 % off departs from a
      rotation by 0.024, as far as a slide along a wall by a sixtieth of its distance does,
      and by this measure by a tenth of that; the slide's own departure shrinks by at most
      1.15, and an arc that turns to keep the wall centred keeps it too. A camera that turns
      toward the side it slides to by about as much (in radians, against |t| / d) reads as
      such a pan: to first order, it is one.

    All but the percentiles and the grid come from one Gram matrix of a few rows over the
    points. The pair table stores exactly these values.

    Args:
        p0: (N, 2) reference pixels.
        p1: (N, 2) current pixels.
        width: image width, pixels.
        height: image height, pixels.
        names: which features, any subset of ``EXTRA_FEATURE_NAMES`` in any order.
        camera: (fx, fy, cx, cy), pixels, for the ``x_rotation_departure*`` features.

    Returns:
        (len(names),) float64 in the order of ``names``; all NaN for an empty set.

    Raises:
        GeometryError: an unknown name, mismatched point arrays, or a bad camera
            (:func:`input_plan`).
    """
    plan = input_plan(width, height, Scaling.RESOLUTION_FREE, tuple(names), camera=camera)
    return np.array(MeasuredPair(p0, p1, plan).features(plan)[1], dtype=np.float64)


class MeasuredPair:
    """One correspondence set measured in one pass, for the input vectors of one or more
    plans of one image size (:meth:`inputs`).

    The points go into one (5, N) float64 buffer, rows x0, y0, 1, x1, y1. A plan with fit
    features maps it once into the fit rows (:func:`_fit_buffer`), whose Gram matrix also
    gives the disparity's mean and spread. A later plan with the same fit rows reuses the
    buffer, the Gram matrix and the linear homography (a model file's referee reads other
    features of the same pass); one with other fit rows measures afresh, so every plan's
    values are the ones it would get alone. Every value equals the straightforward numpy
    computation (``raw_features`` of earlier releases, ``np.percentile``) to the last bit,
    except the disparity's mean and standard deviation where a fit is made, the grid entropy
    and the fit features (to about 1e-15, 1e-15, 1e-6 and 1e-3 relative at worst).
    """

    __slots__ = (
        '_dlt',
        '_extents',
        'd',
        'disparity',
        'finite',
        'fit',
        'fit_rows',
        'gram',
        'n',
        'p0',
        'p1',
        'rows',
        'size',
        'sums',
        'unit',
    )

    def __init__(self, p0: np.ndarray, p1: np.ndarray, plan: InputPlan):
        p0 = _as_points(p0, 'p0')
        p1 = _as_points(p1, 'p1')
        if p0.shape != p1.shape:
            raise GeometryError(f'p0 and p1 differ in shape: {p0.shape} vs {p1.shape}')
        self.p0, self.p1, self.size = p0, p1, (plan.width, plan.height)
        self.fit_rows, self._dlt = plan._fit_rows, None
        n = self.n = p0.shape[0]
        if n == 0:
            return
        rows = self.rows = np.empty((5, n))
        rows[0:2] = p0.T
        rows[2] = 1.0
        rows[3:5] = p1.T
        fit = None
        if plan._fit_rows and n >= 3:
            extents, d, padded = _fit_buffer(rows, plan)
            fit = padded[1:]
            m = _row_minima(extents, 1).tolist()  # x0, y0, x1, y1, then minus their maxima
            lo, hi = [m[0], m[1], 1.0, m[2], m[3]], [-m[4], -m[5], 1.0, -m[6], -m[7]]
            if not math.isfinite(sum(m)):  # a NaN taints every fit row: measure one by one
                fit = None
        if fit is not None:
            self.finite = True
            # The Gram matrix with a zero row first: two operands at different addresses make
            # numpy call the general product, at 0.6x the cost of the symmetric one it calls
            # for fit @ fit.T (a few hundred points; 0.8x at 50).
            gram = self.gram = padded @ fit.T
            sums = self.sums = gram[1:7, 0:6].tolist()  # X, Y, 1, u, v, |d| against each other
            disparity, unit = fit[5], plan._unit  # fit units: pixels / plan._unit
            mean = sums[5][2] * unit / n
            std = math.sqrt(max(sums[5][5] * unit * unit / n - mean * mean, 0.0))
        else:
            lo = rows.min(axis=1).tolist()  # x0, y0, 1, x1, y1
            hi = rows.max(axis=1).tolist()
            self.finite = math.isfinite(sum(lo) + sum(hi))  # else every extra feature is NaN
            d = rows[3:5] - rows[0:2]
            disparity, unit = np.hypot(d[0], d[1]), 1.0
            mean = float(disparity.sum()) / n
            std = math.sqrt(max(float(disparity @ disparity) / n - mean * mean, 0.0))
        self.fit, self.d, self.disparity, self.unit = fit, d, disparity, unit
        extents = [float(n), mean, std, lo[0], hi[0], lo[1], hi[1], lo[3], hi[3], lo[4], hi[4]]
        extents += [hi[0] - lo[0], hi[1] - lo[1], hi[3] - lo[3], hi[4] - lo[4]]
        self._extents = extents

    def _same_pass(self, plan: InputPlan) -> bool:
        return plan._fit_rows == self.fit_rows and (plan.width, plan.height) == self.size

    def inputs(self, plan: InputPlan) -> tuple[list[float], float]:
        """:func:`model_inputs` of this set under ``plan`` (from this pass when its fit rows
        and image size are the plan's, else from a pass of its own)."""
        if not self._same_pass(plan):
            return MeasuredPair(self.p0, self.p1, plan).inputs(plan)
        raw, extra = self.features(plan)
        values = list(map(operator.truediv, raw[:15], plan._divisors))
        if plan.directions:
            bins = raw[15:]
            norm = max(math.sqrt(sum(map(operator.mul, bins, bins))), 1.0)  # non-zero: >= 1
            values += [c / norm for c in bins]
        else:
            values += _NO_DIRECTIONS
        values += extra
        return values, raw[1]

    def features(self, plan: InputPlan) -> tuple[list[float], list[float]]:
        """The 23 raw features and the plan's extra features, as floats (the plan's fit rows
        and image size must be this pass's: see :meth:`inputs`)."""
        n = self.n
        if n == 0:
            return [0.0] * N_FEATURES, [math.nan] * len(plan._pick)
        raw = list(self._extents)
        if plan.directions:  # (angles of the fit's d: the same, scaled by a power of two)
            d = self.d
            sector = np.bincount(
                _DIRECTION_EDGES.searchsorted(np.arctan2(d[1], d[0]), 'right'), minlength=9
            ).tolist()
            raw += [sector[4], sector[3], sector[2], sector[1], sector[0] + sector[8]]
            raw += sector[7:4:-1]
        else:
            raw += _NO_DIRECTIONS
        if not plan._pick:
            return raw, []
        values = [math.nan] * len(EXTRA_FEATURE_NAMES)
        if self.finite:
            diag, unit = plan._diag, self.unit
            if plan._percentiles:
                values[0:3] = [
                    q * unit / diag  # (q * unit: exact, a power of two)
                    for q in _linear_quantiles(np.sort(self.disparity), _DISPARITY_PERCENTILES)
                ]
            if plan._grid:
                rows = self.rows
                cells = np.bincount(
                    plan._grid_x.searchsorted(rows[0], 'right')
                    + plan._grid_y4.searchsorted(rows[1], 'right'),
                    minlength=_GRID_CELLS * _GRID_CELLS,
                ).tolist()
                # entropy = -sum (c / n) log(c / n) = log n - sum c log c / n
                c_log_c = sum(map(_c_log_c, cells)) if n < len(_C_LOG_C) else _sum_c_log_c(cells)
                values[3] = (len(cells) - cells.count(0)) / float(len(cells))
                values[4] = (math.log(n) - c_log_c / n) / _LOG_GRID
            if self.fit is not None:
                _fit_features(self, plan, values)
        return raw, plan._take(values)


_NO_DIRECTIONS = [0.0] * 8


def _sum_c_log_c(counts: list[int]) -> float:
    return sum(c * math.log(c) for c in counts if c)


#: c log c for the cell counts of up to 4095 points, looked up rather than computed.
_C_LOG_C = [0.0, *(c * math.log(c) for c in range(1, 4096))]
_c_log_c = _C_LOG_C.__getitem__


def _linear_quantiles(ordered: np.ndarray, qs: tuple[float, ...]) -> list[float]:
    """``np.percentile(x, 100 * q)`` for each q of the sorted values ``ordered``: the same
    arithmetic (numpy's linear method), on two looked-up neighbours per q."""
    index, weight = _quantile_positions(len(ordered), qs)
    v = ordered.take(index).tolist()
    out = []
    for k, t in enumerate(weight):
        a, b = v[2 * k], v[2 * k + 1]
        diff = b - a
        out.append(b - diff * (1 - t) if t >= 0.5 else a + diff * t)  # t = 0 at the top
    return out


@lru_cache(maxsize=1024)
def _quantile_positions(n: int, qs: tuple[float, ...]) -> tuple[list[int], list[float]]:
    """Neighbour indices (2 per q) and interpolation weights of numpy's linear quantiles."""
    index, weight = [], []
    for q in qs:
        virtual = (n - 1) * q
        if virtual >= n - 1:  # numpy takes the last value
            index += [n - 1, n - 1]
            weight.append(0.0)
            continue
        below = math.floor(virtual)
        index += [below, below + 1]
        weight.append(virtual - below)
    return index, weight


def _fit_buffer(rows: np.ndarray, plan: InputPlan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The extents, the disparity and the fit rows of the points ``rows`` (x0, y0, 1, x1, y1).

    One matrix product fills a (33, N) buffer: (8, N) x0, y0, x1, y1 and their negatives
    (whose minima are the extents, exactly), the two factors (-u, -u, -v, -v, dX, dY) and (X,
    Y, X, Y, dX, dY), and a row of zeros followed by X, Y, 1, u, v. One product of the factors
    gives -uX, -uY, -vX, -vY (for the homographies) and dX^2, dY^2, from which |d| follows, so
    the fit rows X, Y, 1, u, v, |d| and -uX, -uY, -vX, -vY lie one after the other, after the
    zero row (its Gram matrix entries are the zeros of the DLT's system: :func:`_dlt_terms`).

    X, Y (reference) and u, v (current) are pixels minus the image centre times a power of
    two near 1 / the image size, ``1 / plan._unit`` (for conditioning; the disparity
    d = (u - X, v - Y) = (dX, dY) and its norm |d| are then the pixel values times it).

    Returns:
        (8, N) extent rows, (2, N) d, (1 + plan._fit_rows, N) the zero row and the fit rows.
    """
    n = rows.shape[1]
    buffer = np.empty((33, n))
    np.matmul(plan._to_fit, rows, out=buffer[0:26])
    if plan._fit_rows > 6:  # -uX, -uY, -vX, -vY and the squares of d
        np.multiply(buffer[8:14], buffer[14:20], out=buffer[27:33])
    else:
        np.multiply(buffer[12:14], buffer[18:20], out=buffer[31:33])
    norm = buffer[26]
    np.add(buffer[31], buffer[32], out=norm)
    np.sqrt(norm, out=norm)
    return buffer[0:8], buffer[12:14], buffer[20 : 21 + plan._fit_rows]


def _fit_features(pair: MeasuredPair, plan: InputPlan, values: list[float]) -> None:
    """The extra features of the Gram matrix of the fit rows, in pixels (or unitless), into
    ``values`` (indexed as ``EXTRA_FEATURE_NAMES``; at least 3 points).

    The pair's Gram matrix of the fit rows (:func:`_fit_buffer`) gives every sum the
    features need:

    * affine: closed form from the covariances (``np.linalg.lstsq`` when the reference points
      are collinear), its residual and the divergence, curl and deformation of its linear part;
    * the flow and point moments: sums of the rows and of their squares;
    * the linear homography (DLT, h33 = 1): the normal equations are entries of the Gram
      matrix; its algebraic residual ``y^T y - b^T h`` needs no pass over the points, and the
      least-squares transfer residual (``x_homography_residual``, only when the plan has it)
      one Gauss-Newton step (:func:`_homography_residual`).
    """
    fit, n = pair.fit, pair.n
    unit = plan._unit / plan._diag  # fit units -> pixels / image diagonal
    sums = pair.sums
    (xx, xy, x1, xu, xv, _), (_, yy, y1, yu, yv, _), (*_, u1, v1, d1) = sums[0:3]
    uu, vv = sums[3][3], sums[4][4]
    # Covariances times n^2 (a common factor that cancels in the ratios below).
    sxx, sxy, syy = n * xx - x1 * x1, n * xy - x1 * y1, n * yy - y1 * y1
    det = sxx * syy - sxy * sxy
    if det > 1e-12 * sxx * syy:
        # (u, v) = A (X, Y) + t: the rows of A from the covariances of u and v with X and Y.
        bx, by = n * xu - x1 * u1, n * yu - y1 * u1
        cx, cy = n * xv - x1 * v1, n * yv - y1 * v1
        a11, a12 = (syy * bx - sxy * by) / det, (sxx * by - sxy * bx) / det
        a21, a22 = (syy * cx - sxy * cy) / det, (sxx * cy - sxy * cx) / det
        ss = (n * uu - u1 * u1 - a11 * bx - a12 * by) + (n * vv - v1 * v1 - a21 * cx - a22 * cy)
        values[5] = 0.0 if n == 3 else math.sqrt(max(ss, 0.0)) * unit / n
        values[12] = 0.5 * (a11 + a22) - 1.0
        values[13] = 0.5 * (a21 - a12)
        values[14] = math.hypot(0.5 * (a11 - a22), 0.5 * (a12 + a21))
    else:
        values[5] = _affine_residual_lstsq(pair.p0, pair.p1) / plan._diag
    mdx, mdy = (u1 - x1) / n, (v1 - y1) / n
    values[7], values[8] = mdx * unit, mdy * unit
    values[9] = math.hypot(mdx, mdy) * n / d1 if d1 > 0 else 0.0
    var_d = (uu - 2.0 * xu + xx + vv - 2.0 * yv + yy) / n - mdx * mdx - mdy * mdy
    values[10] = math.sqrt(max(var_d, 0.0)) * unit
    values[11] = math.sqrt(max(sxx + syy, 0.0)) * unit / n
    if plan._fit_rows > 6 and n >= 4:
        if pair._dlt is None:  # (False: no solution)
            pair._dlt = _linear_homography(pair.gram) or False
        solution = pair._dlt
        if solution:
            ss, vector, factor = solution
            values[15] = math.sqrt(ss / n) * unit if math.isfinite(ss) else math.nan
            if plan._homography:
                values[6] = _homography_residual(fit[0:5], vector * factor) * unit
            if plan._camera_fit is not None:
                g = _rotation_map((vector * factor).ravel().tolist(), plan._camera_fit)
                values[_ROTATION_DEPARTURE] = _departure(g)
                if _FOCAL_DEPARTURE in plan._pick:
                    values[_FOCAL_DEPARTURE] = _least_focal_departure(g)


def _linear_homography(gram: np.ndarray) -> tuple[float, np.ndarray, float] | None:
    """The least-squares DLT homography (h33 = 1) of the fit rows whose Gram matrix is
    ``gram`` ((11, 10): the zero row, then the fit rows, against the fit rows; see
    :class:`MeasuredPair`): (its algebraic sum of squares s, v, c) with h = c v (8, 1), or
    None when A is singular.

    One solve of the bordered system M = [[A, b], [b^T, y^T y]] for its last column of the
    inverse gives both: that column is [-h / s; 1 / s] with s = y^T y - b^T h, the residual
    (the Schur complement of A), so v is its top and c = -s (the students read only s: the
    product is left to the caller that needs h). Where M is singular to working precision (a
    homography that fits exactly, s ~ 0), A h = b is solved on its own (v = h, c = 1).
    """
    # (flat indices into the (11, 10) Gram matrix of a plan with all 10 fit rows, the only
    # one that reaches here: see _fit_features)
    system = (gram.take(_DLT_FIRST) + gram.take(_DLT_SECOND)).reshape(9, 9)
    ok, column = cv2.solve(system, _LAST_UNIT)
    if ok and column[8, 0] > 0.0:
        ss = 1.0 / float(column[8, 0])
        return ss, column[0:8], -ss
    ok, h = cv2.solve(system[0:8, 0:8], system[0:8, 8:9])
    if not ok:
        return None
    return max(float(system[8, 8] - system[8, 0:8] @ h[:, 0]), 0.0), h, 1.0


def _rotation_map(
    h: list[float], camera_fit: tuple[float, float, float, float]
) -> tuple[tuple[float, ...], ...] | None:
    """The rows of G = K^-1 H K / cbrt(det H) for the homography ``h`` (its 8 entries, h33 =
    1) of the fit coordinates, with ``camera_fit`` = (fx, fy, cx, cy) of K in those
    coordinates: a rotation for any pure rotation; None for a singular H. Written out on
    floats: a 3 x 3 product in numpy costs more than all of it."""
    a, b, p, q = camera_fit
    h0, h1, h2, h3, h4, h5, h6, h7 = h
    det = h0 * (h4 - h5 * h7) - h1 * (h3 - h5 * h6) + h2 * (h3 * h7 - h4 * h6)
    if not (math.isfinite(det) and det != 0.0):
        return None
    # H K, then K^-1 (H K): rows (r0 - p r2) / a, (r1 - q r2) / b, r2
    c2 = h6 * p + h7 * q + 1.0
    r2 = (h6 * a, h7 * b, c2)
    r0 = (h0 * a - p * r2[0], h1 * b - p * r2[1], h0 * p + h1 * q + h2 - p * c2)
    r1 = (h3 * a - q * r2[0], h4 * b - q * r2[1], h3 * p + h4 * q + h5 - q * c2)
    s = math.copysign(abs(det) ** (-1.0 / 3.0), det)
    return (
        tuple(v * s / a for v in r0),
        tuple(v * s / b for v in r1),
        tuple(v * s for v in r2),
    )


def _departure(g: tuple[tuple[float, ...], ...] | None) -> float:
    """||G^T G - I||_F of :func:`_rotation_map`'s G: 0 for a rotation; NaN for None."""
    if g is None:
        return math.nan
    g0, g1, g2 = g
    total = 0.0
    for i in range(3):
        for j in range(i, 3):
            m = g0[i] * g0[j] + g1[i] * g1[j] + g2[i] * g2[j] - (i == j)
            total += m * m if i == j else 2.0 * m * m
    return math.sqrt(total)


def _least_focal_departure(g: tuple[tuple[float, ...], ...] | None) -> float:
    """The least :func:`_departure` of S^-1 G S over S = diag(s, s, 1), s in the rotation
    test's focal scales (``geometry.ROTATION_FOCAL_SCALES``): the focal length the camera
    states may be that far off, and a pan through the wrong one is G = S R S^-1, a rotation
    again at the right s; a slide along a plane keeps its departure (divided by s). NaN for
    None."""
    if g is None:
        return math.nan
    G = np.array(g)
    scaled = np.broadcast_to(G, (len(_FOCAL_SCALES), 3, 3)).copy()
    scaled[:, 0:2, 2] /= _FOCAL_SCALES[:, None]
    scaled[:, 2, 0:2] *= _FOCAL_SCALES[:, None]
    gram = np.einsum('kji,kjl->kil', scaled, scaled) - np.eye(3)
    return float(np.sqrt((gram * gram).sum(axis=(1, 2))).min())


def _homography_residual(fit: np.ndarray, h: np.ndarray) -> float:
    """RMS transfer residual of the least-squares homography, in fit units; NaN on failure.

    The linear (DLT) fit with h33 = 1 gives a start H0; one Gauss-Newton step on the transfer
    error sum_i |(u, v)_i - H(X, Y)_i|^2 at H0 then predicts its minimum,
    ``r^T r - g^T (J^T J)^-1 g`` (the step itself is not applied). On the 2,010 pairs of the
    rendered test sequences this equals the residual of ``cv2.findHomography(p0, p1, 0)``
    (a DLT refined by Levenberg-Marquardt) to 1e-7 relative for the median pair and 1e-3 at
    worst, and no model decision of the shipped file changes; it costs a tenth of it.
    """
    n = fit.shape[1]
    # One product gives w, then X, Y, 1 and H's first two rows applied to them (rows w, a, q).
    jac = np.empty((10, n))
    np.matmul(
        np.concatenate((h[6:8, 0], _ONE, _EYE3, h[0:6, 0])).reshape(6, 3), fit[0:3], out=jac[0:6]
    )
    np.divide(jac[1:6], jac[0], out=jac[1:6])  # b = (X, Y, 1) / w, then (pu, pv)
    np.multiply(jac[4:6, None], jac[None, 1:3], out=jac[6:10].reshape(2, 2, n))
    np.subtract(jac[4:6], fit[3:5], out=jac[4:6])  # residuals
    normal = _GAUSS_NEWTON_MAP @ (jac[1:10] @ jac[1:10].T).ravel()
    g = normal[64:72].reshape(8, 1)
    ok, step = cv2.solve(normal[:64].reshape(8, 8), g)
    if not ok:
        return math.nan
    ss = float(normal[72]) - float(g.ravel() @ step.ravel())
    return math.sqrt(max(ss, 0.0) / n) if math.isfinite(ss) else math.nan


def _affine_residual_lstsq(p0: np.ndarray, p1: np.ndarray) -> float:
    """RMS residual, pixels, of the affine map p0 -> p1 by ``np.linalg.lstsq`` (any rank)."""
    q0 = np.asarray(p0, dtype=np.float64)
    q1 = np.asarray(p1, dtype=np.float64)
    A = np.column_stack((q0, np.ones(len(q0))))
    sol, *_ = np.linalg.lstsq(A, q1, rcond=None)
    return math.sqrt(float(np.mean(np.sum((q1 - A @ sol) ** 2, axis=1))))
