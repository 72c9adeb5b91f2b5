"""Sequences with ground truth: TUM, EuRoC and KITTI folders, ROS 1 and ROS 2 bags, poses.

``open_sequence(path)`` picks the reader: a folder with ``rgb.txt`` is a TUM folder, one with
``mav0/cam0/data.csv`` (or such a ``mav0``) a EuRoC MAV sequence, one with ``times.txt``,
``calib.txt`` and ``image_0/`` a KITTI odometry sequence (or a KITTI root with ``sequences/NN``,
given ``sequence='NN'``), a ``.bag`` file a ROS 1 bag, a folder with ``metadata.yaml`` (or a
``.db3``/``.mcap`` file) a ROS 2 bag.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets.euroc import EurocSequence, is_euroc_folder
from initsel_ros.datasets.kitti import (
    KittiSequence,
    is_kitti_root,
    is_kitti_sequence,
    missing_kitti_parts,
)
from initsel_ros.datasets.poses import interpolate_poses, pose_matrices
from initsel_ros.datasets.sequence import Frame, Sequence
from initsel_ros.datasets.tum import TumSequence, is_tum_folder, read_trajectory
from initsel_ros.errors import ConfigError, DatasetError

#: The layouts :func:`open_sequence` reads, as named in its error messages and ``--help``.
LAYOUTS = ('TUM folder', 'EuRoC ASL folder', 'KITTI odometry sequence', 'ROS 1 bag', 'ROS 2 bag')


def is_bag(path: Path) -> bool:
    """True for a ROS 1 ``.bag`` file or a ROS 2 bag (folder with metadata.yaml, .db3, .mcap)."""
    path = Path(path)
    if path.is_file():
        return path.suffix in {'.bag', '.db3', '.mcap'}
    return path.is_dir() and (path / 'metadata.yaml').is_file()


def sequence_kind(path: Path | str) -> str | None:
    """'tum', 'euroc', 'kitti', 'kitti_root' or 'bag' for a path :func:`open_sequence` reads,
    else None."""
    path = Path(path)
    if is_tum_folder(path):
        return 'tum'
    if is_euroc_folder(path):
        return 'euroc'
    if is_kitti_sequence(path):
        return 'kitti'
    if is_kitti_root(path):
        return 'kitti_root'
    if is_bag(path):
        return 'bag'
    return None


def reader_options(
    path: Path | str,
    *,
    nearest_tolerance: float | None = None,
    image_topic: str | None = None,
    intrinsics: Intrinsics | None = None,
    camera: str | None = None,
    sequence: str | None = None,
) -> dict[str, Any]:
    """The :func:`open_sequence` options a tool's settings give the reader of ``path``:
    ``nearest_tolerance`` for TUM, EuRoC and bags, ``image_topic`` for bags, ``sequence`` for
    KITTI, ``intrinsics`` and ``camera`` as given (:func:`open_sequence` refuses them where
    they do not apply); unset ones left out."""
    kind = sequence_kind(Path(path))
    options: dict[str, Any] = {}
    if sequence is not None and kind in ('kitti', 'kitti_root'):
        options['sequence'] = sequence
    if camera is not None:
        options['camera'] = camera
    if nearest_tolerance is not None and kind in ('tum', 'euroc', 'bag'):
        options['nearest_tolerance'] = nearest_tolerance
    if image_topic is not None and kind == 'bag':
        options['image_topic'] = image_topic
    if intrinsics is not None:
        options['intrinsics'] = intrinsics
    return options


def open_sequence(
    path: Path | str, sequence: str | None = None, camera: str | None = None, **options: Any
) -> Sequence:
    """Open a TUM, EuRoC or KITTI folder or a bag as a :class:`Sequence`.

    Args:
        path: TUM folder, EuRoC folder (holding ``mav0``, or ``mav0`` itself), KITTI
            ``sequences/NN`` folder or KITTI root, ROS 1 ``.bag`` file or ROS 2 bag.
        sequence: the KITTI sequence ('NN') when ``path`` is a KITTI root.
        camera: which camera of a multi-camera folder: EuRoC ``cam0``/``cam1`` (or ``0``,
            ``1``), KITTI ``0``-``3`` (or ``image_2``...); None for the reader's default.
        **options: passed to the reader (:class:`TumSequence`, :class:`EurocSequence`,
            :class:`KittiSequence`, ``bags.BagSequence``); e.g. ``nearest_tolerance``,
            ``max_gap``; for bags ``image_topic``, ``depth_topic``, ``info_topic``,
            ``pose_topic``, ``tf_parent``, ``tf_child``, ``groundtruth``; for TUM folders and
            bags ``intrinsics`` (an :class:`Intrinsics` that replaces ``intrinsics.yaml`` or
            CameraInfo, and the TUM fr3 default without them).

    Raises:
        DatasetError: the path does not exist or is none of these, or ``sequence`` or
            ``intrinsics`` was given for a layout they do not apply to.
    """
    path = Path(path)
    if not path.exists():
        raise DatasetError(f'{path}: no such file or directory')
    kind = sequence_kind(path)
    if kind is None and sequence is not None and (path / 'sequences').is_dir():
        kind = 'kitti_root'  # whose sequences are all broken: the reader says how
    if sequence is not None and kind not in ('kitti', 'kitti_root'):
        raise DatasetError(f'{path}: --sequence {sequence} applies to KITTI odometry only')
    if camera is not None:
        options['camera'] = _camera_option(path, kind, str(camera))
    if options.get('intrinsics') is not None and kind not in ('tum', 'bag'):
        raise DatasetError(
            f'{path}: --intrinsics applies to TUM folders and bags; EuRoC and KITTI folders '
            'carry their own calibration (sensor.yaml, calib.txt)'
        )
    if kind == 'tum':
        return TumSequence(path, **options)
    if kind == 'euroc':
        return EurocSequence(path, **options)
    if kind in ('kitti', 'kitti_root'):
        return KittiSequence(path, sequence=sequence, **options)
    if kind == 'bag':
        from initsel_ros.datasets.bags import BagSequence

        return BagSequence(path, **options)
    hint = layout_hint(path)
    raise DatasetError(
        f'{path}: not a TUM folder (no rgb.txt), EuRoC folder (no mav0/cam0/data.csv), KITTI '
        'odometry sequence (no times.txt, calib.txt, image_0/) nor a bag (.bag file, or '
        'folder with metadata.yaml)' + (f'; {hint}' if hint else '')
    )


def open_source(
    source: Path | str,
    *,
    sequence: str | None = None,
    camera: str | None = None,
    bag_image_topic: str | None = None,
    intrinsics: Path | str | None = None,
    ground_truth: bool = True,
) -> Sequence:
    """A tool's source by its command-line options (``initsel replay``, ``initsel trace``):
    :func:`open_sequence` with the KITTI ``sequence``, the EuRoC or KITTI ``camera``, a bag's
    ``bag_image_topic`` and an ``intrinsics`` YAML file (as ``intrinsics.yaml``) replacing a
    TUM folder's or a bag's calibration; ``ground_truth`` False leaves the ground truth unread
    (a malformed one then does not keep the frames from being read).

    Raises:
        ConfigError: ``bag_image_topic`` for a source that is not a bag, an unreadable
            ``intrinsics`` file.
        DatasetError: as :func:`open_sequence`.
    """
    reader: dict[str, Any] = {'ground_truth': ground_truth}
    if bag_image_topic is not None:
        if sequence_kind(Path(source)) != 'bag':
            raise ConfigError('--bag-image-topic applies to bags only')
        reader['image_topic'] = bag_image_topic
    if intrinsics is not None:
        reader['intrinsics'] = Intrinsics.load_yaml(intrinsics)
    return open_sequence(source, sequence=sequence, camera=camera, **reader)


def _camera_option(path: Path, kind: str | None, camera: str) -> str | int:
    """The reader's ``camera`` argument for ``--camera``: EuRoC ``camN``, KITTI ``N``."""
    if kind == 'euroc':
        return camera if camera.startswith('cam') else f'cam{camera}'
    if kind in ('kitti', 'kitti_root'):
        number = camera.removeprefix('image_')
        if number not in ('0', '1', '2', '3'):
            raise DatasetError(
                f'{path}: a KITTI camera is 0-3 (image_0 ... image_3), got {camera!r}'
            )
        return int(number)
    raise DatasetError(
        f'{path}: --camera {camera} applies to EuRoC and KITTI folders (a TUM folder holds '
        'one camera; a bag is read by its image topic)'
    )


def layout_hint(path: Path) -> str:
    """What a path that no reader opens is probably meant to be ('' when nothing fits): a
    folder inside a sequence, a folder of sequences, or a sequence missing a part."""
    path = Path(os.path.abspath(path))
    if not path.is_dir():
        return ''
    try:
        inside = sorted(p.name for p in path.iterdir() if p.is_dir() and sequence_kind(p))
    except OSError:  # (unreadable: the error itself says enough)
        return ''
    if inside:
        shown = ', '.join(inside[:5]) + (', ...' if len(inside) > 5 else '')
        return f'it holds sequences ({shown}): give one of them'
    for parent in list(path.parents)[:3]:  # cam0/, mav0/cam0/data, image_0/ and the like
        if sequence_kind(parent) not in (None, 'kitti_root'):
            return f'it is inside the sequence {parent}: give that folder'
    if (path / 'mav0').is_dir() or path.name == 'mav0':
        return 'a EuRoC folder needs mav0/cam0/data.csv and mav0/cam0/data/'
    if any((path / name).exists() for name in ('times.txt', 'calib.txt', 'image_0', 'image_2')):
        return f'a KITTI sequence, but no {", ".join(missing_kitti_parts(path))}'
    if (path / 'sequences').is_dir():  # a KITTI root whose sequences all lack a part
        broken = [
            f'{p.name}: no {", ".join(missing_kitti_parts(p))}'
            for p in sorted((path / 'sequences').iterdir())
            if p.is_dir() and missing_kitti_parts(p)
        ]
        if broken:
            return (
                'a KITTI root, but ' + '; '.join(broken[:3]) + ('; ...' if len(broken) > 3 else '')
            )
    return ''


__all__ = [
    'LAYOUTS',
    'DatasetError',
    'EurocSequence',
    'Frame',
    'KittiSequence',
    'Sequence',
    'TumSequence',
    'interpolate_poses',
    'is_bag',
    'is_euroc_folder',
    'is_kitti_root',
    'is_kitti_sequence',
    'is_tum_folder',
    'layout_hint',
    'open_sequence',
    'open_source',
    'pose_matrices',
    'read_trajectory',
    'reader_options',
    'sequence_kind',
]
