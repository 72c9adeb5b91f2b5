"""EuRoC MAV sequences in the ASL folder layout (``mav0/``), and a writer for tests.

Layout read (the folder holding ``mav0``, or ``mav0`` itself)::

    mav0/cam0/data/<t_ns>.png                 8-bit grey (16-bit and colour also accepted)
    mav0/cam0/data.csv                        #timestamp [ns],filename
    mav0/cam0/sensor.yaml                     T_BS, resolution, rate_hz, camera_model pinhole,
                                              intrinsics [fu, fv, cu, cv],
                                              distortion_model radial-tangential
                                              ([k1, k2, p1, p2]) or equidistant
                                              (fisheye, [k1, k2, k3, k4]),
                                              distortion_coefficients
    mav0/state_groundtruth_estimate0/data.csv #timestamp [ns], p_RS_R x y z [m],
                                              q_RS w x y z [], (velocity and biases ignored)

The ground truth gives body (IMU) poses ``T_WB``; ``T_BS`` in ``sensor.yaml`` is the camera
(sensor) pose in the body frame, so the camera-to-world pose is ``T_WC = T_WB @ T_BS``. Body
poses are interpolated to the image times (linear position, slerp rotation) before ``T_BS``
is applied. Frame stamps are the exact nanoseconds of ``data.csv``. There is no depth.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets.poses import DEFAULT_MAX_GAP, check_trajectory, interpolate_poses
from initsel_ros.datasets.sequence import Frame, Sequence, read_image_file, without_alpha
from initsel_ros.datasets.tum import content_lines, one_file_per_stamp
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.timestamps import ns_to_seconds
from initsel_ros.transforms import matrix_to_pose, pose_matrix

_LOG = logging.getLogger(__name__)

GROUNDTRUTH_DIR = 'state_groundtruth_estimate0'
#: Kalibr's names of OpenCV's standard model (the first is written) and of the fisheye one.
RADTAN_NAMES = ('radial-tangential', 'radtan', 'plumb_bob')
EQUIDISTANT = 'equidistant'
IMAGE_LISTING_FORMAT = '#timestamp [ns],filename'
GROUNDTRUTH_FORMAT = (
    '#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], '
    'q_RS_x [], q_RS_y [], q_RS_z []'
)


def euroc_root(path: Path) -> Path | None:
    """The ``mav0`` folder of ``path`` (the folder holding mav0, or mav0 itself), or None."""
    path = Path(path)
    for candidate in (path / 'mav0', path):
        if (candidate / 'cam0' / 'data.csv').is_file():
            return candidate
    return None


def is_euroc_folder(path: Path) -> bool:
    """True for a folder holding ``mav0/cam0/data.csv`` or for such a ``mav0`` folder."""
    return Path(path).is_dir() and euroc_root(path) is not None


def _csv_rows(path: Path, min_columns: int, expected: str) -> list[tuple[int, list[str]]]:
    """(line number, fields) of a EuRoC csv; '#' lines are comments."""
    rows = []
    for number, stripped in content_lines(path):
        fields = [f.strip() for f in stripped.split(',')]
        if len(fields) < min_columns:
            raise DatasetError(
                f'{path}:{number}: expected at least {min_columns} columns '
                f'`{expected}`, got {len(fields)}'
            )
        rows.append((number, fields))
    return rows


def _int_ns(path: Path, number: int, text: str) -> int:
    try:
        return int(text)
    except ValueError as exc:
        raise DatasetError(
            f'{path}:{number}: {text!r} is not an integer timestamp in nanoseconds'
        ) from exc


def read_image_listing(path: Path) -> tuple[list[int], list[str]]:
    """``cam0/data.csv`` -> (stamps in integer ns, file names), sorted by time."""
    path = Path(path)
    rows = [
        (n, _int_ns(path, n, f[0]), f[0], f[1])
        for n, f in _csv_rows(path, 2, IMAGE_LISTING_FORMAT)
    ]
    rows.sort(key=lambda r: r[1])
    return one_file_per_stamp(path, rows)


def read_groundtruth(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``state_groundtruth_estimate0/data.csv`` -> (stamps (N,) int64 ns, positions (N, 3) m,
    quaternions (N, 4) xyzw), sorted by time."""
    path = Path(path)
    stamps, values = [], []
    for number, fields in _csv_rows(path, 8, GROUNDTRUTH_FORMAT):
        stamps.append(_int_ns(path, number, fields[0]))
        try:
            row = [float(v) for v in fields[1:8]]
        except ValueError as exc:
            raise DatasetError(
                f'{path}:{number}: not a number ({exc}); expected `{GROUNDTRUTH_FORMAT}`'
            ) from exc
        if not all(math.isfinite(v) for v in row) or math.hypot(*row[3:7]) < 1e-9:
            raise DatasetError(f'{path}:{number}: non-finite value or zero quaternion')
        values.append(row)
    data = np.asarray(values, dtype=np.float64).reshape(-1, 7)
    quats_xyzw = data[:, [4, 5, 6, 3]]
    return check_trajectory(
        np.asarray(stamps, dtype=np.int64), data[:, 0:3], quats_xyzw, str(path), 'w x y z'
    )


def _matrix(node: Any, source: Path, key: str) -> np.ndarray:
    """A ``{rows, cols, data}`` mapping (EuRoC / OpenCV style) as a float64 matrix."""
    try:
        rows, cols = int(node['rows']), int(node['cols'])
        out = np.asarray(node['data'], dtype=np.float64).reshape(rows, cols)
    except (KeyError, TypeError, ValueError) as exc:
        raise DatasetError(f'{source}: {key} must be {{rows, cols, data}}: {exc}') from exc
    if not np.all(np.isfinite(out)):
        raise DatasetError(f'{source}: {key} has non-finite values')
    return out


#: Keys of the distortion coefficients in a camera's yaml: EuRoC's, then Kalibr's.
DISTORTION_KEYS = ('distortion_coefficients', 'distortion_coeffs')


def _distortion_coefficients(data: dict, path: Path) -> list:
    """The coefficients under EuRoC's or Kalibr's key ([] when neither is there)."""
    present = [key for key in DISTORTION_KEYS if data.get(key) is not None]
    if len(present) > 1 and list(data[present[0]]) != list(data[present[1]]):
        raise DatasetError(f'{path}: {present[0]} and {present[1]} differ; keep one')
    return list(data[present[0]]) if present else []


def read_sensor_yaml(path: Path) -> tuple[Intrinsics, np.ndarray, float | None]:
    """``cam0/sensor.yaml`` -> (intrinsics with radial-tangential or equidistant (fisheye)
    distortion, T_BS (4, 4), rate in Hz or None).

    Raises:
        DatasetError: missing keys, a camera model other than pinhole, or a distortion model
            other than radial-tangential and equidistant (Kalibr's names).
    """
    import yaml

    path = Path(path)
    try:
        text = path.read_text(encoding='utf-8-sig')
        # Some ASL tools write OpenCV's '%YAML:1.0' directive, which PyYAML rejects.
        lines = [ln for ln in text.splitlines() if not ln.startswith('%YAML')]
        data = yaml.safe_load('\n'.join(lines))
    except FileNotFoundError as exc:
        raise DatasetError(f'{path}: file not found') from exc
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise DatasetError(f'{path}: cannot read camera calibration: {exc}') from exc
    if not isinstance(data, dict):
        raise DatasetError(f'{path}: expected a mapping (EuRoC sensor.yaml)')
    model = str(data.get('camera_model', 'pinhole'))
    if model != 'pinhole':
        raise DatasetError(f'{path}: camera_model {model!r} is not supported (pinhole only)')
    distortion_model = str(data.get('distortion_model', 'radial-tangential'))
    if distortion_model not in (*RADTAN_NAMES, EQUIDISTANT, 'none'):
        raise DatasetError(
            f'{path}: distortion_model {distortion_model!r} is not supported '
            f'(radial-tangential or {EQUIDISTANT})'
        )
    try:
        fu, fv, cu, cv = (float(v) for v in data['intrinsics'])
        width, height = (int(v) for v in data['resolution'])
        coeffs = tuple(float(v) for v in _distortion_coefficients(data, path))
    except (KeyError, TypeError, ValueError) as exc:
        raise DatasetError(
            f'{path}: needs intrinsics [fu, fv, cu, cv] and resolution [width, height]: {exc}'
        ) from exc
    fisheye = distortion_model == EQUIDISTANT
    if distortion_model == 'none':
        coeffs = ()
    if 'distortion_model' in data and distortion_model != 'none' and not coeffs:
        raise DatasetError(
            f'{path}: distortion_model {distortion_model!r} without its coefficients '
            f'({" or ".join(DISTORTION_KEYS)}); write distortion_model: none for a lens '
            'without distortion'
        )
    if len(coeffs) not in ((4,) if fisheye else (0, 4, 5)):
        kind = 'equidistant distortion needs 4 coefficients k1 k2 k3 k4'
        if not fisheye:
            kind = 'radial-tangential distortion needs 4 coefficients k1 k2 p1 p2'
        raise DatasetError(f'{path}: {kind}, got {len(coeffs)}')
    if not fisheye and not any(c != 0.0 for c in coeffs):
        coeffs = ()
    try:
        intrinsics = Intrinsics(fu, fv, cu, cv, width, height, coeffs, fisheye)
    except ConfigError as exc:
        raise DatasetError(f'{path}: {exc}') from exc
    if 'T_BS' in data:
        T_BS = _matrix(data['T_BS'], path, 'T_BS')
        if T_BS.shape != (4, 4):
            raise DatasetError(f'{path}: T_BS must be 4x4, got {T_BS.shape}')
        R = T_BS[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
            raise DatasetError(f'{path}: T_BS rotation is not a rotation matrix')
    else:
        _LOG.warning('%s: no T_BS; the camera is taken to be at the body frame', path)
        T_BS = np.eye(4)
    rate = data.get('rate_hz')
    return intrinsics, T_BS, float(rate) if rate is not None else None


class EurocSequence(Sequence):
    """A EuRoC MAV sequence (ASL layout), loaded lazily.

    Args:
        path: the folder holding ``mav0``, or ``mav0`` itself.
        camera: which camera folder, ``cam0`` (default) or ``cam1``.
        max_gap: largest gap (s) between ground-truth samples to interpolate across.
        nearest_tolerance: frames outside the ground truth take the nearest sample within this
            many seconds (0: no pose).
        ground_truth: False leaves every frame without a pose and the ground truth unread.

    Attributes:
        T_BS: (4, 4) camera pose in the body frame, from ``sensor.yaml``.
        rate_hz: the camera rate from ``sensor.yaml`` (None when absent).
    """

    def __init__(
        self,
        path: Path | str,
        *,
        camera: str = 'cam0',
        max_gap: float = DEFAULT_MAX_GAP,
        nearest_tolerance: float = 0.0,
        ground_truth: bool = True,
    ) -> None:
        path = Path(path)
        root = euroc_root(path)
        if root is None:
            raise DatasetError(f'{path}: not a EuRoC folder (no mav0/cam0/data.csv)')
        cam_dir = root / camera
        if not (cam_dir / 'data.csv').is_file():
            cameras = sorted(d.name for d in root.glob('cam*') if (d / 'data.csv').is_file())
            raise DatasetError(f'{root}: no camera {camera} (cameras: {", ".join(cameras)})')
        intrinsics, self.T_BS, self.rate_hz = read_sensor_yaml(cam_dir / 'sensor.yaml')
        stamps_ns, names = read_image_listing(cam_dir / 'data.csv')
        if not stamps_ns:
            raise DatasetError(f'{cam_dir / "data.csv"}: no frames listed')
        t0 = stamps_ns[0]
        rel = np.array([(t - t0) * 1e-9 for t in stamps_ns])  # precise relative seconds
        poses: list[np.ndarray | None] = [None] * len(stamps_ns)
        gt_path = root / GROUNDTRUTH_DIR / 'data.csv'
        if not ground_truth:
            _LOG.debug('%s: ground truth not read (not asked for)', root)
        elif gt_path.is_file():
            gt_ns, positions, quats = read_groundtruth(gt_path)
            gt_rel = (gt_ns - t0).astype(np.float64) * 1e-9
            t, q = interpolate_poses(rel, gt_rel, positions, quats, max_gap, nearest_tolerance)
            valid = ~np.isnan(t[:, 0])
            if np.any(valid):
                T_WC = pose_matrix(t[valid], q[valid]) @ self.T_BS
                for k, i in enumerate(np.flatnonzero(valid)):
                    poses[i] = T_WC[k]
            missing = int(np.sum(~valid))
            if missing:
                _LOG.warning(
                    '%s: %d of %d frames have no ground-truth pose (outside %s or in '
                    'a gap over %.3f s)',
                    root,
                    missing,
                    len(poses),
                    GROUNDTRUTH_DIR,
                    max_gap,
                )
        else:
            _LOG.info('%s: no %s/data.csv; frames have no poses', root, GROUNDTRUTH_DIR)
        frames = [
            Frame(i, ns_to_seconds(ns), poses[i], None, stamp_ns=ns)
            for i, ns in enumerate(stamps_ns)
        ]
        named = Path(os.path.abspath(root))  # ('.' names nothing)
        name = named.parent.name if named.name == 'mav0' else named.name
        super().__init__(name or 'euroc', intrinsics, frames, root)
        self.image_files = [cam_dir / 'data' / n for n in names]

    def _load_native(self, i: int) -> np.ndarray:
        return without_alpha(read_image_file(self.image_files[i], cv2.IMREAD_UNCHANGED))

    def _load_depth(self, i: int) -> np.ndarray | None:
        return None


def _sensor_yaml(intrinsics: Intrinsics, T_BS: np.ndarray, rate_hz: float) -> str:
    coeffs = list(intrinsics.distortion[:4]) + [0.0] * max(0, 4 - len(intrinsics.distortion))
    if len(intrinsics.distortion) > 4 and any(intrinsics.distortion[4:]):
        raise ConfigError('EuRoC radial-tangential distortion holds k1 k2 p1 p2 only')
    distortion_model = EQUIDISTANT if intrinsics.fisheye else RADTAN_NAMES[0]
    data = ', '.join(repr(float(v)) for v in np.asarray(T_BS, dtype=np.float64).reshape(-1))
    return (
        '# General sensor definitions.\n'
        'sensor_type: camera\n'
        'comment: written by initsel_ros.datasets.euroc.write_euroc\n\n'
        '# Sensor extrinsics wrt. the body-frame.\n'
        f'T_BS:\n  cols: 4\n  rows: 4\n  data: [{data}]\n\n'
        '# Camera specific definitions.\n'
        f'rate_hz: {rate_hz:g}\n'
        f'resolution: [{intrinsics.width}, {intrinsics.height}]\n'
        'camera_model: pinhole\n'
        f'intrinsics: [{intrinsics.fx!r}, {intrinsics.fy!r}, {intrinsics.cx!r}, '
        f'{intrinsics.cy!r}] #fu, fv, cu, cv\n'
        f'distortion_model: {distortion_model}\n'
        f'distortion_coefficients: [{", ".join(repr(float(c)) for c in coeffs)}]\n'
    )


def write_euroc(
    sequence: Sequence,
    out: Path | str,
    *,
    T_BS: np.ndarray | None = None,
    groundtruth_ns: np.ndarray | None = None,
    rate_hz: float = 30.0,
) -> Path:
    """Write ``sequence`` in the EuRoC ASL layout (grey PNGs; for tests and conversions).

    Args:
        sequence: frames with camera-to-world poses.
        out: the folder to hold ``mav0`` (created).
        T_BS: camera pose in the body frame (default identity); the body poses written are
            ``T_WB = T_WC @ inv(T_BS)``.
        groundtruth_ns: times (int ns) of the ground-truth samples; default the frame times.
            Other times are interpolated from the frames' poses (slerp).
        rate_hz: written to ``sensor.yaml``.

    Returns:
        The ``mav0`` folder.
    """
    root = Path(out) / 'mav0'
    data_dir = root / 'cam0' / 'data'
    data_dir.mkdir(parents=True, exist_ok=True)
    T_BS = np.eye(4) if T_BS is None else np.asarray(T_BS, dtype=np.float64)
    lines = [IMAGE_LISTING_FORMAT]
    for f in sequence.frames:
        name = f'{f.stamp_ns}.png'
        native = sequence.native_image(f.index)
        grey = native if native.ndim == 2 else cv2.cvtColor(native, cv2.COLOR_BGR2GRAY)
        if not cv2.imwrite(str(data_dir / name), grey):
            raise DatasetError(f'{data_dir / name}: cannot write image')
        lines.append(f'{f.stamp_ns},{name}')
    (root / 'cam0' / 'data.csv').write_text('\n'.join(lines) + '\n')
    (root / 'cam0' / 'sensor.yaml').write_text(_sensor_yaml(sequence.intrinsics, T_BS, rate_hz))

    with_pose = [f for f in sequence.frames if f.pose is not None]
    if with_pose:
        frame_ns = np.array([f.stamp_ns for f in with_pose], dtype=np.int64)
        T_WB = np.stack([f.pose for f in with_pose]) @ np.linalg.inv(T_BS)
        p, q = matrix_to_pose(T_WB)
        gt_ns = frame_ns if groundtruth_ns is None else np.asarray(groundtruth_ns, np.int64)
        t0 = frame_ns[0]
        p, q = interpolate_poses((gt_ns - t0) * 1e-9, (frame_ns - t0) * 1e-9, p, q, max_gap=np.inf)
        keep = ~np.isnan(p[:, 0])
        rows = [
            GROUNDTRUTH_FORMAT + ', v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], '
            'v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], '
            'b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], '
            'b_a_RS_S_z [m s^-2]'
        ]
        for t_ns, pos, quat in zip(gt_ns[keep], p[keep], q[keep], strict=True):
            wxyz = (quat[3], quat[0], quat[1], quat[2])
            values = [*pos, *wxyz] + [0.0] * 9
            rows.append(f'{int(t_ns)},' + ','.join(repr(float(v)) for v in values))
        (root / GROUNDTRUTH_DIR).mkdir(exist_ok=True)
        (root / GROUNDTRUTH_DIR / 'data.csv').write_text('\n'.join(rows) + '\n')
    return root


__all__ = [
    'EurocSequence',
    'euroc_root',
    'is_euroc_folder',
    'read_groundtruth',
    'read_image_listing',
    'read_sensor_yaml',
    'write_euroc',
]
