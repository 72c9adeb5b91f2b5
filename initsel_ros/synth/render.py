"""Render a scene of textured planes: per-plane homography warps plus an exact z-buffer.

For each plane the texture is warped into the image with ``cv2.warpPerspective`` (restricted to
the plane's bounding box, mip level chosen from its distance), the plane's polygon (clipped at a
near plane) is rasterized as a mask, and per-pixel depth follows from the ray-plane intersection
``z = d / (n . K^-1 [x, y, 1])``. Depth is the camera-frame z in metres (as TUM), 0 where no
surface is hit.
"""

from __future__ import annotations

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.synth.effects import Effects, exposure_gains  # noqa: F401 (former home)
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


def render_frame(
    scene: Scene,
    intrinsics: Intrinsics,
    T_wc: np.ndarray,
    rows: tuple[int, int] | None = None,
    color: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Render one ideal (noise-free, pinhole) frame, or a band of its rows.

    Args:
        scene: the planes.
        intrinsics: pinhole camera (distortion ignored here).
        T_wc: (4, 4) camera-to-world pose.
        rows: ``(first, stop)`` renders only image rows ``first <= y < stop`` (a band of a
            rolling-shutter frame); the arrays returned are that band.
        color: False skips the texture warps (the image is left at the background colour);
            depth is still exact.

    Returns:
        ``(image (h, W, 3) uint8 BGR, depth (h, W) float32 metres, 0 = no surface)``, ``h`` the
        image height or the band's.
    """
    W, H = intrinsics.width, intrinsics.height
    row0, row1 = (0, H) if rows is None else (max(int(rows[0]), 0), min(int(rows[1]), H))
    if row1 <= row0:
        raise ValueError(f'empty row band {rows} for an image of {H} rows')
    K = intrinsics.K
    K_inv = np.linalg.inv(K)
    T_cw = np.linalg.inv(T_wc)
    R_cw, t_cw = T_cw[:3, :3], T_cw[:3, 3]
    image = np.empty((row1 - row0, W, 3), np.uint8)
    image[:] = scene.background
    # inverse depth buffer (0 = nothing), scaled by (1 + _TIE) so later coplanar planes win
    wbuf = np.zeros((row1 - row0, W), np.float32)
    for plane in scene.planes:
        _draw_plane(plane, K, K_inv, R_cw, t_cw, image, wbuf, row0, color)
    with np.errstate(divide='ignore'):
        depth = np.float32(1.0 + _TIE) / wbuf
    depth[wbuf <= 0] = 0.0
    return image, depth


_TIE = 1e-5


def _draw_plane(
    plane: Plane,
    K: np.ndarray,
    K_inv: np.ndarray,
    R_cw: np.ndarray,
    t_cw: np.ndarray,
    image: np.ndarray,
    wbuf: np.ndarray,
    row0: int = 0,
    color: bool = True,
) -> None:
    """Draw one plane into the buffers, which hold image rows ``row0 .. row0 + len(wbuf)``."""
    H, W = wbuf.shape
    corners_c = plane.corners() @ R_cw.T + t_cw
    poly = _clip_near(corners_c, NEAR_PLANE)
    if len(poly) < 3:
        return
    proj = poly @ K.T
    px = proj[:, :2] / proj[:, 2:3]
    x0, y0 = np.floor(px.min(axis=0)).astype(int)
    x1, y1 = np.ceil(px.max(axis=0)).astype(int) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, row0), min(x1, W), min(y1, row0 + H)
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
    wroi = wbuf[y0 - row0 : y1 - row0, x0:x1]
    closer = cv2.compare(w, wroi, cv2.CMP_GE)
    draw = cv2.bitwise_and(mask, closer)
    if not cv2.countNonZero(draw):
        return
    cv2.copyTo(w, draw, wroi)  # in place: the ROI views share memory with the buffers
    if not color:
        return
    # mip level: texture pixels per image pixel at the nearest visible point
    z_near = max(float(poly[:, 2].min()), NEAR_PLANE)
    ratio = plane.ppm * z_near / K[0, 0]
    level = int(np.clip(np.floor(np.log2(max(ratio, 1.0))), 0, len(plane.levels) - 1))
    tex = plane.levels[level]
    step = (1 << level) / plane.ppm
    Hm = K @ np.column_stack([R_cw @ plane.u * step, R_cw @ plane.v * step, o_c])
    Hm = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]]) @ Hm
    colour = cv2.warpPerspective(
        tex, Hm, (bw, bh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
    )
    cv2.copyTo(colour, draw, image[y0 - row0 : y1 - row0, x0:x1])


class Distorter:
    """Lens distortion (OpenCV's standard or fisheye model) of ideal pinhole renders, by
    remapping.

    Each output (sensor) pixel takes the ideal pixel that its undistorted ray falls on; colour
    is interpolated bilinearly, depth by nearest neighbour (kept exact). The ideal render is
    made on a larger ``canvas`` (the same focal lengths, the principal point shifted) that
    holds every undistorted ray, so that barrel-distorted frames have no empty borders.

    Attributes:
        camera: the distorted camera (sensor image size and coefficients).
        canvas: the pinhole camera to render ideal frames with.
        map_x, map_y: (H, W) float32 canvas pixel of each sensor pixel.

    Raises:
        ConfigError: when the coefficients do not map the image one-to-one (the distortion
            polynomial folds over inside the field of view).
    """

    def __init__(self, camera: Intrinsics) -> None:
        W, H = camera.width, camera.height
        K = camera.K
        grid = np.mgrid[0:H, 0:W][::-1].reshape(2, -1).T.astype(np.float64)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
        dist = camera.lens_coefficients
        # (camera.undistort_pixels, to 1e-10 rather than OpenCV's default precision)
        if camera.fisheye:
            und = cv2.fisheye.undistortPoints(
                grid.reshape(-1, 1, 2), K, dist, R=np.eye(3), P=K, criteria=criteria
            ).reshape(-1, 2)
        else:
            und = cv2.undistortPoints(
                grid.reshape(-1, 1, 2), K, dist, None, None, K, criteria
            ).reshape(-1, 2)
        rays = np.column_stack(
            [(und - [camera.cx, camera.cy]) / [camera.fx, camera.fy], np.ones(len(und))]
        )
        err = np.linalg.norm(camera.project(rays) - grid, axis=1)
        if not np.all(np.isfinite(und)) or np.max(err) > 0.05:
            raise ConfigError(
                f'distortion {camera.distortion} does not map the {W}x{H} image one-to-one '
                f'(round trip error up to {np.nanmax(err):.2g} px): use smaller coefficients'
            )
        left = max(0, int(np.ceil(-und[:, 0].min())) + 2)
        top = max(0, int(np.ceil(-und[:, 1].min())) + 2)
        right = max(0, int(np.ceil(und[:, 0].max())) - W + 3)
        bottom = max(0, int(np.ceil(und[:, 1].max())) - H + 3)
        self.camera = camera
        self.canvas = Intrinsics(
            camera.fx,
            camera.fy,
            camera.cx + left,
            camera.cy + top,
            W + left + right,
            H + top + bottom,
        )
        und = und.reshape(H, W, 2).astype(np.float32)
        self.map_x = np.ascontiguousarray(und[..., 0] + np.float32(left))
        self.map_y = np.ascontiguousarray(und[..., 1] + np.float32(top))

    def rows_needed(self, first: int, stop: int) -> tuple[int, int]:
        """Canvas rows ``(first, stop)`` that sensor rows ``first <= y < stop`` sample from."""
        band = self.map_y[first:stop]
        lo = max(int(np.floor(band.min())) - 1, 0)
        hi = min(int(np.ceil(band.max())) + 2, self.canvas.height)
        return lo, hi

    def image(
        self,
        canvas_band: np.ndarray,
        first: int = 0,
        stop: int | None = None,
        canvas_row0: int = 0,
    ) -> np.ndarray:
        """Distort colour: sensor rows ``first:stop`` from a canvas band starting at row
        ``canvas_row0`` (the whole canvas by default)."""
        stop = self.camera.height if stop is None else stop
        return cv2.remap(
            canvas_band,
            self.map_x[first:stop],
            self.map_y[first:stop] - np.float32(canvas_row0),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )

    def depth(self, canvas_depth: np.ndarray) -> np.ndarray:
        """Distort a whole-canvas depth map (nearest neighbour)."""
        return cv2.remap(
            canvas_depth, self.map_x, self.map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT
        )

    def __call__(self, image: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distort a whole-canvas colour image and depth map."""
        return self.image(image), self.depth(depth)


__all__ = ['Distorter', 'render_frame']
