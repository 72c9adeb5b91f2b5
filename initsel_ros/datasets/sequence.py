"""The common sequence interface shared by TUM folders and bags.

A :class:`Sequence` is a list of :class:`Frame` records (timestamps and ground-truth poses, cheap)
plus lazy access to the images and depth maps behind them (loaded on demand).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import DatasetError
from initsel_ros.image import to_bgr
from initsel_ros.timestamps import seconds_to_ns

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Frame:
    """One colour frame of a sequence.

    Attributes:
        index: position in the sequence, 0-based.
        stamp: colour image time, seconds (float; for timing and interpolation).
        pose: (4, 4) float64 camera-to-world ground truth at ``stamp``, or None when unknown.
        depth_stamp: time of the associated depth map (seconds) or None when there is none.
        stamp_ns: the exact colour image time, integer nanoseconds, as the source stores it
            (bag header, EuRoC ns, TUM decimal text); rounded from ``stamp`` when not given.
    """

    index: int
    stamp: float
    pose: np.ndarray | None
    depth_stamp: float | None = None
    stamp_ns: int | None = None

    def __post_init__(self) -> None:
        if self.stamp_ns is None:
            object.__setattr__(self, 'stamp_ns', seconds_to_ns(self.stamp))
        else:
            object.__setattr__(self, 'stamp_ns', int(self.stamp_ns))


def paired_frames(
    stamps: np.ndarray,
    stamps_ns: np.ndarray | list[int],
    poses: list[np.ndarray | None],
    depth_stamps: np.ndarray,
    depth_match: np.ndarray,
) -> list[Frame]:
    """The frames of colour images at ``stamps`` (seconds; exact ``stamps_ns``) with their
    ``poses`` and the depth map ``depth_match[i]`` of ``depth_stamps`` (-1: none)."""
    return [
        Frame(
            i,
            float(s),
            poses[i],
            float(depth_stamps[depth_match[i]]) if depth_match[i] >= 0 else None,
            stamp_ns=stamps_ns[i],
        )
        for i, s in enumerate(stamps)
    ]


class Sequence:
    """Base class: frames, intrinsics and lazy image access.

    Subclasses implement :meth:`_load_native` (the image as stored) or :meth:`_load_image`
    (BGR uint8), and :meth:`_load_depth` (metres).
    """

    def __init__(
        self, name: str, intrinsics: Intrinsics, frames: list[Frame], path: Path | None = None
    ) -> None:
        self.name = name
        self.intrinsics = intrinsics
        self.frames = frames
        self.path = path

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[Frame]:
        return iter(self.frames)

    def __repr__(self) -> str:
        return (
            f'{type(self).__name__}({self.name!r}, {len(self)} frames, '
            f'{self.intrinsics.width}x{self.intrinsics.height})'
        )

    @property
    def stamps(self) -> np.ndarray:
        """(N,) float64 colour image times, seconds."""
        return np.array([f.stamp for f in self.frames], dtype=np.float64)

    @property
    def stamps_ns(self) -> np.ndarray:
        """(N,) int64 colour image times, exact integer nanoseconds (``Frame.stamp_ns``)."""
        return np.array([f.stamp_ns for f in self.frames], dtype=np.int64)

    @property
    def has_depth(self) -> bool:
        """True when at least one frame has a depth map."""
        return any(f.depth_stamp is not None for f in self.frames)

    @property
    def has_pose(self) -> np.ndarray:
        """(N,) bool, True where the frame has a ground-truth pose."""
        return np.array([f.pose is not None for f in self.frames], dtype=bool)

    def poses(self) -> np.ndarray:
        """(N, 4, 4) float64 camera-to-world poses, NaN where unknown."""
        out = np.full((len(self), 4, 4), np.nan)
        for f in self.frames:
            if f.pose is not None:
                out[f.index] = f.pose
        return out

    def _check_index(self, i: int) -> int:
        if not -len(self) <= i < len(self):
            raise IndexError(f'frame {i} out of range for {len(self)} frames')
        return i % len(self)

    def image(self, i: int) -> np.ndarray:
        """Colour frame ``i`` as (H, W, 3) uint8 BGR.

        Raises:
            DatasetError: the frame is not of the intrinsics' size (:meth:`_check_size`).
        """
        i = self._check_index(i)
        return self._check_size(self._load_image(i), i, 'image')

    def gray(self, i: int) -> np.ndarray:
        """Frame ``i`` as (H, W) uint8 grey."""
        native = self.native_image(i)
        if native.ndim == 2 and native.dtype == np.uint8:
            return native
        return cv2.cvtColor(bgr_from_any(native), cv2.COLOR_BGR2GRAY)

    def native_image(self, i: int) -> np.ndarray:
        """Frame ``i`` as stored: (H, W) grey or (H, W, 3) BGR, uint8 or uint16 (16-bit PNGs,
        mono16 messages). Readers of grey or 16-bit data override :meth:`_load_native`."""
        i = self._check_index(i)
        return self._check_size(self._load_native(i), i, 'image')

    def depth(self, i: int) -> np.ndarray | None:
        """Depth of frame ``i`` as (H, W) float32 metres (0 = no data), or None if absent.

        Raises:
            DatasetError: the depth map is not of the images' size (registered depth is).
        """
        i = self._check_index(i)
        if self.frames[i].depth_stamp is None:
            return None
        depth = self._load_depth(i)
        return None if depth is None else self._check_size(depth, i, 'depth map')

    def _check_size(self, pixels: np.ndarray, i: int, what: str) -> np.ndarray:
        """``pixels`` when they are of the intrinsics' size; else a DatasetError: tracks and
        labels on another size would be measured with the wrong K (or depth read at the
        wrong pixels) without a word."""
        h, w = pixels.shape[:2]
        width, height = self.intrinsics.width, self.intrinsics.height
        if (w, h) != (width, height):
            raise DatasetError(
                f'{self.name}: frame {i}: the {what} is {w}x{h} but the intrinsics are for '
                f'{width}x{height}; give the intrinsics of these images (or a depth map '
                'registered to them)'
            )
        return pixels

    def _load_image(self, i: int) -> np.ndarray:
        return bgr_from_any(self._load_native(i))

    def _load_native(self, i: int) -> np.ndarray:
        return self._load_image(i)

    def _load_depth(self, i: int) -> np.ndarray | None:
        raise NotImplementedError


def read_image_file(path: Path, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """``cv2.imread`` that raises DatasetError naming the file when it is missing or corrupt."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f'{path}: image file not found')
    try:
        img = cv2.imread(str(path), flags)
    except cv2.error as exc:
        raise DatasetError(f'{path}: cannot decode image: {exc}') from exc
    if img is None or img.size == 0:
        raise DatasetError(f'{path}: unreadable, empty or corrupt image file')
    return img


def without_alpha(img: np.ndarray) -> np.ndarray:
    """BGRA -> BGR (any depth); grey and BGR images unchanged."""
    if img.ndim == 3 and img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[..., 0]
    return img


#: :func:`initsel_ros.image.to_bgr` under its former name.
bgr_from_any = to_bgr


__all__ = [
    'Frame',
    'Sequence',
    'bgr_from_any',
    'paired_frames',
    'read_image_file',
    'without_alpha',
]
