"""Harness of the in-process node tests: a SelectorNode and a client node on one executor.

No launch, no subprocesses: a private rclpy context on a private DDS domain. Frames are fed
one at a time and each waits for its ``~/status``, so nothing is dropped and every frame is
accounted for. Test modules wrap :func:`ros_context` and :func:`harnesses` in fixtures.
"""

from __future__ import annotations

import itertools
import json
import time
from collections.abc import Callable, Iterator

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers import DOMAIN_ID, configure_this_process
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import String
from std_srvs.srv import Trigger

from initsel_ros.camera import Intrinsics
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.node import DIAGNOSTIC_NAME, LATCHED_QOS, SelectorNode

configure_this_process()
TIMEOUT_S = 20.0
_namespaces = itertools.count()


def ros_context() -> Iterator[rclpy.Context]:
    """A private rclpy context on this run's domain (body of a module-scoped fixture)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


class Harness:
    """A selector node plus a client node publishing images and recording every output."""

    def __init__(self, context: rclpy.Context, **parameters: object) -> None:
        self.namespace = f'/itest{next(_namespaces)}'
        overrides = [Parameter(k.replace('__', '.'), value=v) for k, v in parameters.items()]
        self.node = SelectorNode(context=context, namespace=self.namespace,
                                 parameter_overrides=overrides)
        self.client = rclpy.create_node('initsel_test_client', namespace=self.namespace,
                                        context=context)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        compressed = parameters.get('image_transport') == 'compressed'
        self.image_pub = (
            self.client.create_publisher(CompressedImage, 'image_raw/compressed', reliable)
            if compressed else self.client.create_publisher(Image, 'image_raw', reliable))
        self.info_pub = self.client.create_publisher(CameraInfo, 'camera_info', reliable)
        self.status: list[dict] = []
        self.diagnostics: list[DiagnosticStatus] = []
        self.diagnostic_stamps: list[Time] = []
        self.method: list[str] = []
        self.pose: list[PoseStamped] = []
        self.points: list[PointCloud2] = []
        c = self.client
        c.create_subscription(String, 'selector/status',
                              lambda m: self.status.append(json.loads(m.data)), reliable)
        c.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, reliable)
        c.create_subscription(String, 'init/method', lambda m: self.method.append(m.data),
                              LATCHED_QOS)
        c.create_subscription(PoseStamped, 'init/pose', self.pose.append, LATCHED_QOS)
        c.create_subscription(PointCloud2, 'init/points', self.points.append, LATCHED_QOS)
        self.reset_client = c.create_client(Trigger, 'selector/reset')
        self.set_client = c.create_client(SetParameters, 'selector/set_parameters')
        self.get_client = c.create_client(GetParameters, 'selector/get_parameters')
        self.describe_client = c.create_client(DescribeParameters, 'selector/describe_parameters')
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        self.spin_until(lambda: self.image_pub.get_subscription_count() > 0
                        and self.client.count_publishers(f'{self.namespace}/selector/status'),
                        what='discovery')

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        mine = [s for s in msg.status if s.name == DIAGNOSTIC_NAME
                and s.hardware_id == self.node.get_fully_qualified_name()]
        self.diagnostics.extend(mine)
        if mine:
            self.diagnostic_stamps.append(msg.header.stamp)

    def spin_until(self, predicate: Callable[[], bool], timeout: float = TIMEOUT_S,
                   what: str = 'condition') -> None:
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.05)

    def send(self, msg: Image) -> dict:
        """Publish one image and return the status it produced."""
        count = len(self.status)
        self.image_pub.publish(msg)
        self.spin_until(lambda: len(self.status) > count, what='a status')
        return self.status[-1]

    def send_array(self, image: np.ndarray, stamp: float | Time, encoding: str = 'bgr8') -> dict:
        """Publish pixels (as ``encoding``, or JPEG when the node takes compressed images)."""
        if image.ndim == 2 and encoding == 'bgr8':
            encoding = 'mono16' if image.dtype == np.uint16 else 'mono8'
        stamp = stamp if isinstance(stamp, Time) else conv.seconds_to_stamp(stamp)
        if self.image_pub.msg_type is CompressedImage:
            return self.send(conv.numpy_to_compressed(image, 'jpeg', stamp=stamp,
                                                      frame_id='camera_optical_frame'))
        return self.send(conv.numpy_to_image(image, encoding, stamp=stamp,
                                             frame_id='camera_optical_frame'))

    def call(self, client, request, what: str):
        """Call a service of the node and spin until it answers."""
        assert client.wait_for_service(timeout_sec=TIMEOUT_S), what
        future = client.call_async(request)
        self.spin_until(future.done, what=what)
        return future.result()

    def set_parameters(self, **values: object) -> list:
        """``/selector/set_parameters`` as ``ros2 param set`` calls it; one result per value."""
        request = SetParameters.Request(parameters=[
            Parameter(k.replace('__', '.'), value=v).to_parameter_msg()
            for k, v in values.items()])
        return list(self.call(self.set_client, request, 'set_parameters').results)

    def get_parameter(self, name: str) -> object:
        """The value ``/selector/get_parameters`` reports for ``name``."""
        from rclpy.parameter import parameter_value_to_python

        response = self.call(self.get_client, GetParameters.Request(names=[name]),
                             'get_parameters')
        return parameter_value_to_python(response.values[0])

    def send_camera_info(self, intrinsics: Intrinsics | CameraInfo) -> None:
        msg = (intrinsics if isinstance(intrinsics, CameraInfo)
               else conv.intrinsics_to_camera_info(intrinsics))
        self.info_pub.publish(msg)
        for _ in range(5):
            self.executor.spin_once(timeout_sec=0.02)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.client.destroy_node()


def harnesses(context: rclpy.Context) -> Iterator[Callable[..., Harness]]:
    """A factory of :class:`Harness` closed afterwards (body of a function fixture)."""
    made: list[Harness] = []

    def make(**parameters: object) -> Harness:
        h = Harness(context, **parameters)
        made.append(h)
        return h

    yield make
    for h in made:
        h.close()


def as_sequence(fixture_value):
    """Conftest fixtures may hand out a Sequence or a path to one."""
    if hasattr(fixture_value, 'frames'):
        return fixture_value
    from initsel_ros.datasets import open_sequence

    return open_sequence(fixture_value)


def play(h: Harness, sequence, stamps: list[Time] | None = None,
         convert: Callable[[np.ndarray], np.ndarray] | None = None,
         until_initialized: bool = False) -> list[dict]:
    """Send the sequence's camera_info and frames (with ``stamps``, pixels via ``convert``)."""
    h.send_camera_info(sequence.intrinsics)
    statuses = []
    for i, frame in enumerate(sequence.frames):
        image = sequence.image(i) if convert is None else convert(sequence.image(i))
        statuses.append(h.send_array(image, frame.stamp if stamps is None else stamps[i]))
        if until_initialized and statuses[-1]['method']:
            break
    return statuses


def double_model_file(tmp_path) -> str:
    """A test-double model file: constant probabilities, nothing ever fires."""
    from test_selector import constant_models

    path = tmp_path / 'constant_models.json'
    constant_models().save(path)
    return str(path)
