"""The ``storeroom`` scene: the second rendering style, a stand-in for another renderer.

Boxes and crates of 0.2-0.9 m on a flagstone floor, a tall shelf, a brick back wall about 6 m
behind the scene target and a wooden side wall, all lit by one directional light
(:func:`~initsel_ros.synth.materials.shade`): depths from under 1 m (a crate in front of a
camera moving in) to 11 m, many small planes at every orientation, and textures made by
generators the first style's scenes do not use. The synthetic trajectories look at the same
scene target, so every trajectory kind renders it; a box drawn where a camera of the near or
far trajectory, or of the generated ones, would stand in or just above it is drawn again.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from initsel_ros.synth import materials as mat
from initsel_ros.synth.scene import _NOMINAL_VIEW, _UP, Plane, make_plane

#: Distance of the brick back wall behind the scene target, metres (horizontal).
BACK_WALL = 6.0
#: Distance of the wooden side wall to the side of the scene target, metres.
SIDE_WALL = 5.0
#: Horizontal range around the target where boxes stand: (behind, in front), metres along
#: the cameras' mean viewing direction; in front of the target they are kept low.
BOX_DEPTH = (-3.5, 0.35)
LOW_BOX_HEIGHT = 0.35
#: Clearance kept between a box and any camera of :func:`camera_positions`, metres.
CLEARANCE = 0.3
#: Draws of a box's place before it is left out.
MAX_DRAWS = 20


@lru_cache(maxsize=1)
def camera_positions() -> np.ndarray:
    """(N, 3) where cameras stand: every pose of the near and far trajectories (the real
    hand-held path and its 2x-scaled copy) and the generated trajectories' viewpoints at 0.8-2.4
    m from the target (static, rotation, forward, arc, the centre of random), world frame."""
    from initsel_ros.synth.trajectories import make_trajectory, nominal_eye

    near = make_trajectory('near')[1][:, :3, 3]
    far = make_trajectory('far')[1][:, :3, 3]
    generated = np.array([nominal_eye(d) for d in np.linspace(0.8, 2.4, 17)])
    return np.concatenate((near, far, generated))


def clear_of_cameras(
    centre: np.ndarray, size: tuple[float, float, float], yaw: float, eyes: np.ndarray
) -> bool:
    """Whether no camera of ``eyes`` (N, 3) stands within :data:`CLEARANCE` of a box on the
    floor (its footprint grown by it, below its top plus it)."""
    a, b, h = size
    d = eyes[:, :2] - centre[:2]
    c, s = np.cos(yaw), np.sin(yaw)
    along, across = d @ [c, s], d @ [-s, c]
    inside = (
        (np.abs(along) < a / 2 + CLEARANCE)
        & (np.abs(across) < b / 2 + CLEARANCE)
        & (eyes[:, 2] < h + CLEARANCE)
    )
    return not inside.any()


def _axes() -> tuple[np.ndarray, np.ndarray]:
    """Unit horizontal vectors toward the cameras (``ahead``) and to their left (``side``)."""
    ahead = np.array([_NOMINAL_VIEW[0], _NOMINAL_VIEW[1], 0.0])
    ahead /= np.linalg.norm(ahead)
    return ahead, np.cross(_UP, ahead)


def _upright(
    name: str,
    centre_bottom: np.ndarray,
    normal: np.ndarray,
    width: float,
    texture: np.ndarray,
    ppm: float,
    light: np.ndarray,
    ambient: float,
) -> Plane:
    """A vertical face whose bottom edge is centred on ``centre_bottom``, facing ``normal``."""
    u = np.cross(normal, _UP)  # u x (-up) = normal
    height = texture.shape[0] / ppm
    origin = centre_bottom - u * width / 2 + _UP * height
    return make_plane(name, origin, u, -_UP, mat.shade(texture, normal, light, ambient), ppm)


def _box(
    rng: np.random.Generator,
    name: str,
    centre: np.ndarray,
    size: tuple[float, float, float],
    yaw: float,
    ppm: float,
    light: np.ndarray,
    ambient: float,
) -> list[Plane]:
    """The top and four sides of a box standing on the floor (crate or cardboard)."""
    a, b, h = size
    e1 = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    e2 = np.cross(_UP, e1)
    crate = rng.random() < 0.4

    def texture(width: float, height: float) -> np.ndarray:
        w, hh = max(8, round(width * ppm)), max(8, round(height * ppm))
        return mat.wood_texture(rng, w, hh) if crate else mat.cardboard_texture(rng, w, hh)

    planes = []
    for k, (normal, half, along) in enumerate(((e1, a, b), (-e1, a, b), (e2, b, a), (-e2, b, a))):
        bottom = centre + normal * half / 2
        tex = texture(along, h)
        planes.append(_upright(f'{name}_side{k}', bottom, normal, along, tex, ppm, light, ambient))
    top = texture(a, b)
    origin = centre - e1 * a / 2 - e2 * b / 2 + _UP * h
    planes.append(
        make_plane(f'{name}_top', origin, e1, e2, mat.shade(top, _UP, light, ambient), ppm)
    )
    return planes


def storeroom_planes(rng: np.random.Generator, target: np.ndarray, ppm: float) -> list[Plane]:
    """The storeroom's planes around ``target`` (the trajectories' look-at point)."""
    ahead, side = _axes()
    light = rng.uniform([-0.6, -0.6, 0.5], [0.6, 0.6, 1.0])
    light /= np.linalg.norm(light)
    ambient = float(rng.uniform(0.35, 0.55))
    base = np.array([target[0], target[1], 0.0])
    floor_ppm, wall_ppm = 150.0, 100.0
    half = 6.0  # the floor: 12 m x 12 m centred on the target
    floor = mat.stone_texture(rng, round(2 * half * floor_ppm), round(2 * half * floor_ppm), 45.0)
    origin = base - ahead * half - side * half
    planes = [
        make_plane('floor', origin, ahead, side, mat.shade(floor, _UP, light, ambient), floor_ppm)
    ]
    brick = mat.brick_texture(rng, round(14 * wall_ppm), round(4 * wall_ppm), (24.0, 8.0))
    back = base - ahead * BACK_WALL
    planes.append(_upright('back_wall', back, ahead, 14.0, brick, wall_ppm, light, ambient))
    panels = mat.wood_texture(rng, round(12 * wall_ppm), round(3 * wall_ppm))
    side_wall = base + side * SIDE_WALL - ahead * 1.0
    planes.append(_upright('side_wall', side_wall, -side, 12.0, panels, wall_ppm, light, ambient))
    shelf = base - ahead * 2.6 + side * rng.uniform(-1.5, 1.5)
    planes += _box(
        rng,
        'shelf',
        shelf,
        (0.5, 1.6, 1.9),
        float(np.arctan2(ahead[1], ahead[0])),
        0.5 * ppm,
        light,
        ambient,
    )
    # one box at the target, so every trajectory's view centre has structure; then the rest
    boxes = [(0.0, 0.0)] + [(rng.uniform(*BOX_DEPTH), rng.uniform(-2.5, 2.5)) for _ in range(13)]
    eyes = camera_positions()
    for i, (s, lateral) in enumerate(boxes):
        for _ in range(MAX_DRAWS):  # (the draws in the order of the first version of the scene)
            tall = s < 0.0
            size = (
                float(rng.uniform(0.25, 0.8)),
                float(rng.uniform(0.25, 0.8)),
                float(rng.uniform(0.2, 0.9 if tall else LOW_BOX_HEIGHT)),
            )
            centre = base + ahead * s + side * lateral
            yaw = float(rng.uniform(0, np.pi))
            if clear_of_cameras(centre, size, yaw, eyes):
                planes += _box(rng, f'box{i}', centre, size, yaw, ppm, light, ambient)
                break
            s, lateral = rng.uniform(*BOX_DEPTH), rng.uniform(-2.5, 2.5)
    return planes


__all__ = [
    'BACK_WALL',
    'CLEARANCE',
    'SIDE_WALL',
    'camera_positions',
    'clear_of_cameras',
    'storeroom_planes',
]
