"""Synthetic images shared by the tracking, selector and node tests."""

from __future__ import annotations

import cv2
import numpy as np


def texture(seed: int = 0, shape=(480, 640)) -> np.ndarray:
    """A smooth random texture (uint8, rich in corners) of ``shape``."""
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0, 255, (shape[0] // 8, shape[1] // 8)).astype(np.float32)
    img = cv2.resize(coarse, shape[::-1], interpolation=cv2.INTER_CUBIC)
    img += rng.normal(0, 4, shape).astype(np.float32)
    return np.clip(cv2.GaussianBlur(img, (3, 3), 0.8), 0, 255).astype(np.uint8)


def shifted(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``img`` translated by (dx, dy) pixels, borders reflected (a small pan's flow)."""
    M = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(
        img, M, img.shape[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
    )
