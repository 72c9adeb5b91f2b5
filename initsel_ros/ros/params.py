"""Parameters of the ``selector`` node: names, defaults, descriptions and validation.

One table (:data:`PARAMETERS`) feeds the node's ``declare_parameter`` calls, ``--help``,
``config/selector.yaml`` (a test keeps them equal) and ``docs/node.md``. This module imports no
ROS packages, so the settings can be checked without rclpy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

from initsel_ros.camera import TUM_FR3, Intrinsics
from initsel_ros.errors import ConfigError

PARAMS_FILE_NAME = 'selector.yaml'
NODE_NAME = 'selector'
MODEL_NAMES = ('F', 'E', 'H', 'R')


class Mode(str, Enum):
    """What happens after a successful initialization."""

    ONCE = 'once'  # publish once, then report 'already initialized' until ~/reset
    CONTINUOUS = 'continuous'  # start over with a new reference and initialize again


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: name (dotted for YAML nesting), default value, description."""

    name: str
    default: Any
    description: str


PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec('model_file', '', "model file (JSON); '' = the packaged config/models.json"),
    *(
        ParameterSpec(
            f'thresholds.{m}', -1.0,
            f"probability threshold of model {m} in [0, 1]; negative = the model file's",
        )
        for m in MODEL_NAMES
    ),
    ParameterSpec(
        'r_veto', ['F', 'E'],
        'models silenced when model R (pure rotation) fires; subset of F, E, H',
    ),
    ParameterSpec('max_features', 300, 'Shi-Tomasi corners detected in a reference frame'),
    ParameterSpec(
        'min_tracks', 50, 'fewer tracked points than this: no decision, pick a new reference'
    ),
    ParameterSpec('min_points', 50, 'a pose needs at least this many triangulated points'),
    ParameterSpec('min_parallax_deg', 1.0, 'a pose needs this median parallax, degrees'),
    ParameterSpec(
        'max_frames_since_reference', 90,
        "frames after which a new reference frame is taken (the paper's batch length)",
    ),
    ParameterSpec(
        'mode', Mode.ONCE.value,
        "'once': initialize once until ~/reset; 'continuous': start over after each",
    ),
    ParameterSpec(
        'reference_frame_id', 'initsel_reference_optical',
        'frame id of the reference camera (optical frame) for init/pose, init/points, TF',
    ),
    ParameterSpec(
        'camera_frame_id', '',
        "TF child frame (the current camera); '' = the image's frame id",
    ),
    ParameterSpec('publish_tf', True, 'broadcast the pose on /tf (when tf2_msgs is installed)'),
    ParameterSpec(
        'use_camera_info', True,
        'take intrinsics and distortion from the camera_info topic when it arrives',
    ),
    ParameterSpec('camera.fx', TUM_FR3['fx'], 'focal length x, pixels (until camera_info)'),
    ParameterSpec('camera.fy', TUM_FR3['fy'], 'focal length y, pixels'),
    ParameterSpec('camera.cx', TUM_FR3['cx'], 'principal point x, pixels'),
    ParameterSpec('camera.cy', TUM_FR3['cy'], 'principal point y, pixels'),
    ParameterSpec('camera.width', TUM_FR3['width'], 'image width, pixels'),
    ParameterSpec('camera.height', TUM_FR3['height'], 'image height, pixels'),
    ParameterSpec(
        'camera.distortion', [0.0, 0.0, 0.0, 0.0, 0.0],
        'OpenCV distortion k1 k2 p1 p2 [k3 ...]; all zero = none',
    ),
)


@dataclass(frozen=True)
class NodeSettings:
    """Validated parameter values of the node."""

    model_file: str
    thresholds: dict[str, float]  # only the overrides (non-negative values)
    r_veto: frozenset[str]
    max_features: int
    min_tracks: int
    min_points: int
    min_parallax_deg: float
    max_frames_since_reference: int
    mode: Mode
    reference_frame_id: str
    camera_frame_id: str
    publish_tf: bool
    use_camera_info: bool
    intrinsics: Intrinsics

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> NodeSettings:
        """Validate a name -> value mapping (missing names take their defaults).

        Raises:
            ConfigError: naming the parameter and the accepted values.
        """
        v = {spec.name: spec.default for spec in PARAMETERS}
        unknown = sorted(set(values) - set(v))
        if unknown:
            raise ConfigError(f'unknown selector parameters: {", ".join(unknown)}')
        v.update(values)
        thresholds: dict[str, float] = {}
        for m in MODEL_NAMES:
            value = float(v[f'thresholds.{m}'])
            if value > 1.0:
                raise ConfigError(f'thresholds.{m} must be <= 1 (negative = file), got {value}')
            if value >= 0.0:
                thresholds[m] = value
        r_veto = frozenset(str(m) for m in v['r_veto'])
        if not r_veto <= {'F', 'E', 'H'}:
            raise ConfigError(f'r_veto must name models among F, E, H, got {sorted(r_veto)}')
        try:
            mode = Mode(v['mode'])
        except ValueError as exc:
            raise ConfigError(f"mode must be 'once' or 'continuous', got {v['mode']!r}") from exc
        for name in ('max_features', 'min_tracks', 'min_points', 'max_frames_since_reference'):
            if int(v[name]) < 1:
                raise ConfigError(f'{name} must be >= 1, got {v[name]}')
        if float(v['min_parallax_deg']) < 0:
            raise ConfigError(f'min_parallax_deg must be >= 0, got {v["min_parallax_deg"]}')
        if not v['reference_frame_id']:
            raise ConfigError('reference_frame_id must not be empty')
        distortion = tuple(float(d) for d in v['camera.distortion'])
        intrinsics = Intrinsics(
            float(v['camera.fx']), float(v['camera.fy']), float(v['camera.cx']),
            float(v['camera.cy']), int(v['camera.width']), int(v['camera.height']),
            distortion if any(distortion) else (),
        )
        return cls(
            model_file=str(v['model_file']), thresholds=thresholds, r_veto=r_veto,
            max_features=int(v['max_features']), min_tracks=int(v['min_tracks']),
            min_points=int(v['min_points']), min_parallax_deg=float(v['min_parallax_deg']),
            max_frames_since_reference=int(v['max_frames_since_reference']), mode=mode,
            reference_frame_id=str(v['reference_frame_id']),
            camera_frame_id=str(v['camera_frame_id']), publish_tf=bool(v['publish_tf']),
            use_camera_info=bool(v['use_camera_info']), intrinsics=intrinsics,
        )

    def model_path(self) -> Path:
        """The model file to load: ``model_file`` or the packaged default.

        Raises:
            ModelFileError: when the default cannot be found.
        """
        from initsel_ros.models import default_model_path

        return Path(self.model_file).expanduser() if self.model_file else default_model_path()

    def selector_config(self) -> Any:
        """The :class:`initsel_ros.selector.SelectorConfig` these settings describe."""
        from initsel_ros.policy import PolicyConfig
        from initsel_ros.selector import SelectorConfig
        from initsel_ros.tracking import TrackerConfig

        return SelectorConfig(
            tracker=dataclasses.replace(TrackerConfig(), max_features=self.max_features),
            policy=PolicyConfig(
                thresholds=dict(self.thresholds), r_veto=self.r_veto,
                min_tracks=self.min_tracks, min_points=self.min_points,
                min_parallax_deg=self.min_parallax_deg,
            ),
            mode=self.mode.value,
            max_frames_since_reference=self.max_frames_since_reference,
        )


def default_params_file() -> Path:
    """The packaged ``config/selector.yaml`` (ament share dir, install prefix or source tree).

    Raises:
        ModelFileError: when it cannot be found (the message lists where it looked).
    """
    from initsel_ros.models import find_config_file

    return find_config_file(PARAMS_FILE_NAME)


def load_params_file(path: Path) -> dict[str, Any]:
    """Flattened ``selector: ros__parameters:`` values of a ROS 2 parameter file.

    Raises:
        ConfigError: unreadable file or no ``selector``/``/**`` section.
    """
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f'{path}: cannot read parameters: {exc}') from exc
    for key in (NODE_NAME, f'/{NODE_NAME}', f'/**/{NODE_NAME}', '/**'):
        section = (data or {}).get(key, {}) if isinstance(data, dict) else {}
        if isinstance(section, dict) and 'ros__parameters' in section:
            return _flatten(section['ros__parameters'] or {})
    raise ConfigError(f'{path}: no "{NODE_NAME}: ros__parameters:" section')


def _flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            out.update(_flatten(value, f'{name}.'))
        else:
            out[name] = value
    return out


__all__ = [
    'MODEL_NAMES',
    'NODE_NAME',
    'PARAMETERS',
    'PARAMS_FILE_NAME',
    'Mode',
    'NodeSettings',
    'ParameterSpec',
    'default_params_file',
    'load_params_file',
]
