"""Parameters of the ``selector`` node: names, defaults, descriptions, ranges and validation.

One table (:data:`PARAMETERS`) feeds the node's ``declare_parameter`` calls (descriptions,
read-only flags, constraints), its on-set-parameters callback, ``--help``,
``config/selector.yaml`` (a test keeps them equal) and ``docs/node.md``. Each entry says
whether the parameter is *live* (applied while the node runs) or read-only (needs a restart)
and carries its validator; :meth:`NodeSettings.from_values` runs the same validators at
start-up and for every live change. A parameter added to the table is live unless it says
``live=False``. Parameters that configure the core take their defaults from the core's
dataclasses (:class:`~initsel_ros.selector.SelectorConfig` and the configs inside it), so the
two cannot drift (a test also holds ``config/selector.yaml`` to them). This module imports no
ROS packages, so the settings can be checked without rclpy.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from enum import Enum
from pathlib import Path
from typing import Any

from initsel_ros.camera import (
    FISHEYE_MODEL,
    STANDARD_MODELS,
    TUM_FR3,
    Intrinsics,
    check_distortion,
)
from initsel_ros.errors import ConfigError
from initsel_ros.image import MAX_DECODED_PIXELS
from initsel_ros.names import MODEL_NAMES, POSE_METHODS, Mode
from initsel_ros.policy import PolicyConfig
from initsel_ros.selector import SelectorConfig
from initsel_ros.stamps import DEFAULT_RESTART_TOLERANCE_NS
from initsel_ros.tracking import TrackerConfig
from initsel_ros.verify import VerifyConfig

PARAMS_FILE_NAME = 'selector.yaml'
NODE_NAME = 'selector'
#: Keys of a parameter file's node section, in the order they are looked up.
SECTION_KEYS = (NODE_NAME, f'/{NODE_NAME}', f'/**/{NODE_NAME}', '/**')
#: Upper bound of ``max_features`` (and of the counts compared with it).
MAX_FEATURES_LIMIT = 10_000
#: Smallest ``max_tracking_width``: narrower frames hold too few corners far enough apart.
MIN_TRACKING_WIDTH = 320
#: Default ``max_image_pixels``: 4096 x 2160 (DCI 4K).
DEFAULT_MAX_IMAGE_PIXELS = 4096 * 2160


class ImageTransport(str, Enum):
    """How images arrive."""

    RAW = 'raw'  # sensor_msgs/Image on image_raw
    COMPRESSED = 'compressed'  # sensor_msgs/CompressedImage (JPEG, PNG) on image_raw/compressed


# ---------------------------------------------------------------------------------- validators
def _kind(value: Any) -> str:
    return f'{value!r} ({type(value).__name__})'


@dataclass(frozen=True)
class Number:
    """A finite number in ``[low, high]`` (None = unbounded), optionally an integer."""

    low: float | None = None
    high: float | None = None
    integer: bool = False
    note: str = ''

    def __call__(self, name: str, value: Any) -> int | float:
        numeric = isinstance(value, int) if self.integer else isinstance(value, (int, float))
        if isinstance(value, bool) or not numeric:
            raise ConfigError(f'{name} must be {self}, got {_kind(value)}')
        number = int(value) if self.integer else float(value)
        if (
            not math.isfinite(number)
            or (self.low is not None and number < self.low)
            or (self.high is not None and number > self.high)
        ):
            raise ConfigError(f'{name} must be {self}, got {value!r}')
        return number

    def __str__(self) -> str:
        kind = 'an integer' if self.integer else 'a finite number'
        if self.low is not None and self.high is not None:
            bounds = f' in [{self.low:g}, {self.high:g}]'
        elif self.low is not None:
            bounds = f' >= {self.low:g}'
        elif self.high is not None:
            bounds = f' <= {self.high:g}'
        else:
            bounds = ''
        return kind + bounds + (f' ({self.note})' if self.note else '')


@dataclass(frozen=True)
class Choice:
    """One of a few values."""

    values: tuple[Any, ...]

    def __call__(self, name: str, value: Any) -> Any:
        if isinstance(value, bool) or value not in self.values:
            raise ConfigError(f'{name} must be {self}, got {value!r}')
        return value

    def __str__(self) -> str:
        return 'one of ' + ', '.join(repr(v) for v in self.values)


@dataclass(frozen=True)
class Text:
    """A string, optionally non-empty."""

    non_empty: bool = False

    def __call__(self, name: str, value: Any) -> str:
        if not isinstance(value, str):
            raise ConfigError(f'{name} must be a string, got {_kind(value)}')
        if self.non_empty and not value:
            raise ConfigError(f'{name} must not be empty')
        return value

    def __str__(self) -> str:
        return 'a non-empty string' if self.non_empty else 'a string'


@dataclass(frozen=True)
class FrameId(Text):
    """A TF frame id: a string without a leading '/' (tf2 refuses those), optionally
    non-empty."""

    def __call__(self, name: str, value: Any) -> str:
        value = super().__call__(name, value)
        if value.startswith('/'):
            raise ConfigError(
                f"{name} must not start with '/' (tf2 refuses such frame ids), got {value!r}"
            )
        if any(c.isspace() for c in value):
            raise ConfigError(f'{name} must not contain white space, got {value!r}')
        return value

    def __str__(self) -> str:
        return f"{super().__str__()} without a leading '/' or white space"


@dataclass(frozen=True)
class Flag:
    """A boolean."""

    def __call__(self, name: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{name} must be true or false, got {_kind(value)}')
        return value

    def __str__(self) -> str:
        return 'true or false'


@dataclass(frozen=True)
class Subset:
    """A list of distinct names among ``allowed`` (empty allowed)."""

    allowed: tuple[str, ...]

    def __call__(self, name: str, value: Any) -> frozenset[str]:
        if isinstance(value, str) or not isinstance(value, Sequence):
            raise ConfigError(f'{name} must be {self}, got {_kind(value)}')
        names = [v if isinstance(v, str) else repr(v) for v in value]
        if not set(names) <= set(self.allowed):
            raise ConfigError(
                f'{name} must name models among {", ".join(self.allowed)}, got {sorted(names)}'
            )
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:  # (a typo for another model, most likely: say so rather than merge)
            raise ConfigError(f'{name} names {", ".join(repeated)} more than once: {names}')
        return frozenset(names)

    def __str__(self) -> str:
        return f'a list of names among {", ".join(self.allowed)} ([] = none)'


@dataclass(frozen=True)
class Distortion:
    """OpenCV distortion coefficients: 0, 4, 5, 8, 12 or 14 finite numbers (all-zero = none)."""

    def __call__(self, name: str, value: Any) -> tuple[float, ...]:
        if isinstance(value, str) or not isinstance(value, Sequence):
            raise ConfigError(f'{name} must be a list of numbers, got {_kind(value)}')
        coefficients = []
        for d in value:
            if isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d):
                raise ConfigError(f'{name} must be finite numbers, got {list(value)}')
            coefficients.append(float(d))
        try:
            check_distortion(coefficients)
        except ConfigError as exc:
            raise ConfigError(f'{name}: {exc}') from exc
        return tuple(coefficients) if any(coefficients) else ()

    def __str__(self) -> str:
        return '0, 4, 5, 8, 12 or 14 finite numbers (all zero = none)'


@dataclass(frozen=True)
class ZeroOr:
    """0 (meaning ``zero``) or an integer in [``low``, ``high``]."""

    low: int
    high: int
    zero: str

    def __call__(self, name: str, value: Any) -> int:
        if (
            isinstance(value, bool)
            or not isinstance(value, int)
            or not (value == 0 or self.low <= value <= self.high)
        ):
            raise ConfigError(f'{name} must be {self}, got {value!r}')
        return int(value)

    def __str__(self) -> str:
        return f'0 ({self.zero}) or an integer in [{self.low}, {self.high}]'


Validator = Callable[[str, Any], Any]


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter.

    Attributes:
        name: dotted for YAML nesting (``thresholds.E``).
        default: declared default (its type is the parameter's type).
        description: one line for ``ros2 param describe``, ``--help`` and the docs.
        check: validator; returns the normalized value or raises ConfigError.
        live: applied while the node runs; False = declared read-only (needs a restart).
    """

    name: str
    default: Any
    description: str
    check: Validator = field(default=Text())
    live: bool = True

    @property
    def constraints(self) -> str:
        """The accepted values, in words (the descriptor's ``additional_constraints``)."""
        return str(self.check)


_COUNT = Number(1, MAX_FEATURES_LIMIT, integer=True)
_THRESHOLD = Number(high=1.0, note="negative = the model file's")
#: The core's defaults, which the parameters below start from.
_SELECTOR = SelectorConfig()
_POLICY: PolicyConfig = _SELECTOR.policy
_TRACKER: TrackerConfig = _SELECTOR.tracker
_VERIFY: VerifyConfig = _SELECTOR.verify

PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec(
        'model_file',
        '',
        "model file (JSON); '' = the packaged config/models.json",
        Text(),
        live=False,
    ),
    *(
        ParameterSpec(
            f'thresholds.{m}',
            -1.0,
            f"probability threshold of model {m} in [0, 1]; negative = the model file's"
            + (
                ''
                if m == 'R'
                else ' (at 1.0 the rotation re-check can still try E and H: '
                'rotation_recheck_frames 0 stops it)'
            ),
            _THRESHOLD,
        )
        for m in MODEL_NAMES
    ),
    ParameterSpec(
        'r_veto',
        [m for m in POSE_METHODS if m in _POLICY.r_veto],
        'models silenced when model R (pure rotation) fires; subset of F, E, H',
        Subset(POSE_METHODS),
    ),
    ParameterSpec(
        'max_features',
        _TRACKER.max_features,
        'Shi-Tomasi corners detected in a reference frame',
        _COUNT,
        live=False,
    ),
    ParameterSpec(
        'min_tracks',
        _POLICY.min_tracks,
        'fewer tracked points than this: no decision, pick a new reference',
        _COUNT,
    ),
    ParameterSpec(
        'min_points',
        _POLICY.min_points,
        'a pose needs at least this many triangulated points',
        _COUNT,
    ),
    ParameterSpec(
        'min_parallax_deg',
        _POLICY.min_parallax_deg,
        'a pose needs this median parallax, degrees',
        Number(0.0, 90.0),
    ),
    ParameterSpec(
        'min_homography_parallax_deg',
        _POLICY.min_homography_parallax_deg,
        "H's median parallax floor, degrees, where H's plane is the scene "
        "(min_homography_plane_share; its pose comes from the plane's perspective change)",
        Number(0.0, 90.0),
    ),
    ParameterSpec(
        'min_homography_plane_share',
        _POLICY.min_homography_plane_share,
        "H's own parallax floor holds when H triangulates at least this share of the tracks "
        '(the scene is one plane); on less, H needs min_parallax_deg too, and an E or F '
        'whose triangulated points leave H less than this share is not refused for a '
        'lower-GRIC H',
        Number(0.0, 1.0),
    ),
    ParameterSpec(
        'min_rotation_residual_sigma',
        _POLICY.min_rotation_residual_sigma,
        'flow left after the best pure rotation must reach this many times the tracking '
        'noise measured on the same tracks (less: a rotation alone explains it)',
        Number(0.0, 100.0),
    ),
    ParameterSpec(
        'min_plane_residual_sigma',
        _POLICY.min_plane_residual_sigma,
        'between this and min_rotation_residual_sigma times the noise, H alone is tried, kept '
        "where it triangulates min_homography_plane_share of the tracks (a plane's perspective "
        'change is parallax for H before it is for E and F); at or above '
        'min_rotation_residual_sigma: off',
        Number(0.0, 100.0),
    ),
    ParameterSpec(
        'max_translation_sigma_deg',
        _POLICY.max_translation_sigma_deg,
        'a refined seed map is published only when it fixes the direction of motion to '
        'within this standard deviation, degrees (0 = off)',
        Number(0.0, 90.0),
    ),
    ParameterSpec(
        'max_edge_point_share',
        _POLICY.max_edge_point_share,
        'a seed map is refused when more than this share of its points lie on straight edges '
        'of the reference frame, where tracks slide along the edge (too little texture); '
        '1 = off',
        Number(0.0, 1.0),
    ),
    ParameterSpec(
        'max_frames_since_reference',
        _SELECTOR.max_frames_since_reference,
        "frames after which a new reference frame is taken (the paper's batch length), "
        'once min_seconds_since_reference have passed too',
        Number(1, 1_000_000, integer=True),
    ),
    ParameterSpec(
        'min_seconds_since_reference',
        _SELECTOR.min_seconds_since_reference,
        'a new reference for age is taken only this many seconds after the reference, by the '
        'image stamps: a 60 Hz camera keeps the 3 s that 90 frames are at 30 Hz (0 = frames '
        'only)',
        Number(0.0, 1e6),
    ),
    ParameterSpec(
        'rotation_recheck_frames',
        _SELECTOR.rotation_recheck_frames,
        "while model R's yes holds every other model back, the rotation test re-checks it "
        'every this many frames after the reference, and sooner where the last fire-path run '
        "predicts when the evidence it lacked reaches its bar; a model's yes before a frame "
        'so scheduled by a rotation test is held (0 = never: every yes runs the fire path)',
        Number(0, 1_000_000, integer=True),
    ),
    ParameterSpec(
        'rotation_rereference_share',
        _SELECTOR.rotation_rereference_share,
        'when the rotation test finds a rotation at the noise level (at most half '
        "min_rotation_residual_sigma) and at most this share of the reference frame's tracks "
        "is left, the frame becomes the reference: a rotation loses no baseline, and a pan's "
        'background leaves the image while objects moving on their own stay (0 = never)',
        Number(0.0, 1.0),
    ),
    ParameterSpec(
        'mode',
        _SELECTOR.mode.value,
        "'once': initialize once until ~/reset; 'continuous': start over after each",
        Choice(tuple(m.value for m in Mode)),
    ),
    ParameterSpec(
        'refine',
        _SELECTOR.refine,
        'bundle-adjust the chosen pose and points before publishing (docs/initialization.md)',
        Flag(),
    ),
    ParameterSpec(
        'snap_to_plane',
        _SELECTOR.snap_to_plane,
        'publish the points of an H initialization that agree with its plane to within their own '
        'depth uncertainty on that plane (false: each point as triangulated)',
        Flag(),
    ),
    ParameterSpec(
        'verify_frames',
        _VERIFY.frames,
        'frames that must confirm a candidate by PnP before it is published (3 times as '
        'many while both decompositions of an H hold); 0 = off',
        Number(0, 100, integer=True),
    ),
    ParameterSpec(
        'verify_min_fraction',
        _VERIFY.min_fraction,
        'share of the map points in view that must stay PnP inliers in every verification frame',
        Number(0.01, 1.0),
    ),
    ParameterSpec(
        'verify_max_rms_px',
        _VERIFY.max_rms_px,
        'largest PnP reprojection RMS of those inliers in a verification frame, pixels (k/2 '
        "times it at k > 2 times the initializing frame's distance from the reference)",
        Number(0.01, 100.0),
    ),
    ParameterSpec(
        'reference_frame_id',
        'initsel_reference_optical',
        'frame id of the reference camera (optical frame) for init/pose, init/points, TF',
        FrameId(non_empty=True),
    ),
    ParameterSpec(
        'camera_frame_id',
        '',
        "TF child frame (the current camera); '' = the image's frame id; not reference_frame_id",
        FrameId(),
    ),
    ParameterSpec(
        'publish_tf', True, 'broadcast the pose on /tf (when tf2_msgs is installed)', Flag()
    ),
    ParameterSpec(
        'image_transport',
        ImageTransport.RAW.value,
        "'raw': sensor_msgs/Image on image_raw; 'compressed': sensor_msgs/CompressedImage "
        '(JPEG, PNG) on image_raw/compressed',
        Choice(tuple(t.value for t in ImageTransport)),
        live=False,
    ),
    ParameterSpec(
        'bit_depth',
        0,
        'significant bits of mono16/16UC1 pixels (8-16); 0 = automatic: the bits that hold '
        'all but 0.1 % of the pixels, raised only when 3 frames in a row need more; ~/reset '
        'forgets it',
        ZeroOr(8, 16, 'automatic'),
    ),
    ParameterSpec(
        'max_image_pixels',
        DEFAULT_MAX_IMAGE_PIXELS,
        'frames of more pixels (width x height, read from the header of compressed ones) are '
        'skipped before decoding; default 4096 x 2160',
        Number(1, MAX_DECODED_PIXELS, integer=True),
    ),
    ParameterSpec(
        'max_tracking_width',
        0,
        'frames wider than this many pixels are shrunk by the smallest whole factor (2, 3, '
        '...) that brings them within it, by area averaging, before anything else (the '
        'intrinsics shrink with them; init/points keeps full-size pixels); 0 = full size. '
        '1280 tracks 1920x1080 at 960x540 and 3840x2160 at 1280x720',
        ZeroOr(MIN_TRACKING_WIDTH, 65536, 'full size'),
    ),
    ParameterSpec(
        'restart_tolerance_s',
        DEFAULT_RESTART_TOLERANCE_NS / 1e9,
        'a frame older than the latest by at most this many seconds is jitter (skipped as out '
        'of order); a jump back by more is a restart (new reference; mode once keeps its '
        'initialization until ~/reset)',
        Number(0.0, 86_400.0),
    ),
    ParameterSpec(
        'use_camera_info',
        True,
        'take intrinsics and distortion from the camera_info topic when it arrives',
        Flag(),
        live=False,
    ),
    ParameterSpec(
        'camera.fx', TUM_FR3['fx'], 'focal length x, pixels (until camera_info)', Number()
    ),
    ParameterSpec('camera.fy', TUM_FR3['fy'], 'focal length y, pixels', Number()),
    ParameterSpec(
        'camera.cx', TUM_FR3['cx'], 'principal point x, pixels (0 to camera.width)', Number()
    ),
    ParameterSpec(
        'camera.cy', TUM_FR3['cy'], 'principal point y, pixels (0 to camera.height)', Number()
    ),
    ParameterSpec(
        'camera.width', TUM_FR3['width'], 'image width, pixels', Number(1, 100_000, integer=True)
    ),
    ParameterSpec(
        'camera.height',
        TUM_FR3['height'],
        'image height, pixels',
        Number(1, 100_000, integer=True),
    ),
    ParameterSpec(
        'camera.distortion',
        [0.0, 0.0, 0.0, 0.0, 0.0],
        'OpenCV distortion k1 k2 p1 p2 [k3 ...] (0, 4, 5, 8, 12 or 14 values; all zero = '
        'none), or k1 k2 k3 k4 with camera.distortion_model equidistant',
        Distortion(),
    ),
    ParameterSpec(
        'camera.distortion_model',
        STANDARD_MODELS[0],
        "the lens model of camera.distortion, as CameraInfo names it: 'plumb_bob' or "
        "'rational_polynomial' (OpenCV's standard model) or 'equidistant' (fisheye)",
        Choice((*STANDARD_MODELS, FISHEYE_MODEL)),
    ),
)

#: The table by name.
SPECS: dict[str, ParameterSpec] = {spec.name: spec for spec in PARAMETERS}
#: Parameters that describe the camera (live only until a camera_info arrives).
CAMERA_PARAMETERS = frozenset(name for name in SPECS if name.startswith('camera.'))


@dataclass(frozen=True)
class NodeSettings:
    """Validated parameter values of the node.

    ``values`` holds every parameter's value by name as given, defaults filled in (what the
    node re-validates with a change when a parameter is set).
    """

    model_file: str
    thresholds: dict[str, float]  # only the overrides (non-negative values)
    r_veto: frozenset[str]
    max_features: int
    min_tracks: int
    min_points: int
    min_parallax_deg: float
    min_homography_parallax_deg: float
    min_homography_plane_share: float
    min_rotation_residual_sigma: float
    min_plane_residual_sigma: float
    max_translation_sigma_deg: float
    max_edge_point_share: float
    max_frames_since_reference: int
    min_seconds_since_reference: float
    rotation_recheck_frames: int
    rotation_rereference_share: float
    mode: Mode
    refine: bool
    snap_to_plane: bool
    verify_frames: int
    verify_min_fraction: float
    verify_max_rms_px: float
    reference_frame_id: str
    camera_frame_id: str
    publish_tf: bool
    image_transport: ImageTransport
    bit_depth: int
    max_image_pixels: int
    max_tracking_width: int
    restart_tolerance_s: float
    use_camera_info: bool
    intrinsics: Intrinsics
    values: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> NodeSettings:
        """Validate a name -> value mapping (missing names take their defaults).

        The same checks run at start-up and for every live change.

        Raises:
            ConfigError: one line naming the parameter and the accepted values.
        """
        raw = {spec.name: spec.default for spec in PARAMETERS}
        unknown = sorted(set(values) - set(raw))
        if unknown:
            raise ConfigError(f'unknown selector parameters: {", ".join(unknown)}')
        raw.update(values)
        v = {name: SPECS[name].check(name, value) for name, value in raw.items()}
        if v['camera_frame_id'] and v['camera_frame_id'] == v['reference_frame_id']:
            raise ConfigError(
                f'camera_frame_id is reference_frame_id ({v["reference_frame_id"]!r}): the TF '
                'of the pose would be a frame to itself'
            )
        for name in ('min_tracks', 'min_points'):
            if v[name] > v['max_features']:
                raise ConfigError(
                    f'{name} ({v[name]}) > max_features ({v["max_features"]}): no frame could '
                    'ever have enough'
                )
        try:
            intrinsics = Intrinsics(
                v['camera.fx'],
                v['camera.fy'],
                v['camera.cx'],
                v['camera.cy'],
                v['camera.width'],
                v['camera.height'],
                v['camera.distortion'],
                v['camera.distortion_model'] == FISHEYE_MODEL,
            )
        except ConfigError as exc:
            raise ConfigError(f'camera.* parameters: {exc}') from exc
        converted = {
            'thresholds': {
                m: v[f'thresholds.{m}'] for m in MODEL_NAMES if v[f'thresholds.{m}'] >= 0.0
            },
            'mode': Mode(v['mode']),
            'image_transport': ImageTransport(v['image_transport']),
            'intrinsics': intrinsics,
            'values': raw,
        }
        # every other field is the parameter of the same name as checked
        checked = {f.name: v[f.name] for f in fields(cls) if f.name not in converted}
        return cls(**checked, **converted)

    @property
    def default_intrinsics(self) -> bool:
        """True when ``camera.*`` hold the TUM fr3 defaults (unset, or set to those values:
        the two cannot be told apart, since config/selector.yaml lists them)."""
        return all(
            self.values.get(name, SPECS[name].default) == SPECS[name].default
            for name in CAMERA_PARAMETERS
        )

    def model_path(self) -> Path:
        """The model file to load: ``model_file`` or the packaged default.

        Raises:
            ModelFileError: when the default cannot be found.
        """
        from initsel_ros.models import default_model_path

        return Path(self.model_file).expanduser() if self.model_file else default_model_path()

    def selector_config(self) -> SelectorConfig:
        """The :class:`initsel_ros.selector.SelectorConfig` these settings describe."""
        return SelectorConfig(
            tracker=dataclasses.replace(TrackerConfig(), max_features=self.max_features),
            policy=PolicyConfig(
                thresholds=dict(self.thresholds),
                r_veto=self.r_veto,
                min_tracks=self.min_tracks,
                min_points=self.min_points,
                min_parallax_deg=self.min_parallax_deg,
                min_homography_parallax_deg=self.min_homography_parallax_deg,
                min_homography_plane_share=self.min_homography_plane_share,
                min_rotation_residual_sigma=self.min_rotation_residual_sigma,
                min_plane_residual_sigma=self.min_plane_residual_sigma,
                max_translation_sigma_deg=self.max_translation_sigma_deg,
                max_edge_point_share=self.max_edge_point_share,
            ),
            mode=self.mode,
            max_frames_since_reference=self.max_frames_since_reference,
            min_seconds_since_reference=self.min_seconds_since_reference,
            rotation_recheck_frames=self.rotation_recheck_frames,
            rotation_rereference_share=self.rotation_rereference_share,
            refine=self.refine,
            snap_to_plane=self.snap_to_plane,
            verify=VerifyConfig(
                frames=self.verify_frames,
                min_fraction=self.verify_min_fraction,
                max_rms_px=self.verify_max_rms_px,
            ),
            bit_depth=self.bit_depth,
        )


def default_params_file() -> Path:
    """The packaged ``config/selector.yaml`` (ament share dir, install prefix or source tree).

    Raises:
        ModelFileError: when it cannot be found (the message lists where it looked).
    """
    from initsel_ros.config_files import find_config_file

    return find_config_file(PARAMS_FILE_NAME)


def read_params_yaml(path: Path) -> Any:
    """Parse a ROS 2 parameter file as YAML.

    Raises:
        ConfigError: one line: unreadable file, or the syntax error with line and column.
    """
    import yaml

    path = Path(path)
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f'{path}: cannot read parameters: {exc}') from exc
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or str(exc).splitlines()[0]
        raise ConfigError(f'{path}: YAML syntax error{where}: {problem}') from exc


def load_params_file(path: Path) -> dict[str, Any]:
    """Flattened ``selector: ros__parameters:`` values of a ROS 2 parameter file.

    Raises:
        ConfigError: unreadable file, YAML syntax error, or no node section.
    """
    data = read_params_yaml(path)
    for key in SECTION_KEYS:
        section = (data or {}).get(key, {}) if isinstance(data, dict) else {}
        if isinstance(section, dict) and 'ros__parameters' in section:
            return _flatten(section['ros__parameters'] or {})
    raise ConfigError(f'{path}: no "{NODE_NAME}: ros__parameters:" section')


def unknown_parameters_note(names: Sequence[str]) -> str:
    """What to say of parameter overrides that are not the selector's (``names``): each one,
    with the parameter it was probably meant to be, e.g. ``min_parralax_deg (min_parallax_deg?)``;
    '' when there are none."""
    import difflib

    known = [spec.name for spec in PARAMETERS]
    lowered = {name.lower(): name for name in known}
    parts = []
    for name in sorted(names):
        guess = lowered.get(name.lower()) or next(
            iter(difflib.get_close_matches(name, known, n=1, cutoff=0.8)), None
        )
        parts.append(f'{name} ({guess}?)' if guess else name)
    return ', '.join(parts)


def parameter_sections(data: Any) -> list[str]:
    """The node names a parameter file's sections are for, fully qualified as written (each
    a ``/``-separated path to a ``ros__parameters`` key: ``/**/selector``, and the nested form
    ``robot: {selector: {ros__parameters: ...}}`` as ``/robot/selector``)."""
    names: list[str] = []

    def walk(tree: Any, path: list[str]) -> None:
        if not isinstance(tree, Mapping):
            return
        if 'ros__parameters' in tree and path:
            names.append('/' + '/'.join(path))
        for key, value in tree.items():
            if key != 'ros__parameters':
                walk(value, [*path, *(t for t in str(key).split('/') if t)])

    walk(data, [])
    return names


def section_applies(section: str, node: str) -> bool:
    """Whether a section for ``section`` (:func:`parameter_sections`) sets the parameters
    of the node whose fully qualified name is ``node``: as rcl matches them, ``*`` stands
    for one name and ``**`` for any number of them (none included)."""

    def match(pattern: list[str], name: list[str]) -> bool:
        if not pattern:
            return not name
        head, rest = pattern[0], pattern[1:]
        if head == '**':
            return any(match(rest, name[k:]) for k in range(len(name) + 1))
        return bool(name) and head in ('*', name[0]) and match(rest, name[1:])

    return match([t for t in section.split('/') if t], [t for t in node.split('/') if t])


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
    'CAMERA_PARAMETERS',
    'DEFAULT_MAX_IMAGE_PIXELS',
    'MAX_FEATURES_LIMIT',
    'MIN_TRACKING_WIDTH',
    'NODE_NAME',
    'PARAMETERS',
    'PARAMS_FILE_NAME',
    'SPECS',
    'ImageTransport',
    'NodeSettings',
    'ParameterSpec',
    'default_params_file',
    'load_params_file',
    'parameter_sections',
    'read_params_yaml',
    'section_applies',
    'unknown_parameters_note',
]
