"""The debug image: tracks, the four probabilities and the decision drawn over a frame.

ROS-free and fast (pure OpenCV drawing, one ``cv2.polylines`` call per colour bin): the node
publishes it on ``~/debug_image`` and :mod:`initsel_ros.pictures` writes it to videos and PNGs.

What is drawn:

- each track as a line from its reference to its current position, coloured by its direction
  (HSV hue of the angle of ``cur - ref`` with image y pointing up: right = red, up = yellow-green,
  left = cyan, down = violet), with a dot at the current end; tracks that have not moved (less
  than half a pixel) are grey dots. A small colour wheel in the corner is the key;
- a panel with one bar per model (F, E, H, R) showing its probability and a white tick at its
  threshold: green when the model fired, orange when it fired but model R vetoed it, red for a
  firing R, grey otherwise;
- the number of tracks, the mean disparity, the frames since the reference and the decision
  with its reason and detail;
- on the initializing frame, the chosen method and its inlier points (yellow squares).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping

import cv2
import numpy as np

from initsel_ros.image import to_bgr
from initsel_ros.names import MODEL_NAMES
from initsel_ros.policy import Decision, Reason
from initsel_ros.selector import FrameResult, Initialization

__all__ = ['direction_colors', 'draw_frame_overlay', 'draw_overlay']

#: Number of hue bins the track directions are quantized into (one polyline call each).
HUE_BINS = 24
#: Tracks shorter than this (pixels) are drawn as grey dots.
STILL_PX = 0.5

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_WHITE = (255, 255, 255)
_GREY = (150, 150, 150)
_GREEN = (80, 220, 80)
_ORANGE = (0, 150, 255)
_RED = (90, 90, 255)
_YELLOW = (0, 255, 255)
_BAR_BG = (70, 70, 70)


@functools.lru_cache(maxsize=4)
def _hue_palette(bins: int) -> tuple[tuple[int, int, int], ...]:
    """BGR colour of each hue bin (bin ``k`` is centred on ``k * 360 / bins`` degrees)."""
    hsv = np.zeros((1, bins, 3), np.uint8)
    hsv[0, :, 0] = np.round(np.arange(bins) * 180.0 / bins).astype(np.uint8) % 180
    hsv[0, :, 1] = 255
    hsv[0, :, 2] = 255
    bgr = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0]
    return tuple((int(b), int(g), int(r)) for b, g, r in bgr)


def _direction_bins(ref: np.ndarray, cur: np.ndarray, bins: int) -> np.ndarray:
    """(N,) int hue bin of each displacement's angle (image y up), in [0, bins)."""
    d = cur - ref
    angle = np.arctan2(-d[:, 1], d[:, 0])  # radians, y up as in the paper's histogram
    return np.round(angle * (bins / (2 * np.pi))).astype(np.int64) % bins


def direction_colors(ref: np.ndarray, cur: np.ndarray) -> np.ndarray:
    """The colour each track is drawn with.

    Args:
        ref: (N, 2) reference pixels.
        cur: (N, 2) current pixels.

    Returns:
        (N, 3) uint8 BGR colours (grey for tracks shorter than :data:`STILL_PX`).
    """
    ref = np.asarray(ref, np.float32).reshape(-1, 2)
    cur = np.asarray(cur, np.float32).reshape(-1, 2)
    palette = np.array(_hue_palette(HUE_BINS), np.uint8)
    out = palette[_direction_bins(ref, cur, HUE_BINS)]
    still = np.linalg.norm(cur - ref, axis=1) < STILL_PX
    out[still] = _GREY
    return out


@functools.lru_cache(maxsize=8)
def _wheel(radius: int) -> np.ndarray:
    """(2r+1, 2r+1, 4) uint8 BGR + mask: the direction colour key (hue by angle, y up)."""
    yy, xx = np.mgrid[-radius : radius + 1, -radius : radius + 1].astype(np.float32)
    angle = np.arctan2(-yy, xx)
    bins = np.round(angle * (HUE_BINS / (2 * np.pi))).astype(np.int64) % HUE_BINS
    palette = np.array(_hue_palette(HUE_BINS), np.uint8)
    img = palette[bins]
    r = np.hypot(xx, yy)
    mask = ((r <= radius) & (r >= radius * 0.45)).astype(np.uint8) * 255
    return np.dstack([img, mask])


def _draw_tracks(canvas: np.ndarray, ref: np.ndarray, cur: np.ndarray, thickness: int) -> None:
    if len(ref) == 0:
        return
    disp = np.linalg.norm(cur - ref, axis=1)
    ok = np.isfinite(disp)
    ref, cur, disp = ref[ok], cur[ok], disp[ok]
    still = disp < STILL_PX
    # Integer polylines with 4 fractional bits for sub-pixel placement.
    shift = 4
    seg = np.round(np.stack([ref, cur], axis=1) * (1 << shift)).astype(np.int32)  # (N, 2, 2)
    dots = np.repeat(seg[:, 1:2], 2, axis=1)  # (N, 2, 2): a zero-length segment at cur
    if still.any():
        cv2.polylines(canvas, list(dots[still]), False, _GREY, thickness + 2, cv2.LINE_8, shift)
    moving = ~still
    if not moving.any():
        return
    bins = _direction_bins(ref[moving], cur[moving], HUE_BINS)
    palette = _hue_palette(HUE_BINS)
    seg, dots = seg[moving], dots[moving]
    order = np.argsort(bins, kind='stable')
    bounds = np.searchsorted(bins[order], np.arange(HUE_BINS + 1))
    for k in range(HUE_BINS):
        idx = order[bounds[k] : bounds[k + 1]]
        if len(idx) == 0:
            continue
        cv2.polylines(canvas, list(seg[idx]), False, palette[k], thickness, cv2.LINE_8, shift)
        cv2.polylines(canvas, list(dots[idx]), False, palette[k], thickness + 2, cv2.LINE_8, shift)


def _draw_inliers(canvas: np.ndarray, pixels: np.ndarray, half: int) -> None:
    pts = np.asarray(pixels, np.float32).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        return
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]], np.int32)
    squares = np.round(pts).astype(np.int32)[:, None, :] + corners[None]  # (M, 4, 2)
    cv2.polylines(canvas, list(squares), True, _YELLOW, 1, cv2.LINE_8)


def _fmt(p: float) -> str:
    return 'n/a' if not math.isfinite(p) else f'{p:.2f}'


def _bar_colour(name: str, decision: Decision, p: float, threshold: float) -> tuple:
    if name in decision.vetoed:
        return _ORANGE
    if name == 'R' and math.isfinite(p) and p >= threshold:
        return _RED
    if name in decision.fired or (math.isfinite(p) and p >= threshold):
        return _GREEN
    return _GREY


def _decision_lines(result: FrameResult, init: Initialization | None) -> list[tuple[str, tuple]]:
    d = result.decision
    reason = d.reason.value if isinstance(d.reason, Reason) else str(d.reason)
    colour = _GREEN if init is not None else (_RED if d.reason is Reason.ROTATION else _WHITE)
    lines = [(f'decision: {reason}', colour)]
    if init is not None:
        lines.append(
            (
                f'INIT {init.method.value}: {len(init.points)} points, '
                f'parallax {init.parallax_deg:.1f} deg',
                _YELLOW,
            )
        )
    selection = init.selection if init is not None else result.selection
    if selection is not None:  # the fire-time candidates: one line each, the winner marked
        for score in selection.scores:
            mark = '*' if score.method is selection.winner else ' '
            text = (
                f'{mark}{score.method.value} GRIC {score.gric:.0f}, {score.n_points} pts'
                if score.ok
                else f' {score.method.value} failed: {score.problem}'
            )
            lines.append((text[:48], _YELLOW if mark == '*' else _GREY))
    if result.verification is not None:
        step = result.verification
        lines.append(
            (
                f'verify: {step.inliers} inliers ({100 * step.fraction:.0f} %), '
                f'RMS {step.rms_px:.2f} px',
                _GREEN if step.ok else _RED,
            )
        )
    if d.vetoed:
        lines.append((f'vetoed by R: {", ".join(d.vetoed)}', _ORANGE))
    if d.detail and init is None:
        detail = d.detail if len(d.detail) <= 48 else d.detail[:45] + '...'
        lines.append((detail, _GREY))
    return lines


def draw_overlay(
    image: np.ndarray,
    result: FrameResult,
    tracks_ref: np.ndarray,
    tracks_cur: np.ndarray,
    thresholds: Mapping[str, float],
    initialization: Initialization | None = None,
) -> np.ndarray:
    """Draw the selector's view of one frame.

    Args:
        image: (H, W, 3) uint8 BGR frame (grey, BGRA and uint16 are converted); not modified.
        result: what :meth:`Selector.process` returned for this frame.
        tracks_ref: (N, 2) reference pixels of the tracks (distorted, as tracked).
        tracks_cur: (N, 2) current pixels of the same tracks.
        thresholds: model name -> probability threshold (``Selector.thresholds``).
        initialization: the initialization to show; defaults to ``result.initialization``.

    Returns:
        (H, W, 3) uint8 BGR debug image of the same size as ``image``.

    Raises:
        ValueError: an image of unsupported shape or type.
    """
    canvas = to_bgr(image, copy=True)
    h, w = canvas.shape[:2]
    init = initialization if initialization is not None else result.initialization
    s = min(w / 640.0, h / 480.0)  # layout scale, 1 at 640x480
    thick = max(1, round(s))
    line_thick = max(1, round(1.5 * s))
    ref = np.asarray(tracks_ref, np.float32).reshape(-1, 2)
    cur = np.asarray(tracks_cur, np.float32).reshape(-1, 2)
    n = min(len(ref), len(cur))
    _draw_tracks(canvas, ref[:n], cur[:n], line_thick)
    if init is not None:
        _draw_inliers(canvas, init.pixels_cur, max(2, round(3 * s)))

    d = result.decision
    font = 0.42 * s
    line = max(8, round(16 * s))
    pad = max(2, round(6 * s))
    lines = _decision_lines(result, init)
    panel_w = min(w, round(300 * s))
    panel_h = min(h, pad * 2 + line * (len(MODEL_NAMES) + 1 + len(lines)))
    roi = canvas[:panel_h, :panel_w]
    cv2.convertScaleAbs(roi, roi, 0.35, 0)  # darken the panel area, in place

    label_x, bar_x = pad, pad + round(18 * s)
    bar_w = max(10, round(150 * s))
    bar_h = max(4, round(10 * s))
    y = pad
    for name in MODEL_NAMES:
        p = float(d.probabilities.get(name, float('nan')))
        thr = float(thresholds.get(name, 0.5))
        base = y + line - (line - bar_h) // 2
        cv2.putText(canvas, name, (label_x, base), _FONT, font, _WHITE, 1, cv2.LINE_AA)
        top = base - bar_h
        cv2.rectangle(canvas, (bar_x, top), (bar_x + bar_w, base), _BAR_BG, -1)
        if math.isfinite(p):
            fill = bar_x + round(bar_w * min(max(p, 0.0), 1.0))
            colour = _bar_colour(name, d, p, thr)
            cv2.rectangle(canvas, (bar_x, top), (fill, base), colour, -1)
        if math.isfinite(thr):
            tx = bar_x + round(bar_w * min(max(thr, 0.0), 1.0))
            cv2.line(canvas, (tx, top - 2), (tx, base + 2), _WHITE, thick)
        tag = _fmt(p)
        if name in d.vetoed:
            tag += ' vetoed'
        cv2.putText(canvas, tag, (bar_x + bar_w + pad, base), _FONT, font, _WHITE, 1, cv2.LINE_AA)
        y += line
    y += line
    stats = (
        f'tracks {d.n_tracks}  disparity {d.mean_disparity:.1f} px  '
        f'+{result.frames_since_reference} frames'
    )
    cv2.putText(canvas, stats, (label_x, y), _FONT, font, _WHITE, 1, cv2.LINE_AA)
    for text, colour in lines:
        y += line
        cv2.putText(canvas, text, (label_x, y), _FONT, font, colour, 1, cv2.LINE_AA)

    _paste_wheel(canvas, max(6, round(18 * s)), pad)
    return canvas


def _paste_wheel(canvas: np.ndarray, radius: int, pad: int) -> None:
    h, w = canvas.shape[:2]
    wheel = _wheel(radius)
    size = wheel.shape[0]
    if size + pad > min(h, w):
        return
    y0, x0 = h - size - pad, w - size - pad
    roi = canvas[y0 : y0 + size, x0 : x0 + size]
    mask = wheel[:, :, 3].astype(bool)
    roi[mask] = wheel[:, :, :3][mask]


def draw_frame_overlay(image: np.ndarray, result: FrameResult) -> np.ndarray:
    """:func:`draw_overlay` with the tracks and thresholds the result carries.

    When the frame published an initialization after the tracker started over (mode
    'continuous', or a verified candidate), the initialization's own correspondences are
    drawn instead of the fresh, zero-length tracks.
    """
    empty = np.zeros((0, 2), np.float32)
    ref = result.tracks_ref if result.tracks_ref is not None else empty
    cur = result.tracks_cur if result.tracks_cur is not None else empty
    init = result.initialization
    if init is not None and (len(ref) == 0 or np.array_equal(ref, cur)):
        ref, cur = init.pixels_ref, init.pixels_cur
    return draw_overlay(image, result, ref, cur, result.thresholds)
