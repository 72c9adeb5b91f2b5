"""Procedural, seeded textures: printed paper, a colourful poster, low-texture surfaces.

All textures are (H, W, 3) uint8 BGR images; their resolution is given in pixels per metre so
that the renderer can map them onto planes of a known size. Features appear at several scales
(letters, figure lines, photo-like blobs) so that Shi-Tomasi corners are found near and far.
"""

from __future__ import annotations

import string

import cv2
import numpy as np

#: Default texture resolution, pixels per metre (about 2x the image resolution at 0.5 m).
PIXELS_PER_METRE = 1000.0

_FONTS = (
    cv2.FONT_HERSHEY_SIMPLEX,
    cv2.FONT_HERSHEY_DUPLEX,
    cv2.FONT_HERSHEY_COMPLEX,
    cv2.FONT_HERSHEY_TRIPLEX,
)
_LETTERS = string.ascii_letters + string.digits


def _word(rng: np.random.Generator, lo: int = 2, hi: int = 9) -> str:
    return ''.join(rng.choice(list(_LETTERS), size=int(rng.integers(lo, hi))))


def photo_noise(
    rng: np.random.Generator, height: int, width: int, scales: tuple[float, ...] = (3.0, 9.0, 27.0)
) -> np.ndarray:
    """Photo-like colour noise: blurred noise summed over several scales, (H, W, 3) uint8."""
    acc = np.zeros((height, width, 3), np.float32)
    for k, sigma in enumerate(scales):
        # blur coarse noise and upsample: the same spectrum as blurring full-size noise, cheaper
        f = max(1.0, sigma / 2.0)
        h, w = max(2, round(height / f)), max(2, round(width / f))
        noise = rng.standard_normal((h, w, 3)).astype(np.float32)
        blurred = cv2.GaussianBlur(noise, (0, 0), sigma / f)
        blurred = cv2.resize(blurred, (width, height), interpolation=cv2.INTER_CUBIC)
        blurred /= blurred.std() + 1e-6
        acc += blurred * (0.6**k)
    acc = (acc - acc.min()) / (np.ptp(acc) + 1e-6)
    tint = rng.uniform(0.4, 1.0, size=3).astype(np.float32)
    return np.clip(acc * 255 * tint + rng.uniform(0, 60), 0, 255).astype(np.uint8)


#: A rectangle of a texture, pixels: (x0, y0, x1, y1), x1 and y1 excluded.
Box = tuple[int, int, int, int]


def _text_block(
    img: np.ndarray, rng: np.random.Generator, box: Box, ink: tuple[int, int, int], scale: float
) -> None:
    """Lines of random words in ``box``."""
    x0, y0, x1, y1 = box
    font = int(rng.choice(_FONTS))
    thickness = max(1, round(scale * 1.6))
    (_, h), _ = cv2.getTextSize('Ag', font, scale, thickness)
    line_step = int(h * rng.uniform(1.6, 2.2)) + 1
    y = y0 + h
    while y < y1:
        x = x0
        while True:
            word = _word(rng)
            (w, _), _ = cv2.getTextSize(word, font, scale, thickness)
            if x + w > x1:
                break
            cv2.putText(img, word, (x, y), font, scale, ink, thickness, cv2.LINE_AA)
            x += w + int(h * rng.uniform(0.6, 1.2))
        y += line_step


def _figure(
    img: np.ndarray, rng: np.random.Generator, box: Box, ink: tuple[int, int, int]
) -> None:
    """A framed figure in ``box``: a photo patch, a plot with axes and curves, or a diagram."""
    x0, y0, x1, y1 = box
    w, h = x1 - x0, y1 - y0
    if w < 8 or h < 8:
        return
    kind = rng.integers(3)
    if kind == 0:
        img[y0:y1, x0:x1] = photo_noise(rng, h, w, scales=(1.5, 5.0, 15.0))
    elif kind == 1:
        cv2.line(img, (x0 + 5, y1 - 5), (x1 - 5, y1 - 5), ink, 2)
        cv2.line(img, (x0 + 5, y1 - 5), (x0 + 5, y0 + 5), ink, 2)
        xs = np.linspace(x0 + 8, x1 - 8, 40)
        for _ in range(int(rng.integers(1, 4))):
            ys = np.cumsum(rng.normal(0, h / 25, 40)) + rng.uniform(y0 + h / 3, y1 - h / 3)
            pts = np.column_stack([xs, np.clip(ys, y0 + 6, y1 - 6)]).astype(np.int32)
            color = tuple(int(c) for c in rng.integers(0, 200, 3))
            cv2.polylines(img, [pts], False, color, 2, cv2.LINE_AA)
            for p in pts[:: int(rng.integers(4, 9))]:
                cv2.rectangle(
                    img, (int(p[0]) - 3, int(p[1]) - 3), (int(p[0]) + 3, int(p[1]) + 3), color, -1
                )
    else:
        for _ in range(int(rng.integers(4, 10))):
            cx, cy = int(rng.integers(x0, x1)), int(rng.integers(y0, y1))
            bw, bh = int(rng.integers(8, max(9, w // 3))), int(rng.integers(8, max(9, h // 3)))
            color = tuple(int(c) for c in rng.integers(0, 220, 3))
            if rng.random() < 0.5:
                cv2.rectangle(
                    img,
                    (cx, cy),
                    (min(cx + bw, x1), min(cy + bh, y1)),
                    color,
                    int(rng.choice([-1, 2])),
                )
            else:
                cv2.circle(img, (cx, cy), min(bw, bh) // 2, color, int(rng.choice([-1, 2])))
            cv2.line(
                img,
                (cx, cy),
                (int(rng.integers(x0, x1)), int(rng.integers(y0, y1))),
                ink,
                1,
                cv2.LINE_AA,
            )
    cv2.rectangle(img, (x0, y0), (x1 - 1, y1 - 1), ink, 1)


def paper_texture(
    rng: np.random.Generator,
    width_m: float,
    height_m: float,
    ppm: float = PIXELS_PER_METRE,
    contrast: float | None = None,
) -> np.ndarray:
    """A printed sheet: title, text columns, figures and photos on off-white paper.

    Args:
        rng: random generator (the texture is a pure function of its state).
        width_m, height_m: sheet size, metres.
        ppm: texture resolution, pixels per metre.
        contrast: ink darkness in (0, 1]; drawn at random in [0.45, 1] when None.

    Returns:
        (round(height_m * ppm), round(width_m * ppm), 3) uint8 BGR.
    """
    w, h = round(width_m * ppm), round(height_m * ppm)
    paper = rng.uniform(215, 250)
    img = np.full((h, w, 3), paper, np.uint8)
    img[:] = np.clip(img + rng.normal(0, 2, (1, 1, 3)), 0, 255).astype(np.uint8)
    contrast = float(rng.uniform(0.45, 1.0)) if contrast is None else contrast
    ink_level = int(paper * (1 - contrast))
    ink = (ink_level, ink_level, ink_level)
    margin = int(0.06 * min(w, h))
    # title
    title_h = int(h * rng.uniform(0.06, 0.12))
    title = (margin, margin, w - margin, margin + title_h)
    _text_block(img, rng, title, ink, scale=max(0.8, title_h / 40))
    y = margin + title_h + margin // 2
    n_cols = int(rng.integers(1, 3))
    col_w = (w - 2 * margin - (n_cols - 1) * margin // 2) // n_cols
    for c in range(n_cols):
        x0 = margin + c * (col_w + margin // 2)
        yy = y
        while yy < h - margin - 20:
            block = int(rng.uniform(0.12, 0.35) * h)
            y1 = min(yy + block, h - margin)
            box = (x0, yy, x0 + col_w, y1)
            if rng.random() < 0.45:
                _figure(img, rng, box, ink)
            else:
                _text_block(img, rng, box, ink, scale=float(rng.uniform(0.45, 1.1)) * ppm / 1000)
            yy = y1 + margin // 3
    return img


def poster_texture(
    rng: np.random.Generator, width_m: float, height_m: float, ppm: float = PIXELS_PER_METRE
) -> np.ndarray:
    """A colourful poster: warm photo-like background, large words, pictures and logos."""
    w, h = round(width_m * ppm), round(height_m * ppm)
    base = np.zeros((h, w, 3), np.float32)
    gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
    base[..., 2] = 200 + 40 * np.sin(gx / w * 3 + rng.uniform(0, 6))  # red
    base[..., 1] = 150 + 50 * np.cos(gy / h * 2 + rng.uniform(0, 6))  # green
    base[..., 0] = 40 + 30 * np.sin((gx + gy) / (w + h) * 5)  # blue
    img = np.clip(base * 0.7 + photo_noise(rng, h, w, (6.0, 20.0, 60.0)) * 0.3, 0, 255)
    img = img.astype(np.uint8)
    for _ in range(int(rng.integers(6, 10))):  # pictures
        pw, ph = int(rng.uniform(0.08, 0.2) * w), int(rng.uniform(0.15, 0.35) * h)
        x0, y0 = int(rng.integers(0, w - pw)), int(rng.integers(0, h - ph))
        _figure(img, rng, (x0, y0, x0 + pw, y0 + ph), (20, 20, 20))
    for _ in range(int(rng.integers(14, 20))):  # big words
        word = _word(rng, 4, 11)
        scale = float(rng.uniform(1.2, 3.5)) * ppm / 1000
        font = int(rng.choice(_FONTS))
        thick = max(2, int(scale * 3))
        (tw, th), _ = cv2.getTextSize(word, font, scale, thick)
        x, y = int(rng.integers(0, max(1, w - tw))), int(rng.integers(th, h))
        cv2.putText(img, word, (x + 3, y + 3), font, scale, (60, 30, 20), thick + 2, cv2.LINE_AA)
        cv2.putText(img, word, (x, y), font, scale, (250, 245, 240), thick, cv2.LINE_AA)
    caption = (int(0.05 * w), int(0.8 * h), int(0.95 * w), h - 5)
    _text_block(img, rng, caption, (40, 20, 20), scale=0.9 * ppm / 1000)
    return img


def low_texture(
    rng: np.random.Generator,
    width_px: int,
    height_px: int,
    base: float = 150.0,
    amplitude: float = 12.0,
) -> np.ndarray:
    """A smooth, nearly uniform grey surface (few corners), (H, W, 3) uint8."""
    gy, gx = np.mgrid[0:height_px, 0:width_px].astype(np.float32)
    angle = rng.uniform(0, np.pi)
    ramp = np.cos(angle) * gx / width_px + np.sin(angle) * gy / height_px
    blotch = cv2.GaussianBlur(
        rng.standard_normal((height_px, width_px)).astype(np.float32),
        (0, 0),
        max(width_px, height_px) / 12,
    )
    blotch /= blotch.std() + 1e-6
    val = base + amplitude * (ramp - 0.5) + 0.4 * amplitude * blotch
    tint = rng.uniform(0.92, 1.05, 3).astype(np.float32)
    return np.clip(val[..., None] * tint, 0, 255).astype(np.uint8)


def repeated_texture(
    rng: np.random.Generator, width_px: int, height_px: int, period_px: int, grout: bool = False
) -> np.ndarray:
    """One random motif tiled with period ``period_px`` (wallpaper, fabric, floor tiles).

    Many strong corners, all alike: descriptor matching finds several equally good candidates
    and a tracker can slip by one period.

    Args:
        rng: random generator.
        width_px, height_px: texture size, pixels.
        period_px: tile side, pixels (at least 8).
        grout: tiles separated by dark grout lines instead of a printed motif.

    Returns:
        (height_px, width_px, 3) uint8 BGR.
    """
    p = max(8, int(period_px))
    paper = float(rng.uniform(160, 235))
    tile = np.full((p, p, 3), paper, np.uint8)
    tint = rng.uniform(0.85, 1.0, 3)
    ink = tuple(int(c) for c in rng.uniform(15, 110) * tint)
    if grout:
        cv2.rectangle(tile, (0, 0), (p - 1, p - 1), ink, max(1, p // 16))
    else:
        font = int(rng.choice(_FONTS))
        scale = p / 45.0
        cv2.putText(
            tile,
            _word(rng, 1, 3),
            (p // 8, (2 * p) // 3),
            font,
            scale,
            ink,
            max(1, round(scale * 1.5)),
            cv2.LINE_AA,
        )
        r = max(2, p // 8)
        cx, cy = int(rng.integers(r, p - r)), int(rng.integers(r, p - r))
        cv2.circle(tile, (cx, cy), r, ink, -1, cv2.LINE_AA)
        cv2.line(tile, (0, p - 1 - p // 6), (p - 1, p - 1 - p // 6), ink, max(1, p // 20))
    reps = (-(-height_px // p), -(-width_px // p), 1)
    return np.ascontiguousarray(np.tile(tile, reps)[:height_px, :width_px])


def mip_levels(texture: np.ndarray, min_size: int = 16) -> list[np.ndarray]:
    """The texture and its successive cv2.pyrDown halvings down to ``min_size`` pixels."""
    levels = [texture]
    while min(levels[-1].shape[:2]) // 2 >= min_size:
        levels.append(cv2.pyrDown(levels[-1]))
    return levels


__all__ = [
    'PIXELS_PER_METRE',
    'low_texture',
    'mip_levels',
    'paper_texture',
    'photo_noise',
    'poster_texture',
    'repeated_texture',
]
