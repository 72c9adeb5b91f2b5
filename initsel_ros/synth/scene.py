"""Scenes of textured planar rectangles, in the world frame of the TUM fr3 motion capture.

The default scene is modelled on fr3/structure_texture: printed sheets lying on the floor in front
of an upright poster bent in a zig-zag, in a room of low-texture floor and wall. Positions were
measured by back-projecting the real depth maps of the near sequence with its ground truth
(world z is up, the floor is z = 0, the poster stands about 2.5-3 m along -x of the mocap
origin; the real camera sees it from 0.7-1.5 m).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from functools import lru_cache

import numpy as np

from initsel_ros.synth import textures as tx


class SceneName(str, Enum):
    """The scene variants."""

    STRUCTURE_TEXTURE = 'structure_texture'
    FLOOR = 'floor'
    ZIGZAG = 'zigzag'
    LOW_TEXTURE = 'low_texture'
    WALL = 'wall'
    REPEATED = 'repeated'
    STOREROOM = 'storeroom'


@dataclass(frozen=True, eq=False)
class Plane:
    """A textured rectangle in the world.

    World point of texture pixel (x, y) at mip level L: ``origin + (u * x + v * y) * 2**L / ppm``.

    Attributes:
        name: label for debugging.
        origin: (3,) metres, world position of the texture's top-left corner.
        u: (3,) unit vector along texture x (columns).
        v: (3,) unit vector along texture y (rows), orthogonal to ``u``.
        size: (width, height) metres.
        ppm: texture pixels per metre at level 0.
        levels: mip pyramid of the (H, W, 3) uint8 BGR texture, level 0 first.
    """

    name: str
    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    size: tuple[float, float]
    ppm: float
    levels: list[np.ndarray] = field(repr=False)

    @property
    def normal(self) -> np.ndarray:
        """(3,) unit normal u x v."""
        return np.cross(self.u, self.v)

    def corners(self) -> np.ndarray:
        """(4, 3) world corners in order (0,0), (w,0), (w,h), (0,h)."""
        w, h = self.size
        return np.array(
            [
                self.origin,
                self.origin + w * self.u,
                self.origin + w * self.u + h * self.v,
                self.origin + h * self.v,
            ]
        )


def make_plane(
    name: str, origin: np.ndarray, u: np.ndarray, v: np.ndarray, texture: np.ndarray, ppm: float
) -> Plane:
    """A plane whose size follows from the texture size and ``ppm``."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    v = np.asarray(v, float) / np.linalg.norm(v)
    h, w = texture.shape[:2]
    return Plane(
        name, np.asarray(origin, float), u, v, (w / ppm, h / ppm), ppm, tx.mip_levels(texture)
    )


@dataclass(frozen=True, eq=False)
class Scene:
    """Planes drawn in order (later planes win depth ties, e.g. sheets lying on the floor).

    Attributes:
        name: the variant.
        planes: the textured rectangles.
        target: (3,) world point the synthetic trajectories look at, metres.
        background: BGR colour where no surface is hit (depth 0).
    """

    name: str
    planes: tuple[Plane, ...]
    target: np.ndarray
    background: tuple[int, int, int] = (60, 60, 60)


#: Zig-zag poster fold lines on the floor (x, y), metres, measured from the real depth maps.
POSTER_VERTICES = np.array([[-2.35, -0.55], [-2.95, 0.10], [-2.45, 0.85], [-3.05, 1.50]])
POSTER_HEIGHT = 0.95
#: Where the optical axes of the real near trajectory converge (least squares), metres.
NEAR_CONVERGENCE = np.array([-2.841, 0.111, 0.099])

_UP = np.array([0.0, 0.0, 1.0])
#: Mean viewing direction of the real near trajectory (camera minus scene target), world frame;
#: ``trajectories.nominal_eye`` derives it from the bundled trajectory, this is its value.
_NOMINAL_VIEW = np.array([0.7516, -0.3713, 0.5452])


def _poster_frame() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start point (2,), unit direction along the poster (2,), unit normal toward the cameras."""
    start = POSTER_VERTICES[0]
    d = POSTER_VERTICES[-1] - start
    d = d / np.linalg.norm(d)
    n = np.array([d[1], -d[0]])
    if n[0] < 0:  # the cameras are on the +x side
        n = -n
    return start, d, n


def scene_target() -> np.ndarray:
    """(3,) world point in the middle of the scene (sheets and poster), metres."""
    start, d, n = _poster_frame()
    length = np.linalg.norm(POSTER_VERTICES[-1] - POSTER_VERTICES[0])
    mid = start + d * length / 2 + n * 0.35
    return np.array([mid[0], mid[1], 0.25])


def _poster_planes(
    rng: np.random.Generator, low: bool, ppm: float, repeated: bool = False
) -> list[Plane]:
    seg = np.diff(POSTER_VERTICES, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    total = float(lengths.sum())
    if low:
        tex = tx.low_texture(rng, round(total * ppm), round(POSTER_HEIGHT * ppm), 170, 20)
    elif repeated:  # wallpaper, 8 cm period
        tex = tx.repeated_texture(
            rng, round(total * ppm), round(POSTER_HEIGHT * ppm), round(0.08 * ppm)
        )
    else:
        tex = tx.poster_texture(rng, total, POSTER_HEIGHT, ppm)
    planes = []
    x0 = 0
    for i, (p, s, length) in enumerate(zip(POSTER_VERTICES[:-1], seg, lengths, strict=True)):
        x1 = round((lengths[: i + 1].sum()) * ppm)
        origin = np.array([p[0], p[1], POSTER_HEIGHT])
        u = np.array([s[0], s[1], 0.0]) / length
        planes.append(make_plane(f'poster{i}', origin, u, -_UP, tex[:, x0:x1].copy(), ppm))
        x0 = x1
    return planes


def _sheet_planes(
    rng: np.random.Generator,
    n: int,
    front: tuple[float, float],
    low: bool,
    ppm: float,
    repeated: bool = False,
) -> list[Plane]:
    """``n`` sheets on the floor in front of the poster line, ``front`` = (near, far) metres."""
    start, d, nrm = _poster_frame()
    length = float(np.linalg.norm(POSTER_VERTICES[-1] - POSTER_VERTICES[0]))
    sizes = np.array([[0.297, 0.210], [0.420, 0.297], [0.594, 0.420]])
    planes = []
    for i in range(n):
        w, h = sizes[rng.choice(3, p=[0.3, 0.5, 0.2])]
        if rng.random() < 0.5:
            w, h = h, w
        s = (i + rng.uniform(0.1, 0.9)) / n * length
        f = rng.uniform(*front)
        centre = start + d * s + nrm * f
        ang = np.arctan2(d[1], d[0]) + rng.uniform(-0.45, 0.45)
        u = np.array([np.cos(ang), np.sin(ang), 0.0])
        v = np.cross(_UP, u)  # in the floor plane; u x v = up
        if low:
            tex = tx.low_texture(rng, round(w * ppm), round(h * ppm), 235, 8)
        elif repeated:  # a print of one motif, 3-6 cm period
            tex = tx.repeated_texture(
                rng, round(w * ppm), round(h * ppm), round(rng.uniform(0.03, 0.06) * ppm)
            )
        else:
            tex = tx.paper_texture(rng, w, h, ppm)
        origin = np.array([centre[0], centre[1], 0.0]) - u * w / 2 - v * h / 2
        planes.append(make_plane(f'sheet{i}', origin, u, v, tex, ppm))
    return planes


def _room_planes(
    rng: np.random.Generator, floor: bool = True, wall: bool = True, tiles: bool = False
) -> list[Plane]:
    ppm = 60.0
    planes = []
    if floor and tiles:  # 9 m x 9 m floor of 0.3 m tiles
        tex = tx.repeated_texture(
            rng, round(9 * ppm), round(9 * ppm), round(0.3 * ppm), grout=True
        )
        planes.append(make_plane('floor', [-6.5, -4.5, 0.0], [1, 0, 0], [0, 1, 0], tex, ppm))
    elif floor:  # 9 m x 9 m floor, z = 0, normal up
        tex = tx.low_texture(rng, round(9 * ppm), round(9 * ppm), 120, 14)
        planes.append(make_plane('floor', [-6.5, -4.5, 0.0], [1, 0, 0], [0, 1, 0], tex, ppm))
    if wall:  # wall behind the poster, x = -4, facing +x
        tex = tx.low_texture(rng, round(9 * ppm), round(3 * ppm), 175, 18)
        planes.append(make_plane('wall', [-4.0, -4.5, 3.0], [0, 1, 0], [0, 0, -1], tex, ppm))
    return planes


def _wall_planes(rng: np.random.Generator, ppm: float) -> list[Plane]:
    """One upright textured wall through the scene target, facing the nominal camera.

    6 m wide, from 2.5 m below the floor level to 2.5 m above it (so that cameras looking
    down at the target see only the wall); a poster-like background with printed sheets
    pinned on it: every visible point lies on one plane (the homography case).
    """
    target = scene_target()
    towards = _NOMINAL_VIEW[:2] / np.linalg.norm(_NOMINAL_VIEW[:2])
    normal = np.array([towards[0], towards[1], 0.0])
    u = np.cross(_UP, normal)  # along the wall; u x v = normal with v pointing down
    width, height = 6.0, 5.0
    wall_ppm = min(ppm, 500.0)
    tex = tx.poster_texture(rng, width, height, wall_ppm)
    for _ in range(40):  # A4 and A3 sheets pinned on the wall
        w, h = (0.297, 0.210) if rng.random() < 0.6 else (0.420, 0.297)
        sheet = tx.paper_texture(rng, w, h, wall_ppm)
        y0 = int(rng.integers(0, tex.shape[0] - sheet.shape[0]))
        x0 = int(rng.integers(0, tex.shape[1] - sheet.shape[1]))
        tex[y0 : y0 + sheet.shape[0], x0 : x0 + sheet.shape[1]] = sheet
    origin = np.array([target[0], target[1], 2.5]) - u * width / 2
    return [make_plane('wall', origin, u, -_UP, tex, wall_ppm)]


def build_scene(
    name: str | SceneName = SceneName.STRUCTURE_TEXTURE,
    seed: int = 0,
    ppm: float = tx.PIXELS_PER_METRE,
) -> Scene:
    """Build a scene variant; the textures are a pure function of ``seed``.

    Scenes are cached (a few are kept): treat them as read-only.

    Args:
        name: 'structure_texture' (sheets, zig-zag poster, room), 'floor' (sheets on the floor
            only: every visible point on z = 0, the homography case), 'zigzag' (poster only),
            'low_texture' (same geometry, nearly textureless surfaces), 'wall' (one upright
            textured wall through the target, facing the cameras: a single plane),
            'repeated' (the structure_texture geometry printed with repeated motifs: sheets
            of 3-6 cm tiles, 8 cm wallpaper on the poster, a floor of 0.3 m tiles),
            'storeroom' (the second rendering style: shaded boxes, shelf, brick and wooden
            walls at 0.5-10 m; :mod:`initsel_ros.synth.storeroom`).
        seed: texture seed.
        ppm: texture resolution of sheets and poster, pixels per metre.
    """
    return _build_scene(SceneName(name), int(seed), float(ppm))


@lru_cache(maxsize=4)
def _build_scene(name: SceneName, seed: int, ppm: float) -> Scene:
    rng = np.random.default_rng(seed)
    target = scene_target()
    if name is SceneName.STRUCTURE_TEXTURE:
        planes = (
            _room_planes(rng)
            + _sheet_planes(rng, 7, (0.35, 0.95), False, ppm)
            + _sheet_planes(rng, 5, (0.8, 1.4), False, ppm)
            + _poster_planes(rng, False, ppm)
        )
    elif name is SceneName.FLOOR:
        planes = (
            _room_planes(rng, wall=False)
            + _sheet_planes(rng, 7, (-0.5, 0.2), False, ppm)
            + _sheet_planes(rng, 7, (0.3, 0.95), False, ppm)
            + _sheet_planes(rng, 5, (0.8, 1.4), False, ppm)
        )
        target = np.array([target[0], target[1], 0.0])
    elif name is SceneName.ZIGZAG:
        planes = _poster_planes(rng, False, ppm)
        target = np.array([target[0], target[1], POSTER_HEIGHT / 2])
    elif name is SceneName.WALL:
        planes = _wall_planes(rng, ppm)
    elif name is SceneName.STOREROOM:
        from initsel_ros.synth.storeroom import storeroom_planes

        planes = storeroom_planes(rng, target, min(ppm, 400.0))
    elif name is SceneName.REPEATED:
        planes = (
            _room_planes(rng, tiles=True)
            + _sheet_planes(rng, 7, (0.35, 0.95), False, ppm, repeated=True)
            + _sheet_planes(rng, 5, (0.8, 1.4), False, ppm, repeated=True)
            + _poster_planes(rng, False, ppm, repeated=True)
        )
    else:
        planes = (
            _room_planes(rng)
            + _sheet_planes(rng, 7, (0.35, 0.95), True, ppm)
            + _poster_planes(rng, True, ppm)
        )
    return Scene(name.value, tuple(planes), target)


__all__ = [
    'NEAR_CONVERGENCE',
    'POSTER_VERTICES',
    'Plane',
    'Scene',
    'SceneName',
    'build_scene',
    'make_plane',
    'scene_target',
]
