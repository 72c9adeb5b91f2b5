"""Render a whole sequence into a TUM folder (and optionally bags)."""

from __future__ import annotations

import logging
import math
import shutil
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets.tum import DEPTH_SCALE, write_listing, write_trajectory
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.synth.effects import Effects
from initsel_ros.synth.movers import make_movers
from initsel_ros.synth.scene import build_scene
from initsel_ros.synth.sensor import PoseTrack, SensorRenderer
from initsel_ros.synth.trajectories import ArcPath, make_trajectory
from initsel_ros.transforms import matrix_to_pose

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class SynthResult:
    """What :func:`render` produced.

    Attributes:
        path: the TUM folder.
        frames: number of frames written.
        seconds: wall time of rendering and writing (bags excluded), seconds.
        bags: bag paths written.
        effects: the effects rendered (drawn from the seed with ``realism``).
        distortion: the lens distortion coefficients rendered.
        renders: ideal renders (or rolling-shutter bands of them) made.
    """

    path: Path
    frames: int
    seconds: float
    bags: tuple[Path, ...] = ()
    effects: Effects = field(default_factory=Effects)
    distortion: tuple[float, ...] = ()
    renders: int = 0

    @property
    def fps(self) -> float:
        """Frames per second, rendering plus PNG writing."""
        return self.frames / self.seconds if self.seconds > 0 else float('inf')


def _camera(
    width: int | None,
    height: int | None,
    intrinsics: Intrinsics | None,
    distortion: tuple[float, ...],
    hfov_deg: float | None = None,
    fisheye: bool = False,
) -> Intrinsics:
    cam = intrinsics or Intrinsics.tum_fr3()
    if width or height:
        w = int(width or round((height or cam.height) * cam.width / cam.height))
        h = int(height or round(w * cam.height / cam.width))
        # a sensor of another size, not the image stretched (Intrinsics.scaled would give
        # 1241x376 pixels 2.5 times as tall as wide)
        cam = cam.resized_sensor(w, h)
    if hfov_deg is not None:
        if not 10.0 <= hfov_deg <= 150.0:
            raise ConfigError(f'hfov_deg must be in [10, 150] degrees, got {hfov_deg}')
        f = cam.width / 2 / math.tan(math.radians(hfov_deg) / 2)
        cam = replace(cam, fx=f, fy=f * cam.fy / cam.fx)
    if fisheye:  # the coefficients given (or none: f-theta) are the fisheye model's
        cam = replace(cam, distortion=tuple(float(d) for d in distortion), fisheye=True)
    elif distortion:
        cam = replace(cam, distortion=tuple(float(d) for d in distortion))
    return cam


def render(
    out_dir: Path | str,
    scene: str = 'structure_texture',
    trajectory: str = 'near',
    frames: int | None = None,
    seed: int = 0,
    *,
    width: int | None = None,
    height: int | None = None,
    intrinsics: Intrinsics | None = None,
    distortion: tuple[float, ...] = (),
    effects: Effects | None = None,
    bags: tuple[str, ...] = (),
    png_compression: int = 1,
    workers: int = 2,
    progress: bool = False,
    start: int = 0,
    realism: bool = False,
    arc: ArcPath | None = None,
    focal_error: float = 0.0,
    hfov_deg: float | None = None,
    fisheye: bool = False,
) -> SynthResult:
    """Render a sequence as a TUM folder with exact ground truth.

    Args:
        out_dir: output folder (created; existing files of the same names are replaced).
        scene: structure_texture, floor, zigzag, low_texture, wall, repeated or storeroom.
        trajectory: near, far, rotation, forward, static, random or arc.
        frames: number of frames (the first N of the trajectory; default all, 1099).
        seed: seeds textures, noise, exposure and the random trajectory.
        width, height: image size in pixels (intrinsics scaled from TUM fr3 or ``intrinsics``).
        intrinsics: camera (default TUM fr3).
        distortion: OpenCV coefficients (k1, k2, p1, p2[, k3]); images and depth are distorted
            and ``intrinsics.yaml`` carries them.
        effects: camera effects (default ``Effects()``: read noise 1.5 grey levels only).
        bags: also write 'ros1' and/or 'ros2' bags next to the folder's files.
        png_compression: zlib level 0-9 for the colour PNGs (depth always uses 1).
        workers: PNG writer threads.
        progress: draw a progress bar on stderr.
        start: skip the first ``start`` frames of the trajectory.
        realism: draw the effects and the distortion at random from ``seed``
            (:func:`initsel_ros.synth.realism.draw_realism`); ``effects`` and
            ``distortion``, when given, replace the drawn ones.
        arc: the ``arc`` trajectory's geometry about the scene's target (None: the fixed
            swing about the default target).
        focal_error: relative error written into ``intrinsics.yaml``'s focal lengths (0.1:
            10 % too long); the images are rendered with the true camera, so a reader gets a
            miscalibrated one.
        hfov_deg: horizontal field of view, degrees (the focal lengths follow, their ratio
            and the principal point kept); None keeps the camera's.
        fisheye: render through a fisheye (equidistant) lens whose k1 k2 k3 k4 are
            ``distortion`` (none: an f-theta lens); with ``hfov_deg`` the focal length is the
            pinhole's of that field of view, so the fisheye image sees more.

    Returns:
        A :class:`SynthResult`.
    """
    out = Path(out_dir)
    if realism:
        from initsel_ros.synth.realism import draw_realism

        drawn = draw_realism(seed)
        effects = drawn.effects if effects is None else effects
        # (a drawn lens is the standard model's: a fisheye keeps only what is given)
        distortion = distortion or (() if fisheye else drawn.distortion)
    effects = Effects() if effects is None else effects
    for b in bags:
        if b not in ('ros1', 'ros2'):
            raise ConfigError(f"bag format must be 'ros1' or 'ros2', got {b!r}")
    if not -0.5 < focal_error < 1.0:
        raise ConfigError(f'focal_error must be in (-0.5, 1), got {focal_error}')
    cam = _camera(width, height, intrinsics, distortion, hfov_deg, fisheye)
    world = build_scene(scene, seed)
    stamps, poses = make_trajectory(
        trajectory,
        frames,
        seed,
        start=start,
        arc=arc,
        target=None if arc is None else world.target,
    )
    movers = make_movers(
        effects.movers,
        np.random.default_rng([seed, 2]),
        world.target,
        poses[:, :3, 3].mean(axis=0),
    )
    sensor = SensorRenderer(
        world, cam, effects, PoseTrack(stamps, poses), np.random.default_rng(seed + 1), movers
    )
    try:
        (out / 'rgb').mkdir(parents=True, exist_ok=True)
        (out / 'depth').mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f'{out}: cannot create output folder: {exc}') from exc

    names = [f'{s:.6f}' for s in stamps]
    if effects.jpeg_quality > 0:
        rgb_ext, rgb_params = '.jpg', [cv2.IMWRITE_JPEG_QUALITY, int(effects.jpeg_quality)]
    else:
        rgb_ext, rgb_params = '.png', [cv2.IMWRITE_PNG_COMPRESSION, int(png_compression)]
    depth_params = [cv2.IMWRITE_PNG_COMPRESSION, 1]

    def write(path: Path, img: np.ndarray, params: list[int]) -> None:
        if not cv2.imwrite(str(path), img, params):
            raise DatasetError(f'{path}: cannot write image')

    # disable=None: quiet when stderr is not a terminal (logs, CI)
    bar = tqdm(total=len(stamps), unit='frame', disable=None if progress else True)
    t_start = time.perf_counter()
    pending: deque[Future[None]] = deque()
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        for i in range(len(stamps)):
            image, depth = sensor.frame(i)
            depth_png = np.clip(np.round(depth * DEPTH_SCALE), 0, 65535).astype(np.uint16)
            pending.append(
                pool.submit(write, out / 'rgb' / (names[i] + rgb_ext), image, rgb_params)
            )
            pending.append(
                pool.submit(write, out / 'depth' / (names[i] + '.png'), depth_png, depth_params)
            )
            while len(pending) > 4 * max(1, workers):
                pending.popleft().result()
            bar.update(1)
        for f in pending:
            f.result()
    bar.close()
    seconds = time.perf_counter() - t_start

    write_listing(
        out / 'rgb.txt',
        stamps,
        [f'rgb/{n}{rgb_ext}' for n in names],
        f'color images (initsel synth: scene {scene}, trajectory {trajectory}, seed {seed})',
    )
    write_listing(out / 'depth.txt', stamps, [f'depth/{n}.png' for n in names], 'depth maps')
    t, q = matrix_to_pose(poses)
    write_trajectory(
        out / 'groundtruth.txt', stamps, t, q, 'ground truth trajectory (camera-to-world, exact)'
    )
    calibration = cam
    if focal_error:
        scale = 1.0 + focal_error
        calibration = replace(cam, fx=cam.fx * scale, fy=cam.fy * scale)
    calibration.save_yaml(out / 'intrinsics.yaml')
    _save_effects(
        out / 'effects.yaml', effects, cam.distortion, realism, seed, len(movers), cam.fisheye
    )

    written: list[Path] = []
    if bags:
        from initsel_ros.datasets import bags as bagio
        from initsel_ros.datasets.tum import TumSequence

        seq = TumSequence(out)
        for fmt in dict.fromkeys(bags):
            target = out / ('sequence.bag' if fmt == 'ros1' else 'sequence_ros2')
            if target.is_dir():
                shutil.rmtree(target)  # our own output of an earlier run
            elif target.exists():
                target.unlink()
            bagio.write_bag(seq, target, fmt)
            written.append(target)
    result = SynthResult(
        out, len(stamps), seconds, tuple(written), effects, cam.distortion, sensor.renders
    )
    _LOG.info('%s: %d frames in %.1f s (%.1f frames/s)', out, result.frames, seconds, result.fps)
    return result


def _save_effects(
    path: Path,
    effects: Effects,
    distortion: tuple[float, ...],
    realism: bool,
    seed: int,
    movers: int,
    fisheye: bool = False,
) -> None:
    """Write the rendered effects next to the frames (provenance)."""
    import yaml

    data = {
        'effects': effects.to_dict(),
        'distortion': list(distortion),
        'fisheye': bool(fisheye),
        'realism': bool(realism),
        'seed': int(seed),
        'movers': movers,
    }
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def render_sequence(out_dir: Path | str, *args: Any, **options: Any) -> Path:
    """Render a TUM folder (the arguments of :func:`render`) and return its path."""
    return render(out_dir, *args, **options).path


__all__ = ['SynthResult', 'render', 'render_sequence']
