"""The ``selector`` node: decides, live from a camera stream, when and how to initialize.

Subscribes ``image_raw`` (or ``image_raw/compressed``) and ``camera_info``, runs
:class:`initsel_ros.selector.Selector` on the newest frame and publishes ``init/method``,
``init/pose``, ``init/points`` (latched) when it initializes, plus a status on ``/diagnostics``
and ``~/status`` for every frame. Every message about a frame carries that frame's
``builtin_interfaces/Time`` unchanged (integer nanoseconds inside, never float seconds).
Parameters are validated at start-up and, for the live ones, applied while it runs. See
docs/node.md for topics, parameters and QoS.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import Header, String
from std_srvs.srv import Trigger

from initsel_ros import timestamps
from initsel_ros.backlog import BacklogWatch
from initsel_ros.camera import MAX_FIELD_ANGLE_DEG, Intrinsics
from initsel_ros.errors import ConfigError, ImageConversionError, InitselError
from initsel_ros.image import (
    HOT_PIXEL_FRACTION,
    downscaled,
    tracking_factor,
    unbinned_pixels,
)
from initsel_ros.models import ModelSet
from initsel_ros.names import Mode
from initsel_ros.overlay import draw_frame_overlay
from initsel_ros.policy import Reason
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.params import (
    CAMERA_PARAMETERS,
    NODE_NAME,
    PARAMETERS,
    SPECS,
    ImageTransport,
    NodeSettings,
    parameter_sections,
    read_params_yaml,
    section_applies,
    unknown_parameters_note,
)
from initsel_ros.selector import FrameResult, Initialization, Selector
from initsel_ros.stamps import (
    CONSEQUENCES,
    RESTART_AFTER_LATE_FRAMES,
    StampCheck,
    StampIssue,
    StampMonitor,
)
from initsel_ros.status import FrameStatus, NodeCounters

try:  # tf2_msgs is not among the PyPI ROS wheels; /tf is broadcast only when it is installed
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

#: Name of the DiagnosticStatus published on /diagnostics.
DIAGNOSTIC_NAME = 'initsel_ros: selector'
#: Suffix of the compressed image topic (image_transport's convention).
COMPRESSED_SUFFIX = '/compressed'


def _keep_last(
    depth: int,
    reliability: ReliabilityPolicy,
    durability: DurabilityPolicy = DurabilityPolicy.VOLATILE,
) -> QoSProfile:
    """A QoS keeping the newest ``depth`` messages."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=reliability,
        durability=durability,
    )


#: Images: best effort (accepts best-effort and reliable publishers), newest two only.
IMAGE_QOS = _keep_last(2, ReliabilityPolicy.BEST_EFFORT)
#: Debug image: newest only, for viewers.
DEBUG_QOS = _keep_last(1, ReliabilityPolicy.BEST_EFFORT)
#: init/*: late subscribers still get the last initialization.
LATCHED_QOS = _keep_last(1, ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
STATUS_QOS = _keep_last(10, ReliabilityPolicy.RELIABLE)
TF_QOS = _keep_last(100, ReliabilityPolicy.RELIABLE)
WARN_THROTTLE_S = 5.0
#: A node that keeps dropping frames says so at most this often, seconds.
BACKLOG_REPEAT_S = 30.0
#: ``~/status``' source_warning clears after this many frames in a row from one camera.
SOURCE_WARNING_FRAMES = 300
#: A frame size seen again within this many frames, after another, is a second camera.
SOURCE_WINDOW_FRAMES = 30
#: Until the first frame and camera_info, the input topics are checked this often, seconds.
TOPIC_CHECK_PERIOD_S = 0.5
#: Without a frame after this long, the node says so, seconds.
NO_FRAMES_NOTE_S = 10.0
#: The executor's wait slice in main(), seconds: how soon a stop signal is seen.
SPIN_SLICE_S = 0.1
#: How long the first frame waits for its camera_info (use_camera_info), seconds; frames
#: arriving meanwhile are dropped as while any frame is processed.
CAMERA_INFO_WAIT_S = 0.2
#: How to give the node real intrinsics (logged and put in ~/status when they are guessed).
CALIBRATE_HINT = (
    'calibrate (ros2 run camera_calibration cameracalibrator) and publish the camera_info, '
    'or set camera.fx/fy/cx/cy/width/height/distortion (docs/node.md, Intrinsics)'
)


def _type_name(message_type: type) -> str:
    """'sensor_msgs/msg/Image' for sensor_msgs.msg.Image (how the ROS graph names types)."""
    package = message_type.__module__.split('.')[0]
    return f'{package}/msg/{message_type.__name__}'


def _transport_hint(type_name: str, transport: ImageTransport) -> str:
    """How to make the node take an image topic of ``type_name`` ('' when no hint)."""
    if type_name == 'sensor_msgs/msg/CompressedImage' and transport is ImageTransport.RAW:
        return (
            ' (the node takes CompressedImage on <base>/compressed, as image_transport names '
            'it: -p image_transport:=compressed with image_raw remapped to <base>; a '
            'CompressedImage topic named otherwise needs a republisher)'
        )
    if type_name == 'sensor_msgs/msg/Image' and transport is ImageTransport.COMPRESSED:
        return " (-p image_transport:=raw, or remap image_raw to the camera's base topic)"
    return ''


def _ignore_event(_status: object) -> None:
    """An event callback that does nothing (replaces rclpy's default warning)."""


class SelectorNode(Node):
    """ROS 2 wrapper around one :class:`Selector`; holds no vision logic.

    Raises:
        ConfigError: invalid parameters.
        ModelFileError: missing or malformed model file.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._settings = NodeSettings.from_values(self._declare_parameters())
        self._warn_uncalibrated_lens(self._settings.intrinsics, 'camera.*')
        # rcl hands over every override of this node; a name the node does not declare would
        # be dropped without a word (a typo in a params file sets nothing)
        overrides = getattr(self, '_parameter_overrides', {})
        unknown = {name for name in overrides if not self.has_parameter(name)}
        if unknown:
            self.get_logger().warning(
                f'ignoring parameters the selector does not have: '
                f'{unknown_parameters_note(sorted(unknown))}'
            )
        model_path = self._settings.model_path()
        models = ModelSet.load(model_path)
        self._selector = Selector(
            models, self._settings.intrinsics, self._settings.selector_config()
        )
        # The parameters' current values (the parameter callbacks' own copy; the worker uses
        # self._settings, replaced between frames).
        self._values = dict(self._settings.values)
        self._intrinsics_source = 'parameters'  # or 'camera_info'
        self._info_intrinsics: Intrinsics | None = None  # from the last valid camera_info
        self._camera_info_seen = False  # read by the parameter callback (camera.* live until)
        self._camera_info_arrived = threading.Event()  # the first valid camera_info
        self._waited_for_camera_info = not self._settings.use_camera_info  # (worker)

        # State shared between the callbacks and the worker.
        self._lock = threading.Lock()
        self._pending: Image | CompressedImage | None = None
        self._pending_intrinsics: Intrinsics | None = None
        self._pending_settings: NodeSettings | None = None
        self._reset_requested = False
        self._received = 0
        self._dropped = 0
        self._dropped_checked = 0  # the dropped count at the last stamp check
        self._skipped = 0
        self._processed = 0
        # Worker-only state.
        self._stamps = StampMonitor(self._tolerance_ns(self._settings))
        self._backlog = BacklogWatch()
        self._initializations = 0
        self._intrinsics_warning = ''  # why the intrinsics are a guess ('' when they are not)
        self._intrinsics_scaled = ''  # the images' size is not the intrinsics' ('' when it is)
        self._guess_logged = False
        self._tf_self_logged = False
        self._info_refused = ''  # why the last camera_info was refused ('' when it was not)
        self._depth_encoding_warned = False
        self._warned_at: dict[str, float] = {}  # each warning's last time (monotonic)
        # the last two frames' frame_id and size (a camera switching back and forth)
        self._sources: deque[tuple[str, int, int]] = deque(maxlen=SOURCE_WINDOW_FRAMES)
        self._source_warning = ''  # ~/status: the last switch between cameras, while recent
        self._frames_one_source = 0

        self._method_pub = self.create_publisher(String, 'init/method', LATCHED_QOS)
        self._pose_pub = self.create_publisher(PoseStamped, 'init/pose', LATCHED_QOS)
        self._points_pub = self.create_publisher(PointCloud2, 'init/points', LATCHED_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATUS_QOS)
        self._status_pub = self.create_publisher(String, '~/status', STATUS_QOS)
        # Drawn only while someone subscribes, after the decision has been published.
        self._debug_pub = self.create_publisher(Image, '~/debug_image', DEBUG_QOS)
        self._tf_pub = None
        self._tf_publisher()

        # Callbacks only store data; a worker thread of the node's own processes the newest
        # frame, so frames keep arriving (and being counted) while one is processed. (A guard
        # condition in a busy callback group would make rclpy's executor spin hot and starve
        # the worker of the GIL: measured 130 ms instead of 6 ms per frame.)
        self._input_group = MutuallyExclusiveCallbackGroup()
        self._wakeup = threading.Event()
        self._stopping = threading.Event()
        self._worker = threading.Thread(
            target=self._run_worker, name='initsel-selector-worker', daemon=True
        )
        if self._settings.image_transport is ImageTransport.COMPRESSED:
            self._image_topic = self.resolve_topic_name('image_raw') + COMPRESSED_SUFFIX
            image_type: type = CompressedImage
        else:
            self._image_topic = self.resolve_topic_name('image_raw')
            image_type = Image
        self.create_subscription(
            image_type,
            self._image_topic,
            self._on_image,
            IMAGE_QOS,
            callback_group=self._input_group,
        )
        if self._settings.use_camera_info:
            self.create_subscription(
                CameraInfo,
                'camera_info',
                self._on_camera_info,
                IMAGE_QOS,
                callback_group=self._input_group,
            )
        # a transient-local camera_info subscription, made once a latched publisher shows up
        # (for its last message, published before the node started); not before: every
        # volatile publisher would log an incompatible-QoS warning about it
        self._latched_info: Any = None
        self._image_type_name = _type_name(image_type)
        self._topic_notes: set[str] = set()
        self._started_at = time.monotonic()
        self._topic_check = self.create_timer(
            TOPIC_CHECK_PERIOD_S, self._check_input_topics, callback_group=self._input_group
        )
        self._check_input_topics()  # (a latched camera_info already in the graph: at once)
        self.create_service(Trigger, '~/reset', self._on_reset, callback_group=self._input_group)
        self.add_pre_set_parameters_callback(self._name_unknown_parameters)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        thresholds = self._selector.thresholds
        self.get_logger().info(
            f'ready: model file {model_path}, {image_type.__name__} on {self._image_topic}, '
            'thresholds '
            + ' '.join(f'{m}={thresholds[m]:.2f}' for m in sorted(thresholds))
            + f', R veto {sorted(self._settings.r_veto)}, mode {self._settings.mode.value}, '
            f'intrinsics from {"camera_info, else " if self._settings.use_camera_info else ""}'
            f'parameters ({self._settings.intrinsics.width}x{self._settings.intrinsics.height})'
            + (
                ''
                if self._tf_pub or not self._settings.publish_tf
                else '; tf2_msgs not installed: no /tf'
            )
        )
        self._worker.start()

    # ---------------------------------------------------------------------------- parameters
    def _declare_parameters(self) -> dict[str, Any]:
        """Declare every parameter of :data:`PARAMETERS`; their values by name.

        Live parameters can be set while the node runs; the others are read-only.

        Raises:
            ConfigError: a value of the wrong type (e.g. ``-p max_features:=many``).
        """
        values: dict[str, Any] = {}
        for spec in PARAMETERS:
            descriptor = ParameterDescriptor(
                description=spec.description + ('' if spec.live else ' (read-only: restart)'),
                additional_constraints=spec.constraints,
                read_only=not spec.live,
            )
            try:
                self.declare_parameter(spec.name, spec.default, descriptor)
                values[spec.name] = _plain(self.get_parameter(spec.name).value)
            except ParameterUninitializedException:
                # An empty list ('r_veto: []') has no type, so ROS leaves it unset.
                values[spec.name] = []
            except ParameterException as exc:
                raise ConfigError(
                    f'parameter {spec.name} (default {spec.default!r}): {exc}'
                ) from exc
        return values

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """On-set callback: accept a change only when the whole new set is valid.

        rclpy has already refused read-only parameters and wrong types; this runs the start-up
        validation (:meth:`NodeSettings.from_values`) on the current values plus the changes.
        """
        changes = _own(parameters)
        camera = sorted(CAMERA_PARAMETERS & changes.keys())
        if camera and self._camera_info_seen:
            return SetParametersResult(
                successful=False,
                reason=f'{", ".join(camera)}: the intrinsics come from camera_info now; '
                'camera.* apply only until the first camera_info arrives',
            )
        try:
            NodeSettings.from_values({**self._values, **changes})
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        """Post-set callback: hand the new settings to the worker (used from the next frame)."""
        changes = _own(parameters)
        if not changes:
            return
        self._values.update(changes)
        settings = NodeSettings.from_values(self._values)
        with self._lock:
            self._pending_settings = settings
        self._wakeup.set()
        self.get_logger().info(
            'parameters set (from the next frame on): '
            + ', '.join(f'{name}={value!r}' for name, value in sorted(changes.items()))
        )

    @staticmethod
    def _tolerance_ns(settings: NodeSettings) -> int:
        return timestamps.seconds_to_ns(settings.restart_tolerance_s)

    def _apply_settings(self, settings: NodeSettings) -> None:
        """Worker: use validated live settings from this frame on."""
        previous, self._settings = self._settings, settings
        self._selector.update_config(settings.selector_config())
        self._stamps.restart_tolerance_ns = self._tolerance_ns(settings)
        if self._intrinsics_source == 'parameters' and not settings.intrinsics.same_camera(
            previous.intrinsics
        ):
            self.get_logger().info(
                f'camera.* changed the intrinsics to {settings.intrinsics}: '
                + self._what_new_intrinsics_do()
            )
            self._warn_uncalibrated_lens(settings.intrinsics, 'camera.*')
        self._tf_publisher()

    def _what_new_intrinsics_do(self) -> str:
        """The log's words for what other intrinsics do to the selector now (they reach it
        fitted to the frames' size: a camera_info of another size for the same camera, its
        intrinsics scaled alike, changes nothing)."""
        if self._selector.initialized and self._settings.mode is Mode.ONCE:
            return (
                'a new reference once ~/reset starts over (mode once has initialized), if '
                "they change the intrinsics fitted to the frames' size"
            )
        return "a new reference if they change the intrinsics fitted to the frames' size"

    def _tf_publisher(self) -> Any:
        """The /tf publisher, created on first need; None when off or tf2_msgs is missing."""
        if self._tf_pub is None and self._settings.publish_tf and TFMessage is not None:
            self._tf_pub = self.create_publisher(TFMessage, '/tf', TF_QOS)
        return self._tf_pub if self._settings.publish_tf else None

    # ----------------------------------------------------------------------------- callbacks
    def _on_image(self, msg: Image | CompressedImage) -> None:
        """Keep only the newest frame; an overwritten, unprocessed frame counts as dropped."""
        with self._lock:
            self._received += 1
            if self._pending is not None:
                self._dropped += 1
            self._pending = msg
        self._wakeup.set()

    def _on_camera_info(self, msg: CameraInfo) -> None:
        try:
            intrinsics = conv.camera_info_to_intrinsics(msg)
        except ConfigError as exc:
            self._info_refused = str(exc)
            self._warn_each(
                f'camera_info: {exc}',
                f'ignoring camera_info: {exc}; keeping the {self._intrinsics_source} intrinsics',
            )
            return
        self._info_refused = ''
        with self._lock:
            self._pending_intrinsics = intrinsics
        self._camera_info_seen = True
        self._camera_info_arrived.set()

    def _check_input_topics(self) -> None:
        """Timer, until the first frame and a camera_info: listen to a latched camera_info
        publisher's last message, and say why no frame arrives where the graph shows it (a
        publisher of another message type on the image or camera_info topic, an image topic
        ending in /compressed/compressed, no frame after NO_FRAMES_NOTE_S)."""
        try:
            info_topic = self.resolve_topic_name('camera_info')
            if self._settings.use_camera_info and not self._camera_info_seen:
                self._listen_to_latched_camera_info(info_topic)
            elif self._latched_info is not None:  # done: a publisher joining later won't warn
                self.destroy_subscription(self._latched_info)
                self._latched_info = None
            if self._received:
                info_done = self._camera_info_seen or not self._settings.use_camera_info
                if info_done and self._latched_info is None:
                    self._topic_check.cancel()
                return
            for key, text in self._input_topic_notes(info_topic):
                if key not in self._topic_notes:
                    self._topic_notes.add(key)
                    self.get_logger().warning(text)
        except Exception as exc:  # a graph query must never take the node down
            self.get_logger().warning(
                f'input topic check failed: {type(exc).__name__}: {exc}',
                throttle_duration_sec=WARN_THROTTLE_S,
            )

    def _listen_to_latched_camera_info(self, info_topic: str) -> None:
        """Subscribe transient local to camera_info while the graph holds latched publishers
        only (a volatile one is heard anyway, and would warn of the mismatch)."""
        if self._latched_info is not None:
            return
        durabilities = {
            info.qos_profile.durability for info in self.get_publishers_info_by_topic(info_topic)
        }
        if durabilities == {DurabilityPolicy.TRANSIENT_LOCAL}:
            self._latched_info = self.create_subscription(
                CameraInfo,
                'camera_info',
                self._on_camera_info,
                LATCHED_QOS,
                callback_group=self._input_group,
                # (volatile publishers on the same topic do not match it: said, not warned)
                event_callbacks=SubscriptionEventCallbacks(incompatible_qos=_ignore_event),
            )

    def _input_topic_notes(self, info_topic: str) -> list[tuple[str, str]]:
        """(what it is about, said once; the text) of each problem the graph shows."""
        wanted = {self._image_topic: self._image_type_name}
        if self._settings.use_camera_info:
            wanted[info_topic] = 'sensor_msgs/msg/CameraInfo'
        notes = []
        right_type = 0  # image publishers of the type the node takes
        for topic, type_name in wanted.items():
            for info in self.get_publishers_info_by_topic(topic):
                if info.topic_type == type_name:
                    right_type += topic == self._image_topic
                    continue
                hint = (
                    _transport_hint(info.topic_type, self._settings.image_transport)
                    if topic == self._image_topic
                    else ''
                )
                notes.append(
                    (
                        f'{topic} {info.topic_type}',
                        f'{topic} has a publisher of {info.topic_type} ({info.node_name}), but '
                        f'the selector takes {type_name} there: nothing arrives from it{hint}',
                    )
                )
        if self._image_topic.endswith(COMPRESSED_SUFFIX * 2):
            notes.append(
                (
                    'compressed twice',
                    f'the image topic is {self._image_topic}: with image_transport compressed, '
                    "remap image_raw to the camera's base topic (the node adds /compressed)",
                )
            )
        if not notes and time.monotonic() - self._started_at >= NO_FRAMES_NOTE_S:
            notes.append(
                (
                    'no frames',
                    f'no frame on {self._image_topic} after {NO_FRAMES_NOTE_S:g} s: '
                    + (
                        f'{right_type} publisher{"s" if right_type != 1 else ""} of '
                        f'{self._image_type_name} there (paused, or frames larger than the '
                        'transport takes: see README, Transport)'
                        if right_type
                        else 'no publisher of the type the node takes; remap image_raw to the '
                        'camera topic'
                    ),
                )
            )
        return notes

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            self._reset_requested = True
            if self._pending is not None:  # dropped: the next frame to arrive is the reference
                self._dropped += 1
                self._pending = None
        response.success = True
        response.message = 'the next frame becomes the reference'
        self.get_logger().info('reset requested: the next frame becomes the reference')
        return response

    # -------------------------------------------------------------------------------- worker
    def _run_worker(self) -> None:
        """Worker thread: wait for a frame, process the newest, until the node is destroyed."""
        while not self._stopping.is_set():
            if not self._wakeup.wait(timeout=0.1):
                continue
            self._wakeup.clear()
            try:
                self._work()
            except Exception as exc:  # never let the worker die silently
                self.get_logger().error(
                    f'worker error: {type(exc).__name__}: {exc}',
                    throttle_duration_sec=WARN_THROTTLE_S,
                )

    def destroy_node(self) -> None:
        """Stop the worker thread, then destroy the node."""
        self._stopping.set()
        self._wakeup.set()
        if self._worker.is_alive() and self._worker is not threading.current_thread():
            self._worker.join(timeout=5.0)
        super().destroy_node()

    def _work(self) -> None:
        """Process the newest frame until none is pending (worker thread)."""
        while True:
            with self._lock:
                msg, self._pending = self._pending, None
                intrinsics, self._pending_intrinsics = self._pending_intrinsics, None
                settings, self._pending_settings = self._pending_settings, None
                reset, self._reset_requested = self._reset_requested, False
                dropped = self._dropped
            try:
                if settings is not None:
                    self._apply_settings(settings)
                if reset:
                    self._selector.reset()
                    self._stamps.forget_last()
                if intrinsics is not None:
                    self._use_camera_info(intrinsics)
            except Exception as exc:  # the frame taken must still end in a counter
                self.get_logger().error(
                    f'applying new settings, a reset or a camera_info failed: '
                    f'{type(exc).__name__}: {exc}',
                    throttle_duration_sec=WARN_THROTTLE_S,
                )
                if msg is not None:
                    self._skipped += 1
                    self._publish_status(
                        msg.header.stamp, None, dropped, Reason.INTERNAL_ERROR, repr(exc)
                    )
                continue
            if msg is None:
                return
            if not self._waited_for_camera_info:
                self._wait_for_camera_info()
            started = time.perf_counter()
            self._process(msg, dropped)
            self._note_backlog(time.perf_counter() - started)

    def _wait_for_camera_info(self) -> None:
        """Worker, first frame: give its camera_info :data:`CAMERA_INFO_WAIT_S` to arrive.

        A camera publishes the two on separate topics, so the first frame can come first;
        processed with the parameters' intrinsics, it would be a reference that the
        camera_info then drops (a new reference one frame later, which made replays differ
        from run to run). Once only: later frames never wait.
        """
        self._waited_for_camera_info = True
        if not self._camera_info_arrived.wait(CAMERA_INFO_WAIT_S):
            refused = self._info_refused
            self.get_logger().info(
                f'no valid camera_info within {CAMERA_INFO_WAIT_S:g} s of the first frame'
                + (f' (one was refused: {refused})' if refused else '')
                + ': the camera.* parameters are used until one arrives'
            )
            return
        with self._lock:
            intrinsics, self._pending_intrinsics = self._pending_intrinsics, None
        if intrinsics is not None:
            self._use_camera_info(intrinsics)

    def _use_camera_info(self, intrinsics: Intrinsics) -> None:
        """Worker: intrinsics of a valid camera_info (another camera starts a new reference)."""
        if self._intrinsics_source != 'camera_info' or self._info_intrinsics is None:
            replaced = self._processed and not intrinsics.same_camera(self._base_intrinsics())
            self.get_logger().info(
                f'intrinsics from camera_info: {intrinsics}'
                + (
                    f', after {self._processed} frame{"s" if self._processed != 1 else ""} '
                    "with the camera.* parameters': "
                    f'{self._what_new_intrinsics_do()}'
                    if replaced
                    else ''
                )
            )
            self._warn_uncalibrated_lens(intrinsics, 'camera_info')
        elif not intrinsics.same_camera(self._info_intrinsics):
            self.get_logger().info(
                f'camera_info changed the intrinsics from {self._info_intrinsics} to '
                f'{intrinsics}: {self._what_new_intrinsics_do()} (at most every '
                f'{WARN_THROTTLE_S:g} s)',
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            self._warn_uncalibrated_lens(intrinsics, 'camera_info')
        self._intrinsics_source = 'camera_info'
        self._info_intrinsics = intrinsics

    def _name_unknown_parameters(self, parameters: list[Parameter]) -> list[Parameter]:
        """Pre-set callback: log the names of parameters the node does not have, with the one
        each was probably meant to be (rclpy refuses them with an empty list of names), and
        pass the list on unchanged."""
        unknown = [p.name for p in parameters if not self.has_parameter(p.name)]
        if unknown:
            self.get_logger().warning(
                f'refused: no such parameter: {unknown_parameters_note(unknown)}'
            )
        return parameters

    def _warn_each(self, key: str, text: str) -> None:
        """Log ``text`` as a warning at most every :data:`WARN_THROTTLE_S` per ``key`` (rclpy
        throttles per call site, so one site's different problems would hide each other)."""
        now = time.monotonic()
        if now - self._warned_at.get(key, -math.inf) < WARN_THROTTLE_S:
            return
        if len(self._warned_at) > 64:
            self._warned_at.clear()
        self._warned_at[key] = now
        self.get_logger().warning(text)

    def _refused_note(self) -> str:
        """The status' word on a refused camera_info ('' when the last was valid)."""
        refused = self._info_refused
        if not refused:
            return ''
        return (
            f'the last camera_info was refused ({refused}): the {self._intrinsics_source} '
            'intrinsics are used'
        )

    def _note_source(self, frame_id: str, width: int, height: int) -> None:
        """Worker: warn when the frames come from more than one camera (another frame_id, or a
        size back and forth): each switch of size starts a new reference, so two publishers
        on one topic keep the selector from ever initializing. ``~/status`` says so
        (``source_warning``) until :data:`SOURCE_WARNING_FRAMES` frames in a row come from
        one camera."""
        source = (frame_id, width, height)
        last = self._sources[-1] if self._sources else None
        back = source in self._sources  # (a size seen within the window, left, and back)
        self._sources.append(source)
        if last is None or last == source or (last[0] == frame_id and not back):
            # the same camera (a size change alone, not back and forth: one camera reconfigured)
            self._frames_one_source += 1
            if self._frames_one_source >= SOURCE_WARNING_FRAMES:
                self._source_warning = ''
            return
        self._frames_one_source = 0
        self._source_warning = (
            f"images from more than one camera on the image topic: frame_id '{frame_id}' "
            f"{width}x{height} after '{last[0]}' {last[1]}x{last[2]}; the selector follows "
            'one camera, and every switch of size starts a new reference'
        )
        self._warn_each('sources', self._source_warning)

    def _warn_uncalibrated_lens(self, intrinsics: Intrinsics, source: str) -> None:
        """Warn of a wide lens given without its distortion (``Intrinsics``' note)."""
        note = intrinsics.uncalibrated_lens_note()
        if note:
            self.get_logger().warning(f'{source}: {note}', throttle_duration_sec=WARN_THROTTLE_S)

    def _base_intrinsics(self) -> Intrinsics:
        """The intrinsics as given (camera_info or camera.*), before fitting the image size."""
        if self._intrinsics_source == 'camera_info' and self._info_intrinsics is not None:
            return self._info_intrinsics
        return self._settings.intrinsics

    def _process(self, msg: Image | CompressedImage, dropped: int) -> None:
        """Worker: one frame ends processed, or skipped with a status saying why."""
        stamp = msg.header.stamp
        stamp_ns = conv.stamp_to_ns(stamp)
        check = self._check_stamp(stamp, stamp_ns, dropped)
        if check.out_of_order:
            self._skipped += 1
            self._publish_status(
                stamp,
                None,
                dropped,
                Reason.OUT_OF_ORDER,
                f'{check.back_ns / 1e9:.9f} s older than the latest frame (at most '
                f'restart_tolerance_s = {self._settings.restart_tolerance_s:g} s: jitter)',
            )
            return
        try:
            image = self._to_image(msg)
            self._note_source(msg.header.frame_id, image.shape[1], image.shape[0])
            factor = tracking_factor(image.shape[1], self._settings.max_tracking_width)
            self._fit_intrinsics(image.shape[1], image.shape[0], factor)
            image = downscaled(image, factor)
            result = self._selector.process(image, stamp_ns)
        except ImageConversionError as exc:
            self._skipped += 1
            self.get_logger().warning(
                f'skipping image: {exc}', throttle_duration_sec=WARN_THROTTLE_S
            )
            self._publish_status(stamp, None, dropped, Reason.SKIPPED_IMAGE, str(exc))
            return
        except Exception as exc:  # keep the node alive; the status says what went wrong
            self._skipped += 1
            self.get_logger().error(
                f'selector failed on a frame: {type(exc).__name__}: {exc}',
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            self._publish_status(stamp, None, dropped, Reason.INTERNAL_ERROR, repr(exc))
            return
        self._processed += 1
        reason, detail = result.decision.reason, result.decision.detail
        if result.decision.reason is Reason.VERIFICATION_FAILED:
            self.get_logger().info(f'{reason.value}: {detail}; looking on')
        if result.initialization is not None:
            try:
                self._publish_initialization(
                    result.initialization,
                    stamp,
                    msg.header.frame_id,
                    factor,
                )
            except Exception as exc:  # never claim an initialization nobody received
                self._selector.reset()
                self.get_logger().error(
                    f'publishing the initialization failed: {type(exc).__name__}: {exc}; '
                    'starting over',
                    throttle_duration_sec=WARN_THROTTLE_S,
                )
                reason = Reason.INTERNAL_ERROR
                detail = f'publishing the initialization failed: {exc!r}'
                result = FrameResult(
                    result.frame_index, result.stamp_ns, result.reference_stamp_ns, result.decision
                )
        self._publish_status(stamp, result, dropped, reason, detail)
        if self._debug_pub.get_subscription_count() > 0:
            self._publish_debug_image(image, result, msg)

    def _note_backlog(self, seconds: float) -> None:
        """Worker, after a frame took ``seconds`` (publishing included): warn when a window
        of frames dropped a steady share of them (``backlog.BacklogWatch``), at most every
        :data:`BACKLOG_REPEAT_S`."""
        with self._lock:
            received, dropped = self._received, self._dropped
        backlog = self._backlog.processed(received, dropped, seconds, time.monotonic())
        if backlog is not None:
            self.get_logger().warning(
                backlog.message(self._settings.max_tracking_width),
                throttle_duration_sec=BACKLOG_REPEAT_S,
            )

    def _to_image(self, msg: Image | CompressedImage) -> np.ndarray:
        """The selector's input (uint8 grey or BGR), decoded by :mod:`initsel_ros.image`.

        16-bit pixels are scaled by the selector's :class:`~initsel_ros.image.BitDepth`.
        """
        bit_depth = self._selector.bit_depth
        before = bit_depth.bits
        max_pixels = self._settings.max_image_pixels
        if isinstance(msg, CompressedImage):
            info = self._info_intrinsics if self._intrinsics_source == 'camera_info' else None
            image = conv.compressed_to_cv(
                msg,
                bit_depth,
                max_pixels=max_pixels,
                size=None if info is None else (info.width, info.height),
            )
        else:
            image = conv.image_to_cv(msg, bit_depth, max_pixels=max_pixels)
            if msg.encoding.upper() == '16UC1' and not self._depth_encoding_warned:
                self._depth_encoding_warned = True
                self.get_logger().warning(
                    '16UC1 images: read as 16-bit intensity, but 16UC1 is what depth cameras '
                    'publish depth in (REP 118); if the image topic is a depth image, remap it '
                    'to the intensity or colour image: a depth map has few corners to track'
                )
        if bit_depth.bits != before and not bit_depth.fixed:
            rise = f', up from {before}: {bit_depth.frames} frames in a row needed more'
            text = (
                f'16-bit images: scaling {bit_depth.bits} significant bits to 8 (bit_depth 0: '
                f'the bits that hold all but {HOT_PIXEL_FRACTION:.1%} of the pixels'
                f'{rise if before else ""}; set bit_depth to fix it)'
            )
            # one severity per call site: rclpy refuses a call site that changes it
            if before:
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)
        return image

    def _check_stamp(self, stamp: Time, stamp_ns: int, dropped: int) -> StampCheck:
        """Log each kind of unusual stamp once, and restarts (at most every 5 s); ``dropped``:
        the node's dropped-frame count when it took this frame.

        A frame a little older than the latest (within ``restart_tolerance_s``) is out of order
        (the caller skips it); a jump back further is a restart: a new reference, but in mode
        once an initialization is kept until ``~/reset``.
        """
        # the frames the node itself dropped before this one are no gap in the stream
        check = self._stamps.check(stamp_ns, unchecked=dropped - self._dropped_checked)
        self._dropped_checked = dropped
        back = f' by {check.back_ns / 1e9:.9f} s' if check.back_ns else ''
        for issue in check.new:
            if issue is not StampIssue.RESTART:
                self.get_logger().warning(
                    f'{issue.value} image stamp (sec {stamp.sec}, nanosec {stamp.nanosec})'
                    f'{back}: {CONSEQUENCES[issue]} (logged once; counted in ~/status '
                    'stamp_issues)'
                )
        if check.restart:
            kept = self._selector.initialized and self._settings.mode is Mode.ONCE
            tolerance = self._settings.restart_tolerance_s
            self.get_logger().warning(
                f'restart image stamp (sec {stamp.sec}, nanosec {stamp.nanosec}){back}, '
                + (
                    f'{RESTART_AFTER_LATE_FRAMES} frames in a row went on from a little back'
                    if check.late_restart
                    else f'more than restart_tolerance_s = {tolerance:g} s'
                )
                + ': '
                + (
                    'the initialization is kept (mode once) until ~/reset'
                    if kept
                    else 'a new reference is taken'
                )
                + f' (restart {self._stamps.counts[StampIssue.RESTART.value]} of this stream)',
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            self._selector.restart()
        return check

    def _fit_intrinsics(self, width: int, height: int, factor: int = 1) -> None:
        """Give the selector the intrinsics for this image size (scaled when they differ),
        binned by ``factor`` where ``max_tracking_width`` shrinks the frames.

        The TUM defaults without a camera_info are a guess: scaled to another size, or at
        their own while a camera_info is expected (``use_camera_info``; without it the
        parameters are the camera); warned once, loudly, and reported in every status until
        real intrinsics arrive.
        """
        base = self._base_intrinsics()
        wanted = base
        self._intrinsics_warning = ''
        self._intrinsics_scaled = ''
        same_size = (width, height) == (base.width, base.height)
        guessed = (
            self._intrinsics_source == 'parameters'
            and self._settings.default_intrinsics
            and (self._settings.use_camera_info or not same_size)
        )
        if guessed:
            fr3 = f'the fr3 camera, {base.width}x{base.height}, fx {base.fx:g}'
            self._intrinsics_warning = (
                'no camera_info and camera.* are the TUM fr3 defaults: the pose uses guessed '
                + (
                    f'intrinsics ({fr3}); {CALIBRATE_HINT} (a TUM fr3 camera: use_camera_info '
                    'false)'
                    if same_size
                    else f'intrinsics ({fr3}, as a {width}x{height} sensor of its field of '
                    f'view); {CALIBRATE_HINT}'
                )
            )
            if not self._guess_logged:
                self._guess_logged = True
                self.get_logger().warning(f'GUESSED INTRINSICS: {self._intrinsics_warning}')
        if not same_size:
            if not guessed:
                self._intrinsics_scaled = (
                    f'images are {width}x{height} but the {self._intrinsics_source} intrinsics '
                    f'are for {base.width}x{base.height}: scaled to the images (right for a '
                    'resized image, wrong for a cropped one)'
                )
                self.get_logger().warning(
                    self._intrinsics_scaled, throttle_duration_sec=WARN_THROTTLE_S
                )
            try:  # a guess is a sensor of that size; given intrinsics, the image resized
                wanted = (
                    base.resized_sensor(width, height) if guessed else base.scaled(width, height)
                )
            except ConfigError as exc:
                raise ImageConversionError(
                    f'a {width}x{height} image does not fit the intrinsics: {exc}'
                ) from exc
        try:  # shrunk for tracking: no guess, no warning
            wanted = wanted.binned(factor)
        except ConfigError as exc:
            raise ImageConversionError(
                f'a {width}x{height} image shrunk {factor} times does not fit the intrinsics: '
                f'{exc}'
            ) from exc
        if not wanted.same_camera(self._selector.intrinsics):
            self._selector.set_intrinsics(wanted)
            angle = wanted.corner_field_angle_deg
            if angle > MAX_FIELD_ANGLE_DEG:
                self.get_logger().warning(
                    f'the image corners are {angle:.0f} degrees off the optical axis: features '
                    f'are tracked only within {MAX_FIELD_ANGLE_DEG:.0f} degrees of it (further '
                    'out they carry little geometry, and past 90 degrees none)'
                )

    def _publish_debug_image(
        self, image: np.ndarray, result: FrameResult, msg: Image | CompressedImage
    ) -> None:
        """Tracks, probabilities and the reason drawn on the frame (see overlay.py)."""
        try:
            debug = draw_frame_overlay(image, result)
            self._debug_pub.publish(
                conv.numpy_to_image(
                    debug, 'bgr8', stamp=msg.header.stamp, frame_id=msg.header.frame_id
                )
            )
        except Exception as exc:  # a drawing problem must never stop the selector
            self.get_logger().error(
                f'debug image failed: {type(exc).__name__}: {exc}',
                throttle_duration_sec=WARN_THROTTLE_S,
            )

    # ---------------------------------------------------------------------------- publishing
    def _publish_status(
        self, stamp: Time, result: FrameResult | None, dropped: int, reason: Reason, detail: str
    ) -> None:
        """``~/status`` (JSON) and ``/diagnostics`` for one frame, stamped with its stamp."""
        counters = NodeCounters(
            initialized=bool(self._selector.initialized),
            initializations=self._initializations,
            received_frames=self._received,
            processed_frames=self._processed,
            dropped_frames=dropped,
            skipped_frames=self._skipped,
            missing_frames=self._stamps.missing,
            intrinsics_source=self._intrinsics_source,
            intrinsics=self._selector.intrinsics.to_dict(),
            intrinsics_guessed=bool(self._info_refused or self._intrinsics_warning),
            intrinsics_warning='; '.join(
                filter(
                    None,
                    (self._refused_note(), self._intrinsics_warning, self._intrinsics_scaled),
                )
            ),
            bit_depth=self._selector.bit_depth.bits or None,
            stamp_issues=self._stamps.counts,
            source_warning=self._source_warning,
        )
        status = FrameStatus.from_result(
            result,
            stamp_sec=stamp.sec,
            stamp_nanosec=stamp.nanosec,
            counters=counters,
            reason=reason,
            detail=detail,
        )
        self._status_pub.publish(String(data=status.to_json()))

        diag = DiagnosticStatus(
            level=DiagnosticStatus.WARN
            if status.diagnostic_level == 'WARN'
            else DiagnosticStatus.OK,
            name=DIAGNOSTIC_NAME,
            message=status.reason.value,
            hardware_id=self.get_fully_qualified_name(),
        )
        diag.values = [KeyValue(key=k, value=v) for k, v in status.diagnostic_values().items()]
        array = DiagnosticArray(status=[diag])
        array.header.stamp = stamp
        self._diag_pub.publish(array)

    def _publish_initialization(
        self,
        init: Initialization,
        stamp: Time,
        image_frame_id: str,
        factor: int = 1,
    ) -> None:
        """init/method, init/pose (current frame's stamp), init/points (reference's), /tf;
        ``factor``: how many times the frames were shrunk for tracking
        (``max_tracking_width``): init/points gives its pixels in the frames' own."""
        frame_id = self._settings.reference_frame_id
        current_stamp = (
            stamp if conv.stamp_to_ns(stamp) == init.stamp_ns else conv.ns_to_stamp(init.stamp_ns)
        )
        current = Header(stamp=current_stamp, frame_id=frame_id)
        reference = Header(stamp=conv.ns_to_stamp(init.reference_stamp_ns), frame_id=frame_id)
        pose = conv.make_pose_stamped(init.R, init.t, current)
        points = conv.make_point_cloud(
            init.points,
            unbinned_pixels(init.pixels_ref, factor),
            unbinned_pixels(init.pixels_cur, factor),
            reference,
        )
        self._method_pub.publish(String(data=init.method.value))
        self._pose_pub.publish(pose)
        self._points_pub.publish(points)
        child = self._settings.camera_frame_id or image_frame_id or 'camera_optical_frame'
        tf_pub = self._tf_publisher()
        if tf_pub is not None and child != frame_id:
            tf_pub.publish(
                TFMessage(transforms=[conv.make_transform(init.R, init.t, current, child)])
            )
        elif tf_pub is not None and not self._tf_self_logged:
            self._tf_self_logged = True
            self.get_logger().warning(
                f"no /tf for this initialization: the images' frame id is reference_frame_id "
                f'({frame_id!r}), a transform from a frame to itself; set camera_frame_id '
                '(logged once)'
            )
        self._initializations += 1
        _, position = conv.camera_pose_in_reference(init.R, init.t)
        direction = position / max(float(np.linalg.norm(position)), 1e-12)
        p = init.probabilities
        self.get_logger().info(
            f'initialized with {init.method.value} '
            f'(p_F={p.get("F", 0):.2f} p_E={p.get("E", 0):.2f} p_H={p.get("H", 0):.2f} '
            f'p_R={p.get("R", 0):.2f}): baseline direction '
            f'({direction[0]:+.2f}, {direction[1]:+.2f}, {direction[2]:+.2f}) in {frame_id}, '
            f'{len(init.points)} points, parallax {init.parallax_deg:.1f} deg, '
            f'{init.frames_since_reference} frames since the reference'
            + (
                f'; chosen because {init.selection.why} [{init.selection.summary()}]'
                if init.selection is not None
                else ''
            )
            + (
                f'; refined{" as one plane" if init.refinement.as_plane else ""}: RMS '
                f'{init.refinement.rms_before_px:.2f} -> '
                f'{init.refinement.rms_after_px:.2f} px, direction of motion +-'
                f'{init.refinement.translation_sigma_deg:.2f} deg'
                if init.refinement is not None
                else ''
            )
            + (
                f'; {init.points_on_plane} of {len(init.points)} points placed on the plane'
                if init.points_on_plane
                else ''
            )
            + (
                f'; verified on {len(init.verification)} frames (last RMS '
                f'{init.verification[-1].rms_px:.2f} px)'
                if init.verification
                else ''
            )
        )


def _own(parameters: list[Parameter]) -> dict[str, Any]:
    """The node's own parameters among ``parameters`` (not rclpy's, e.g. use_sim_time)."""
    return {p.name: _plain(p.value) for p in parameters if p.name in SPECS}


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (array.array -> list)."""
    if value is not None and not isinstance(value, (str, bytes, bool, int, float)):
        try:
            return list(value)
        except TypeError:
            return value
    return value


def _parse_cli(argv: Sequence[str]) -> argparse.Namespace:
    """Non-ROS command-line flags (only --help); ROS arguments are removed first."""
    lines = [
        f'  {s.name} (default {s.default!r}{"" if s.live else ", read-only"}): {s.description}'
        for s in PARAMETERS
    ]
    parser = argparse.ArgumentParser(
        prog='selector',
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            'initsel_ros selector node: decides when and with which method (F, E, H) a '
            'monocular SLAM system initializes.\n\n'
            'Topics: subscribes image_raw (or image_raw/compressed with '
            'image_transport:=compressed), camera_info; publishes init/method, init/pose, '
            'init/points, ~/status, /diagnostics, ~/debug_image (while subscribed; and /tf); '
            'service ~/reset.\n'
            'Usage: selector --ros-args -r image_raw:=/camera/image_raw '
            '--params-file config/selector.yaml -p mode:=continuous\n'
            'Parameters not marked read-only can be changed while it runs (ros2 param set).'
        ),
        epilog='parameters (set with -p NAME:=VALUE or --params-file):\n' + '\n'.join(lines),
    )
    return parser.parse_args(list(argv)[1:])


def params_files(argv: Sequence[str]) -> list[str]:
    """The ``--params-file`` arguments inside ``--ros-args`` sections of ``argv``."""
    files, in_ros = [], False
    tokens = list(argv)
    for i, token in enumerate(tokens):
        if token == '--ros-args':
            in_ros = True
        elif token == '--':
            in_ros = False
        elif in_ros and token == '--params-file' and i + 1 < len(tokens):
            files.append(tokens[i + 1])
    return files


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _check_ros_arguments(argv: Sequence[str]) -> dict[str, Any]:
    """Parse every ``--params-file`` before rcl does, for a one-line syntax error; their
    contents by path.

    Raises:
        ConfigError: an unreadable or syntactically invalid parameter file.
    """
    return {path: read_params_yaml(path) for path in params_files(argv)}


def _warn_of_unused_params_files(files: dict[str, Any], node: Node) -> None:
    """A ``--params-file`` (``files``: contents by path, :func:`_check_ros_arguments`) none
    of whose sections names this node sets nothing: say so."""
    name = node.get_fully_qualified_name()
    for path, data in files.items():
        sections = parameter_sections(data)
        if not any(section_applies(section, name) for section in sections):
            node.get_logger().warning(
                f'{path}: no section for node {name} (sections: '
                f'{", ".join(sections) or "none"}): none of its parameters are applied'
            )


def main(args: Sequence[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; 1 on bad parameters or a bad model file.

    The signals are handled here, not by rclpy's handlers: the executor spins in short slices
    and stops when one arrives. (With rclpy's own handlers the node sometimes missed a SIGTERM
    while its executor waited: about one stop in eight hung in a replay test.)
    """
    argv = list(sys.argv if args is None else args)
    logger = get_logger(NODE_NAME)
    try:
        files = _check_ros_arguments(argv)
        non_ros = remove_ros_args(argv)
    except ConfigError as exc:
        logger.error(f'cannot start: {exc}')
        return 1
    except Exception as exc:  # rcl's argument errors (RCLInvalidROSArgsError, ...)
        logger.error(f'cannot start: invalid ROS arguments: {_first_line(exc)}')
        return 1
    _parse_cli(non_ros)
    stop = threading.Event()
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, lambda *_: stop.set())
    node = None
    status = 0
    try:
        try:
            rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
        except Exception as exc:  # rcl's argument errors (RCLError, ROSArgsError, ...)
            logger.error(f'cannot start: invalid ROS arguments: {_first_line(exc)}')
            return 1
        node = SelectorNode()
        _warn_of_unused_params_files(files, node)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_SLICE_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except InitselError as exc:
        logger.error(f'cannot start: {exc}')
        status = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return status


__all__ = [
    'DIAGNOSTIC_NAME',
    'IMAGE_QOS',
    'LATCHED_QOS',
    'STATUS_QOS',
    'SelectorNode',
    'main',
    'params_files',
]

if __name__ == '__main__':
    sys.exit(main())
