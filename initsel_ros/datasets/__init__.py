"""Sequences with ground truth: TUM folders, ROS 1 and ROS 2 bags, pose utilities.

``open_sequence(path)`` picks the reader: a folder with ``rgb.txt`` is a TUM folder, a ``.bag``
file a ROS 1 bag, a folder with ``metadata.yaml`` (or a ``.db3``/``.mcap`` file) a ROS 2 bag.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from initsel_ros.datasets.poses import (
    interpolate_pose_matrices,
    interpolate_poses,
    matrix_to_pose,
    matrix_to_quaternion,
    pose_matrix,
    quaternion_to_matrix,
)
from initsel_ros.datasets.sequence import Frame, Sequence
from initsel_ros.datasets.tum import TumSequence, is_tum_folder, read_trajectory
from initsel_ros.errors import DatasetError


def is_bag(path: Path) -> bool:
    """True for a ROS 1 ``.bag`` file or a ROS 2 bag (folder with metadata.yaml, .db3, .mcap)."""
    path = Path(path)
    if path.is_file():
        return path.suffix in {'.bag', '.db3', '.mcap'}
    return path.is_dir() and (path / 'metadata.yaml').is_file()


def open_sequence(path: Path | str, **options: Any) -> Sequence:
    """Open a TUM folder or a bag as a :class:`Sequence`.

    Args:
        path: TUM folder, ROS 1 ``.bag`` file or ROS 2 bag folder/file.
        **options: passed to :class:`TumSequence` or ``bags.BagSequence``
            (e.g. ``nearest_tolerance``, ``max_gap``; for bags ``image_topic``, ``depth_topic``,
            ``info_topic``, ``pose_topic``, ``tf_parent``, ``tf_child``, ``groundtruth``).

    Raises:
        DatasetError: the path does not exist or is neither kind.
    """
    path = Path(path)
    if not path.exists():
        raise DatasetError(f'{path}: no such file or directory')
    if is_tum_folder(path):
        return TumSequence(path, **options)
    if is_bag(path):
        from initsel_ros.datasets.bags import BagSequence

        return BagSequence(path, **options)
    raise DatasetError(
        f'{path}: not a TUM folder (no rgb.txt) nor a bag (.bag file, or folder with '
        'metadata.yaml)'
    )


__all__ = [
    'DatasetError',
    'Frame',
    'Sequence',
    'TumSequence',
    'interpolate_pose_matrices',
    'interpolate_poses',
    'is_bag',
    'is_tum_folder',
    'matrix_to_pose',
    'matrix_to_quaternion',
    'open_sequence',
    'pose_matrix',
    'quaternion_to_matrix',
    'read_trajectory',
]
