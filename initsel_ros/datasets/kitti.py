"""KITTI odometry sequences (``sequences/NN``, ``poses/NN.txt``), and a writer for tests.

Layout read::

    <root>/sequences/NN/image_0/000000.png  8-bit grey, rectified (image_1..3 also accepted)
    <root>/sequences/NN/times.txt           one time per frame, seconds (e.g. 1.036205e-01)
    <root>/sequences/NN/calib.txt           'P0: p00 ... p23' (3x4, row-major) ...; K = P0[:, :3]
    <root>/poses/NN.txt                     per frame 12 numbers: the 3x4 row-major cam0-to-world
                                            pose (world = the first cam0 frame); optional

``open_sequence`` accepts the sequence folder (poses then from ``../../poses/NN.txt`` or a
``poses.txt`` inside it) or the root with ``sequence='NN'``. Images are rectified, so there is
no distortion. Stamps are parsed exactly from the decimal text of ``times.txt`` (KITTI's times
start at 0). There is no depth.
"""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets.sequence import Frame, Sequence, read_image_file, without_alpha
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.timestamps import ns_to_seconds, parse_seconds_ns

_LOG = logging.getLogger(__name__)

POSE_FORMAT = 'r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz'


def is_kitti_sequence(path: Path) -> bool:
    """True for a folder with ``times.txt``, ``calib.txt`` and an ``image_N`` folder."""
    path = Path(path)
    return (
        path.is_dir()
        and (path / 'times.txt').is_file()
        and (path / 'calib.txt').is_file()
        and any((path / f'image_{n}').is_dir() for n in range(4))
    )


def missing_kitti_parts(path: Path) -> list[str]:
    """What a folder lacks of a KITTI odometry sequence (``times.txt``, ``calib.txt``, an
    ``image_N/`` folder); empty for a sequence."""
    path = Path(path)
    missing = [name for name in ('times.txt', 'calib.txt') if not (path / name).is_file()]
    if not any((path / f'image_{n}').is_dir() for n in range(4)):
        missing.append('image_0/ (or image_1/-image_3/)')
    return missing


def kitti_sequences(root: Path) -> list[str]:
    """Names of the sequences under ``<root>/sequences`` (sorted), empty when none."""
    seq_dir = Path(root) / 'sequences'
    if not seq_dir.is_dir():
        return []
    return sorted(p.name for p in seq_dir.iterdir() if is_kitti_sequence(p))


def is_kitti_root(path: Path) -> bool:
    """True for a KITTI odometry root: ``sequences/NN`` folders."""
    return Path(path).is_dir() and bool(kitti_sequences(path))


def resolve_sequence_folder(path: Path, sequence: str | None) -> Path:
    """The ``sequences/NN`` folder for a sequence folder, or a root plus ``sequence``.

    Raises:
        DatasetError: neither layout, or a root without a valid ``sequence``.
    """
    path = Path(os.path.abspath(path))  # (its parents hold poses/ and name it: not '.')
    if is_kitti_sequence(path):
        if sequence is not None and path.name != str(sequence):
            raise DatasetError(f'{path}: is KITTI sequence {path.name}, not {sequence}')
        return path
    available = kitti_sequences(path)
    requested = path / 'sequences' / str(sequence) if sequence is not None else None
    if requested is not None and requested.is_dir() and not is_kitti_sequence(requested):
        missing = ', '.join(missing_kitti_parts(requested))
        raise DatasetError(f'{requested}: not a KITTI odometry sequence: no {missing}')
    if not available:
        raise DatasetError(
            f'{path}: not a KITTI odometry sequence (no {", ".join(missing_kitti_parts(path))}) '
            'nor a root with sequences/NN'
        )
    if sequence is None:
        raise DatasetError(
            f'{path}: a KITTI odometry root; choose a sequence with --sequence NN, or give '
            f'its folder (sequences/NN) (found: {", ".join(available)})'
        )
    name = str(sequence)
    if name not in available and name.isdigit() and f'{int(name):02d}' in available:
        name = f'{int(name):02d}'
    if name not in available:
        raise DatasetError(f'{path}: no sequence {sequence!r} (found: {", ".join(available)})')
    return path / 'sequences' / name


def _numbers(path: Path, number: int, fields: list[str], expected: str) -> np.ndarray:
    try:
        out = np.array([float(v) for v in fields], dtype=np.float64)
    except ValueError as exc:
        raise DatasetError(
            f'{path}:{number}: not a number ({exc}); expected `{expected}`'
        ) from exc
    if not np.all(np.isfinite(out)):
        raise DatasetError(f'{path}:{number}: non-finite value; expected `{expected}`')
    return out


def _lines(path: Path) -> list[tuple[int, str]]:
    try:
        text = path.read_text(encoding='utf-8-sig')
    except FileNotFoundError as exc:
        raise DatasetError(f'{path}: file not found') from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f'{path}: cannot read: {exc}') from exc
    return [(n, ln.strip()) for n, ln in enumerate(text.splitlines(), start=1) if ln.strip()]


def read_times(path: Path) -> list[int]:
    """``times.txt`` -> integer nanoseconds, parsed exactly from the decimal text."""
    path = Path(path)
    out, numbers = [], []
    for number, line in _lines(path):
        numbers.append(number)
        try:
            out.append(parse_seconds_ns(line.split()[0]))
        except DatasetError as exc:
            raise DatasetError(
                f'{path}:{number}: {exc}; expected one time in seconds per line'
            ) from exc
    back = [k for k in range(1, len(out)) if out[k] <= out[k - 1]]
    if back:
        _LOG.warning(
            '%s: %d times do not rise (first at line %d): frames keep their order, their '
            'stamps say otherwise',
            path,
            len(back),
            numbers[back[0]],
        )
    return out


def read_calib(path: Path, camera: int = 0) -> np.ndarray:
    """The (3, 4) projection matrix ``P<camera>`` of ``calib.txt``."""
    path = Path(path)
    key = f'P{camera}'
    for number, line in _lines(path):
        name, _, rest = line.partition(':')
        if name.strip() == key:
            values = _numbers(path, number, rest.split(), f'{key}: 12 numbers')
            if values.size != 12:
                raise DatasetError(f'{path}:{number}: {key} needs 12 numbers, got {values.size}')
            return values.reshape(3, 4)
    raise DatasetError(f'{path}: no {key}: line')


#: Largest entry of R^T R - I of a pose's rotation block (KITTI's files are printed to
#: 1e-6 relative; a block scaled, zeroed or mis-ordered is far beyond it).
ROTATION_TOLERANCE = 1e-3


def read_poses(path: Path) -> np.ndarray:
    """``poses/NN.txt`` -> (N, 4, 4) cam0-to-world matrices."""
    path = Path(path)
    rows = []
    for number, line in _lines(path):
        values = _numbers(path, number, line.split(), POSE_FORMAT)
        if values.size != 12:
            raise DatasetError(
                f'{path}:{number}: expected 12 numbers `{POSE_FORMAT}`, got {values.size}'
            )
        R = values.reshape(3, 4)[:, :3]
        error, det = float(np.abs(R.T @ R - np.eye(3)).max()), float(np.linalg.det(R))
        if error > ROTATION_TOLERANCE or det < 0:
            raise DatasetError(
                f'{path}:{number}: the 3x3 block is not a rotation (|R^T R - I| = {error:.3g}, '
                f'det {det:.3g}); expected `{POSE_FORMAT}`'
            )
        rows.append(values)
    out = np.tile(np.eye(4), (len(rows), 1, 1))
    if rows:
        out[:, :3, :] = np.asarray(rows).reshape(-1, 3, 4)
    return out


def png_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR chunk without decoding it; None when not a PNG."""
    try:
        with Path(path).open('rb') as handle:
            head = handle.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b'\x89PNG\r\n\x1a\n' or head[12:16] != b'IHDR':
        return None
    width, height = struct.unpack('>II', head[16:24])
    return int(width), int(height)


def _default_camera(folder: Path) -> int:
    """0, or the first ``image_N`` holding PNGs when ``image_0`` holds none."""
    with_images = [n for n in range(4) if any((folder / f'image_{n}').glob('*.png'))]
    if not with_images or with_images[0] == 0:
        return 0
    _LOG.info(
        '%s: no images in image_0/: reading image_%d/ (P%d; the poses moved to that camera)',
        folder,
        with_images[0],
        with_images[0],
    )
    return with_images[0]


class KittiSequence(Sequence):
    """A KITTI odometry sequence, loaded lazily.

    Args:
        path: ``sequences/NN``, or the dataset root together with ``sequence``.
        sequence: 'NN' when ``path`` is the root.
        camera: 0-3, the ``image_<camera>`` folder and the ``P<camera>`` matrix (default: 0,
            the left grey camera, which the poses describe; the first camera with images in a
            download without ``image_0``, such as the colour-only one, with a note).
        poses: a pose file overriding the one found beside the sequence.
        ground_truth: False leaves every frame without a pose and the pose file unread.

    Attributes:
        P: (3, 4) projection matrix of the camera.
    """

    def __init__(
        self,
        path: Path | str,
        *,
        sequence: str | None = None,
        camera: int | None = None,
        poses: Path | str | None = None,
        ground_truth: bool = True,
    ) -> None:
        folder = resolve_sequence_folder(Path(path), sequence)
        if camera is None:
            camera = _default_camera(folder)
        if camera not in (0, 1, 2, 3):
            raise ConfigError(f'KITTI camera must be 0-3, got {camera}')
        image_dir = folder / f'image_{camera}'
        files = sorted(image_dir.glob('*.png'))
        if not files:
            raise DatasetError(f'{image_dir}: no PNG images')
        stamps_ns = read_times(folder / 'times.txt')
        if len(stamps_ns) != len(files):
            raise DatasetError(
                f'{folder / "times.txt"}: {len(stamps_ns)} times for '
                f'{len(files)} images in {image_dir.name}/'
            )
        self.P = read_calib(folder / 'calib.txt', camera)
        size = png_size(files[0])
        if size is None:
            first = read_image_file(files[0], cv2.IMREAD_UNCHANGED)
            size = (first.shape[1], first.shape[0])
        try:
            intrinsics = Intrinsics.from_matrix(self.P[:, :3], *size)
        except ConfigError as exc:
            raise DatasetError(f'{folder / "calib.txt"}: P{camera}: {exc}') from exc

        pose_file = Path(poses) if poses is not None else self._find_poses(folder)
        matrices: list[np.ndarray | None] = [None] * len(files)
        if not ground_truth:
            pose_file = None
            _LOG.debug('%s: ground truth not read (not asked for)', folder)
        elif pose_file is not None:
            loaded = read_poses(pose_file)
            if len(loaded) != len(files):
                raise DatasetError(f'{pose_file}: {len(loaded)} poses for {len(files)} frames')
            if camera != 0:  # poses are cam0's: P_n = K [I | t], camera n at -t in cam0
                offset = np.eye(4)
                offset[:3, 3] = -np.linalg.solve(self.P[:, :3], self.P[:, 3])
                loaded = loaded @ offset
            matrices = list(loaded)
        else:
            _LOG.info('%s: no poses/%s.txt; frames have no poses', folder, folder.name)
        self.pose_file = pose_file
        frames = [
            Frame(i, ns_to_seconds(ns), matrices[i], None, stamp_ns=ns)
            for i, ns in enumerate(stamps_ns)
        ]
        super().__init__(f'kitti_{folder.name}', intrinsics, frames, folder)
        self.image_files = files

    @staticmethod
    def _find_poses(folder: Path) -> Path | None:
        for candidate in (
            folder.parent.parent / 'poses' / f'{folder.name}.txt',
            folder / 'poses.txt',
        ):
            if candidate.is_file():
                return candidate
        return None

    def _load_native(self, i: int) -> np.ndarray:
        return without_alpha(read_image_file(self.image_files[i], cv2.IMREAD_UNCHANGED))

    def _load_depth(self, i: int) -> np.ndarray | None:
        return None


def write_kitti(sequence: Sequence, root: Path | str, name: str = '00') -> Path:
    """Write ``sequence`` as KITTI odometry ``<root>/sequences/<name>`` and
    ``<root>/poses/<name>.txt`` (grey PNGs, times from 0, poses relative to the first frame).

    Returns:
        The sequence folder.
    """
    root = Path(root)
    folder = root / 'sequences' / name
    (folder / 'image_0').mkdir(parents=True, exist_ok=True)
    for f in sequence.frames:
        native = sequence.native_image(f.index)
        grey = native if native.ndim == 2 else cv2.cvtColor(native, cv2.COLOR_BGR2GRAY)
        target = folder / 'image_0' / f'{f.index:06d}.png'
        if not cv2.imwrite(str(target), grey):
            raise DatasetError(f'{target}: cannot write image')
    t0 = sequence.frames[0].stamp_ns
    (folder / 'times.txt').write_text(
        ''.join(f'{(f.stamp_ns - t0) * 1e-9:e}\n' for f in sequence.frames)
    )
    cam = sequence.intrinsics
    P = np.array([[cam.fx, 0.0, cam.cx, 0.0], [0.0, cam.fy, cam.cy, 0.0], [0.0, 0.0, 1.0, 0.0]])
    calib = [f'P{n}: ' + ' '.join(f'{v:.12e}' for v in P.reshape(-1)) for n in range(4)]
    (folder / 'calib.txt').write_text('\n'.join(calib) + '\n')
    if all(f.pose is not None for f in sequence.frames):
        first_inv = np.linalg.inv(sequence.frames[0].pose)
        rows = [
            ' '.join(f'{v:.12e}' for v in (first_inv @ f.pose)[:3].reshape(-1))
            for f in sequence.frames
        ]
        (root / 'poses').mkdir(exist_ok=True)
        (root / 'poses' / f'{name}.txt').write_text('\n'.join(rows) + '\n')
    return folder


__all__ = [
    'KittiSequence',
    'is_kitti_root',
    'is_kitti_sequence',
    'kitti_sequences',
    'png_size',
    'read_calib',
    'read_poses',
    'read_times',
    'resolve_sequence_folder',
    'write_kitti',
]
