"""Procedural materials of the second rendering style (the ``storeroom`` scene): stone floor,
brick, wood and cardboard, and Lambertian shading under one directional light.

They share no generator with :mod:`initsel_ros.synth.textures` (printed paper and posters):
the corners a tracker finds here are cell and mortar junctions, grain and knots, not letters
and figures, so a model trained on the first style meets image statistics it never saw.
All textures are (H, W, 3) uint8 BGR and a pure function of the generator's state.
"""

from __future__ import annotations

import cv2
import numpy as np

from initsel_ros.synth.textures import photo_noise


def _cells(rng: np.random.Generator, height: int, width: int, cell_px: float) -> np.ndarray:
    """(H, W) int32 label of the nearest of jittered grid seeds (a Voronoi tessellation)."""
    ny, nx = max(1, round(height / cell_px)), max(1, round(width / cell_px))
    gy, gx = np.meshgrid(np.arange(ny), np.arange(nx), indexing='ij')
    ys = np.clip((gy + rng.uniform(0.1, 0.9, gy.shape)) * height / ny, 0, height - 1)
    xs = np.clip((gx + rng.uniform(0.1, 0.9, gx.shape)) * width / nx, 0, width - 1)
    seeds = np.full((height, width), 255, np.uint8)
    seeds[ys.astype(int).ravel(), xs.astype(int).ravel()] = 0
    _, labels = cv2.distanceTransformWithLabels(
        seeds, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL
    )
    return labels


def _edges(labels: np.ndarray, width_px: int) -> np.ndarray:
    """(H, W) bool: pixels within ``width_px`` of a boundary between labels."""
    edge = np.zeros(labels.shape, np.uint8)
    edge[:, 1:] |= (labels[:, 1:] != labels[:, :-1]).astype(np.uint8)
    edge[1:, :] |= (labels[1:, :] != labels[:-1, :]).astype(np.uint8)
    if width_px > 1:
        edge = cv2.dilate(edge, np.ones((width_px, width_px), np.uint8))
    return edge.astype(bool)


def _grain(rng: np.random.Generator, height: int, width: int, amount: float) -> np.ndarray:
    """(H, W, 1) float32 fine luminance grain, zero mean, about ``amount`` grey levels."""
    g = photo_noise(rng, height, width, (1.0, 3.0)).astype(np.float32).mean(axis=2)
    return ((g - g.mean()) / (g.std() + 1e-6) * amount)[..., None]


def stone_texture(
    rng: np.random.Generator, width_px: int, height_px: int, cell_px: float = 40.0
) -> np.ndarray:
    """Flagstones or pebbles: Voronoi cells of varied grey-brown tone, dark joints, grain."""
    labels = _cells(rng, height_px, width_px, cell_px)
    tones = rng.uniform(90, 190, labels.max() + 1).astype(np.float32)
    tint = rng.uniform(0.8, 1.0, 3).astype(np.float32)
    img = tones[labels][..., None] * tint + _grain(rng, height_px, width_px, 10.0)
    img[_edges(labels, max(1, round(cell_px / 12)))] *= 0.35
    return np.clip(img, 0, 255).astype(np.uint8)


def brick_texture(
    rng: np.random.Generator,
    width_px: int,
    height_px: int,
    brick_px: tuple[float, float] = (48.0, 16.0),
) -> np.ndarray:
    """Running-bond brickwork: per-brick red-brown tones, light mortar, grain."""
    bw, bh = brick_px
    rows = np.arange(height_px)[:, None] // bh
    offset = (rows % 2) * bw / 2
    cols = (np.arange(width_px)[None, :] + offset) // bw
    labels = (rows * (width_px // int(bw) + 2) + cols).astype(np.int64)
    n = int(labels.max()) + 1
    base = np.stack(
        [rng.uniform(40, 80, n), rng.uniform(50, 90, n), rng.uniform(120, 190, n)], axis=1
    ).astype(np.float32)
    img = base[labels] + _grain(rng, height_px, width_px, 12.0)
    mortar = max(1, round(bh / 8))
    joint = (np.arange(height_px)[:, None] % bh < mortar) | (
        (np.arange(width_px)[None, :] + offset) % bw < mortar
    )
    img[joint] = rng.uniform(170, 210)
    return np.clip(img, 0, 255).astype(np.uint8)


def wood_texture(rng: np.random.Generator, width_px: int, height_px: int) -> np.ndarray:
    """Planks of wood: warped grain rings along x, a few dark knots, seams between planks."""
    gy = np.arange(height_px, dtype=np.float32)[:, None]
    warp = photo_noise(rng, height_px, width_px, (20.0, 60.0)).astype(np.float32).mean(axis=2)
    warp = (warp - warp.mean()) / (warp.std() + 1e-6)
    period = float(rng.uniform(6.0, 14.0))
    rings = 0.5 + 0.5 * np.sin(2 * np.pi * (gy + 6.0 * warp) / period)
    tone = np.array([40, 90, 150], np.float32) * rng.uniform(0.8, 1.2)
    img = tone * (0.7 + 0.45 * rings[..., None]) + _grain(rng, height_px, width_px, 6.0)
    for _ in range(max(1, width_px * height_px // 40000)):
        centre = (int(rng.integers(width_px)), int(rng.integers(height_px)))
        axes = (int(rng.integers(4, 14)), int(rng.integers(3, 8)))
        cv2.ellipse(img, centre, axes, 0, 0, 360, (20, 35, 60), -1, cv2.LINE_AA)
    plank = int(rng.uniform(60, 120))
    img[(np.arange(height_px) % plank) < 2] *= 0.4
    return np.clip(img, 0, 255).astype(np.uint8)


def cardboard_texture(rng: np.random.Generator, width_px: int, height_px: int) -> np.ndarray:
    """A cardboard box face: brown board, a tape strip, stencilled marks and a label."""
    img = np.empty((height_px, width_px, 3), np.float32)
    img[:] = np.array([70, 120, 170], np.float32) * rng.uniform(0.8, 1.1)
    img += _grain(rng, height_px, width_px, 5.0)
    tape = max(2, height_px // 10)
    y = int(rng.integers(0, max(1, height_px - tape)))
    img[y : y + tape] = img[y : y + tape] * 0.8 + 30
    ink = (30.0, 30.0, 35.0)
    for _ in range(int(rng.integers(2, 5))):  # arrows, bars and circles in stencil ink
        x0, y0 = int(rng.integers(width_px)), int(rng.integers(height_px))
        size = int(rng.integers(max(3, height_px // 12), max(4, height_px // 4)))
        kind = int(rng.integers(3))
        if kind == 0:
            cv2.arrowedLine(img, (x0, y0 + size), (x0, y0), ink, max(1, size // 6), cv2.LINE_AA)
        elif kind == 1:
            cv2.rectangle(img, (x0, y0), (x0 + 2 * size, y0 + size // 3), ink, -1, cv2.LINE_AA)
        else:
            cv2.circle(img, (x0, y0), size // 2, ink, max(1, size // 8), cv2.LINE_AA)
    lw, lh = width_px // 3, height_px // 4
    lx, ly = int(rng.integers(0, width_px - lw + 1)), int(rng.integers(0, height_px - lh + 1))
    img[ly : ly + lh, lx : lx + lw] = 235
    for k in range(1, 4):  # barcode-like lines on the label
        yy = ly + k * lh // 4
        cv2.line(img, (lx + 3, yy), (lx + lw - 4, yy), ink, 1, cv2.LINE_AA)
    return np.clip(img, 0, 255).astype(np.uint8)


def shade(
    texture: np.ndarray, normal: np.ndarray, light: np.ndarray, ambient: float
) -> np.ndarray:
    """The texture under Lambertian shading: ``ambient + (1 - ambient) * max(0, n . l)``.

    Args:
        texture: (H, W, 3) uint8.
        normal: (3,) the surface's outward unit normal.
        light: (3,) unit direction toward the light.
        ambient: the share of light reaching every face, 0-1.
    """
    gain = ambient + (1.0 - ambient) * max(0.0, float(np.dot(normal, light)))
    return cv2.convertScaleAbs(texture, alpha=gain)


__all__ = ['brick_texture', 'cardboard_texture', 'shade', 'stone_texture', 'wood_texture']
