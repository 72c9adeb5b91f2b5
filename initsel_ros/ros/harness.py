"""The in-process harness: the ``selector`` node and a client node on one executor.

The client publishes what a camera driver would (``sensor_msgs/Image`` on ``image_raw``, or
``CompressedImage`` on ``image_raw/compressed`` when the node takes compressed images, and
``CameraInfo`` on ``camera_info``; reliable, which the node's best-effort subscriptions accept)
and records everything the node says: ``~/status`` as :class:`~initsel_ros.status.FrameStatus`
(with arrival times), ``/diagnostics`` (this node's entries), ``init/method``, ``init/pose``
and ``init/points`` (latched, as the node publishes them). ``initsel demo``, ``initsel bench``,
the fuzzer and the tests all use it.

It runs in one of two ways:

* stepped (the default): :meth:`NodeHarness.wait_until` spins the executor in the caller's
  thread until a condition holds, e.g. :meth:`NodeHarness.send` publishes one image and
  returns its status (nothing is dropped, every frame is accounted for);
* in the background (:meth:`NodeHarness.start`): a thread spins the executor while the caller
  publishes on a clock (timed playback, floods) and waits for what it expects.

Either way the node processes frames in its own worker thread.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import String
from std_srvs.srv import Trigger

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import InitselError
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.node import DIAGNOSTIC_NAME, SelectorNode
from initsel_ros.ros.params import NODE_NAME, ImageTransport
from initsel_ros.status import FrameStatus

#: Default wait for discovery, a status or a service answer, seconds.
TIMEOUT_S = 20.0
#: The client's publishers: reliable, as most camera drivers (the node accepts either).
PUBLISH_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: ~/status and /diagnostics: reliable, deep enough for a flood of statuses.
LISTEN_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
#: init/*: transient local like the node's publishers, deep enough for continuous mode.
LATCHED_LISTEN_QOS = QoSProfile(
    depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
#: Frame id of the images the harness builds.
FRAME_ID = 'camera_optical_frame'


class HarnessTimeoutError(InitselError, TimeoutError):
    """The node did not answer in time (discovery, a status, a service)."""


class NodeHarness:
    """A :class:`~initsel_ros.ros.node.SelectorNode` plus a client node, in one process.

    Args:
        parameters: node parameters by (dotted) name, e.g. ``{'thresholds.E': 0.7}``.
        context: the rclpy context to use; None: a private one, initialized here (on
            ``domain_id``) and shut down by :meth:`close`.
        namespace: namespace of both nodes ('' = the root).
        domain_id: DDS domain of a private context (None: ``ROS_DOMAIN_ID``).
        client_name: name of the client node.
        timeout: how long waits last by default, seconds.

    Raises:
        ConfigError, ModelFileError: the node refused its parameters or model file.
        HarnessTimeoutError: the node and the client did not discover each other in time.
    """

    def __init__(
        self,
        parameters: Mapping[str, Any] | None = None,
        *,
        context: rclpy.Context | None = None,
        namespace: str = '',
        domain_id: int | None = None,
        client_name: str = 'initsel_harness_client',
        timeout: float = TIMEOUT_S,
    ) -> None:
        parameters = dict(parameters or {})
        self.timeout = timeout
        self.namespace = namespace
        self._own_context = context is None
        if context is None:
            context = rclpy.Context()
            rclpy.init(context=context, domain_id=domain_id)
        self.context = context
        self.lock = threading.RLock()
        self.statuses: list[FrameStatus] = []
        #: (time.monotonic(), time.time()) at the arrival of each status.
        self.status_arrivals: list[tuple[float, float]] = []
        self.diagnostics: list[DiagnosticStatus] = []
        self.diagnostic_stamps: list[Time] = []
        self.methods: list[str] = []
        self.poses: list[PoseStamped] = []
        self.clouds: list[PointCloud2] = []
        self._thread: threading.Thread | None = None
        self.node: SelectorNode | None = None
        self.client = None
        self.executor = None
        try:
            self._build(parameters, client_name)
        except BaseException:
            self.close()
            raise

    def _build(self, parameters: dict[str, Any], client_name: str) -> None:
        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        self.node = SelectorNode(
            context=self.context, namespace=self.namespace, parameter_overrides=overrides
        )
        self.client = c = rclpy.create_node(
            client_name, namespace=self.namespace, context=self.context
        )
        self.compressed = parameters.get('image_transport') == ImageTransport.COMPRESSED.value
        self.image_pub = (
            c.create_publisher(CompressedImage, 'image_raw/compressed', PUBLISH_QOS)
            if self.compressed
            else c.create_publisher(Image, 'image_raw', PUBLISH_QOS)
        )
        self.info_pub = c.create_publisher(CameraInfo, 'camera_info', PUBLISH_QOS)
        c.create_subscription(String, f'{NODE_NAME}/status', self._on_status, LISTEN_QOS)
        c.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, LISTEN_QOS)
        c.create_subscription(
            String, 'init/method', self._recorder(self.methods, 'data'), LATCHED_LISTEN_QOS
        )
        c.create_subscription(
            PoseStamped, 'init/pose', self._recorder(self.poses), LATCHED_LISTEN_QOS
        )
        c.create_subscription(
            PointCloud2, 'init/points', self._recorder(self.clouds), LATCHED_LISTEN_QOS
        )
        self.reset_client = c.create_client(Trigger, f'{NODE_NAME}/reset')
        self.set_client = c.create_client(SetParameters, f'{NODE_NAME}/set_parameters')
        self.get_client = c.create_client(GetParameters, f'{NODE_NAME}/get_parameters')
        self.describe_client = c.create_client(
            DescribeParameters, f'{NODE_NAME}/describe_parameters'
        )
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(c)
        status_topic = f'{self.namespace.rstrip("/")}/{NODE_NAME}/status'
        self.wait_until(
            lambda: (
                self.image_pub.get_subscription_count() > 0
                and c.count_publishers(status_topic) > 0
            ),
            what='discovery',
        )

    # ----------------------------------------------------------------------------- listening
    def _on_status(self, msg: String) -> None:
        arrival = (time.monotonic(), time.time())
        status = FrameStatus.from_json(msg.data)
        with self.lock:
            self.statuses.append(status)
            self.status_arrivals.append(arrival)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        mine = [
            s
            for s in msg.status
            if s.name == DIAGNOSTIC_NAME and s.hardware_id == self.node.get_fully_qualified_name()
        ]
        if mine:
            with self.lock:
                self.diagnostics.extend(mine)
                self.diagnostic_stamps.append(msg.header.stamp)

    def _recorder(self, into: list, attribute: str | None = None) -> Callable[[Any], None]:
        def record(msg: Any) -> None:
            with self.lock:
                into.append(msg if attribute is None else getattr(msg, attribute))

        return record

    # ------------------------------------------------------------------------------- spinning
    def start(self) -> NodeHarness:
        """Spin the executor in a background thread from now on (until :meth:`close`)."""
        if self._thread is None:
            self._thread = threading.Thread(
                target=self.executor.spin, daemon=True, name='initsel-harness-executor'
            )
            self._thread.start()
        return self

    @property
    def background(self) -> bool:
        """True once :meth:`start` runs the executor in a thread."""
        return self._thread is not None

    def wait_for(self, predicate: Callable[[], Any], timeout: float | None = None) -> bool:
        """Wait until ``predicate()`` is true (spinning, unless in the background).

        The predicate runs under :attr:`lock`. Returns False on timeout.
        """
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            with self.lock:
                if predicate():
                    return True
            if time.monotonic() > deadline:
                return False
            if self.background:
                time.sleep(0.01)
            else:
                self.executor.spin_once(timeout_sec=0.05)

    def wait_until(
        self, predicate: Callable[[], Any], timeout: float | None = None, what: str = 'a condition'
    ) -> None:
        """:meth:`wait_for`, raising on timeout.

        Raises:
            HarnessTimeoutError: naming ``what`` and the timeout.
        """
        timeout = self.timeout if timeout is None else timeout
        if not self.wait_for(predicate, timeout):
            raise HarnessTimeoutError(f'timed out after {timeout} s waiting for {what}')

    def settle(self, cycles: int = 5) -> None:
        """Let pending messages reach their callbacks (a few short spins, or 0.1 s)."""
        if self.background:
            time.sleep(0.02 * cycles)
        else:
            for _ in range(cycles):
                self.executor.spin_once(timeout_sec=0.02)

    # ----------------------------------------------------------------------------- publishing
    def image_message(
        self,
        image: np.ndarray,
        stamp: Time | float,
        encoding: str = 'bgr8',
        frame_id: str = FRAME_ID,
        jpeg_quality: int = 95,
    ) -> Image | CompressedImage:
        """The message a camera would send: JPEG when the node takes compressed images.

        Args:
            image: (H, W) grey (uint8 or uint16) or (H, W, 3) pixels in ``encoding``.
            stamp: header stamp (float seconds are converted).
            encoding: Image encoding; a 2-D image given as 'bgr8' becomes mono8/mono16.
        """
        stamp = stamp if isinstance(stamp, Time) else conv.seconds_to_stamp(stamp)
        if self.compressed:
            return conv.numpy_to_compressed(
                image, 'jpeg', quality=jpeg_quality, stamp=stamp, frame_id=frame_id
            )
        if image.ndim == 2 and encoding == 'bgr8':
            encoding = 'mono16' if image.dtype == np.uint16 else 'mono8'
        return conv.numpy_to_image(image, encoding, stamp=stamp, frame_id=frame_id)

    def publish(self, msg: Image | CompressedImage) -> None:
        """Publish one image message (no waiting)."""
        self.image_pub.publish(msg)

    def publish_camera_info(
        self, info: Intrinsics | CameraInfo, stamp: Time | None = None, frame_id: str = ''
    ) -> None:
        """Publish a camera_info (built from ``info`` when it is Intrinsics; no waiting)."""
        msg = (
            info
            if isinstance(info, CameraInfo)
            else conv.intrinsics_to_camera_info(info, stamp=stamp, frame_id=frame_id)
        )
        self.info_pub.publish(msg)

    def send(self, msg: Image | CompressedImage, timeout: float | None = None) -> FrameStatus:
        """Publish one image and return the status it produced.

        Raises:
            HarnessTimeoutError: no status arrived in time.
        """
        with self.lock:
            count = len(self.statuses)
        self.publish(msg)
        self.wait_until(lambda: len(self.statuses) > count, timeout, what='a status')
        with self.lock:
            return self.statuses[count]

    def send_array(
        self, image: np.ndarray, stamp: Time | float, encoding: str = 'bgr8'
    ) -> FrameStatus:
        """:meth:`send` of :meth:`image_message`."""
        return self.send(self.image_message(image, stamp, encoding))

    def send_camera_info(self, info: Intrinsics | CameraInfo) -> None:
        """Publish a camera_info and let it arrive before the next image."""
        self.publish_camera_info(info)
        self.settle()

    # ------------------------------------------------------------------------------ services
    def call(self, client: Any, request: Any, what: str) -> Any:
        """Call a service of the node and wait for its answer.

        Raises:
            HarnessTimeoutError: the service is not there, or did not answer in time.
        """
        if not client.wait_for_service(timeout_sec=self.timeout):
            raise HarnessTimeoutError(f'the {what} service is not available')
        future = client.call_async(request)
        self.wait_until(future.done, what=f'the {what} answer')
        return future.result()

    def reset(self) -> Trigger.Response:
        """``~/reset``: the next frame becomes the reference."""
        return self.call(self.reset_client, Trigger.Request(), 'reset')

    def set_parameters(self, values: Mapping[str, Any]) -> list[SetParametersResult]:
        """``~/set_parameters`` as ``ros2 param set`` calls it; one result per value."""
        request = SetParameters.Request(
            parameters=[
                Parameter(name, value=value).to_parameter_msg() for name, value in values.items()
            ]
        )
        return list(self.call(self.set_client, request, 'set_parameters').results)

    def get_parameter(self, name: str) -> Any:
        """The value ``~/get_parameters`` reports for ``name``."""
        response = self.call(
            self.get_client, GetParameters.Request(names=[name]), 'get_parameters'
        )
        return parameter_value_to_python(response.values[0])

    # -------------------------------------------------------------------------------- closing
    def close(self) -> None:
        """Stop spinning, destroy both nodes, shut a private context down."""
        if self.executor is not None:
            self.executor.shutdown(timeout_sec=2.0)
        if self.node is not None:
            self.node.destroy_node()
        if self.client is not None:
            self.client.destroy_node()
        if self._own_context:
            rclpy.try_shutdown(context=self.context)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.executor = self.node = self.client = None

    def __enter__(self) -> NodeHarness:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = [
    'FRAME_ID',
    'LATCHED_LISTEN_QOS',
    'LISTEN_QOS',
    'PUBLISH_QOS',
    'TIMEOUT_S',
    'HarnessTimeoutError',
    'NodeHarness',
]
