"""The selector node end to end: a timed replay (30/60 Hz) and a flood (200 Hz, 1920x1080).

The node runs in this process on a SingleThreadedExecutor (as ``initsel demo`` does). For the
replay the publisher shares the process; for the flood it runs in a child process
(``python -m initsel_ros.benchmarks.live publish ...``) so publishing does not compete with
the node for the interpreter lock. rclpy is imported inside the functions.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.benchmarks.common import rss_bytes
from initsel_ros.errors import InitselError

log = logging.getLogger(__name__)

STATUS_TOPIC = '/selector/status'


def configure_ros_environment() -> None:
    """Private DDS domain, localhost discovery, shared-memory profile, temporary log folder.

    Values already in the environment are kept (except the domain, kept when set).
    """
    os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 50 + 150))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='initsel-bench-roslog-'))
    if 'FASTRTPS_DEFAULT_PROFILES_FILE' not in os.environ:
        from initsel_ros.models import find_config_file

        try:
            os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(find_config_file('fastdds_shm.xml'))
        except InitselError:
            log.warning('config/fastdds_shm.xml not found: default Fast DDS transports')


def _percentiles(values: list[float]) -> dict[str, float]:
    if not values:
        return {'median_ms': float('nan'), 'p90_ms': float('nan'), 'p99_ms': float('nan'),
                'max_ms': float('nan')}
    a = np.asarray(values) * 1e3
    return {'median_ms': float(np.median(a)), 'p90_ms': float(np.percentile(a, 90)),
            'p99_ms': float(np.percentile(a, 99)), 'max_ms': float(a.max())}


@dataclass
class NodeRun:
    """What one run against the node showed.

    Attributes:
        label: e.g. 'replay 30 Hz'.
        published: frames published.
        publish_rate_hz: achieved publishing rate.
        received: frames the node received (its own count).
        processed: statuses seen (one per processed frame).
        dropped: frames the node overwrote before processing them (its own count).
        skipped: frames the node could not use (conversion errors).
        latency: publish time -> status arrival percentiles, milliseconds.
        newest_processed: the last published frame was processed.
        rss_start_mb, rss_max_mb, rss_end_mb: resident memory of this process, MiB.
        reasons: status reason -> count.
        seconds: wall-clock length of the publishing phase.
    """

    label: str
    published: int = 0
    publish_rate_hz: float = 0.0
    received: int = 0
    processed: int = 0
    dropped: int = 0
    skipped: int = 0
    latency: dict[str, float] = field(default_factory=dict)
    newest_processed: bool = False
    rss_start_mb: float = 0.0
    rss_max_mb: float = 0.0
    rss_mid_mb: float = 0.0
    rss_end_mb: float = 0.0
    reasons: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain data for --json."""
        return asdict(self)


class _NodeUnderTest:
    """SelectorNode + a listener node on one SingleThreadedExecutor spinning in a thread.

    The node processes frames in a worker thread of its own.
    """

    def __init__(self, model_path: Path, mode: str = 'continuous') -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        from initsel_ros.ros.node import SelectorNode

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.statuses: list[dict[str, Any]] = []
        self.arrivals: list[tuple[float, float]] = []  # (monotonic, wall) arrival times
        self.lock = threading.Lock()
        self.node = SelectorNode(
            context=self.context,
            parameter_overrides=[Parameter('model_file', value=str(model_path)),
                                 Parameter('mode', value=mode)],
        )
        self.listener = rclpy.create_node('initsel_bench_listener', context=self.context)
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.listener.create_subscription(String, STATUS_TOPIC, self._on_status, reliable)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.listener)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_status(self, msg: Any) -> None:
        arrival = (time.monotonic(), time.time())
        status = json.loads(msg.data)
        with self.lock:
            self.statuses.append(status)
            self.arrivals.append(arrival)

    def wait_for(self, predicate: Any, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if predicate():
                    return True
            time.sleep(0.02)
        return False

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.listener.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5.0)


def _summarize(run: NodeRun, node: _NodeUnderTest) -> None:
    with node.lock:
        statuses = list(node.statuses)
    run.processed = len(statuses)
    if statuses:
        last = statuses[-1]
        run.received = int(max(s['received_frames'] for s in statuses))
        run.dropped = int(max(s['dropped_frames'] for s in statuses))
        run.skipped = int(max(s['skipped_frames'] for s in statuses))
        del last
    for s in statuses:
        run.reasons[s['reason']] = run.reasons.get(s['reason'], 0) + 1


def replay(images: list[np.ndarray], intrinsics: Any, model_path: Path, rate_hz: float,
           frames: int, timeout: float = 30.0) -> NodeRun:
    """Publish ``frames`` frames (``images`` played forth and back, bgr8) at ``rate_hz``.

    Latency is publish time -> arrival of the frame's status on ``/selector/status``.
    """
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo, Image

    from initsel_ros.ros import conversions as conv

    configure_ros_environment()
    run = NodeRun(f'node, replay at {rate_hz:g} Hz')
    node = _NodeUnderTest(model_path)
    player = rclpy.create_node('initsel_bench_player', context=node.context)
    try:
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        image_pub = player.create_publisher(Image, 'image_raw', reliable)
        info_pub = player.create_publisher(CameraInfo, 'camera_info', reliable)
        if not node.wait_for(lambda: image_pub.get_subscription_count() > 0, 10.0):
            raise InitselError('the selector node never subscribed to image_raw (discovery)')
        n = len(images)
        order = [k % (2 * n - 2) if n > 1 else 0 for k in range(frames)]
        order = [i if i < n else 2 * n - 2 - i for i in order]
        msgs = [conv.numpy_to_image(images[i], 'bgr8') for i in range(n)]
        published: dict[float, float] = {}
        run.rss_start_mb = rss_bytes() / 2**20
        period = 1.0 / rate_hz
        start = time.monotonic()
        for k, i in enumerate(order):
            due = start + k * period
            time.sleep(max(0.0, due - time.monotonic()))
            stamp = 1.0 + k * period
            header_stamp = conv.seconds_to_stamp(stamp)
            msg = msgs[i]
            msg.header.stamp = header_stamp
            info_pub.publish(conv.intrinsics_to_camera_info(intrinsics, stamp=header_stamp))
            published[round(stamp, 6)] = time.monotonic()
            image_pub.publish(msg)
        run.seconds = time.monotonic() - start
        run.published = len(order)
        run.publish_rate_hz = (len(order) - 1) / run.seconds if run.seconds > 0 else 0.0
        last = round(1.0 + (len(order) - 1) * period, 6)
        run.newest_processed = node.wait_for(
            lambda: any(round(s['stamp'], 6) == last for s in node.statuses[-5:]), timeout)
        time.sleep(0.2)
        run.rss_end_mb = rss_bytes() / 2**20
        latencies = []
        with node.lock:
            for s, (arrival, _) in zip(node.statuses, node.arrivals, strict=True):
                sent = published.get(round(s['stamp'], 6))
                if sent is not None:
                    latencies.append(arrival - sent)
        run.latency = _percentiles(latencies)
        _summarize(run, node)
    finally:
        player.destroy_node()
        node.close()
    return run


# -------------------------------------------------------------------------------- the flood
def textured_frames(width: int, height: int, count: int, shift_px: int = 3,
                    seed: int = 0) -> list[np.ndarray]:
    """``count`` (H, W, 3) uint8 BGR views of one blurred-noise texture, each shifted right.

    Blurred noise has corners everywhere, so the tracker does its full work.
    """
    import cv2

    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, size=(height, width + shift_px * count), dtype=np.uint8)
    base = cv2.GaussianBlur(base, (0, 0), 2.0)
    base = cv2.normalize(base, None, 0, 255, cv2.NORM_MINMAX)
    frames = []
    for k in range(count):
        gray = np.ascontiguousarray(base[:, k * shift_px: k * shift_px + width])
        frames.append(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
    return frames


def flood_publisher(rate_hz: float, seconds: float, width: int, height: int,
                    encoding: str = 'bgr8', wait_s: float = 10.0) -> dict[str, Any]:
    """Publish textured frames on ``image_raw`` as fast as ``rate_hz`` allows.

    Header stamps are wall-clock times (``time.time()``), so a listener on the same machine
    can measure latency. Returns a summary: frames published, achieved rate, last stamp.
    """
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    from initsel_ros.ros import conversions as conv

    configure_ros_environment()
    frames = textured_frames(width, height, 16)
    if encoding == 'mono8':
        import cv2

        frames = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in frames]
    msgs = [conv.numpy_to_image(f, encoding) for f in frames]
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('initsel_flood_publisher', context=context)
    try:
        pub = node.create_publisher(
            Image, 'image_raw', QoSProfile(depth=2, reliability=ReliabilityPolicy.BEST_EFFORT))
        deadline = time.monotonic() + wait_s
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.5)  # let the node's discovery finish too
        period = 1.0 / rate_hz
        start = time.monotonic()
        k, stamp = 0, 0.0
        while True:
            now = time.monotonic()
            if now - start >= seconds:
                break
            due = start + k * period
            if due > now:
                time.sleep(due - now)
            msg = msgs[k % len(msgs)]
            stamp = time.time()
            msg.header.stamp = conv.seconds_to_stamp(stamp)
            pub.publish(msg)
            k += 1
        elapsed = time.monotonic() - start
        time.sleep(0.5)  # keep the writer alive while the last sample is read
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return {'published': k, 'seconds': elapsed, 'rate_hz': k / elapsed if elapsed else 0.0,
            'last_stamp': stamp, 'subscribed': True}


def flood(model_path: Path, seconds: float = 30.0, rate_hz: float = 200.0,
          width: int = 1920, height: int = 1080, encoding: str = 'bgr8',
          timeout: float | None = None) -> NodeRun:
    """Run the node here and a flood publisher in a child process; sample memory meanwhile."""
    configure_ros_environment()
    run = NodeRun(f'node, flood {width}x{height} {encoding} at {rate_hz:g} Hz for {seconds:g} s')
    node = _NodeUnderTest(model_path)
    timeout = timeout if timeout is not None else seconds + 60.0
    env = dict(os.environ)
    env['PYTHONUNBUFFERED'] = '1'
    cmd = [sys.executable, '-m', 'initsel_ros.benchmarks.live', 'publish',
           '--rate', str(rate_hz), '--seconds', str(seconds), '--width', str(width),
           '--height', str(height), '--encoding', encoding]
    try:
        gc_rss = rss_bytes()
        run.rss_start_mb = gc_rss / 2**20
        samples: list[tuple[float, int]] = []
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                                text=True)
        start = time.monotonic()
        try:
            while proc.poll() is None and time.monotonic() - start < timeout:
                samples.append((time.monotonic() - start, rss_bytes()))
                time.sleep(0.25)
        finally:
            out, err = _stop(proc)
        if proc.returncode != 0:
            raise InitselError(f'flood publisher failed (exit {proc.returncode}): {err[-2000:]}')
        summary = json.loads(out.strip().splitlines()[-1])
        run.published = int(summary['published'])
        run.seconds = float(summary['seconds'])
        run.publish_rate_hz = float(summary['rate_hz'])
        last = float(summary['last_stamp'])
        run.newest_processed = node.wait_for(
            lambda: bool(node.statuses) and abs(node.statuses[-1]['stamp'] - last) < 1e-6, 10.0)
        time.sleep(0.2)
        run.rss_end_mb = rss_bytes() / 2**20
        if samples:
            rss = np.array([r for _, r in samples]) / 2**20
            run.rss_max_mb = float(rss.max())
            run.rss_mid_mb = float(rss[len(rss) // 2])
        with node.lock:
            latencies = [wall - s['stamp'] for s, (_, wall) in
                         zip(node.statuses, node.arrivals, strict=True)]
        run.latency = _percentiles(latencies)
        _summarize(run, node)
    finally:
        node.close()
    return run


def _stop(proc: subprocess.Popen, grace: float = 5.0) -> tuple[str, str]:
    """SIGINT, SIGTERM, SIGKILL in turn (``grace`` s each) until ``proc`` ends; its output."""
    import signal

    for sig in (None, signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if sig is not None and proc.poll() is None:
            proc.send_signal(sig)
        try:
            return proc.communicate(timeout=grace)
        except subprocess.TimeoutExpired:
            continue
    return proc.communicate()


def main(argv: list[str] | None = None) -> int:
    """``python -m initsel_ros.benchmarks.live publish ...``: the flood's publisher."""
    parser = argparse.ArgumentParser(prog='initsel_ros.benchmarks.live')
    sub = parser.add_subparsers(dest='command', required=True)
    pub = sub.add_parser('publish', help='publish textured frames on image_raw')
    pub.add_argument('--rate', type=float, default=200.0)
    pub.add_argument('--seconds', type=float, default=30.0)
    pub.add_argument('--width', type=int, default=1920)
    pub.add_argument('--height', type=int, default=1080)
    pub.add_argument('--encoding', choices=('bgr8', 'mono8'), default='bgr8')
    args = parser.parse_args(argv)
    summary = flood_publisher(args.rate, args.seconds, args.width, args.height, args.encoding)
    print(json.dumps(summary), flush=True)
    return 0


__all__ = ['STATUS_TOPIC', 'NodeRun', 'configure_ros_environment', 'flood', 'flood_publisher',
           'replay', 'textured_frames']

if __name__ == '__main__':
    sys.exit(main())
