"""KLT tracking from a reference frame: Shi-Tomasi corners, pyramidal Lucas-Kanade.

Tracks are carried frame to frame (previous -> current) so that they survive large total
motion, with a forward-backward check that drops a track when tracking the current point
back to the previous frame misses by more than ``fb_max_error_px``.

Carried from frame to frame, a track's small per-step errors add up (a random walk, and on
weakly textured or magnified patches a drift): on a poster 1.2 m away the chained tracks were
0.9-2.8 px off the truth at the 90th percentile after 9-30 frames, against 0.2-0.3 px for the
same points measured against the reference directly, and a homography from them had E_t
0.07-0.14 instead of 0.002-0.007. :meth:`KltTracker.anchored` re-measures the current points
against the reference frame, starting from the chained ones: what geometry is estimated from
(the fire path, the verification) reads those; the per-frame decision reads the chained ones.

Lucas-Kanade assumes brightness constancy, which auto-exposure and gain changes break: the
tracks drift. ``TrackerConfig.photometric`` compensates (see :class:`Photometric`):
``gain_bias`` maps every frame onto the previous one's brightness with a gain and a bias fitted
to the tracked patches, ``zncc`` tracks on locally zero-mean, unit-variance images.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from initsel_ros.errors import ImageConversionError


class Photometric(str, Enum):
    """Compensation of brightness changes between frames.

    - ``none``: plain KLT on the frames.
    - ``gain_bias``: after a first KLT pass, a gain and a bias ``prev ~ a * cur + b`` are fitted
      (a line with outlier rejection) to the mean intensities of the tracked patches (patches
      with saturated or black pixels left out; the previous frame's are kept from its own step
      when it was not mapped); when they change the frame's brightness by more than
      ``photometric_min_change`` grey levels, the frame is mapped by them and tracked again,
      starting from the first pass's result. A first pass that loses a quarter of the tracks
      or more (a step of exposure or gain can lose all of them) first tries a mapping fitted
      to the whole frames' intensity quantiles (:func:`fit_gain_bias_global`). Each frame is
      so kept at the reference's brightness; frames without a brightness change are tracked
      exactly as with ``none`` (and a first look at the means' mean and spread skips the
      robust fit on them).
    - ``zncc``: both frames are locally normalized (zero mean, unit variance over the KLT
      window) before tracking, which removes any local gain and bias.
    """

    NONE = 'none'
    GAIN_BIAS = 'gain_bias'
    ZNCC = 'zncc'


@dataclass(frozen=True)
class TrackerConfig:
    """Feature detection and tracking settings.

    Attributes:
        max_features: feature budget per reference frame.
        grid_cols: columns of the grid that spreads features over the image.
        grid_rows: rows of that grid.
        quality_level: Shi-Tomasi quality relative to the strongest corner.
        min_distance_px: minimum spacing of corners, pixels.
        block_size: corner detector block size, pixels.
        window_px: Lucas-Kanade window side, pixels.
        pyramid_levels: Lucas-Kanade pyramid levels above the base.
        fb_max_error_px: forward-backward error above which a track is dropped, pixels.
        lk_iterations: Lucas-Kanade iterations per pyramid level (at most).
        lk_epsilon_px: Lucas-Kanade stops when an update is smaller than this, pixels.
        photometric: brightness compensation (:class:`Photometric`).
        photometric_min_change: ``gain_bias`` maps a frame anew only when the fitted gain and
            bias change the mean intensity of the tracked patches (5-95 % of them) by more
            than this, grey levels.
        anchor_max_move_px: :meth:`KltTracker.anchored` keeps the chained point where the
            one measured against the reference lies farther from it than this, pixels (the
            search fell into another minimum; a chained track is checked forward and backward
            on every step).
    """

    max_features: int = 300
    grid_cols: int = 8
    grid_rows: int = 6
    quality_level: float = 0.01
    min_distance_px: float = 8.0
    block_size: int = 7
    window_px: int = 17
    pyramid_levels: int = 3
    fb_max_error_px: float = 1.0
    lk_iterations: int = 10
    lk_epsilon_px: float = 0.03
    photometric: Photometric = Photometric.GAIN_BIAS
    photometric_min_change: float = 1.0
    anchor_max_move_px: float = 3.0

    def __post_init__(self) -> None:
        object.__setattr__(self, 'photometric', Photometric(self.photometric))


@dataclass(frozen=True)
class Tracks:
    """Surviving correspondences between the reference and the current frame.

    Attributes:
        ref: (N, 2) float32 reference pixels.
        cur: (N, 2) float32 current pixels.
        ids: (N,) int64 feature ids (index in the reference detection).
    """

    ref: np.ndarray
    cur: np.ndarray
    ids: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.shape[0])


def detect_features(
    gray: np.ndarray, config: TrackerConfig = TrackerConfig(), region: np.ndarray | None = None
) -> np.ndarray:
    """Shi-Tomasi corners spread over a grid, strongest first within each cell.

    Each grid cell keeps at most ``ceil(max_features / cells)`` corners; any budget left
    goes to the strongest remaining corners anywhere.

    Args:
        gray: (H, W) uint8 image.
        config: detection settings.
        region: (H, W) bool, where corners may lie (None: anywhere).

    Returns:
        (N, 2) float32 pixel coordinates, N <= ``config.max_features``.
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ImageConversionError(f'expected (H, W) uint8, got {gray.shape} {gray.dtype}')
    h, w = gray.shape
    if config.max_features <= 0 or h < 2 * config.block_size or w < 2 * config.block_size:
        return np.zeros((0, 2), np.float32)
    corners = cv2.goodFeaturesToTrack(
        gray,
        maxCorners=2 * config.max_features,
        qualityLevel=config.quality_level,
        minDistance=config.min_distance_px,
        mask=None if region is None else region.astype(np.uint8),
        blockSize=config.block_size,
    )
    if corners is None:
        return np.zeros((0, 2), np.float32)
    pts = corners.reshape(-1, 2).astype(np.float32)  # strongest first
    cols, rows = max(config.grid_cols, 1), max(config.grid_rows, 1)
    cx = np.minimum((pts[:, 0] * cols / w).astype(np.int64), cols - 1)
    cy = np.minimum((pts[:, 1] * rows / h).astype(np.int64), rows - 1)
    cell = cy * cols + cx
    order = np.argsort(cell, kind='stable')  # by cell, strength order kept inside a cell
    sorted_cell = cell[order]
    rank_in_cell = np.arange(len(pts)) - np.searchsorted(sorted_cell, sorted_cell)
    rank = np.empty_like(rank_in_cell)
    rank[order] = rank_in_cell
    cap = math.ceil(config.max_features / (cols * rows))
    chosen = rank < cap
    if chosen.sum() > config.max_features:
        chosen[np.flatnonzero(chosen)[config.max_features :]] = False
    spare = config.max_features - int(chosen.sum())
    if spare > 0:
        chosen[np.flatnonzero(~chosen)[:spare]] = True
    return pts[np.flatnonzero(chosen)]


class KltTracker:
    """Tracks features from a reference frame through the following frames.

    ``region`` ((H, W) bool, or None for the whole image): where features are detected and
    kept; a track that leaves it is dropped as if it had left the image (a lens's usable
    field, :meth:`Intrinsics.field_mask`). A region of another size than the frames is
    refused at :meth:`reset`.
    """

    def __init__(
        self, config: TrackerConfig = TrackerConfig(), region: np.ndarray | None = None
    ) -> None:
        self.config = config
        self.region = None if region is None else np.asarray(region, dtype=bool)
        self._criteria = (
            cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT,
            config.lk_iterations,
            config.lk_epsilon_px,
        )
        self._prev: np.ndarray | None = None
        self._reference: np.ndarray | None = None  # the reference frame, as tracked on
        self._ref = np.zeros((0, 2), np.float32)
        self._cur = np.zeros((0, 2), np.float32)
        self._ids = np.zeros(0, np.int64)
        self.frames_since_reference = 0
        #: features detected in the reference frame (the tracks it started with)
        self.reference_tracks = 0
        #: gain and bias mapping the last frame onto the reference brightness (gain_bias)
        self.last_gain_bias = (1.0, 0.0)
        self._gain_bias = (1.0, 0.0)
        #: frames that ``gain_bias`` mapped to a new brightness (since construction)
        self.photometric_remaps = 0
        # patch means and unclipped flags of the previous frame at the current points, when
        # the last step read them there (gain_bias)
        self._prev_patches: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def has_reference(self) -> bool:
        """True once :meth:`reset` has been given a frame."""
        return self._prev is not None

    @property
    def n_tracks(self) -> int:
        """Number of tracks still alive."""
        return int(self._ids.shape[0])

    @property
    def reference_image(self) -> np.ndarray | None:
        """The reference frame as it is tracked on (``zncc``: normalized), or None before
        :meth:`reset`."""
        return self._reference

    @property
    def image_shape(self) -> tuple[int, ...] | None:
        """Shape of the frames being tracked, or None before a reference."""
        return None if self._prev is None else self._prev.shape

    def clear(self) -> None:
        """Forget the reference; the next :meth:`reset` starts over."""
        self._prev = self._reference = None
        self._ref = self._cur = np.zeros((0, 2), np.float32)
        self._ids = np.zeros(0, np.int64)
        self.frames_since_reference = 0
        self.reference_tracks = 0

    def reset(self, gray: np.ndarray) -> int:
        """Make ``gray`` ((H, W) uint8) the reference frame; returns the features found."""
        if self.region is not None and self.region.shape != gray.shape[:2]:
            raise ImageConversionError(
                f'tracking region {self.region.shape} differs from the frame {gray.shape[:2]}'
            )
        pts = detect_features(gray, self.config, self.region)
        self._prev = _zncc(gray, self.config.window_px) if self._zncc else gray
        self._reference = self._prev
        self._gain_bias = (1.0, 0.0)
        self._prev_patches = None
        self._ref = pts
        self._cur = pts.copy()
        self._ids = np.arange(len(pts), dtype=np.int64)
        self.frames_since_reference = 0
        self.reference_tracks = len(pts)
        return len(pts)

    def tracks(self) -> Tracks:
        """The current correspondences (reference, current)."""
        return Tracks(self._ref.copy(), self._cur.copy(), self._ids.copy())

    def anchored(self) -> Tracks:
        """The current correspondences with each current point measured against the
        reference frame (pyramidal Lucas-Kanade from the reference point, starting at the
        chained one, on the finest two levels), not carried from frame to frame: the error
        of one measurement instead of the sum of every step's (module docstring). The
        current frame is compared as it was tracked (``gain_bias``: mapped onto the
        reference's brightness; ``zncc``: normalized). Where that search fails, or ends more
        than ``anchor_max_move_px`` from the chained point, the chained point is kept."""
        tracks = self.tracks()
        if not len(tracks) or self._reference is None or self._prev is self._reference:
            return tracks
        cfg = self.config
        guess = tracks.cur.reshape(-1, 1, 2).copy()
        found, status, _ = cv2.calcOpticalFlowPyrLK(
            self._reference,
            self._prev,
            tracks.ref.reshape(-1, 1, 2),
            guess,
            winSize=(cfg.window_px, cfg.window_px),
            maxLevel=min(cfg.pyramid_levels, _ANCHOR_LEVELS),
            criteria=self._criteria,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        found = found.reshape(-1, 2)
        h, w = self._prev.shape[:2]
        moved = np.linalg.norm(found - tracks.cur, axis=1)
        good = (
            (status.ravel() == 1)
            & (moved <= cfg.anchor_max_move_px)
            & (found[:, 0] >= 0)
            & (found[:, 0] <= w - 1)
            & (found[:, 1] >= 0)
            & (found[:, 1] <= h - 1)
        )
        cur = np.where(good[:, None], found, tracks.cur).astype(np.float32)
        return Tracks(tracks.ref, cur, tracks.ids)

    def track(self, gray: np.ndarray) -> Tracks:
        """Track into the next frame ((H, W) uint8, same size as the reference).

        Returns:
            The surviving correspondences between the reference and ``gray``.
        """
        if self._prev is None:
            raise RuntimeError('track() before reset(): no reference frame')
        if gray.shape != self._prev.shape:
            raise ImageConversionError(
                f'frame size {gray.shape} differs from the reference {self._prev.shape}'
            )
        self.frames_since_reference += 1
        if self._zncc:
            gray = _zncc(gray, self.config.window_px)
        if len(self._ids):
            gray = self._step(gray)
            if self.region is not None:
                self._keep_in_region()
        self._prev = gray
        return self.tracks()

    def _keep_in_region(self) -> None:
        """Drop the tracks whose current point left :attr:`region`."""
        assert self.region is not None
        h, w = self.region.shape
        x = np.clip(np.rint(self._cur[:, 0]).astype(np.int64), 0, w - 1)
        y = np.clip(np.rint(self._cur[:, 1]).astype(np.int64), 0, h - 1)
        inside = self.region[y, x]
        if not inside.all():
            self._ref, self._cur, self._ids = (
                self._ref[inside],
                self._cur[inside],
                self._ids[inside],
            )
            self._prev_patches = None  # (read at the points before the drop)

    @property
    def _zncc(self) -> bool:
        return self.config.photometric is Photometric.ZNCC

    def _lk(
        self,
        prev: np.ndarray,
        gray: np.ndarray,
        guess: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Forward-backward KLT of the current points.

        Args:
            prev: the previous frame; gray: the frame to track into.
            guess: ``(forward, backward)`` (N, 2) results of an earlier pass, to start both
                directions from.

        Returns:
            ``(next points (N, 2), keep (N,), backward points (N, 2))``.
        """
        cfg = self.config
        lk = {
            'winSize': (cfg.window_px, cfg.window_px),
            'maxLevel': cfg.pyramid_levels,
            'criteria': self._criteria,
        }
        prev_pts = self._cur.reshape(-1, 1, 2)
        if guess is None:
            nxt, status, _ = cv2.calcOpticalFlowPyrLK(prev, gray, prev_pts, None, **lk)
            back, status_back, _ = cv2.calcOpticalFlowPyrLK(gray, prev, nxt, None, **lk)
        else:
            start = cv2.OPTFLOW_USE_INITIAL_FLOW
            nxt, status, _ = cv2.calcOpticalFlowPyrLK(
                prev, gray, prev_pts, guess[0].reshape(-1, 1, 2).copy(), flags=start, **lk
            )
            back, status_back, _ = cv2.calcOpticalFlowPyrLK(
                gray, prev, nxt, guess[1].reshape(-1, 1, 2).copy(), flags=start, **lk
            )
        nxt = nxt.reshape(-1, 2)
        back = back.reshape(-1, 2)
        fb = np.linalg.norm(back - self._cur, axis=1)
        h, w = gray.shape
        keep = (
            (status.ravel() == 1)
            & (status_back.ravel() == 1)
            & (fb <= cfg.fb_max_error_px)
            & (nxt[:, 0] >= 0)
            & (nxt[:, 0] <= w - 1)
            & (nxt[:, 1] >= 0)
            & (nxt[:, 1] <= h - 1)
        )
        return nxt, keep, back

    def _step(self, gray: np.ndarray) -> np.ndarray:
        """Track into ``gray``; returns the frame to keep as the previous one."""
        cfg = self.config
        prev = self._prev
        assert prev is not None
        if cfg.photometric is not Photometric.GAIN_BIAS:
            nxt, keep, _ = self._lk(prev, gray)
        else:
            nxt, keep, gray = self._step_gain_bias(prev, gray)
        self._ref = self._ref[keep]
        self._cur = nxt[keep].astype(np.float32)
        self._ids = self._ids[keep]
        return gray

    def _step_gain_bias(
        self, prev: np.ndarray, gray: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Track with gain and bias compensation: (next points, keep, the mapped frame).

        The frame is predicted with the last mapping (brightness changes smoothly) and
        tracked; the mapping is fitted to the raw frame at the tracks found (the previous
        frame's patch means are read once), and only when it changes a patch mean by more
        than ``photometric_min_change`` is the frame mapped anew and tracked again, from the
        first pass's result, until the mapping settles.
        """
        cfg = self.config
        k = cfg.window_px
        a, b = self._gain_bias
        mapped = gray if (a, b) == (1.0, 0.0) else _map(gray, a, b)
        nxt, keep, back = self._lk(prev, mapped)
        tolerance = cfg.photometric_min_change
        remapped = False
        if keep.sum() < _JUMP_KEPT_SHARE * len(keep):  # a brightness jump, or lost anyway
            jump = self._track_brightness_jump(prev, gray, (a, b), int(keep.sum()))
            if jump is not None:
                (a, b), mapped, (nxt, keep, back) = jump
                self.photometric_remaps += 1
                remapped, tolerance = True, _GAIN_BIAS_SETTLED
        if self._prev_patches is not None:  # read last frame, at these very points
            m_prev, ok_prev = self._prev_patches
        else:
            m_prev, ok_prev = _patch_means_at(prev, self._cur, np.ones(len(self._cur), bool), k)
        self._prev_patches = None
        m_cur, ok_cur = m_prev, np.zeros_like(ok_prev)
        for _ in range(_GAIN_BIAS_ROUNDS):
            m_cur, ok_cur = _patch_means_at(gray, nxt, keep, k)
            use = ok_prev & ok_cur
            if use.sum() < _MIN_PHOTOMETRIC_POINTS:
                break
            if not remapped and _plainly_unchanged(m_prev[use], m_cur[use], a, b, tolerance):
                break
            fit = _fit_patch_means(m_prev, m_cur, use)
            if fit is None:
                break
            a_new, b_new, means = fit
            span = _order_statistics(means, (0.05, 0.95))  # robust ends of the intensities
            change = _mapping_change((a, b), (a_new, b_new), span)
            if change <= tolerance:
                break
            if not remapped:
                self.photometric_remaps += 1
            remapped = True
            tolerance = _GAIN_BIAS_SETTLED
            a, b = a_new, b_new
            mapped = _map(gray, a, b)
            nxt, keep, back = self._lk(prev, mapped, guess=(nxt, back))
        if mapped is gray and not remapped:
            # the next frame's previous frame is this raw one and its points are these: keep
            # what was read (read again otherwise: points moved, or the frame was mapped)
            self._prev_patches = (m_cur[keep], ok_cur[keep])
        self._gain_bias = (a, b)
        self.last_gain_bias = (a, b)
        return nxt, keep, mapped

    def _track_brightness_jump(
        self, prev: np.ndarray, gray: np.ndarray, mapping: tuple[float, float], kept: int
    ) -> tuple[tuple[float, float], np.ndarray, tuple[np.ndarray, ...]] | None:
        """Where a pass lost many tracks (too many, perhaps, to fit a gain and bias from):
        the mapping fitted to the two whole frames' intensity quantiles
        (:func:`fit_gain_bias_global`) and the pass under it, when that mapping changes the
        frame by at least :data:`_JUMP_MIN_CHANGE` grey levels and its pass keeps more tracks;
        else None."""
        fit = fit_gain_bias_global(prev, gray)
        if fit is None:
            return None
        a, b = fit
        if _mapping_change(mapping, fit, _INTENSITY_ENDS) < _JUMP_MIN_CHANGE:
            return None
        mapped = _map(gray, a, b)
        result = self._lk(prev, mapped)
        if int(result[1].sum()) <= kept:
            return None
        return (a, b), mapped, result


def _mapping_change(
    old: tuple[float, float], new: tuple[float, float], intensities: np.ndarray
) -> float:
    """The most the mapping ``new`` (gain, bias) moves any of ``intensities`` from where
    ``old`` puts them, grey levels."""
    return float(np.max(np.abs((new[0] - old[0]) * intensities + (new[1] - old[1]))))


def _patch_means_at(
    img: np.ndarray, pts: np.ndarray, wanted: np.ndarray, window_px: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`patch_means` of the ``wanted`` points ((N,) bool) whose window lies inside the
    frame; the others get mean 0 and are marked clipped (left out of the fit)."""
    means = np.zeros(len(pts))
    unclipped = np.zeros(len(pts), dtype=bool)
    index = np.flatnonzero(wanted)
    if index.size:
        xy = np.rint(pts[index]).astype(np.int64)
        inside = _inside(xy[:, 0], xy[:, 1], img.shape, window_px)
        index, xy = index[inside], xy[inside]
        patches = _inside_patches(img, xy[:, 0], xy[:, 1], window_px)
        means[index] = _patch_mean(_patch_sums(patches), window_px)
        unclipped[index] = _unclipped(patches)
    return means, unclipped


def _map(gray: np.ndarray, a: float, b: float) -> np.ndarray:
    """``a * gray + b``, rounded and saturated to uint8."""
    return cv2.LUT(gray, np.clip(np.rint(a * np.arange(256) + b), 0, 255).astype(np.uint8))


#: Pyramid levels above the base that :meth:`KltTracker.anchored` searches (it starts at the
#: chained point, a fraction of a pixel away as a rule).
_ANCHOR_LEVELS = 1
_MIN_PHOTOMETRIC_POINTS = 20
_GAIN_BIAS_ROUNDS = 4
#: refits stop when the mapping changes a patch mean by less than this, grey levels
_GAIN_BIAS_SETTLED = 0.1
#: A pass that keeps less than this share of the tracks looks for a brightness jump in the
#: whole frames (a step of the camera's exposure or gain loses most tracks at once; motion
#: at video rates loses a few a frame).
_JUMP_KEPT_SHARE = 0.75
#: The quantiles of the whole frames' intensities that a brightness jump is fitted to, and
#: the intensities at which a change of mapping is judged (the ends of a typical frame's).
_GLOBAL_QUANTILES = np.linspace(0.05, 0.95, 19)
_INTENSITY_ENDS = np.array([25.0, 230.0])
#: The least change of brightness at those ends, grey levels, that is taken for a jump (KLT
#: itself holds its tracks through a few grey levels; the patches' fit follows those).
_JUMP_MIN_CHANGE = 10.0


def fit_gain_bias(
    prev: np.ndarray,
    cur: np.ndarray,
    p_prev: np.ndarray,
    p_cur: np.ndarray,
    window_px: int,
    iterations: int = 3,
) -> tuple[float, float, np.ndarray] | None:
    """Gain and bias mapping ``cur`` onto ``prev`` brightness: ``prev ~ a * cur + b``.

    Fitted to the mean intensities of ``window_px`` patches around corresponding points by a
    reduced-major-axis line (the means and spreads of both sides matched: misplaced current
    points do not bias it as least squares would), leaving out patches with saturated
    (>= 250) or black (<= 5) pixels and, over ``iterations`` rounds, residuals above 3 robust
    standard deviations.

    Args:
        prev, cur: (H, W) uint8 frames.
        p_prev, p_cur: (N, 2) corresponding pixels.
        window_px: patch side, pixels.
        iterations: outlier-rejection rounds.

    Returns:
        ``(a, b, cur_means)`` (``cur_means``: the patch means used, grey levels), or None when
        fewer than 20 patches qualify or their intensities span less than 10 grey levels.
    """
    m_prev, ok_prev = patch_means(prev, p_prev, window_px)
    m_cur, ok_cur = patch_means(cur, p_cur, window_px)
    return _fit_patch_means(m_prev, m_cur, ok_prev & ok_cur, iterations)


def fit_gain_bias_global(prev: np.ndarray, cur: np.ndarray) -> tuple[float, float] | None:
    """Gain and bias mapping ``cur`` onto ``prev`` brightness, ``prev ~ a * cur + b``, from
    the two whole frames: a least-squares line through their intensity quantiles at 5, 10,
    ..., 95 % (from their histograms), leaving out the quantiles black or saturated in either.

    Between frames at video rate the view changes little and the distributions match but for
    the mapping, so this needs no tracks: it is the estimate when a jump of exposure or gain
    lost them (:class:`KltTracker` then tracks again under it, and refines it from the patches).

    Returns:
        ``(a, b)``, or None when fewer than 5 quantiles qualify, they span less than 10 grey
        levels, or the gain is outside 0.2-5.
    """
    q_prev, q_cur = _intensity_quantiles(prev), _intensity_quantiles(cur)
    use = (q_prev > _BLACK) & (q_prev < _SATURATED) & (q_cur > _BLACK) & (q_cur < _SATURATED)
    x, y = q_cur[use], q_prev[use]
    if len(x) < 5 or np.ptp(x) < 10:
        return None
    dx = x - x.mean()
    a = float(dx @ (y - y.mean())) / float(dx @ dx)
    if not 0.2 < a < 5.0:
        return None
    return a, float(y.mean() - a * x.mean())


def _intensity_quantiles(img: np.ndarray) -> np.ndarray:
    """The grey levels at :data:`_GLOBAL_QUANTILES` of a uint8 frame (the first level whose
    cumulative share reaches each)."""
    hist = cv2.calcHist([img], [0], None, [256], [0, 256]).ravel()
    cdf = np.cumsum(hist) / max(float(hist.sum()), 1.0)
    return np.searchsorted(cdf, _GLOBAL_QUANTILES).astype(np.float64)


def _fit_patch_means(
    m_prev: np.ndarray, m_cur: np.ndarray, use: np.ndarray, iterations: int = 3
) -> tuple[float, float, np.ndarray] | None:
    """:func:`fit_gain_bias` on patch means already read ((N,) each; ``use``: unclipped)."""
    x_all, y_all = m_cur[use], m_prev[use]
    inliers = np.ones(len(x_all), dtype=bool)
    a = b = 0.0
    for _ in range(max(1, iterations)):
        x, y = x_all[inliers], y_all[inliers]
        count = len(x)
        if count < _MIN_PHOTOMETRIC_POINTS or np.ptp(x) < 10:
            return None
        # reduced major axis: both means are noisy (the current points are a first estimate)
        mean_x, mean_y = float(x.sum()) / count, float(y.sum()) / count
        dx, dy = x - mean_x, y - mean_y
        sxx, syy, sxy = float(dx @ dx), float(dy @ dy), float(dx @ dy)
        a = math.copysign(math.sqrt(syy / max(sxx, 1e-18)), sxy)
        b = mean_y - a * mean_x
        residual = np.abs(y_all - (a * x_all + b))
        scale = 1.4826 * float(_order_statistics(residual[inliers], (0.5,))[0]) + 1e-3
        inliers &= residual <= 3 * scale
    if not (0.2 < a < 5.0) or inliers.sum() < _MIN_PHOTOMETRIC_POINTS:
        return None
    return float(a), float(b), x_all[inliers]


def _plainly_unchanged(
    m_prev: np.ndarray, m_cur: np.ndarray, a: float, b: float, tolerance: float
) -> bool:
    """The mapping ``prev ~ a cur + b`` still holds by the means' first two moments.

    Any gain and bias change shows in the mean of ``prev - (a cur + b)`` or in the spread of
    ``prev`` against ``a`` times that of ``cur``; when the change they imply at the ends of the
    intensities (1.645 standard deviations: the 5-95 % range of a normal spread) is below
    half ``tolerance``, the robust fit is not needed (it would find no change either;
    outliers only make this test more cautious).
    """
    count = len(m_cur)
    mean_cur, mean_prev = float(m_cur.sum()) / count, float(m_prev.sum()) / count
    d_cur, d_prev = m_cur - mean_cur, m_prev - mean_prev
    spread = abs(
        math.sqrt(float(d_prev @ d_prev) / count) - a * math.sqrt(float(d_cur @ d_cur) / count)
    )
    shift = abs(mean_prev - (a * mean_cur + b))
    return shift + 1.645 * spread < 0.5 * tolerance


def _order_statistics(values: np.ndarray, fractions: tuple[float, ...]) -> np.ndarray:
    """The values of rank ``round(f (N - 1))`` for each fraction f: quantiles without
    interpolation, from one partial sort (np.median and np.percentile cost ten times more on
    a few hundred values)."""
    ranks = [round(f * (len(values) - 1)) for f in fractions]
    return np.partition(values, ranks)[ranks]


#: A patch with a pixel at or above the first, or at or below the second, is clipped.
_SATURATED, _BLACK = 250, 5


def _unclipped(patches: np.ndarray) -> np.ndarray:
    """(N,) bool: no pixel of the (N, k * k) uint8 patches is saturated or black."""
    return (patches.max(axis=1) < _SATURATED) & (patches.min(axis=1) > _BLACK)


def _inside(x: np.ndarray, y: np.ndarray, shape: tuple[int, ...], k: int) -> np.ndarray:
    """(N,) bool: the k x k windows centred (as OpenCV centres them) on the integer pixels
    ``(x, y)`` lie inside an image of ``shape``."""
    h, w = shape[:2]
    before, after = k // 2, k - 1 - k // 2
    return (x >= before) & (x + after < w) & (y >= before) & (y + after < h)


def _inside_patches(img: np.ndarray, x: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """(N, k * k) uint8 pixels of the k x k windows at the integer pixels ``(x, y)``, every
    window inside the image: one gather of whole windows from a strided view of the frame
    (a quarter of the time of gathering N k^2 flat indices, which must be built first)."""
    if len(x) == 0:  # (no window fits a frame smaller than k: nothing to view)
        return np.empty((0, k * k), dtype=img.dtype)
    before = k // 2
    windows = sliding_window_view(img, (k, k))
    return windows[y - before, x - before].reshape(len(x), k * k)


def _patch_sums(patches: np.ndarray) -> np.ndarray:
    """(N,) exact integer sums of (N, k * k) uint8 patches (in uint32: exact below k = 4104,
    and cheaper to accumulate than int64)."""
    return patches.sum(axis=1, dtype=np.uint32)


def patch_means(img: np.ndarray, pts: np.ndarray, window_px: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean intensity of the ``window_px`` patch at each point, and whether it is unclipped.

    The values of ``cv2.blur`` (float32, reflected border) and of the ``cv2.dilate`` /
    ``cv2.erode`` test (no pixel >= 250 or <= 5 inside the image) at the rounded, clamped
    points, bit for bit, but read from the patches alone: no operation touches the whole
    frame (filtering or padding it cost more than the rest of the gain and bias fit).

    Args:
        img: (H, W) uint8 frame.
        pts: (N, 2) pixels.
        window_px: patch side, pixels.

    Returns:
        ``(means, unclipped)``: (N,) float64 patch means, (N,) bool.
    """
    h, w = img.shape
    xy = np.rint(pts).astype(np.int64)
    x = np.clip(xy[:, 0], 0, w - 1)
    y = np.clip(xy[:, 1], 0, h - 1)
    k = window_px
    if min(h, w) <= k:  # reflection beyond one image width: let OpenCV handle the border
        size = (k, k)
        mean = cv2.blur(img.astype(np.float32), size)
        hi = cv2.dilate(img, np.ones(size, np.uint8))
        lo = cv2.erode(img, np.ones(size, np.uint8))
        return mean[y, x].astype(np.float64), (hi[y, x] < _SATURATED) & (lo[y, x] > _BLACK)
    sums = np.empty(len(x), dtype=np.int64)
    unclipped = np.empty(len(x), dtype=bool)
    inside = _inside(x, y, img.shape, k)
    if inside.any():
        patches = _inside_patches(img, x[inside], y[inside], k)
        sums[inside] = _patch_sums(patches)
        unclipped[inside] = _unclipped(patches)
    border = ~inside
    if border.any():
        # the frame reflected as blur pads it (reflect 101); the clipped test sees only the
        # pixels inside the frame (dilate and erode ignore the border)
        before = k // 2
        offsets = np.arange(-before, k - before)
        rows, cols = y[border, None] + offsets, x[border, None] + offsets  # (B, k)
        valid = ((rows >= 0) & (rows < h))[:, :, None] & ((cols >= 0) & (cols < w))[:, None, :]
        rows = np.abs(rows)
        rows = np.where(rows > h - 1, 2 * (h - 1) - rows, rows)
        cols = np.abs(cols)
        cols = np.where(cols > w - 1, 2 * (w - 1) - cols, cols)
        patches = img[rows[:, :, None], cols[:, None, :]].reshape(len(rows), -1)
        sums[border] = _patch_sums(patches)
        unclipped[border] = _unclipped(np.where(valid.reshape(len(rows), -1), patches, 128))
    return _patch_mean(sums, k), unclipped


def _patch_mean(sums: np.ndarray, k: int) -> np.ndarray:
    """Means of k x k patches from their exact integer sums, as OpenCV's blur rounds them
    (scaled in double, stored as float32)."""
    return (sums.astype(np.float64) * (1.0 / (k * k))).astype(np.float32).astype(np.float64)


def _zncc(gray: np.ndarray, window_px: int) -> np.ndarray:
    """Locally zero-mean, unit-variance image (over ``window_px`` windows), as uint8 around
    128 (32 grey levels per standard deviation)."""
    f = gray.astype(np.float32)
    k = (window_px, window_px)
    mean = cv2.blur(f, k)
    var = cv2.blur(f * f, k) - mean * mean
    norm = (f - mean) / np.sqrt(np.maximum(var, 0.0) + 4.0)
    return np.clip(norm * 32.0 + 128.0, 0, 255).astype(np.uint8)
