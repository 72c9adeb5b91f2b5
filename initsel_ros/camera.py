"""Pinhole camera intrinsics (with optional distortion) and their file form.

Two lens models, named as ROS's ``sensor_msgs/CameraInfo`` names them:

* ``plumb_bob`` / ``rational_polynomial``: OpenCV's standard model (k1 k2 p1 p2 [k3 ...]);
* ``equidistant``: the fisheye (Kannala-Brandt) model of ``cv2.fisheye``, k1 k2 k3 k4.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.errors import ConfigError

#: Plausible focal lengths, as multiples of the image diagonal (fields of view of about
#: 0.6 to 179 degrees).
MIN_FOCAL_PER_DIAGONAL = 0.005
MAX_FOCAL_PER_DIAGONAL = 100.0

#: TUM RGB-D freiburg3 colour camera (no distortion), 640x480.
TUM_FR3 = {'fx': 535.4, 'fy': 539.2, 'cx': 320.1, 'cy': 247.6, 'width': 640, 'height': 480}
#: Numbers of distortion coefficients OpenCV accepts (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4
#: [tx ty]]]]); 0 = none. Any other length makes ``cv2.undistortPoints`` fail on every frame.
DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)
#: The fisheye (equidistant) model's coefficients: k1 k2 k3 k4.
FISHEYE_LENGTH = 4
#: ``CameraInfo.distortion_model`` names of the standard model and of the fisheye one.
STANDARD_MODELS = ('plumb_bob', 'rational_polynomial')
FISHEYE_MODEL = 'equidistant'
#: Past this angle off the optical axis a track's undistorted (pinhole) pixel lies more than
#: 5.7 focal lengths from the centre, and at 90 degrees at infinity: tracks there carry little
#: geometry and, beyond 90 degrees, none (a fisheye's undistortion returns nonsense).
MAX_FIELD_ANGLE_DEG = 80.0
#: Undistorted, the image's border must span at least this share of its width and height.
#: Barrel distortion spreads it, pincushion shrinks it by tens of per cent; a calibration
#: that folds it much further is a wrong one.
MIN_UNDISTORTED_SPAN = 0.25
#: A camera without distortion coefficients whose pinhole K gives more than this horizontal
#: field of view is probably a wide lens whose distortion was not calibrated: few lenses this
#: wide are pinholes, and an uncorrected one bends a pan's flow so that it passes for motion
#: (a probe's 118-degree lens without its D initialized on a pure pan and published an orbit
#: with its translation reversed).
WIDE_PINHOLE_FOV_DEG = 100.0


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels, image size in pixels, OpenCV distortion coefficients.

    ``fisheye``: ``distortion`` holds the k1 k2 k3 k4 of the equidistant (Kannala-Brandt)
    model (``cv2.fisheye``; ROS ``equidistant``) instead of OpenCV's standard model.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    distortion: tuple[float, ...] = field(default=())
    fisheye: bool = False

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy, *self.distortion)
        if not all(math.isfinite(v) for v in values):
            raise ConfigError(f'intrinsics must be finite, got {self}')
        if self.fx <= 0 or self.fy <= 0:
            raise ConfigError(f'focal lengths must be positive, got fx={self.fx} fy={self.fy}')
        if self.width <= 0 or self.height <= 0:
            raise ConfigError(f'image size must be positive, got {self.width}x{self.height}')
        check_distortion(self.distortion, self.fisheye)
        for name, c, size in (('cx', self.cx, self.width), ('cy', self.cy, self.height)):
            if not 0 <= c <= size:
                raise ConfigError(
                    f'principal point {name}={c:g} px is outside the {self.width}x{self.height} '
                    f'image (expected 0 <= {name} <= {size})'
                )
        if self.has_distortion:
            self._check_lens_span()
        diagonal = math.hypot(self.width, self.height)
        for name, f in (('fx', self.fx), ('fy', self.fy)):
            if not MIN_FOCAL_PER_DIAGONAL * diagonal <= f <= MAX_FOCAL_PER_DIAGONAL * diagonal:
                raise ConfigError(
                    f'{name}={f:g} px is implausible for a {self.width}x{self.height} image '
                    f'(expected {MIN_FOCAL_PER_DIAGONAL:g} to {MAX_FOCAL_PER_DIAGONAL:g} '
                    'times the diagonal)'
                )

    def _check_lens_span(self) -> None:
        """Raise ConfigError when the distortion folds the image onto a sliver: undistorted,
        its border must span at least :data:`MIN_UNDISTORTED_SPAN` of the image across and
        down (k1 = 1e30 maps every pixel to the principal point, and every track then reads
        as a still camera)."""
        w, h = self.width, self.height
        border = np.array(
            [[0, 0], [w / 2, 0], [w, 0], [w, h / 2], [w, h], [w / 2, h], [0, h], [0, h / 2]],
            dtype=np.float64,
        )
        ideal = self.undistort_pixels(border).astype(np.float64)
        for axis, size, name in ((0, w, 'across'), (1, h, 'down')):
            values = ideal[:, axis]
            if not np.all(np.isfinite(values)):
                continue  # beyond a fisheye's horizon: a wide lens, not a sliver
            span = float(values.max() - values.min())
            if span < MIN_UNDISTORTED_SPAN * size:
                raise ConfigError(
                    f'distortion {list(self.distortion)} folds the {w}x{h} image onto '
                    f'{span:.3g} px {name} ({span / size:.1%} of it; at least '
                    f'{MIN_UNDISTORTED_SPAN:.0%} expected): not a lens calibration'
                )

    def same_camera(self, other: Intrinsics) -> bool:
        """True when ``other`` has the same size, K and distortion (all-zero = none)."""
        return (self.fx, self.fy, self.cx, self.cy, self.width, self.height) == (
            other.fx,
            other.fy,
            other.cx,
            other.cy,
            other.width,
            other.height,
        ) and _effective(self) == _effective(other)

    @property
    def horizontal_fov_deg(self) -> float:
        """The horizontal field of view of the pinhole K across the image width, degrees."""
        left, right = math.atan(self.cx / self.fx), math.atan((self.width - self.cx) / self.fx)
        return math.degrees(left + right)

    def uncalibrated_lens_note(self) -> str:
        """Why these intrinsics are probably a wide lens without its distortion ('' when
        they are not): no distortion coefficients and a field of view over
        :data:`WIDE_PINHOLE_FOV_DEG`."""
        fov = self.horizontal_fov_deg
        if self.fisheye or any(self.distortion) or fov <= WIDE_PINHOLE_FOV_DEG:
            return ''
        return (
            f'a {fov:.0f}-degree field of view with no distortion coefficients: a lens this '
            'wide is rarely a pinhole, and its uncorrected distortion can make a rotation pass '
            'for motion; give its calibration (D, or distortion_model equidistant for a '
            'fisheye)'
        )

    @classmethod
    def tum_fr3(cls) -> Intrinsics:
        """The TUM fr3 colour camera: fx 535.4, fy 539.2, cx 320.1, cy 247.6, 640x480."""
        return cls(**TUM_FR3)

    @classmethod
    def from_matrix(
        cls,
        K: np.ndarray,
        width: int,
        height: int,
        distortion: tuple[float, ...] = (),
        fisheye: bool = False,
    ) -> Intrinsics:
        """Build from a (3, 3) camera matrix."""
        K = np.asarray(K, dtype=float).reshape(3, 3)
        return cls(
            float(K[0, 0]),
            float(K[1, 1]),
            float(K[0, 2]),
            float(K[1, 2]),
            int(width),
            int(height),
            tuple(float(d) for d in distortion),
            bool(fisheye),
        )

    @classmethod
    def from_camera_info(
        cls,
        K: np.ndarray,
        width: int,
        height: int,
        d: Sequence[float],
        distortion_model: str,
        binning: tuple[int, int] = (0, 0),
        roi: tuple[int, int, int, int] = (0, 0, 0, 0),
    ) -> Intrinsics:
        """Build from the fields of a ``sensor_msgs/CameraInfo`` (ROS 1 or 2): K, size, D and
        the distortion model's name (see :func:`lens_from_camera_info`), and its ``binning``
        (x, y) and ``roi`` (x_offset, y_offset, width, height). The one reader of a
        CameraInfo: the node's messages and the bags' both come here.

        As REP 104 defines them, K and the size are the full sensor's, the ROI is in its
        (unbinned) pixels, and the images are the ROI binned: fx / bx, (cx - x_offset) / bx,
        size roi / binning (binning 0 = 1; an all-zero ROI = the full sensor). The lens
        coefficients act on normalized coordinates, which this leaves unchanged.

        Raises:
            ConfigError: K not finite or not of the form [fx 0 cx; 0 fy cy; 0 0 1] (a skew
                would be dropped silently), bad intrinsics (:class:`Intrinsics`), or a
                distortion model or D this package cannot use.
        """
        K = np.asarray(K, dtype=float)
        if K.size != 9:
            raise ConfigError(f'invalid K {K.ravel().tolist()}: expected 9 values')
        K = K.reshape(3, 3)
        if not (
            np.all(np.isfinite(K))
            and K[0, 1] == 0.0
            and K[1, 0] == 0.0
            and K[2, 0] == 0.0
            and K[2, 1] == 0.0
            and math.isclose(K[2, 2], 1.0)
        ):
            raise ConfigError(
                f'invalid K {K.ravel().tolist()}: expected [fx 0 cx; 0 fy cy; 0 0 1], finite'
            )
        distortion, fisheye = lens_from_camera_info(distortion_model, d)
        K, width, height = _binned_roi(K, int(width), int(height), binning, roi)
        return cls.from_matrix(K, width, height, distortion, fisheye)

    @property
    def distortion_model(self) -> str:
        """The ``CameraInfo.distortion_model`` name of this lens: ``equidistant`` for a
        fisheye, else ``plumb_bob`` (up to 5 coefficients) or ``rational_polynomial``."""
        if self.fisheye:
            return FISHEYE_MODEL
        return STANDARD_MODELS[len(self.distortion) > 5]

    @property
    def pinhole(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy), pixels."""
        return (self.fx, self.fy, self.cx, self.cy)

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the conventional name
        """(3, 3) float64 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def has_distortion(self) -> bool:
        """True for a fisheye lens and when any coefficient is non-zero."""
        return self.fisheye or any(d != 0.0 for d in self.distortion)

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """(N, 2) float32 pixels with this camera's lens distortion removed (same K).

        The node, ``initsel dataset`` and ``initsel seedmap`` all undistort tracks this way.
        """
        pts = np.asarray(pixels, dtype=np.float32).reshape(-1, 2)
        if not self.has_distortion or len(pts) == 0:
            return pts
        import cv2

        K = self.K
        undistort = cv2.fisheye.undistortPoints if self.fisheye else cv2.undistortPoints
        out = undistort(pts.reshape(-1, 1, 2), K, self.lens_coefficients, P=K)
        return out.reshape(-1, 2).astype(np.float32)

    def project(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) float64 pixels of camera-frame points (N, 3), through this lens (the inverse
        of :meth:`undistort_pixels` on their pinhole pixels; z must be positive)."""
        import cv2

        X = np.asarray(points, dtype=np.float64).reshape(-1, 1, 3)
        if len(X) == 0:
            return np.zeros((0, 2))
        coefficients = self.lens_coefficients
        project = cv2.fisheye.projectPoints if self.fisheye else cv2.projectPoints
        pixels, _ = project(X, np.zeros(3), np.zeros(3), self.K, coefficients)
        return pixels.reshape(-1, 2)

    @property
    def corner_field_angle_deg(self) -> float:
        """The largest angle off the optical axis of the image corners' rays, degrees (90 when
        a corner lies at or beyond the pinhole's horizon, as past a fisheye's 180 degrees)."""
        corners = np.array(
            [[0.0, 0.0], [self.width, 0.0], [0.0, self.height], [self.width, self.height]]
        )
        return float(self._field_angles_deg(corners).max())

    def field_mask(self, max_angle_deg: float = MAX_FIELD_ANGLE_DEG) -> np.ndarray | None:
        """(height, width) bool: the pixels whose rays lie within ``max_angle_deg`` of the
        optical axis; None when every pixel does (every pinhole camera short of that field of
        view). The trackers keep to it (:class:`tracking.KltTracker`'s ``region``). Made once
        per camera and angle (the offline tools build a tracker per batch): read-only."""
        return _field_mask(self, float(max_angle_deg))

    def _field_angles_deg(self, pixels: np.ndarray) -> np.ndarray:
        """(N,) angles off the optical axis of the rays of (N, 2) pixels, degrees (90 at or
        beyond the pinhole's horizon)."""
        if self.fisheye:  # invert theta_d = theta (1 + k1 theta^2 + ...) where it is monotone
            theta_d = np.hypot(
                (pixels[:, 0] - self.cx) / self.fx, (pixels[:, 1] - self.cy) / self.fy
            )
            k = (*self.distortion, 0.0, 0.0, 0.0, 0.0)[:FISHEYE_LENGTH]
            theta = np.linspace(0.0, math.pi / 2, 9001)
            along = theta * (1 + sum(c * theta ** (2 * i + 2) for i, c in enumerate(k)))
            rising = np.flatnonzero(np.diff(along) <= 0)
            top = int(rising[0]) + 1 if len(rising) else len(theta)
            angles = np.interp(theta_d, along[:top], theta[:top], right=math.pi / 2)
            angles[theta_d >= along[top - 1]] = math.pi / 2
            return np.degrees(angles)
        ideal = self.undistort_pixels(pixels).astype(np.float64)
        r = np.hypot((ideal[:, 0] - self.cx) / self.fx, (ideal[:, 1] - self.cy) / self.fy)
        return np.where(np.isfinite(r), np.degrees(np.arctan(r)), 90.0)

    @property
    def lens_coefficients(self) -> np.ndarray | None:
        """The coefficients as OpenCV's functions of this lens take them: (4,) for a fisheye
        (zeros when none are given), else the standard model's, or None without distortion."""
        if self.fisheye:
            return np.asarray(self.distortion or (0.0,) * FISHEYE_LENGTH, dtype=np.float64)
        return np.asarray(self.distortion, dtype=np.float64) if self.has_distortion else None

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera for an image resized to ``width`` x ``height``."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            self.fx * sx,
            self.fy * sy,
            self.cx * sx,
            self.cy * sy,
            width,
            height,
            self.distortion,
            self.fisheye,
        )

    def binned(self, factor: int) -> Intrinsics:
        """The camera of this one's images shrunk by averaging whole blocks of ``factor`` x
        ``factor`` pixels (:func:`~initsel_ros.image.downscaled`), size floor(size /
        factor): focal lengths divided by ``factor``, and a pixel centre x of this camera at
        (x + 0.5) / factor - 0.5 (:func:`~initsel_ros.image.unbinned_pixels` maps back);
        itself for a factor of 1. (:meth:`scaled` and a camera_info's REP 104 binning take
        cx / factor instead, a quarter pixel off at a factor of 2: kept apart on purpose, this
        one is exact for block-averaged images.)"""
        if factor <= 1:
            return self
        k = float(factor)
        return replace(
            self,
            fx=self.fx / k,
            fy=self.fy / k,
            cx=(self.cx + 0.5) / k - 0.5,
            cy=(self.cy + 0.5) / k - 0.5,
            width=self.width // factor,
            height=self.height // factor,
        )

    def resized_sensor(self, width: int, height: int) -> Intrinsics:
        """A camera like this one with a sensor of ``width`` x ``height``: the same horizontal
        field of view and pixel aspect ratio (fx and fy scale with the width), the principal
        point at the same place relative to each side. Equal to :meth:`scaled` for the same
        aspect ratio; for another one, :meth:`scaled` stretches the image instead."""
        s = width / self.width
        return Intrinsics(
            self.fx * s,
            self.fy * s,
            self.cx * s,
            self.cy * height / self.height,
            width,
            height,
            self.distortion,
            self.fisheye,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (for YAML/JSON); ``fisheye`` only when set."""
        data = asdict(self) | {'distortion': list(self.distortion)}
        if not self.fisheye:
            del data['fisheye']
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = '<dict>') -> Intrinsics:
        """Inverse of :meth:`to_dict`; raises ConfigError naming ``source`` on bad input."""
        try:
            return cls(
                float(data['fx']),
                float(data['fy']),
                float(data['cx']),
                float(data['cy']),
                int(data['width']),
                int(data['height']),
                tuple(float(d) for d in data.get('distortion', []) or []),
                _flag(data.get('fisheye', False)),
            )
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise ConfigError(
                f'{source}: intrinsics need fx, fy, cx, cy, width, height '
                f'(and optional distortion, fisheye: true|false): {exc}'
            ) from exc
        except ConfigError as exc:  # values Intrinsics refuses: say which file held them
            raise ConfigError(f'{source}: {exc}') from exc

    def save_yaml(self, path: Path) -> None:
        """Write as a small YAML file."""
        import yaml

        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False))

    @classmethod
    def load_yaml(cls, path: Path) -> Intrinsics:
        """Read a file written by :meth:`save_yaml`."""
        import yaml

        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text())
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            reason = ' '.join(str(exc).split())  # YAML errors span lines: one line here
            raise ConfigError(f'{path}: cannot read intrinsics: {reason}') from exc
        if not isinstance(data, dict):
            raise ConfigError(f'{path}: expected a mapping of intrinsics')
        return cls.from_dict(data, source=str(path))


@lru_cache(maxsize=16)
def _field_mask(camera: Intrinsics, max_angle_deg: float) -> np.ndarray | None:
    """:meth:`Intrinsics.field_mask`, computed."""
    if camera.corner_field_angle_deg <= max_angle_deg:
        return None
    y, x = np.mgrid[0 : camera.height, 0 : camera.width]
    pixels = np.column_stack([x.ravel(), y.ravel()]).astype(np.float64)
    angles = camera._field_angles_deg(pixels).reshape(camera.height, camera.width)
    mask = angles <= max_angle_deg
    mask.flags.writeable = False
    return mask


def check_distortion(distortion: tuple[float, ...] | list[float], fisheye: bool = False) -> None:
    """Raise ConfigError unless OpenCV accepts this many coefficients: 0, 4, 5, 8, 12 or 14
    for the standard model (all-zero vectors of any length mean "no distortion" and pass),
    0 or 4 for the fisheye one (0: k1 to k4 all zero, a pure f-theta lens).
    """
    if fisheye:
        if len(distortion) not in (0, FISHEYE_LENGTH):
            raise ConfigError(
                f'{len(distortion)} distortion coefficients {list(distortion)}: the fisheye '
                f'(equidistant) model takes {FISHEYE_LENGTH} (k1 k2 k3 k4)'
            )
        return
    if len(distortion) not in DISTORTION_LENGTHS and any(d != 0.0 for d in distortion):
        raise ConfigError(
            f'{len(distortion)} distortion coefficients {list(distortion)}: OpenCV needs '
            f'{", ".join(map(str, DISTORTION_LENGTHS[1:]))} (k1 k2 p1 p2 [k3 ...]) or none'
        )


def _binned_roi(
    K: np.ndarray,
    width: int,
    height: int,
    binning: tuple[int, int],
    roi: tuple[int, int, int, int],
) -> tuple[np.ndarray, int, int]:
    """K and image size of the images a CameraInfo describes (REP 104's binning and ROI)."""
    bx, by = (max(1, int(b)) for b in binning)
    x0, y0, w, h = (int(v) for v in roi)
    if (x0, y0, w, h) == (0, 0, 0, 0):
        x0, y0, w, h = 0, 0, width, height
    elif w <= 0 or h <= 0 or x0 < 0 or y0 < 0 or x0 + w > width or y0 + h > height:
        raise ConfigError(
            f'roi x_offset={x0} y_offset={y0} width={w} height={h} does not lie within the '
            f'{width}x{height} sensor'
        )
    if (bx, by, x0, y0, w, h) == (1, 1, 0, 0, width, height):
        return K, width, height
    K = K.copy()
    K[0, 0] /= bx
    K[1, 1] /= by
    K[0, 2] = (K[0, 2] - x0) / bx
    K[1, 2] = (K[1, 2] - y0) / by
    return K, w // bx, h // by


def lens_from_camera_info(
    distortion_model: str, d: Sequence[float]
) -> tuple[tuple[float, ...], bool]:
    """(coefficients, fisheye) of a ``CameraInfo``'s ``distortion_model`` and ``D``.

    ``plumb_bob`` and ``rational_polynomial`` (and an empty name) are OpenCV's standard
    model, where an all-zero or empty ``D`` means no distortion. ``equidistant`` is its
    fisheye model, a lens even with k1 to k4 all zero (f-theta, not a pinhole). Another
    name passes only with an all-zero ``D``.

    Raises:
        ConfigError: non-finite coefficients, a count the model cannot take, or another
            model name with non-zero coefficients (they would be misread).
    """
    distortion = tuple(float(v) for v in d)
    if not all(math.isfinite(v) for v in distortion):
        raise ConfigError(f'non-finite distortion {list(distortion)}')
    model = str(distortion_model)
    if model == FISHEYE_MODEL:
        distortion = distortion if any(distortion) else (0.0,) * FISHEYE_LENGTH
        check_distortion(distortion, fisheye=True)
        return distortion, True
    if not any(distortion):
        return (), False
    if model not in (*STANDARD_MODELS, ''):
        raise ConfigError(
            f'distortion model {model!r} is not supported '
            f'({", ".join((*STANDARD_MODELS, FISHEYE_MODEL))})'
        )
    check_distortion(distortion)
    return distortion, False


def _flag(value: Any) -> bool:
    """A YAML/JSON boolean (true/false), not any truthy value."""
    if not isinstance(value, bool):
        raise ValueError(f'fisheye must be true or false, got {value!r}')
    return value


def _effective(camera: Intrinsics) -> tuple[bool, tuple[float, ...]]:
    """The lens with its coefficients' trailing zeros dropped (so (), (0, 0, 0, 0, 0) and
    (k1, 0, 0, 0) compare)."""
    values = list(camera.distortion)
    while values and values[-1] == 0.0:
        values.pop()
    return (camera.fisheye, tuple(values))
