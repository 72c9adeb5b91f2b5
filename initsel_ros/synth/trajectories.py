"""Camera trajectories (camera-to-world poses with timestamps) for the synthetic scenes.

``near`` replays the real motion-capture trajectory of fr3/structure_texture_near at its 1099
colour frame times (bundled in ``synth/data``); ``far`` is the same motion scaled by 2 about
the point its optical axes converge to; the others are generated around the scene target.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from initsel_ros.datasets.tum import read_trajectory
from initsel_ros.errors import ConfigError
from initsel_ros.synth.scene import NEAR_CONVERGENCE, scene_target
from initsel_ros.transforms import pose_matrix

DATA_DIR = Path(__file__).resolve().parent / 'data'
NEAR_FILE = DATA_DIR / 'structure_texture_near.txt'
#: First colour frame time of the real near sequence (s); generated trajectories start here too.
START_TIME = 1341839327.392692
FRAME_RATE = 30.0
#: Mean viewing direction of the real near trajectory (camera minus scene target), world frame
#: (what :func:`nominal_eye` derives from the bundled trajectory).
_NOMINAL_VIEW_DIRECTION = np.array([0.7516, -0.3713, 0.5452])


class TrajectoryName(str, Enum):
    """The trajectory kinds."""

    NEAR = 'near'
    FAR = 'far'
    ROTATION = 'rotation'
    FORWARD = 'forward'
    STATIC = 'static'
    RANDOM = 'random'
    ARC = 'arc'


@dataclass(frozen=True)
class ArcPath:
    """A parameterized sideways ``arc`` (or straight slide) in front of the scene target.

    The eye starts ``distance`` metres from the target, seen from ``elevation_deg`` above the
    horizontal, in the nominal viewing direction's vertical plane, and moves sideways by
    ``extent * sin(2 pi 0.1 t)`` metres (the full extent is reached at 2.5 s, frame 75 at
    30 Hz): along the horizontal circle about the target for an arc, along a straight line
    for a slide. ``centring`` 1 keeps looking at the target (the plane stays centred), 0 keeps
    the start orientation (a pure translation), and values between turn part of the way.

    Attributes:
        distance: start distance from the target, metres.
        extent: sideways amplitude, metres (the baseline to the first frame grows up to it).
        centring: 0..1, share of the rotation that keeps the target centred.
        elevation_deg: viewing elevation, degrees (None: the nominal view's, about 33).
        straight: slide on a straight line instead of the circle.
    """

    distance: float = 3.5
    extent: float = 0.3
    centring: float = 1.0
    elevation_deg: float | None = None
    straight: bool = False

    def __post_init__(self) -> None:
        if not 0.05 <= self.distance <= 100.0:
            raise ConfigError(f'arc distance must be in [0.05, 100] m, got {self.distance}')
        if not 0.0 <= self.extent < self.distance:
            raise ConfigError(
                f'arc extent must be in [0, distance), got {self.extent} (distance '
                f'{self.distance})'
            )
        if not 0.0 <= self.centring <= 1.0:
            raise ConfigError(f'arc centring must be in [0, 1], got {self.centring}')
        if self.elevation_deg is not None and not -80.0 <= self.elevation_deg <= 85.0:
            raise ConfigError(f'arc elevation must be in [-80, 85] deg, got {self.elevation_deg}')

    def poses(self, t: np.ndarray, target: np.ndarray) -> np.ndarray:
        """(N, 4, 4) camera-to-world poses at times ``t`` (seconds) about ``target``."""
        view = _NOMINAL_VIEW_DIRECTION
        horizontal = np.array([view[0], view[1], 0.0]) / np.linalg.norm(view[:2])
        if self.elevation_deg is None:
            elevation = np.arcsin(view[2] / np.linalg.norm(view))
        else:
            elevation = np.deg2rad(self.elevation_deg)
        radius = self.distance * np.cos(elevation)
        height = self.distance * np.sin(elevation)
        side = np.cross(np.array([0.0, 0.0, 1.0]), horizontal)  # left to right, horizontal
        lateral = self.extent * np.sin(2 * np.pi * 0.1 * t)
        start = target + radius * horizontal + [0.0, 0.0, height]
        if self.straight:
            eyes = start + lateral[:, None] * side
        else:
            angle = lateral / max(radius, 1e-9)
            eyes = (
                target
                + radius * np.cos(angle)[:, None] * horizontal
                + radius * np.sin(angle)[:, None] * side
                + [0.0, 0.0, height]
            )
        looks = target + (1.0 - self.centring) * (eyes - start)
        return look_at(eyes, looks)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) camera-to-world pose at ``eye`` looking at ``target`` (x right, y down, z ahead).

    Vectorized: eye and target (N, 3) give (N, 4, 4).
    """
    eye = np.asarray(eye, float)
    target = np.asarray(target, float)
    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, float)
    z = target - eye
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(z, up)
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    T = np.zeros((*eye.shape[:-1], 4, 4))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2], T[..., :3, 3] = x, y, z, eye
    T[..., 3, 3] = 1.0
    return T


def _axis_rotation(axis: int, angles: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about camera axis 0 (x), 1 (y) or 2 (z) by ``angles`` radians."""
    c, s = np.cos(angles), np.sin(angles)
    R = np.tile(np.eye(3), (len(angles), 1, 1))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[:, i, i], R[:, i, j], R[:, j, i], R[:, j, j] = c, -s, s, c
    return R


def near_trajectory(path: Path = NEAR_FILE) -> tuple[np.ndarray, np.ndarray]:
    """The real fr3/structure_texture_near trajectory at its colour frame times.

    Returns:
        ``(stamps (1099,) seconds, poses (1099, 4, 4) camera-to-world)``.
    """
    stamps, positions, quats = read_trajectory(path)
    return stamps, pose_matrix(positions, quats)


def nominal_eye(distance: float = 1.2) -> np.ndarray:
    """(3,) a viewpoint ``distance`` metres from the scene target, where the real camera was."""
    _, poses = near_trajectory()
    mean_eye = poses[:, :3, 3].mean(axis=0)
    target = scene_target()
    d = mean_eye - target
    return target + distance * d / np.linalg.norm(d)


def make_trajectory(
    name: str | TrajectoryName,
    frames: int | None = None,
    seed: int = 0,
    target: np.ndarray | None = None,
    start: int = 0,
    arc: ArcPath | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Timestamps and camera-to-world poses for a trajectory kind.

    Args:
        name: near, far, rotation, forward, static, random or arc (the eye swings +-25
            degrees on a horizontal arc of 1.3 m radius about the target, looking at it).
        frames: number of frames (default: 1099, the length of the real near sequence).
        seed: for ``random``.
        target: (3,) world point the generated trajectories look at (default: scene target).
        start: skip this many frames first (e.g. the near trajectory barely moves in its first
            40 frames; from frame 80 it moves 0.22 m in 30 frames).
        arc: the ``arc`` trajectory's geometry (None: the fixed 1.3 m, +-25 degree swing);
            with another name it is an error.

    Returns:
        ``(stamps (N,) seconds, poses (N, 4, 4) camera-to-world)``.
    """
    name = TrajectoryName(name)
    if frames is not None and frames <= 0:
        raise ConfigError(f'frames must be positive, got {frames}')
    if start < 0:
        raise ConfigError(f'start must be >= 0, got {start}')
    if arc is not None and name is not TrajectoryName.ARC:
        raise ConfigError(f'arc settings apply to the arc trajectory, not {name.value}')
    if name in (TrajectoryName.NEAR, TrajectoryName.FAR):
        stamps, poses = near_trajectory()
        stop = len(stamps) if frames is None else start + frames
        if stop > len(stamps) or start >= len(stamps):
            raise ConfigError(
                f'the {name.value} trajectory has {len(stamps)} frames, '
                f'frames {start}..{stop - 1} requested'
            )
        stamps, poses = stamps[start:stop], poses[start:stop]
        if name is TrajectoryName.FAR:
            poses = poses.copy()
            poses[:, :3, 3] = NEAR_CONVERGENCE + 2.0 * (poses[:, :3, 3] - NEAR_CONVERGENCE)
        return stamps, poses
    n = 1099 if frames is None else frames
    t = (start + np.arange(n)) / FRAME_RATE
    stamps = START_TIME + t
    target = scene_target() if target is None else np.asarray(target, float)
    eye = nominal_eye(1.2)
    base = look_at(eye, target)
    if name is TrajectoryName.STATIC:
        return stamps, np.repeat(base[None], n, axis=0)
    if name is TrajectoryName.ROTATION:
        # pan (about camera y) and tilt (about camera x) about the optical centre
        yaw = np.deg2rad(15.0) * np.sin(2 * np.pi * 0.2 * t)
        pitch = np.deg2rad(6.0) * np.sin(2 * np.pi * 0.13 * t + 0.5)
        R = base[:3, :3] @ _axis_rotation(1, yaw) @ _axis_rotation(0, pitch)
        poses = np.repeat(base[None], n, axis=0)
        poses[:, :3, :3] = R
        return stamps, poses
    if name is TrajectoryName.FORWARD:
        # along the optical axis, between 1.6 m and 0.8 m from the target, 0.1 s^-1 cycle
        direction = (eye - target) / np.linalg.norm(eye - target)
        dist = 1.2 + 0.4 * np.cos(2 * np.pi * 0.05 * t)
        poses = np.repeat(base[None], n, axis=0)
        poses[:, :3, 3] = target + dist[:, None] * direction
        return stamps, poses
    if name is TrajectoryName.ARC and arc is not None:
        return stamps, arc.poses(t, target)
    if name is TrajectoryName.ARC:
        # 1.3 m from the target, swinging +-25 degrees about the vertical through it, 0.1 Hz
        offset = nominal_eye(1.3) - target
        angle = np.deg2rad(25.0) * np.sin(2 * np.pi * 0.1 * t)
        c, s = np.cos(angle), np.sin(angle)
        eyes = np.stack(
            [
                target[0] + c * offset[0] - s * offset[1],
                target[1] + s * offset[0] + c * offset[1],
                np.full(n, target[2] + offset[2]),
            ],
            axis=1,
        )
        return stamps, look_at(eyes, np.repeat(target[None], n, axis=0))
    # RANDOM: smooth sums of sinusoids for the eye, the looked-at point and roll
    rng = np.random.default_rng(seed)

    def smooth(amplitude: float, dims: int) -> np.ndarray:
        freqs = rng.uniform(0.03, 0.35, (3, dims))
        phases = rng.uniform(0, 2 * np.pi, (3, dims))
        amps = rng.uniform(0.3, 1.0, (3, dims))
        wave = np.sum(
            amps[None] * np.sin(2 * np.pi * freqs[None] * t[:, None, None] + phases[None]), axis=1
        )
        return amplitude * wave / amps.sum(axis=0)

    distance = rng.uniform(0.9, 2.4)
    eyes = nominal_eye(distance) + smooth(0.5, 3) * [1.0, 1.0, 0.4]
    eyes[:, 2] = np.maximum(eyes[:, 2], 0.3)
    looks = target + smooth(0.25, 3)
    poses = look_at(eyes, looks)
    roll = np.deg2rad(6.0) * smooth(1.0, 1)[:, 0]
    poses[:, :3, :3] = poses[:, :3, :3] @ _axis_rotation(2, roll)
    return stamps, poses


__all__ = [
    'NEAR_FILE',
    'START_TIME',
    'ArcPath',
    'TrajectoryName',
    'look_at',
    'make_trajectory',
    'near_trajectory',
    'nominal_eye',
]
