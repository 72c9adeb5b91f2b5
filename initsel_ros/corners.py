"""Which tracked points are corners, and which lie on a straight edge.

Lucas-Kanade fixes a point along each direction in which its window's intensity varies: the
structure tensor (the sum of the gradient's outer products over the window) has one
eigenvalue per direction. At a corner both are large. On a straight edge one is large and the
other comes from noise and antialiasing only, so the track is free to slide along the edge:
as the view changes, it follows whatever the edge's ends and the shading do, not a point of
the scene. Shi-Tomasi detection ranks points by the smaller eigenvalue relative to the
strongest corner of the frame, and a frame of nearly untextured surfaces has few corners: its
detections fill up with points along the edges between the surfaces (FAST, ORB's detector,
never fires on a straight edge; SIFT drops keypoints whose principal curvatures differ more
than tenfold, :data:`EDGE_ISOTROPY`).

:func:`structure_isotropy` measures the ratio of the two eigenvalues at given points, from the
same 3x3 Sobel gradients and box window as OpenCV's ``cornerEigenValsAndVecs``, read from the
points' own patches only (no filtering of the whole frame).
"""

from __future__ import annotations

import numpy as np

#: A point whose structure tensor's eigenvalues differ more than tenfold lies on an edge (the
#: bound of SIFT's edge test, Lowe 2004, there on the Hessian's principal curvatures).
EDGE_ISOTROPY = 0.1
#: The window the structure tensor is summed over, pixels (Shi-Tomasi detection's
#: ``TrackerConfig.block_size``).
DEFAULT_BLOCK_PX = 7


def structure_isotropy(
    gray: np.ndarray, points: np.ndarray, block_px: int = DEFAULT_BLOCK_PX
) -> np.ndarray:
    """The smaller over the larger eigenvalue of the structure tensor at each point.

    Args:
        gray: (H, W) image (uint8 or float).
        points: (N, 2) pixels (rounded to the nearest; a window that would leave the image
            is moved inside it).
        block_px: side of the window the gradients' products are summed over (odd).

    Returns:
        (N,) float64 in [0, 1]: 1 where the window varies alike in every direction, near 0
        on a straight edge, 0 on a flat patch.
    """
    image = np.asarray(gray, dtype=np.float32)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    h, w = image.shape[:2]
    r = block_px // 2
    side = block_px + 2  # the Sobel kernel reads one pixel beyond the window
    if len(pts) == 0 or h < side or w < side:
        return np.zeros(len(pts))
    x = np.clip(np.rint(pts[:, 0]).astype(np.int64), r + 1, w - r - 2)
    y = np.clip(np.rint(pts[:, 1]).astype(np.int64), r + 1, h - r - 2)
    patches = np.lib.stride_tricks.sliding_window_view(image, (side, side))
    p = patches[y - r - 1, x - r - 1]  # (N, side, side)
    across = p[:, :, 2:] - p[:, :, :-2]  # (N, side, block): [-1, 0, 1] along x
    gx = across[:, :-2] + 2.0 * across[:, 1:-1] + across[:, 2:]  # [1, 2, 1] along y
    down = p[:, 2:, :] - p[:, :-2, :]
    gy = down[:, :, :-2] + 2.0 * down[:, :, 1:-1] + down[:, :, 2:]
    a = np.einsum('nij,nij->n', gx, gx, dtype=np.float64)
    b = np.einsum('nij,nij->n', gx, gy, dtype=np.float64)
    c = np.einsum('nij,nij->n', gy, gy, dtype=np.float64)
    half_trace = 0.5 * (a + c)
    spread = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    larger = half_trace + spread
    smaller = np.maximum(half_trace - spread, 0.0)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(larger > 0.0, smaller / larger, 0.0)


__all__ = ['DEFAULT_BLOCK_PX', 'EDGE_ISOTROPY', 'structure_isotropy']
