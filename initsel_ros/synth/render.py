"""Render a scene of textured planes: per-plane homography warps plus an exact z-buffer.

For each plane the texture is warped into the image with ``cv2.warpPerspective`` (restricted to
the plane's bounding box, mip level chosen from its distance), the plane's polygon (clipped at a
near plane) is rasterized as a mask, and per-pixel depth follows from the ray-plane intersection
``z = d / (n . K^-1 [x, y, 1])``. Depth is the camera-frame z in metres (as TUM), 0 where no
surface is hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.synth.scene import Plane, Scene

NEAR_PLANE = 0.05  # metres
_SHIFT = 4  # sub-pixel bits for polygon rasterization


def _clip_near(points: np.ndarray, near: float) -> np.ndarray:
    """Clip a convex polygon (M, 3) in camera coordinates to z >= near."""
    out = []
    m = len(points)
    for i in range(m):
        a, b = points[i], points[(i + 1) % m]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            s = (near - a[2]) / (b[2] - a[2])
            out.append(a + s * (b - a))
    return np.array(out).reshape(-1, 3)


def render_frame(scene: Scene, intrinsics: Intrinsics, T_wc: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Render one ideal (noise-free, pinhole) frame.

    Args:
        scene: the planes.
        intrinsics: pinhole camera (distortion ignored here).
        T_wc: (4, 4) camera-to-world pose.

    Returns:
        ``(image (H, W, 3) uint8 BGR, depth (H, W) float32 metres, 0 = no surface)``.
    """
    W, H = intrinsics.width, intrinsics.height
    K = intrinsics.K
    K_inv = np.linalg.inv(K)
    T_cw = np.linalg.inv(T_wc)
    R_cw, t_cw = T_cw[:3, :3], T_cw[:3, 3]
    image = np.empty((H, W, 3), np.uint8)
    image[:] = scene.background
    # inverse depth buffer (0 = nothing), scaled by (1 + _TIE) so later coplanar planes win
    wbuf = np.zeros((H, W), np.float32)
    for plane in scene.planes:
        _draw_plane(plane, K, K_inv, R_cw, t_cw, image, wbuf)
    with np.errstate(divide='ignore'):
        depth = np.float32(1.0 + _TIE) / wbuf
    depth[wbuf <= 0] = 0.0
    return image, depth


_TIE = 1e-5


def _draw_plane(plane: Plane, K: np.ndarray, K_inv: np.ndarray, R_cw: np.ndarray,
                t_cw: np.ndarray, image: np.ndarray, wbuf: np.ndarray) -> None:
    H, W = wbuf.shape
    corners_c = plane.corners() @ R_cw.T + t_cw
    poly = _clip_near(corners_c, NEAR_PLANE)
    if len(poly) < 3:
        return
    proj = poly @ K.T
    px = proj[:, :2] / proj[:, 2:3]
    x0, y0 = np.floor(px.min(axis=0)).astype(int)
    x1, y1 = np.ceil(px.max(axis=0)).astype(int) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if x1 <= x0 or y1 <= y0:
        return
    bw, bh = x1 - x0, y1 - y0
    # plane in camera frame: n_c . X = d_c; inverse depth 1/z = (n_c . K^-1 [x, y, 1]) / d_c
    n_c = R_cw @ plane.normal
    o_c = R_cw @ plane.origin + t_cw
    d_c = float(n_c @ o_c)
    if abs(d_c) < 1e-9:
        return  # seen edge-on
    a, b, c = (n_c @ K_inv) * (1.0 + _TIE) / d_c
    xs = np.arange(x0, x1, dtype=np.float32) * np.float32(a)
    ys = np.arange(y0, y1, dtype=np.float32) * np.float32(b) + np.float32(c)
    w = xs[None, :] + ys[:, None]
    mask = np.zeros((bh, bw), np.uint8)
    pts = np.round((px - [x0, y0]) * (1 << _SHIFT)).astype(np.int32)
    cv2.fillConvexPoly(mask, pts, 1, cv2.LINE_8, _SHIFT)
    wroi = wbuf[y0:y1, x0:x1]
    closer = cv2.compare(w, wroi, cv2.CMP_GE)
    draw = cv2.bitwise_and(mask, closer)
    if not cv2.countNonZero(draw):
        return
    # mip level: texture pixels per image pixel at the nearest visible point
    z_near = max(float(poly[:, 2].min()), NEAR_PLANE)
    ratio = plane.ppm * z_near / K[0, 0]
    level = int(np.clip(np.floor(np.log2(max(ratio, 1.0))), 0, len(plane.levels) - 1))
    tex = plane.levels[level]
    step = (1 << level) / plane.ppm
    Hm = K @ np.column_stack([R_cw @ plane.u * step, R_cw @ plane.v * step, o_c])
    Hm = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]]) @ Hm
    color = cv2.warpPerspective(tex, Hm, (bw, bh), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REFLECT)
    cv2.copyTo(w, draw, wroi)  # in place: the ROI views share memory with the buffers
    cv2.copyTo(color, draw, image[y0:y1, x0:x1])


@dataclass(frozen=True)
class Effects:
    """Sensor effects applied after rendering (all off = the ideal image).

    Attributes:
        noise: Gaussian pixel noise standard deviation, grey levels (0-255).
        blur: Gaussian blur sigma, pixels (0 = none).
        exposure: amplitude of slow exposure changes, relative gain (e.g. 0.15 = +-15 %).
    """

    noise: float = 1.5
    blur: float = 0.0
    exposure: float = 0.0


def exposure_gains(n: int, amplitude: float, rng: np.random.Generator,
                   rate_hz: float = 30.0) -> np.ndarray:
    """(n,) smooth random gains around 1 (a sum of slow sinusoids), amplitude relative."""
    if amplitude <= 0 or n == 0:
        return np.ones(n)
    t = np.arange(n) / rate_hz
    freqs = rng.uniform(0.05, 0.4, 3)
    phases = rng.uniform(0, 2 * np.pi, 3)
    wave = np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0) / 3
    return 1.0 + amplitude * wave / max(np.abs(wave).max(), 1e-9)


def apply_effects(image: np.ndarray, effects: Effects, gain: float,
                  rng: np.random.Generator) -> np.ndarray:
    """Blur, exposure gain and noise on a (H, W, 3) uint8 image; returns uint8."""
    if effects.blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), effects.blur)
    if effects.noise <= 0 and gain == 1.0:
        return image
    out = image.astype(np.float32)
    if gain != 1.0:
        out *= np.float32(gain)
    if effects.noise > 0:
        out += rng.standard_normal(out.shape, dtype=np.float32) * np.float32(effects.noise)
    return np.clip(out, 0, 255).astype(np.uint8)


class Distorter:
    """Applies lens distortion (OpenCV model) to ideal pinhole renders by remapping.

    Each output pixel takes the ideal pixel that its undistorted ray falls on; colour is
    interpolated bilinearly, depth by nearest neighbour (kept exact).
    """

    def __init__(self, intrinsics: Intrinsics) -> None:
        W, H = intrinsics.width, intrinsics.height
        K = intrinsics.K
        grid = np.mgrid[0:H, 0:W][::-1].reshape(2, -1).T.astype(np.float32)
        und = cv2.undistortPoints(grid.reshape(-1, 1, 2), K, np.array(intrinsics.distortion),
                                  P=K).reshape(H, W, 2)
        self.map_x = np.ascontiguousarray(und[..., 0])
        self.map_y = np.ascontiguousarray(und[..., 1])

    def __call__(self, image: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        img = cv2.remap(image, self.map_x, self.map_y, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT)
        dep = cv2.remap(depth, self.map_x, self.map_y, cv2.INTER_NEAREST,
                        borderMode=cv2.BORDER_CONSTANT)
        return img, dep


__all__ = ['Distorter', 'Effects', 'apply_effects', 'exposure_gains', 'render_frame']
