"""The real ORB-SLAM3 monocular system as a seed-map baseline (row ``ORB-SLAM3 (real)``).

``orbslam3-python`` (2.0.0, GPL-3, the ORB-SLAM3 v1.0 monocular system) depends on
``opencv-python``, which clashes with the ``opencv-python-headless`` of this package's
environment, so it lives in a venv of its own (``scripts/setup_orbslam3.sh``, default
``.venv-orbslam3`` or ``$INITSEL_ORBSLAM3_VENV``). Each batch runs in one subprocess of that
interpreter (:mod:`.orbslam3_worker`), with a timeout: a crash or a time-out is a failed batch.

ORB-SLAM3 is fed the batch's grey frames (sensor noise included) with their stamps, from the
batch's first frame, and judged at its first initialization: the relative pose of the two
initializing keyframes at their own stamps (it may replace its first reference frame) against
the ground truth, its tracked map points for the depth error (projected into the reference
frame for the ground-truth depth). Its RANSAC seed is fixed: repeated runs are identical.

It needs a vocabulary; the one used here is the substitute of :mod:`.vocabulary` (its
monocular initializer matches by image grid, not through the vocabulary). Tracking after the
initialization is not judged.
"""

from __future__ import annotations

import json
import logging
import math
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError

_LOG = logging.getLogger(__name__)

#: Environment variable naming the ORB-SLAM3 venv.
VENV_ENV = 'INITSEL_ORBSLAM3_VENV'
#: Default venv folder (relative to the working directory, as scripts/setup_orbslam3.sh makes it).
DEFAULT_VENV = '.venv-orbslam3'
#: Vocabulary file name inside the venv (written by scripts/setup_orbslam3.sh).
VOCABULARY_NAME = 'initsel_orbvoc.txt'
#: The worker script, run by the venv's interpreter.
WORKER = Path(__file__).with_name('orbslam3_worker.py')


@dataclass(frozen=True)
class Orbslam3Setup:
    """Where the real ORB-SLAM3 is: its interpreter, vocabulary and per-batch timeout."""

    python: str
    vocabulary: str
    timeout_s: float = 300.0


def find_orbslam3(
    venv: Path | str | None = None,
    vocabulary: Path | str | None = None,
    timeout_s: float = 300.0,
) -> Orbslam3Setup:
    """The ORB-SLAM3 setup, checked.

    Args:
        venv: the venv folder (default ``$INITSEL_ORBSLAM3_VENV`` or ``./.venv-orbslam3``).
        vocabulary: DBoW2 text vocabulary (default ``VENV/initsel_orbvoc.txt``).

    Raises:
        ConfigError: the venv, its orbslam3 package or the vocabulary is missing.
    """
    folder = Path(os.path.abspath(venv or os.environ.get(VENV_ENV) or DEFAULT_VENV))
    python = folder / 'bin' / 'python'
    hint = 'make it with scripts/setup_orbslam3.sh (or pass --orbslam3-venv)'
    if not python.exists():
        raise ConfigError(f'no ORB-SLAM3 venv at {folder} ({python} missing): {hint}')
    voc = Path(vocabulary) if vocabulary else folder / VOCABULARY_NAME
    if not voc.is_file():
        raise ConfigError(
            f'no ORB-SLAM3 vocabulary at {voc}: {hint}, or train one with initsel orbvocab'
        )
    probe = subprocess.run(
        [str(python), '-c', 'import orbslam3'],
        env=worker_env(),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    if probe.returncode != 0:
        last = (probe.stderr.strip().splitlines() or ['?'])[-1]
        raise ConfigError(f'{python} cannot import orbslam3 ({last}): {hint}')
    return Orbslam3Setup(str(python), str(voc.resolve()), timeout_s)


def worker_env() -> dict[str, str]:
    """The environment of the ORB-SLAM3 interpreter: ours without the ROS wheels' library path
    and bootstrap marker (the wheel brings its own OpenCV, Boost and Pangolin)."""
    env = dict(os.environ)
    for name in ('LD_LIBRARY_PATH', '_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'PYTHONPATH'):
        env.pop(name, None)
    return env


def _real(value: float) -> str:
    """A real as ORB-SLAM3's settings reader wants it: always with a decimal point."""
    text = repr(float(value))
    return text if ('.' in text or 'e' in text or 'n' in text) else text + '.0'


def settings_yaml(intrinsics: Intrinsics, fps: float, n_features: int = 1000) -> str:
    """ORB-SLAM3 v1.0 settings for a monocular camera: ``PinHole`` (k1 k2 p1 p2 [k3]) or, for
    a fisheye lens, ``KannalaBrandt8`` (k1 k2 k3 k4, the same model as ``cv2.fisheye``).

    Every real-valued setting is written as a real (``0.0``, not ``0``): ORB-SLAM3's reader
    aborts on an integer where it expects a real. Integers (size, fps, features, levels, FAST
    thresholds) stay integers.
    """
    reals = {
        'Camera1.fx': intrinsics.fx,
        'Camera1.fy': intrinsics.fy,
        'Camera1.cx': intrinsics.cx,
        'Camera1.cy': intrinsics.cy,
    }
    if intrinsics.fisheye:
        camera_type = 'KannalaBrandt8'
        k = [float(v) for v in intrinsics.lens_coefficients]  # type: ignore[union-attr]
        reals.update({f'Camera1.k{i + 1}': k[i] for i in range(4)})
    else:
        camera_type = 'PinHole'
        d = tuple(intrinsics.distortion) + (0.0,) * (5 - len(intrinsics.distortion))
        names = ('Camera1.k1', 'Camera1.k2', 'Camera1.p1', 'Camera1.p2')
        reals.update(zip(names, d[:4], strict=True))
        if d[4] != 0.0:
            reals['Camera1.k3'] = d[4]
        if any(d[5:]):
            _LOG.warning(
                "ORB-SLAM3's PinHole model takes k1 k2 p1 p2 k3: the camera's coefficients %s "
                'are left out, so ORB-SLAM3 undistorts with a lens that is not quite this one',
                list(d[5:]),
            )
    lines = ['%YAML:1.0', 'File.version: "1.0"', f'Camera.type: "{camera_type}"']
    lines += [f'{k}: {_real(v)}' for k, v in reals.items()]
    lines += [
        f'Camera.width: {int(intrinsics.width)}',
        f'Camera.height: {int(intrinsics.height)}',
        f'Camera.fps: {max(1, round(fps))}',
        'Camera.RGB: 0',
        f'ORBextractor.nFeatures: {int(n_features)}',
        f'ORBextractor.scaleFactor: {_real(1.2)}',
        'ORBextractor.nLevels: 8',
        'ORBextractor.iniThFAST: 20',
        'ORBextractor.minThFAST: 7',
    ]
    viewer = {
        'KeyFrameSize': 0.05,
        'KeyFrameLineWidth': 1.0,
        'GraphLineWidth': 0.9,
        'PointSize': 2.0,
        'CameraSize': 0.08,
        'CameraLineWidth': 3.0,
        'ViewpointX': 0.0,
        'ViewpointY': -0.7,
        'ViewpointZ': -1.8,
        'ViewpointF': 500.0,
    }
    lines += [f'Viewer.{k}: {_real(v)}' for k, v in viewer.items()]
    return '\n'.join(lines) + '\n'


@dataclass(frozen=True)
class Orbslam3Init:
    """ORB-SLAM3's first initialization in a batch (indices relative to the batch's start).

    Attributes:
        status: 'initialized', 'not initialized' or 'failed' (crash, time-out, bad output).
        reference: index of the reference keyframe.
        current: index of the second keyframe (the initializing frame).
        T_w_ref: (4, 4) reference keyframe, camera to ORB-SLAM3's world.
        T_w_cur: (4, 4) second keyframe, camera to world.
        points: (M, 3) map points in the reference camera frame.
        detail: why it failed (empty otherwise).
    """

    status: str
    reference: int = -1
    current: int = -1
    T_w_ref: np.ndarray | None = None
    T_w_cur: np.ndarray | None = None
    points: np.ndarray | None = None
    detail: str = ''

    @property
    def pose(self) -> tuple[np.ndarray, np.ndarray]:
        """``(R, t)`` with ``x_cur = R x_ref + t``."""
        from initsel_ros.metrics import relative_pose

        return relative_pose(self.T_w_ref, self.T_w_cur)


def _nearest(stamps_s: np.ndarray, stamp: float) -> int:
    return int(np.argmin(np.abs(stamps_s - stamp)))


def parse_result(result: dict, stamps_s: np.ndarray) -> Orbslam3Init:
    """The worker's JSON -> :class:`Orbslam3Init` (stamps mapped back to frame indices)."""
    if not result.get('initialized'):
        return Orbslam3Init('not initialized')
    keyframes = result.get('keyframes') or []
    if len(keyframes) < 2:
        return Orbslam3Init('failed', detail=f'{len(keyframes)} keyframes at initialization')
    (s_ref, T_ref), (s_cur, T_cur) = keyframes[0], keyframes[-1]
    T_w_ref = np.asarray(T_ref, dtype=np.float64).reshape(4, 4)
    T_w_cur = np.asarray(T_cur, dtype=np.float64).reshape(4, 4)
    world = np.asarray(result.get('points') or [], dtype=np.float64).reshape(-1, 3)
    points = (world - T_w_ref[:3, 3]) @ T_w_ref[:3, :3]  # R_wc^T (X - C)
    return Orbslam3Init(
        'initialized',
        _nearest(stamps_s, s_ref),
        _nearest(stamps_s, s_cur),
        T_w_ref,
        T_w_cur,
        points,
    )


def run_orbslam3(
    gray: list[np.ndarray] | np.ndarray,
    stamps_ns: np.ndarray,
    intrinsics: Intrinsics,
    setup: Orbslam3Setup,
) -> Orbslam3Init:
    """Run the real ORB-SLAM3 on grey frames in a subprocess (never raises for its failures)."""
    stamps_s = np.asarray(stamps_ns, dtype=np.float64) / 1e9
    fps = 1.0 / float(np.median(np.diff(stamps_s))) if len(stamps_s) > 1 else 30.0
    with tempfile.TemporaryDirectory(prefix='initsel-orbslam3-') as tmp:
        folder = Path(tmp)
        np.savez(folder / 'batch.npz', images=np.stack(gray).astype(np.uint8), stamps=stamps_s)
        (folder / 'settings.yaml').write_text(settings_yaml(intrinsics, fps))
        out = folder / 'out.json'
        command = [
            setup.python,
            '-I',  # isolated: no script folder, user site or PYTHON* variables on the path
            str(WORKER),
            str(folder / 'batch.npz'),
            setup.vocabulary,
            str(folder / 'settings.yaml'),
            str(out),
        ]
        try:
            proc = subprocess.run(
                command,
                env=worker_env(),
                cwd=folder,
                capture_output=True,
                text=True,
                timeout=setup.timeout_s,
                check=False,
            )
        except subprocess.TimeoutExpired:
            return Orbslam3Init('failed', detail=f'timed out after {setup.timeout_s:g} s')
        if proc.returncode != 0 or not out.is_file():
            tail = ' | '.join(proc.stderr.strip().splitlines()[-3:])
            return Orbslam3Init('failed', detail=f'exit {proc.returncode}: {tail}')
        try:
            result = json.loads(out.read_text())
        except json.JSONDecodeError as exc:
            return Orbslam3Init('failed', detail=f'bad output: {exc}')
    init = parse_result(result, stamps_s)
    if init.status == 'initialized' and not all(
        math.isfinite(v) for v in np.concatenate([init.T_w_ref.ravel(), init.T_w_cur.ravel()])
    ):
        return Orbslam3Init('failed', detail='non-finite keyframe pose')
    return init


__all__ = [
    'DEFAULT_VENV',
    'VENV_ENV',
    'Orbslam3Init',
    'Orbslam3Setup',
    'find_orbslam3',
    'parse_result',
    'run_orbslam3',
    'settings_yaml',
    'worker_env',
]
