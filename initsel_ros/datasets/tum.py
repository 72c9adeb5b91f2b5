"""TUM RGB-D folders: ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``, ``intrinsics.yaml``.

Reading follows the benchmark's tools: ``#`` lines are comments; listings have
``timestamp filename`` per line; the trajectory has exactly ``timestamp tx ty tz qx qy qz qw``
(camera-to-world, metres, seconds). Colour and depth are associated by nearest timestamp
(at most 0.02 s apart, unique, closest pairs first, like TUM's ``associate.py``); ground truth is
interpolated to the colour times.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence as Seq
from pathlib import Path

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets.poses import (
    DEFAULT_MAX_GAP,
    check_trajectory,
    interpolate_poses,
    pose_matrices,
)
from initsel_ros.datasets.sequence import (
    Sequence,
    paired_frames,
    read_image_file,
    without_alpha,
)
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.timestamps import ns_to_seconds, parse_seconds_ns

_LOG = logging.getLogger(__name__)

#: TUM depth PNG scale: metres = value / DEPTH_SCALE.
DEPTH_SCALE = 5000.0
#: Largest colour/depth time difference for association, seconds (TUM associate.py default).
MAX_ASSOCIATION_DIFF = 0.02

LISTING_FORMAT = 'timestamp filename'
TRAJECTORY_FORMAT = 'timestamp tx ty tz qx qy qz qw'


def read_text(path: Path) -> str:
    """A dataset text file's content (UTF-8; a byte-order mark, as Windows editors write,
    is dropped); a missing or unreadable file is one DatasetError line."""
    path = Path(path)
    try:
        return path.read_text(encoding='utf-8-sig')
    except FileNotFoundError as exc:
        raise DatasetError(f'{path}: file not found') from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f'{path}: cannot read: {exc}') from exc


def content_lines(path: Path) -> list[tuple[int, str]]:
    """(line number, stripped text) of the lines of a text file that are neither blank nor
    '#' comments."""
    out = []
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        stripped = line.strip()
        if stripped and not stripped.startswith('#'):
            out.append((number, stripped))
    return out


def _data_lines(path: Path) -> list[tuple[int, list[str]]]:
    """(line number, fields) of the non-comment, non-blank lines of a text file."""
    return [(number, text.replace(',', ' ').split()) for number, text in content_lines(path)]


def _float(path: Path, number: int, value: str, expected: str) -> float:
    try:
        out = float(value)
    except ValueError as exc:
        raise DatasetError(
            f'{path}:{number}: {value!r} is not a number; expected `{expected}`'
        ) from exc
    if not np.isfinite(out):
        raise DatasetError(f'{path}:{number}: non-finite value {value!r}; expected `{expected}`')
    return out


def read_listing(path: Path) -> tuple[np.ndarray, list[str]]:
    """Read ``rgb.txt`` or ``depth.txt``.

    Returns:
        ``(stamps (N,) float64 seconds, relative file names)``.
    """
    stamps_ns, names = read_listing_ns(path)
    return np.array([ns_to_seconds(t) for t in stamps_ns], dtype=np.float64), names


def read_listing_ns(path: Path) -> tuple[list[int], list[str]]:
    """Read ``rgb.txt`` or ``depth.txt`` with exact times.

    Returns:
        ``(stamps as integer nanoseconds, parsed from the decimal text exactly, file names)``.
    """
    path = Path(path)
    rows = []
    for number, fields in _data_lines(path):
        if len(fields) != 2:
            raise DatasetError(
                f'{path}:{number}: expected 2 columns `{LISTING_FORMAT}`, got {len(fields)}'
            )
        _float(path, number, fields[0], LISTING_FORMAT)  # the error message for bad text
        rows.append((number, parse_seconds_ns(fields[0]), fields[0], fields[1]))
    return one_file_per_stamp(path, rows)


def one_file_per_stamp(
    path: Path, rows: Seq[tuple[int, int, str, str]]
) -> tuple[list[int], list[str]]:
    """An image listing's rows (line number, stamp in ns, the stamp as written, file name) ->
    (stamps, file names) in the rows' order, each stamp once.

    Raises:
        DatasetError: one time listed with two files (which frame is it?); the same line
            twice is read once, with a warning.
    """
    stamps: list[int] = []
    names: list[str] = []
    seen: dict[int, tuple[int, str]] = {}  # stamp -> (line, file)
    repeated = 0
    for number, stamp, text, name in rows:
        if stamp in seen:
            line, first = seen[stamp]
            if first != name:
                raise DatasetError(
                    f'{path}:{number}: time {text} is also line {line}, with another file '
                    f'({first} and {name}): which frame is it?'
                )
            repeated += 1  # the same line twice: one frame
            continue
        seen[stamp] = (number, name)
        stamps.append(stamp)
        names.append(name)
    if repeated:
        _LOG.warning('%s: %d repeated lines read once', path, repeated)
    return stamps, names


def read_trajectory(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a TUM trajectory (``groundtruth.txt``).

    Returns:
        ``(stamps (N,) seconds, positions (N, 3) metres, quaternions (N, 4) xyzw)``,
        sorted by time.
    """
    path = Path(path)
    rows = []
    for number, fields in _data_lines(path):
        if len(fields) != 8:
            raise DatasetError(
                f'{path}:{number}: expected 8 columns `{TRAJECTORY_FORMAT}`, got {len(fields)}'
            )
        row = [_float(path, number, v, TRAJECTORY_FORMAT) for v in fields]
        if np.linalg.norm(row[4:]) < 1e-9:
            raise DatasetError(f'{path}:{number}: zero quaternion; expected `{TRAJECTORY_FORMAT}`')
        rows.append(row)
    data = np.array(rows, dtype=np.float64).reshape(-1, 8)
    return check_trajectory(data[:, 0], data[:, 1:4], data[:, 4:8], str(path))


def write_listing(path: Path, stamps: Seq[float], names: Seq[str], title: str) -> None:
    """Write ``rgb.txt``/``depth.txt`` (``title`` e.g. 'color images' or 'depth maps')."""
    lines = [f'# {title}', f'# {LISTING_FORMAT}']
    lines += [f'{s:.6f} {n}' for s, n in zip(stamps, names, strict=True)]
    Path(path).write_text('\n'.join(lines) + '\n')


def write_trajectory(
    path: Path,
    stamps: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    title: str = 'ground truth trajectory',
) -> None:
    """Write a TUM trajectory file; positions (N, 3) metres, quaternions (N, 4) xyzw."""
    data = np.column_stack(
        [
            np.asarray(stamps, dtype=np.float64).reshape(-1, 1),
            np.asarray(positions).reshape(-1, 3),
            np.asarray(quaternions).reshape(-1, 4),
        ]
    )
    lines = [f'# {title}', f'# {TRAJECTORY_FORMAT}']
    lines += [f'{r[0]:.6f} ' + ' '.join(f'{v:.9f}' for v in r[1:]) for r in data]
    Path(path).write_text('\n'.join(lines) + '\n')


def associate(
    first: np.ndarray, second: np.ndarray, max_difference: float = MAX_ASSOCIATION_DIFF
) -> np.ndarray:
    """Match two timestamp lists one-to-one, closest pairs first, at most ``max_difference`` apart.

    Args:
        first: (N,) seconds.
        second: (M,) seconds.

    Returns:
        (N,) int: index into ``second`` for each of ``first``, -1 where unmatched.
    """
    first = np.asarray(first, dtype=np.float64)
    second = np.asarray(second, dtype=np.float64)
    match = np.full(len(first), -1, dtype=np.int64)
    if len(first) == 0 or len(second) == 0:
        return match
    order = np.argsort(second, kind='stable')
    sorted_second = second[order]
    pos = np.searchsorted(sorted_second, first)
    cand_a, cand_b = [], []
    for offset in (-2, -1, 0, 1):  # the candidates within tolerance around each time
        j = pos + offset
        valid = (j >= 0) & (j < len(second))
        cand_a.append(np.flatnonzero(valid))
        cand_b.append(order[j[valid]])
    a = np.concatenate(cand_a)
    b = np.concatenate(cand_b)
    diff = np.abs(first[a] - second[b])
    keep = diff <= max_difference
    a, b, diff = a[keep], b[keep], diff[keep]
    used_b = np.zeros(len(second), dtype=bool)
    for k in np.lexsort((a, diff)):
        if match[a[k]] < 0 and not used_b[b[k]]:
            match[a[k]] = b[k]
            used_b[b[k]] = True
    return match


class TumSequence(Sequence):
    """A TUM RGB-D folder, loaded lazily.

    Args:
        path: the folder holding ``rgb.txt`` (required), ``depth.txt`` and ``groundtruth.txt``
            (optional) and ``intrinsics.yaml`` (optional; TUM fr3 when absent).
        intrinsics: overrides the folder's intrinsics.
        groundtruth: another trajectory file to use instead of ``groundtruth.txt``.
        max_gap: largest gap (s) between ground-truth samples to interpolate across.
        nearest_tolerance: frames outside the ground truth (or in a larger gap) take the nearest
            pose when it is at most this far away (s); 0 (default) leaves them without a pose.
        max_association_diff: colour/depth association tolerance, seconds.
        depth_scale: depth PNG value per metre.
        ground_truth: False leaves every frame without a pose and the trajectory file unread
            (a replay that does not publish it needs none, malformed or not).
    """

    def __init__(
        self,
        path: Path,
        *,
        intrinsics: Intrinsics | None = None,
        groundtruth: Path | None = None,
        max_gap: float = DEFAULT_MAX_GAP,
        nearest_tolerance: float = 0.0,
        max_association_diff: float = MAX_ASSOCIATION_DIFF,
        depth_scale: float = DEPTH_SCALE,
        ground_truth: bool = True,
    ) -> None:
        path = Path(path)
        if not path.is_dir():
            raise DatasetError(f'{path}: not a TUM folder (directory not found)')
        if intrinsics is None:
            intrinsics = self._read_intrinsics(path)
        rgb_ns, rgb_names = read_listing_ns(path / 'rgb.txt')
        if len(rgb_ns) == 0:
            raise DatasetError(f'{path / "rgb.txt"}: no frames listed')
        order = sorted(range(len(rgb_ns)), key=rgb_ns.__getitem__)
        rgb_ns = [rgb_ns[i] for i in order]
        rgb_names = [rgb_names[i] for i in order]
        rgb_stamps = np.array([ns_to_seconds(t) for t in rgb_ns], dtype=np.float64)

        depth_match = np.full(len(rgb_stamps), -1)
        depth_stamps, depth_names = np.zeros(0), []
        if (path / 'depth.txt').exists():
            depth_stamps, depth_names = read_listing(path / 'depth.txt')
            depth_match = associate(rgb_stamps, depth_stamps, max_association_diff)
            n_missing = int(np.sum(depth_match < 0))
            if n_missing:
                _LOG.warning(
                    '%s: %d of %d colour frames have no depth within %.3f s',
                    path,
                    n_missing,
                    len(rgb_stamps),
                    max_association_diff,
                )

        gt_path = Path(groundtruth) if groundtruth is not None else path / 'groundtruth.txt'
        poses: list[np.ndarray | None] = [None] * len(rgb_stamps)
        if not ground_truth:
            _LOG.debug('%s: ground truth not read (not asked for)', path)
        elif groundtruth is not None or gt_path.exists():
            stamps, positions, quats = read_trajectory(gt_path)
            poses = pose_matrices(
                *interpolate_poses(
                    rgb_stamps, stamps, positions, quats, max_gap, nearest_tolerance
                )
            )
            n_missing = sum(p is None for p in poses)
            if n_missing:
                _LOG.warning(
                    '%s: %d of %d frames have no ground-truth pose (outside the trajectory or '
                    'in a gap over %.3f s; nearest tolerance %.3f s)',
                    path,
                    n_missing,
                    len(poses),
                    max_gap,
                    nearest_tolerance,
                )
        else:
            _LOG.info('%s: no groundtruth.txt; frames have no poses', path)

        frames = paired_frames(rgb_stamps, rgb_ns, poses, depth_stamps, depth_match)
        super().__init__(path.resolve().name, intrinsics, frames, path)
        self.depth_scale = float(depth_scale)
        self.rgb_files = [path / n for n in rgb_names]
        self.depth_files: list[Path | None] = [
            path / depth_names[j] if j >= 0 else None for j in depth_match
        ]

    @staticmethod
    def _read_intrinsics(path: Path) -> Intrinsics:
        yaml_path = path / 'intrinsics.yaml'
        if not yaml_path.exists():
            return Intrinsics.tum_fr3()
        try:
            return Intrinsics.load_yaml(yaml_path)
        except ConfigError as exc:
            raise DatasetError(str(exc)) from exc

    def _load_native(self, i: int) -> np.ndarray:
        return without_alpha(read_image_file(self.rgb_files[i], cv2.IMREAD_UNCHANGED))

    def _load_depth(self, i: int) -> np.ndarray | None:
        file = self.depth_files[i]
        if file is None:
            return None
        raw = read_image_file(file, cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2:
            raise DatasetError(f'{file}: depth must be a single-channel 16-bit PNG')
        if raw.dtype == np.float32:
            return raw
        if raw.dtype != np.uint16:  # an 8-bit PNG / depth_scale would be millimetres at most
            raise DatasetError(
                f'{file}: depth must be a 16-bit PNG (TUM: {self.depth_scale:g} per metre), '
                f'got {raw.dtype}'
            )
        return (raw.astype(np.float32) / np.float32(self.depth_scale)).astype(np.float32)


def is_tum_folder(path: Path) -> bool:
    """True when ``path`` is a directory with an ``rgb.txt``."""
    path = Path(path)
    return path.is_dir() and (path / 'rgb.txt').is_file()


__all__ = [
    'DEPTH_SCALE',
    'LISTING_FORMAT',
    'MAX_ASSOCIATION_DIFF',
    'TRAJECTORY_FORMAT',
    'TumSequence',
    'associate',
    'is_tum_folder',
    'read_listing',
    'read_listing_ns',
    'read_trajectory',
    'write_listing',
    'write_trajectory',
]
