"""Pinhole camera intrinsics (with optional distortion) and their file form."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
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


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels, image size in pixels, OpenCV distortion coefficients."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    distortion: tuple[float, ...] = field(default=())

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy, *self.distortion)
        if not all(math.isfinite(v) for v in values):
            raise ConfigError(f'intrinsics must be finite, got {self}')
        if self.fx <= 0 or self.fy <= 0:
            raise ConfigError(f'focal lengths must be positive, got fx={self.fx} fy={self.fy}')
        if self.width <= 0 or self.height <= 0:
            raise ConfigError(f'image size must be positive, got {self.width}x{self.height}')
        check_distortion(self.distortion)
        for name, c, size in (('cx', self.cx, self.width), ('cy', self.cy, self.height)):
            if not 0 <= c <= size:
                raise ConfigError(
                    f'principal point {name}={c:g} px is outside the {self.width}x{self.height} '
                    f'image (expected 0 <= {name} <= {size})'
                )
        diagonal = math.hypot(self.width, self.height)
        for name, f in (('fx', self.fx), ('fy', self.fy)):
            if not MIN_FOCAL_PER_DIAGONAL * diagonal <= f <= MAX_FOCAL_PER_DIAGONAL * diagonal:
                raise ConfigError(
                    f'{name}={f:g} px is implausible for a {self.width}x{self.height} image '
                    f'(expected {MIN_FOCAL_PER_DIAGONAL:g} to {MAX_FOCAL_PER_DIAGONAL:g} '
                    'times the diagonal)'
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
        ) and _effective(self.distortion) == _effective(other.distortion)

    @classmethod
    def tum_fr3(cls) -> Intrinsics:
        """The TUM fr3 colour camera: fx 535.4, fy 539.2, cx 320.1, cy 247.6, 640x480."""
        return cls(**TUM_FR3)

    @classmethod
    def from_matrix(
        cls, K: np.ndarray, width: int, height: int, distortion: tuple[float, ...] = ()
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
        )

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
        """True when any distortion coefficient is non-zero."""
        return any(d != 0.0 for d in self.distortion)

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """(N, 2) float32 pixels with this camera's lens distortion removed (same K).

        The node, ``initsel dataset`` and ``initsel seedmap`` all undistort tracks this way.
        """
        pts = np.asarray(pixels, dtype=np.float32).reshape(-1, 2)
        if not self.has_distortion or len(pts) == 0:
            return pts
        import cv2

        K = self.K
        out = cv2.undistortPoints(
            pts.reshape(-1, 1, 2), K, np.asarray(self.distortion, dtype=np.float64), P=K
        )
        return out.reshape(-1, 2).astype(np.float32)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera for an image resized to ``width`` x ``height``."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy, width, height, self.distortion
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (for YAML/JSON)."""
        return asdict(self) | {'distortion': list(self.distortion)}

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
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(
                f'{source}: intrinsics need fx, fy, cx, cy, width, height '
                f'(and optional distortion): {exc}'
            ) from exc

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
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f'{path}: cannot read intrinsics: {exc}') from exc
        if not isinstance(data, dict):
            raise ConfigError(f'{path}: expected a mapping of intrinsics')
        return cls.from_dict(data, source=str(path))


def check_distortion(distortion: tuple[float, ...] | list[float]) -> None:
    """Raise ConfigError unless OpenCV accepts this many coefficients (or all are zero).

    All-zero vectors of any length mean "no distortion" and pass.
    """
    if len(distortion) not in DISTORTION_LENGTHS and any(d != 0.0 for d in distortion):
        raise ConfigError(
            f'{len(distortion)} distortion coefficients {list(distortion)}: OpenCV needs '
            f'{", ".join(map(str, DISTORTION_LENGTHS[1:]))} (k1 k2 p1 p2 [k3 ...]) or none'
        )


def _effective(distortion: tuple[float, ...]) -> tuple[float, ...]:
    """Distortion without trailing zeros (so (), (0, 0, 0, 0, 0) and (k1, 0, 0, 0) compare)."""
    values = list(distortion)
    while values and values[-1] == 0.0:
        values.pop()
    return tuple(values)
