"""Independently moving objects: textured planes swinging in front of the scene.

A mover is a printed board (0.15-0.4 m a side) placed between the camera path and the scene
target, swinging sideways (and a little up and down) on its own sinusoidal trajectory while
turning about the vertical. Its pixels move with the board, not with the camera: they have no
valid ground truth for the camera motion (see ``docs/synth.md``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from initsel_ros.synth import textures as tx
from initsel_ros.synth.scene import Plane, Scene, make_plane

_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class Mover:
    """A plane that moves on its own.

    Attributes:
        plane: the board at its rest pose.
        centre: (3,) world rest position of the board's centre, metres.
        direction: (3,) unit direction of the swing.
        amplitude: swing amplitude, metres.
        frequency: swing frequency, Hz.
        phase: swing phase at t = 0, radians.
        spin: amplitude of the turn about the vertical through the centre, radians.
    """

    plane: Plane
    centre: np.ndarray
    direction: np.ndarray
    amplitude: float
    frequency: float
    phase: float
    spin: float

    def plane_at(self, t: float) -> Plane:
        """The board ``t`` seconds after the first frame."""
        arg = 2 * np.pi * self.frequency * t + self.phase
        offset = self.direction * self.amplitude * np.sin(arg)
        angle = self.spin * np.sin(0.7 * arg)
        c, s = np.cos(angle), np.sin(angle)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        origin = self.centre + offset + R @ (self.plane.origin - self.centre)
        return dataclasses.replace(
            self.plane, origin=origin, u=R @ self.plane.u, v=R @ self.plane.v
        )


def make_movers(
    n: int, rng: np.random.Generator, target: np.ndarray, eye: np.ndarray
) -> tuple[Mover, ...]:
    """``n`` boards between ``eye`` (the mean camera position) and ``target``.

    Each is centred 35-65 % of the way from the target to the camera, up to 30 % of that
    distance aside, and swings 0.2-0.5 m at 0.1-0.3 Hz (peak speed up to about 0.9 m/s).
    """
    target = np.asarray(target, float)
    view = np.asarray(eye, float) - target
    dist = float(np.linalg.norm(view))
    forward = view / dist  # from the target toward the camera
    lateral = np.cross(_UP, forward)
    lateral /= max(np.linalg.norm(lateral), 1e-9)
    up = np.cross(forward, lateral)
    movers = []
    for i in range(n):
        w, h = rng.uniform(0.15, 0.4, 2)
        ppm = 800.0
        if rng.random() < 0.5:
            tex = tx.paper_texture(rng, w, h, ppm)
        else:
            tex = tx.photo_noise(rng, round(h * ppm), round(w * ppm), (4.0, 12.0, 36.0))
        centre = (
            target
            + forward * dist * rng.uniform(0.35, 0.65)
            + lateral * dist * rng.uniform(-0.3, 0.3)
            + up * dist * rng.uniform(-0.15, 0.15)
        )
        origin = centre - lateral * w / 2 + up * h / 2
        plane = make_plane(f'mover{i}', origin, lateral, -up, tex, ppm)
        direction = lateral + up * rng.uniform(-0.3, 0.3)
        movers.append(
            Mover(
                plane,
                centre,
                direction / np.linalg.norm(direction),
                float(rng.uniform(0.2, 0.5)),
                float(rng.uniform(0.1, 0.3)),
                float(rng.uniform(0, 2 * np.pi)),
                float(rng.uniform(0.0, 0.5)),
            )
        )
    return tuple(movers)


def scene_at(scene: Scene, movers: tuple[Mover, ...], t: float) -> Scene:
    """``scene`` with the movers at time ``t`` (seconds after the first frame) drawn last."""
    if not movers:
        return scene
    return dataclasses.replace(scene, planes=scene.planes + tuple(m.plane_at(t) for m in movers))


__all__ = ['Mover', 'make_movers', 'scene_at']
