"""The camera: ideal renders turned into sensor frames with the effects of :class:`Effects`.

Motion blur and rolling shutter are rendered, not faked: a frame is the mean of ``n`` renders
at times spread evenly over the exposure, and with a rolling shutter each band of sensor rows
is rendered at its own time (bands and sub-frames are chosen so that the image moves at most
0.5 px between bands and 0.75 px between sub-frames; the motion is measured on the frame's
depth map and the poses around it). Poses between frames are interpolated (linear position,
slerp rotation); moving objects are evaluated at the exact time.

The depth map and the ground-truth pose of a frame are those of its time stamp: the middle of
the exposure and, with a rolling shutter, the middle row's exposure.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.synth.effects import (
    Effects,
    NoiseBank,
    exposure_gains,
    ramp_gains,
    sensor_noise,
    vignette_map,
)
from initsel_ros.synth.movers import Mover, scene_at
from initsel_ros.synth.render import NEAR_PLANE, Distorter, render_frame
from initsel_ros.synth.scene import Scene
from initsel_ros.transforms import matrix_to_pose, pose_matrix, slerp

#: Largest image motion between two sub-frames of an exposure, pixels.
SUBFRAME_STEP_PX = 0.75
#: Largest image motion between two rolling-shutter bands, pixels.
BAND_STEP_PX = 0.5
MAX_SUBFRAMES = 48
MAX_BANDS = 240


class PoseTrack:
    """Camera-to-world poses at frame times, interpolated at any time.

    Between frames: linear position, slerp rotation; before the first and after the last frame
    the first and last segments are extrapolated.

    Args:
        stamps: (N,) increasing seconds.
        poses: (N, 4, 4) camera-to-world.
    """

    def __init__(self, stamps: np.ndarray, poses: np.ndarray) -> None:
        self.stamps = np.asarray(stamps, np.float64)
        self.poses = np.asarray(poses, np.float64)
        if self.stamps.ndim != 1 or len(self.stamps) == 0 or len(self.stamps) != len(self.poses):
            raise ValueError('PoseTrack needs N > 0 stamps and N poses')
        if np.any(np.diff(self.stamps) <= 0):
            raise ValueError('PoseTrack stamps must increase strictly')
        self._rel = self.stamps - self.stamps[0]
        self._t, self._q = matrix_to_pose(self.poses)

    def pose_at(self, seconds: float) -> np.ndarray:
        """(4, 4) pose ``seconds`` after the first frame."""
        n = len(self._rel)
        if n == 1:
            return self.poses[0]
        i = int(np.clip(np.searchsorted(self._rel, seconds, side='right') - 1, 0, n - 2))
        a = (seconds - self._rel[i]) / (self._rel[i + 1] - self._rel[i])
        if a == 0.0:
            return self.poses[i]
        position = (1 - a) * self._t[i] + a * self._t[i + 1]
        q = slerp(self._q[i : i + 1], self._q[i + 1 : i + 2], np.array([a]))[0]
        return pose_matrix(position, q)


class SensorRenderer:
    """Renders the frames of a trajectory through a camera with effects.

    Args:
        scene: the static planes.
        camera: the sensor camera (with its distortion coefficients, if any).
        effects: the effects.
        track: the camera trajectory.
        rng: seeds the noise and the random exposure changes.
        movers: independently moving planes.
    """

    def __init__(
        self,
        scene: Scene,
        camera: Intrinsics,
        effects: Effects,
        track: PoseTrack,
        rng: np.random.Generator,
        movers: Sequence[Mover] = (),
    ) -> None:
        self.scene, self.camera, self.effects, self.track = scene, camera, effects, track
        self.movers = tuple(movers)
        self.distorter = Distorter(camera) if camera.has_distortion else None
        self.canvas = (
            self.distorter.canvas
            if self.distorter is not None
            else Intrinsics(
                camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height
            )
        )
        shape = (camera.height, camera.width, 3)
        shot = effects.full_well > 0
        # draw order kept from the first renderer (noise bank, then gains): same bytes per seed
        self.bank = (
            NoiseBank(shape, rng, effects.noise, integer=True)
            if effects.noise > 0 and not shot
            else NoiseBank(shape, rng, 1.0, integer=False)
            if shot
            else None
        )
        rel = track.stamps - track.stamps[0]
        self.gains = exposure_gains(len(rel), effects.exposure, rng) * ramp_gains(
            rel, effects.gain_ramp
        )
        self.vignette = None
        if effects.vignetting > 0:
            rays = None
            if self.distorter is not None:
                c = self.canvas
                rays = ((self.distorter.map_x - c.cx) / c.fx, (self.distorter.map_y - c.cy) / c.fy)
            self.vignette = vignette_map(camera, effects.vignetting, rays)[..., None]
        self.renders = 0  # ideal renders (or bands of them) made, for speed reports

    def frame(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``i``: ``(image (H, W, 3) uint8 BGR, depth (H, W) float32 metres)``."""
        t = float(self.track.stamps[i] - self.track.stamps[0])
        pose = self.track.poses[i]
        scene = scene_at(self.scene, self.movers, t)
        if not self.effects.temporal:
            image, depth = render_frame(scene, self.canvas, pose)
            self.renders += 1
            if self.distorter is not None:
                image, depth = self.distorter(image, depth)
        else:
            _, canvas_depth = render_frame(scene, self.canvas, pose, color=False)
            image = self._integrate(t, pose, canvas_depth)
            depth = canvas_depth if self.distorter is None else self.distorter.depth(canvas_depth)
        return self._photometry(image, float(self.gains[i])), depth

    # ------------------------------------------------------------------ optics over time
    def _image_motion(self, pose: np.ndarray, depth: np.ndarray, t_a: float, t_b: float) -> float:
        """Largest image displacement (pixels) of scene points between times t_a and t_b."""
        K = self.canvas.K
        step = 16
        v, u = np.mgrid[step // 2 : depth.shape[0] : step, step // 2 : depth.shape[1] : step]
        z = depth[v, u]
        ok = z > 0
        rays = np.linalg.inv(K) @ np.vstack([u[ok], v[ok], np.ones(int(ok.sum()))])
        world = (pose[:3, :3] @ (rays * z[ok]) + pose[:3, 3:4]).T
        motion = 0.0
        groups = [(world, world)]
        groups += [(m.plane_at(t_a).corners(), m.plane_at(t_b).corners()) for m in self.movers]
        poses = self.track.pose_at(t_a), self.track.pose_at(t_b)
        for pts_a, pts_b in groups:
            if len(pts_a) == 0:
                continue
            px = []
            front = np.ones(len(pts_a), bool)
            for T, pts in zip(poses, (pts_a, pts_b), strict=True):
                T_cw = np.linalg.inv(T)
                cam = pts @ T_cw[:3, :3].T + T_cw[:3, 3]
                front &= cam[:, 2] > NEAR_PLANE
                proj = cam @ K.T
                px.append(proj[:, :2] / np.maximum(proj[:, 2:3], NEAR_PLANE))
            if front.any():
                d = np.linalg.norm(px[1][front] - px[0][front], axis=1)
                motion = max(motion, float(d.max()))
        return motion

    def _integrate(self, t: float, pose: np.ndarray, canvas_depth: np.ndarray) -> np.ndarray:
        """Mean of renders over the exposure, each band of rows at its own time (float32).

        With both motion blur and a rolling shutter the bands last one sub-frame step, so that
        consecutive bands share sub-frame times: one render of the union of the rows exposed
        at a time serves them all (``n_sub + n_bands - 1`` renders instead of their product).
        """
        e = self.effects
        H, W = self.camera.height, self.camera.width
        n_sub, step = 1, 0.0
        if e.exposure_time > 0:
            motion = self._image_motion(
                pose, canvas_depth, t - e.exposure_time / 2, t + e.exposure_time / 2
            )
            n_sub = int(np.clip(math.ceil(motion / SUBFRAME_STEP_PX), 1, MAX_SUBFRAMES))
            if e.line_delay > 0:  # a band lasts at least one row
                n_sub = max(1, min(n_sub, int(e.exposure_time / e.line_delay)))
            step = e.exposure_time / n_sub
        offsets = step * (np.arange(n_sub) - (n_sub - 1) / 2)
        n_bands, band_dt = 1, 0.0
        if e.line_delay > 0:
            if n_sub > 1 or e.exposure_time > 0:
                band_dt = step
            else:
                half = (H - 1) / 2 * e.line_delay
                motion = self._image_motion(pose, canvas_depth, t - half, t + half)
                n_rs = int(np.clip(math.ceil(motion / BAND_STEP_PX), 1, min(H, MAX_BANDS)))
                band_dt = H * e.line_delay / n_rs
            band_dt = max(band_dt, e.line_delay)
            n_bands = max(1, math.ceil(H * e.line_delay / band_dt - 1e-9))
        # band of each row, from the row's exposure time
        if n_bands > 1:
            row_t = (np.arange(H) - (H - 1) / 2) * e.line_delay
            band_of_row = np.clip(np.floor(row_t / band_dt + n_bands / 2), 0, n_bands - 1)
            starts = np.searchsorted(band_of_row, np.arange(n_bands + 1), side='left')
        else:
            starts = np.array([0, H])
        acc = np.zeros((H, W, 3), np.float32)
        for j in range(n_bands + n_sub - 1):  # render j: bands b with sub-frame k = j - b
            b_lo, b_hi = max(0, j - n_sub + 1), min(n_bands - 1, j)
            r0, r1 = int(starts[b_lo]), int(starts[b_hi + 1])
            if r1 <= r0:
                continue
            when = t + (b_lo - (n_bands - 1) / 2) * band_dt + float(offsets[j - b_lo])
            rows = (r0, r1) if self.distorter is None else self.distorter.rows_needed(r0, r1)
            band, _ = render_frame(
                scene_at(self.scene, self.movers, when),
                self.canvas,
                self.track.pose_at(when),
                rows=rows,
            )
            self.renders += 1
            if self.distorter is not None:
                band = self.distorter.image(band, r0, r1, rows[0])
            acc[r0:r1] += band
        if n_sub > 1:
            acc *= np.float32(1.0 / n_sub)
        return acc

    # ------------------------------------------------------------------ photometry, noise
    def _photometry(self, image: np.ndarray, gain: float) -> np.ndarray:
        """Defocus blur, vignetting, gain, noise and 8-bit quantization."""
        e = self.effects
        if e.blur > 0:
            image = cv2.GaussianBlur(image, (0, 0), e.blur)
        shot = e.full_well > 0
        if image.dtype == np.uint8 and self.vignette is None and not shot:
            if gain != 1.0:
                image = cv2.convertScaleAbs(image, alpha=gain)
            if self.bank is not None:
                image = cv2.add(image, self.bank.draw(), dtype=cv2.CV_8U)
            return image
        signal = image.astype(np.float32)  # a copy
        if self.vignette is not None:
            signal *= self.vignette
        if gain != 1.0:
            signal *= np.float32(gain)
        if shot:
            assert self.bank is not None
            signal = sensor_noise(signal, self.bank.draw(), e.noise, e.full_well, gain)
        elif self.bank is not None:
            signal += self.bank.draw()
        np.clip(signal, 0, 255, out=signal)
        return np.rint(signal).astype(np.uint8)


__all__ = ['BAND_STEP_PX', 'SUBFRAME_STEP_PX', 'PoseTrack', 'SensorRenderer']
