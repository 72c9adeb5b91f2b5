"""The ``selector`` node: decides, live from a camera stream, when and how to initialize.

Subscribes ``image_raw`` (and ``camera_info``), runs :class:`initsel_ros.selector.Selector` on
the newest frame and publishes ``init/method``, ``init/pose``, ``init/points`` (latched) when it
initializes, plus a status on ``/diagnostics`` and ``~/status`` for every frame. See
docs/node.md for topics, parameters and QoS.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Header, String
from std_srvs.srv import Trigger

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError, ImageConversionError, InitselError
from initsel_ros.models import ModelSet
from initsel_ros.overlay import draw_selector_overlay
from initsel_ros.policy import Reason
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.params import NODE_NAME, PARAMETERS, Mode, NodeSettings
from initsel_ros.selector import FrameResult, Initialization, Selector

try:  # tf2_msgs is not among the PyPI ROS wheels; /tf is broadcast only when it is installed
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

#: Name of the DiagnosticStatus published on /diagnostics.
DIAGNOSTIC_NAME = 'initsel_ros: selector'
#: Status reasons of frames that never reached the selector.
SKIPPED_IMAGE = 'image skipped'
INTERNAL_ERROR = 'internal error'
#: Reasons reported with level WARN (everything else is OK).
WARN_REASONS = frozenset({Reason.TOO_FEW_TRACKS.value, Reason.POSE_FAILED.value, SKIPPED_IMAGE})

#: Images: best effort (accepts best-effort and reliable publishers), newest two only.
IMAGE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=2, reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
#: Debug image: newest only, for viewers.
DEBUG_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
#: init/*: late subscribers still get the last initialization.
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
TF_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: A stamp this far (seconds) before the previous one is a restart (bag loop): start over.
TIME_JUMP_BACK_S = 1.0
WARN_THROTTLE_S = 5.0
#: The executor's wait slice in main(), seconds: how soon a stop signal is seen.
SPIN_SLICE_S = 0.1


class SelectorNode(Node):
    """ROS 2 wrapper around one :class:`Selector`; holds no vision logic.

    Raises:
        ConfigError: invalid parameters.
        ModelFileError: missing or malformed model file.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._settings = NodeSettings.from_values(self._declare_parameters())
        model_path = self._settings.model_path()
        models = ModelSet.load(model_path)
        self._selector = Selector(models, self._settings.intrinsics,
                                  self._settings.selector_config())
        self._intrinsics_source = 'parameters'

        # State shared between the subscription callbacks and the worker.
        self._lock = threading.Lock()
        self._pending: Image | None = None
        self._pending_intrinsics: Intrinsics | None = None
        self._reset_requested = False
        self._received = 0
        self._dropped = 0
        self._skipped = 0
        # Worker-only state.
        self._last_stamp = -math.inf
        self._initializations = 0

        self._method_pub = self.create_publisher(String, 'init/method', LATCHED_QOS)
        self._pose_pub = self.create_publisher(PoseStamped, 'init/pose', LATCHED_QOS)
        self._points_pub = self.create_publisher(PointCloud2, 'init/points', LATCHED_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATUS_QOS)
        self._status_pub = self.create_publisher(String, '~/status', STATUS_QOS)
        # Drawn only while someone subscribes, after the decision has been published.
        self._debug_pub = self.create_publisher(Image, '~/debug_image', DEBUG_QOS)
        self._tf_pub = None
        if self._settings.publish_tf and TFMessage is not None:
            self._tf_pub = self.create_publisher(TFMessage, '/tf', TF_QOS)

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
        self.create_subscription(
            Image, 'image_raw', self._on_image, IMAGE_QOS, callback_group=self._input_group
        )
        if self._settings.use_camera_info:
            self.create_subscription(
                CameraInfo, 'camera_info', self._on_camera_info, IMAGE_QOS,
                callback_group=self._input_group,
            )
        self.create_service(
            Trigger, '~/reset', self._on_reset, callback_group=self._input_group
        )
        thresholds = self._selector.thresholds
        self.get_logger().info(
            f'ready: model file {model_path}, thresholds '
            + ' '.join(f'{m}={thresholds[m]:.2f}' for m in sorted(thresholds))
            + f', R veto {sorted(self._settings.r_veto)}, mode {self._settings.mode.value}, '
            f'intrinsics from {"camera_info, else " if self._settings.use_camera_info else ""}'
            f'parameters ({self._settings.intrinsics.width}x{self._settings.intrinsics.height})'
            + ('' if self._tf_pub or not self._settings.publish_tf
               else '; tf2_msgs not installed: no /tf')
        )
        self._worker.start()

    def _declare_parameters(self) -> dict[str, Any]:
        """Declare every parameter of :data:`PARAMETERS`; their values by name.

        Raises:
            ConfigError: a value of the wrong type (e.g. ``-p max_features:=many``).
        """
        values: dict[str, Any] = {}
        for spec in PARAMETERS:
            try:
                self.declare_parameter(
                    spec.name, spec.default, ParameterDescriptor(description=spec.description)
                )
                values[spec.name] = self.get_parameter(spec.name).value
            except ParameterUninitializedException:
                # An empty list ('r_veto: []') has no type, so ROS leaves it unset.
                values[spec.name] = []
            except ParameterException as exc:
                raise ConfigError(
                    f'parameter {spec.name} (default {spec.default!r}): {exc}'
                ) from exc
        return values

    # ----------------------------------------------------------------------------- callbacks
    def _on_image(self, msg: Image) -> None:
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
            self.get_logger().warning(
                f'ignoring camera_info: {exc}; keeping the {self._intrinsics_source} intrinsics',
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            return
        with self._lock:
            self._pending_intrinsics = intrinsics

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            self._reset_requested = True
            self._pending = None  # the next frame to arrive becomes the reference
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
                reset, self._reset_requested = self._reset_requested, False
                dropped = self._dropped
            if reset:
                self._selector.reset()
                self._last_stamp = -math.inf
            if intrinsics is not None and intrinsics != self._selector.intrinsics:
                if self._intrinsics_source != 'camera_info':
                    self.get_logger().info(f'intrinsics from camera_info: {intrinsics}')
                self._intrinsics_source = 'camera_info'
                self._selector.set_intrinsics(intrinsics)
            if msg is None:
                return
            self._process(msg, dropped)

    def _process(self, msg: Image, dropped: int) -> None:
        stamp = conv.stamp_to_seconds(msg.header.stamp)
        stamp_ns = conv.stamp_to_ns(msg.header.stamp)
        try:
            image = conv.image_to_cv(msg)
            self._match_image_size(image.shape[1], image.shape[0])
            if stamp < self._last_stamp - TIME_JUMP_BACK_S:
                self.get_logger().info(
                    f'time jumped back {self._last_stamp - stamp:.1f} s (bag loop?): start over'
                )
                self._selector.reset()
            result = self._selector.process(image, stamp_ns)
        except ImageConversionError as exc:
            self._skipped += 1
            self.get_logger().warning(
                f'skipping image: {exc}', throttle_duration_sec=WARN_THROTTLE_S
            )
            self._publish_status(stamp, None, dropped, SKIPPED_IMAGE, str(exc))
            return
        except Exception as exc:  # keep the node alive; the status says what went wrong
            self._skipped += 1
            self.get_logger().error(
                f'selector failed on a frame: {type(exc).__name__}: {exc}',
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            self._publish_status(stamp, None, dropped, INTERNAL_ERROR, repr(exc))
            return
        self._last_stamp = stamp
        self._publish_status(stamp, result, dropped, result.decision.reason.value,
                             result.decision.detail)
        if result.initialization is not None:
            self._publish_initialization(result.initialization, msg.header.frame_id)
        if self._debug_pub.get_subscription_count() > 0:
            self._publish_debug_image(image, result, msg)

    def _publish_debug_image(self, image: np.ndarray, result: FrameResult, msg: Image) -> None:
        """Tracks, probabilities and the reason drawn on the frame (see overlay.py)."""
        try:
            debug = draw_selector_overlay(image, self._selector, result)
            self._debug_pub.publish(conv.numpy_to_image(
                debug, 'bgr8', stamp=msg.header.stamp, frame_id=msg.header.frame_id
            ))
        except Exception as exc:  # a drawing problem must never stop the selector
            self.get_logger().error(
                f'debug image failed: {type(exc).__name__}: {exc}',
                throttle_duration_sec=WARN_THROTTLE_S,
            )

    def _match_image_size(self, width: int, height: int) -> None:
        """Rescale the intrinsics when the images are not the size they describe."""
        current = self._selector.intrinsics
        if (width, height) == (current.width, current.height):
            return
        self.get_logger().warning(
            f'images are {width}x{height} but the {self._intrinsics_source} intrinsics are for '
            f'{current.width}x{current.height}: scaling the intrinsics',
            throttle_duration_sec=WARN_THROTTLE_S,
        )
        try:
            self._selector.set_intrinsics(current.scaled(width, height))
        except ConfigError as exc:
            raise ImageConversionError(
                f'a {width}x{height} image does not fit the intrinsics: {exc}'
            ) from exc

    # ---------------------------------------------------------------------------- publishing
    def _publish_status(
        self, stamp: float, result: FrameResult | None, dropped: int, reason: str, detail: str
    ) -> None:
        decision = result.decision if result is not None else None
        probabilities = dict(decision.probabilities) if decision is not None else {}
        status = {
            'stamp': stamp,
            'frame_index': result.frame_index if result is not None else None,
            'reason': reason,
            'detail': detail,
            'level': 'WARN' if reason in WARN_REASONS else 'OK',
            'probabilities': {m: probabilities.get(m) for m in ('F', 'E', 'H', 'R')},
            'fired': list(decision.fired) if decision is not None else [],
            'vetoed': list(decision.vetoed) if decision is not None else [],
            'tracks': decision.n_tracks if decision is not None else 0,
            'mean_disparity_px': decision.mean_disparity if decision is not None else 0.0,
            'frames_since_reference': result.frames_since_reference if result else 0,
            'new_reference': bool(result.new_reference) if result else False,
            'method': (result.initialization.method.value
                       if result is not None and result.initialization is not None else None),
            'initialized': bool(self._selector.initialized),
            'initializations': self._initializations
            + int(result is not None and result.initialization is not None),
            'received_frames': self._received,
            'dropped_frames': dropped,
            'skipped_frames': self._skipped,
        }
        self._status_pub.publish(String(data=json.dumps(status)))

        diag = DiagnosticStatus(
            level=DiagnosticStatus.WARN if reason in WARN_REASONS else DiagnosticStatus.OK,
            name=DIAGNOSTIC_NAME, message=reason, hardware_id=self.get_fully_qualified_name(),
        )
        values = {
            **{f'p_{m}': _fmt(status['probabilities'][m]) for m in ('F', 'E', 'H', 'R')},
            'tracks': str(status['tracks']),
            'mean_disparity_px': _fmt(status['mean_disparity_px']),
            'frames_since_reference': str(status['frames_since_reference']),
            'dropped_frames': str(dropped),
            'reason': reason if not detail else f'{reason}: {detail}',
        }
        diag.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        array = DiagnosticArray(status=[diag])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

    def _publish_initialization(self, init: Initialization, image_frame_id: str) -> None:
        self._initializations += 1
        frame_id = self._settings.reference_frame_id
        current = Header(stamp=conv.ns_to_stamp(init.stamp_ns), frame_id=frame_id)
        reference = Header(stamp=conv.ns_to_stamp(init.reference_stamp_ns), frame_id=frame_id)
        self._method_pub.publish(String(data=init.method.value))
        self._pose_pub.publish(conv.make_pose_stamped(init.R, init.t, current))
        self._points_pub.publish(
            conv.make_point_cloud(init.points, init.pixels_ref, init.pixels_cur, reference)
        )
        child = self._settings.camera_frame_id or image_frame_id or 'camera_optical_frame'
        if self._tf_pub is not None and child != frame_id:
            self._tf_pub.publish(
                TFMessage(transforms=[conv.make_transform(init.R, init.t, current, child)])
            )
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
        )


def _fmt(value: float | None) -> str:
    return '' if value is None else f'{value:.4f}'


def _parse_cli(argv: Sequence[str]) -> argparse.Namespace:
    """Non-ROS command-line flags (only --help); ROS arguments are removed first."""
    lines = [f'  {s.name} (default {s.default!r}): {s.description}' for s in PARAMETERS]
    parser = argparse.ArgumentParser(
        prog='selector',
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            'initsel_ros selector node: decides when and with which method (F, E, H) a '
            'monocular SLAM system initializes.\n\n'
            'Topics: subscribes image_raw, camera_info; publishes init/method, init/pose, '
            'init/points, ~/status, /diagnostics, ~/debug_image (while subscribed; and /tf); '
            'service ~/reset.\n'
            'Usage: selector --ros-args -r image_raw:=/camera/image_raw '
            '--params-file config/selector.yaml -p mode:=continuous'
        ),
        epilog='parameters (set with -p NAME:=VALUE or --params-file):\n' + '\n'.join(lines),
    )
    return parser.parse_args(list(argv)[1:])


def main(args: Sequence[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; 1 on bad parameters or a bad model file.

    The signals are handled here, not by rclpy's handlers: the executor spins in short slices
    and stops when one arrives. (With rclpy's own handlers the node sometimes missed a SIGTERM
    while its executor waited: about one stop in eight hung in a replay test.)
    """
    argv = list(sys.argv if args is None else args)
    _parse_cli(remove_ros_args(argv))
    stop = threading.Event()
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, lambda *_: stop.set())
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    status = 0
    try:
        node = SelectorNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_SLICE_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except InitselError as exc:
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {exc}')
        status = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return status


__all__ = ['DIAGNOSTIC_NAME', 'IMAGE_QOS', 'LATCHED_QOS', 'Mode', 'SelectorNode', 'main']

if __name__ == '__main__':
    sys.exit(main())
