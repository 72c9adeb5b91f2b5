"""Camera effects of ``initsel synth``, each a parameter with a physical unit.

The sensor model, in the order it is applied to a frame (see ``docs/synth.md``):

1. optics: motion blur (the frame integrates renders along the pose over ``exposure_time``
   seconds), rolling shutter (sensor row ``r`` is exposed ``(r - (H - 1) / 2) * line_delay``
   seconds after the frame time), lens distortion, defocus ``blur``;
2. photometry: vignetting (a ``cos^4`` falloff of the ray angle, mixed in by ``vignetting``),
   exposure gain over time (``gain_ramp`` and the slow random ``exposure`` changes);
3. noise: shot noise of a sensor with ``full_well`` electrons at grey level 255 (gain 1), and
   Gaussian read noise of ``noise`` grey levels;
4. 8-bit quantization with saturation at 255, and JPEG compression at ``jpeg_quality``.

``movers`` adds independently moving textured planes to the scene.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError


@dataclass(frozen=True)
class Effects:
    """Camera effects (all off = the ideal image, except 1.5 grey levels of read noise).

    Attributes:
        noise: Gaussian read noise standard deviation, grey levels (0-255 scale).
        blur: Gaussian (defocus) blur sigma, pixels (0 = none).
        exposure: amplitude of slow random exposure changes, relative gain (0.15 = +-15 %).
        exposure_time: shutter open time, seconds; the frame is the mean of renders along the
            pose over ``[t - exposure_time / 2, t + exposure_time / 2]`` (0 = instantaneous).
        line_delay: rolling shutter, seconds between the exposures of consecutive rows
            (0 = global shutter); the frame time is the middle row's.
        gain_ramp: ``(gain_from, gain_to, duration_s[, start_s])``: the gain goes linearly
            from ``gain_from`` to ``gain_to`` over ``duration_s`` seconds starting ``start_s``
            (default 0) seconds after the first frame, as auto-exposure does; () = off.
        vignetting: fraction of the natural ``cos^4`` falloff, 0-1 (relative illumination
            ``1 - vignetting * (1 - cos^4 theta)``, theta the ray's angle to the optical axis).
        full_well: electrons that fill grey level 255 at gain 1 (shot noise: variance
            ``gain * 255 / full_well * I`` grey levels squared at intensity ``I``); 0 = no
            shot noise.
        jpeg_quality: JPEG quality 1-100 of the colour frames (written as ``.jpg``); 0 = PNG.
        movers: number of independently moving textured planes in front of the scene.
    """

    noise: float = 1.5
    blur: float = 0.0
    exposure: float = 0.0
    exposure_time: float = 0.0
    line_delay: float = 0.0
    gain_ramp: tuple[float, ...] = ()
    vignetting: float = 0.0
    full_well: float = 0.0
    jpeg_quality: int = 0
    movers: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, 'gain_ramp', tuple(float(g) for g in self.gain_ramp))
        checks = (
            ('noise', self.noise >= 0),
            ('blur', self.blur >= 0),
            ('exposure', 0 <= self.exposure < 1),
            ('exposure_time', self.exposure_time >= 0),
            ('line_delay', self.line_delay >= 0),
            ('vignetting', 0 <= self.vignetting <= 1),
            ('full_well', self.full_well >= 0),
            ('jpeg_quality', 0 <= self.jpeg_quality <= 100),
            ('movers', self.movers >= 0),
        )
        for name, ok in checks:
            value = getattr(self, name)
            if not ok or not math.isfinite(value):
                raise ConfigError(f'effect {name}={value!r} is out of range')
        if self.gain_ramp:
            ramp = self.gain_ramp
            if (
                len(ramp) not in (3, 4)
                or not all(map(math.isfinite, ramp))
                or min(ramp[:2]) <= 0
                or ramp[2] < 0
                or (len(ramp) == 4 and ramp[3] < 0)
            ):
                raise ConfigError(
                    f'gain_ramp must be (gain_from > 0, gain_to > 0, duration_s >= 0'
                    f'[, start_s >= 0]), got {ramp}'
                )

    @property
    def temporal(self) -> bool:
        """True when a frame needs renders at more than one time (motion blur, rolling
        shutter)."""
        return self.exposure_time > 0 or self.line_delay > 0

    def to_dict(self) -> dict[str, object]:
        """Plain-data form (for ``effects.yaml``)."""
        out = asdict(self)
        out['gain_ramp'] = list(self.gain_ramp)
        return out


def exposure_gains(
    n: int, amplitude: float, rng: np.random.Generator, rate_hz: float = 30.0
) -> np.ndarray:
    """(n,) smooth random gains around 1 (a sum of slow sinusoids), amplitude relative."""
    if amplitude <= 0 or n == 0:
        return np.ones(n)
    t = np.arange(n) / rate_hz
    freqs = rng.uniform(0.05, 0.4, 3)
    phases = rng.uniform(0, 2 * np.pi, 3)
    wave = np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0) / 3
    return 1.0 + amplitude * wave / max(np.abs(wave).max(), 1e-9)


def ramp_gains(seconds: np.ndarray, ramp: tuple[float, ...]) -> np.ndarray:
    """Gain at ``seconds`` after the first frame for a ``gain_ramp`` (ones when empty)."""
    t = np.asarray(seconds, np.float64)
    if not ramp:
        return np.ones_like(t)
    g0, g1, duration = ramp[:3]
    start = ramp[3] if len(ramp) > 3 else 0.0
    if duration <= 0:
        return np.where(t >= start, g1, g0).astype(np.float64)
    return g0 + (g1 - g0) * np.clip((t - start) / duration, 0.0, 1.0)


def vignette_map(
    camera: Intrinsics, strength: float, rays: tuple[np.ndarray, np.ndarray] | None = None
) -> np.ndarray:
    """(H, W) float32 relative illumination ``1 - strength * (1 - cos^4 theta)``.

    Args:
        camera: the sensor camera.
        strength: 0 (none) to 1 (the full natural falloff).
        rays: (H, W) normalized undistorted ray coordinates ``(x / z, y / z)`` of each pixel
            (for a distorted camera); default: the pinhole rays of ``camera``.
    """
    if rays is None:
        ys, xs = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float32)
        rx, ry = (xs - camera.cx) / camera.fx, (ys - camera.cy) / camera.fy
    else:
        rx, ry = rays
    cos2 = 1.0 / (1.0 + rx * rx + ry * ry)
    return (1.0 - strength * (1.0 - cos2 * cos2)).astype(np.float32)


class NoiseBank:
    """Seeded noise frames drawn with a random flip per frame (cheap per-frame noise).

    Args:
        shape: (H, W, 3).
        rng: the generator (8 frames drawn from it here; then two integers per frame).
        sigma: scales the standard normal frames; with ``integer`` they are rounded to int16
            (the read-noise-only path, added in 8 bits); otherwise float32 unit normals.
        size: frames in the bank.
    """

    def __init__(
        self,
        shape: tuple[int, int, int],
        rng: np.random.Generator,
        sigma: float = 1.0,
        integer: bool = True,
        size: int = 8,
    ) -> None:
        self.rng = rng
        if integer:
            self.frames = [
                np.round(rng.standard_normal(shape, dtype=np.float32) * sigma).astype(np.int16)
                for _ in range(size)
            ]
        else:
            self.frames = [
                rng.standard_normal(shape, dtype=np.float32) * np.float32(sigma)
                for _ in range(size)
            ]

    def draw(self) -> np.ndarray:
        """One noise frame (a bank frame, possibly flipped)."""
        noise = self.frames[int(self.rng.integers(len(self.frames)))]
        flip = int(self.rng.integers(-1, 3))
        return cv2.flip(noise, flip) if flip < 2 else noise


def sensor_noise(
    signal: np.ndarray, unit_noise: np.ndarray, read_noise: float, full_well: float, gain: float
) -> np.ndarray:
    """Signal plus shot and read noise, grey levels (float32, not clipped).

    Args:
        signal: (H, W, 3) float32 mean grey levels after gain.
        unit_noise: standard normal samples of the same shape.
        read_noise: read noise sigma, grey levels.
        full_well: electrons at grey level 255 and gain 1 (> 0).
        gain: the analog gain the signal was multiplied by.
    """
    k = np.float32(gain * 255.0 / full_well)
    variance = np.maximum(signal, np.float32(0.0))
    variance *= k
    variance += np.float32(read_noise * read_noise)
    np.sqrt(variance, out=variance)
    variance *= unit_noise
    variance += signal
    return variance


__all__ = ['Effects', 'NoiseBank', 'exposure_gains', 'ramp_gains', 'sensor_noise', 'vignette_map']
