"""The node end to end for ``initsel bench``: timed replays (30/60 Hz, one core) and a flood.

For the replays the node runs as a process of its own (``python -m initsel_ros.ros.node``),
as it is deployed, and this process publishes and listens: a node sharing the interpreter
lock with its publisher and listener measured up to 43 ms publish -> status where its own
process took 26 ms on the same frames. For the flood the node runs in this process
(:class:`NodeHarness`) and a child process publishes (``python -m
initsel_ros.cli.flood_publisher ...``), so that memory can be sampled here. The records and the
ROS-free helpers are in :mod:`initsel_ros.benchmarks.live`.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
import rclpy.executors
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image

from initsel_ros.benchmarks.common import rss_bytes
from initsel_ros.benchmarks.live import (
    NodeRun,
    configure_ros_environment,
    percentiles,
    stop_process,
    summarize,
    textured_frames,
)
from initsel_ros.errors import InitselError
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.harness import NodeHarness

#: How long the node and the harness may take to discover each other, seconds.
DISCOVERY_S = 10.0
#: Wait after the publisher sees the node's subscription, before the first frame: the node's
#: side of the match can lag (at load 8, 0.5 s lost the first frame of a replay).
DISCOVERY_SETTLE_S = 1.5


def _node_under_test(model_path: Path, mode: str = 'continuous') -> NodeHarness:
    """The node (and the harness's listener) spinning in the background."""
    harness = NodeHarness(
        {'model_file': str(model_path), 'mode': mode},
        client_name='initsel_bench_listener',
        timeout=DISCOVERY_S,
    )
    return harness.start()


# -------------------------------------------------------------------------------- the flood
def flood_publisher(
    rate_hz: float,
    seconds: float,
    width: int,
    height: int,
    encoding: str = 'bgr8',
    wait_s: float = 10.0,
) -> dict[str, Any]:
    """Publish textured frames on ``image_raw`` as fast as ``rate_hz`` allows.

    Header stamps are wall-clock times (``time.time()``), so a listener on the same machine
    can measure latency. Returns a summary: frames published, achieved rate, last stamp.
    """
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
            Image, 'image_raw', QoSProfile(depth=2, reliability=ReliabilityPolicy.BEST_EFFORT)
        )
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
    return {
        'published': k,
        'seconds': elapsed,
        'rate_hz': k / elapsed if elapsed else 0.0,
        'last_stamp': stamp,
        'subscribed': True,
    }


def flood(
    model_path: Path,
    seconds: float = 30.0,
    rate_hz: float = 200.0,
    width: int = 1920,
    height: int = 1080,
    encoding: str = 'bgr8',
    timeout: float | None = None,
) -> NodeRun:
    """Run the node here and a flood publisher in a child process; sample memory meanwhile."""
    configure_ros_environment()
    run = NodeRun(f'node, flood {width}x{height} {encoding} at {rate_hz:g} Hz for {seconds:g} s')
    timeout = timeout if timeout is not None else seconds + 60.0
    env = dict(os.environ)
    env['PYTHONUNBUFFERED'] = '1'
    cmd = [
        sys.executable,
        '-m',
        'initsel_ros.cli.flood_publisher',
        '--rate',
        str(rate_hz),
        '--seconds',
        str(seconds),
        '--width',
        str(width),
        '--height',
        str(height),
        '--encoding',
        encoding,
    ]
    with _node_under_test(model_path) as h:
        run.rss_start_mb = rss_bytes() / 2**20
        samples: list[tuple[float, int]] = []
        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True
        )
        start = time.monotonic()
        try:
            while proc.poll() is None and time.monotonic() - start < timeout:
                samples.append((time.monotonic() - start, rss_bytes()))
                time.sleep(0.25)
        finally:
            out, err = stop_process(proc)
        if proc.returncode != 0:
            raise InitselError(f'flood publisher failed (exit {proc.returncode}): {err[-2000:]}')
        summary = json.loads(out.strip().splitlines()[-1])
        run.published = int(summary['published'])
        run.seconds = float(summary['seconds'])
        run.publish_rate_hz = float(summary['rate_hz'])
        last = float(summary['last_stamp'])
        run.newest_processed = h.wait_for(
            lambda: bool(h.statuses) and abs(h.statuses[-1].stamp - last) < 1e-6, 10.0
        )
        time.sleep(0.2)
        run.rss_end_mb = rss_bytes() / 2**20
        if samples:
            rss = np.array([r for _, r in samples]) / 2**20
            run.rss_max_mb = float(rss.max())
            run.rss_mid_mb = float(rss[len(rss) // 2])
        with h.lock:
            latencies = [
                wall - s.stamp for s, (_, wall) in zip(h.statuses, h.status_arrivals, strict=True)
            ]
            statuses = list(h.statuses)
        run.latency = percentiles(latencies)
        summarize(run, statuses)
    return run


# ------------------------------------------------------------------------- one core
@dataclass
class CoreRun:
    """The node in a process of its own, on one core or unpinned, fed at a fixed rate.

    Attributes:
        run: counts and latency as for the replay.
        pinned: the node ran under ``taskset -c <node_core>`` and this process (the
            publisher) on ``publisher_core``.
        cpu_seconds: the node process's utime + stime over the run, seconds.
        cpu_share: ``cpu_seconds`` over the run's wall time (1.0 = one core busy).
        initializations: statuses that reported an initialization.
    """

    run: NodeRun
    pinned: bool
    cpu_seconds: float = 0.0
    cpu_share: float = float('nan')
    initializations: int = 0

    def to_dict(self) -> dict[str, Any]:
        """Plain data for --json."""
        own = {f.name: getattr(self, f.name) for f in fields(self) if f.name != 'run'}
        return own | self.run.to_dict()


def _cpu_seconds(pid: int) -> float:
    """utime + stime of process ``pid`` (all its threads), seconds."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def node_in_own_process(
    images: list[np.ndarray],
    intrinsics: Any,
    model_path: Path,
    rate_hz: float = 30.0,
    frames: int = 300,
    pinned: bool = False,
    node_core: int = 0,
    publisher_core: int = 1,
    timeout: float = 60.0,
) -> CoreRun:
    """Run the node as ``python -m initsel_ros.ros.node`` (mode continuous), pinned with
    ``taskset -c node_core`` when ``pinned``, and publish ``frames`` frames (``images``
    forth and back, bgr8, with camera_info) at ``rate_hz`` from this process, itself pinned
    to ``publisher_core`` meanwhile; measure the node's CPU time over the run.

    Raises:
        InitselError: taskset is missing, the node did not start or was not discovered.
    """
    from std_msgs.msg import String

    from initsel_ros.ros.harness import LISTEN_QOS, PUBLISH_QOS
    from initsel_ros.ros.params import NODE_NAME
    from initsel_ros.status import FrameStatus

    configure_ros_environment()
    label = f'node on core {node_core}' if pinned else 'node, replay'
    result = CoreRun(NodeRun(f'{label} at {rate_hz:g} Hz'), pinned)
    cmd = [sys.executable, '-m', 'initsel_ros.ros.node', '--ros-args', '-p']
    cmd += [f'model_file:={model_path}', '-p', 'mode:=continuous']
    if pinned:
        taskset = shutil.which('taskset')
        if taskset is None:
            raise InitselError('taskset (util-linux) is needed to pin the node to one core')
        cmd = [taskset, '-c', str(node_core), *cmd]
    affinity = os.sched_getaffinity(0)
    if pinned:
        os.sched_setaffinity(0, {publisher_core})  # before the client's threads start
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ), text=True
    )
    context = rclpy.Context()
    statuses: list[tuple[FrameStatus, float]] = []
    lock = threading.Lock()
    thread = None
    try:
        rclpy.init(context=context)
        client = rclpy.create_node('initsel_bench_core_client', context=context)

        def on_status(msg: String) -> None:
            with lock:
                statuses.append((FrameStatus.from_json(msg.data), time.monotonic()))

        image_pub = client.create_publisher(Image, 'image_raw', PUBLISH_QOS)
        info_pub = client.create_publisher(CameraInfo, 'camera_info', PUBLISH_QOS)
        client.create_subscription(String, f'{NODE_NAME}/status', on_status, LISTEN_QOS)
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(client)

        def spin() -> None:
            # the context is shut down at the end of the run
            with contextlib.suppress(rclpy.executors.ExternalShutdownException):
                executor.spin()

        thread = threading.Thread(target=spin, daemon=True)
        thread.start()
        deadline = time.monotonic() + timeout
        while not (
            image_pub.get_subscription_count() > 0
            and client.count_publishers(f'/{NODE_NAME}/status') > 0
        ):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise InitselError(
                    f'the node did not start or was not discovered: {stop_process(proc)[1][-500:]}'
                )
            time.sleep(0.05)
        time.sleep(DISCOVERY_SETTLE_S)  # the node must match the publisher too
        n = len(images)
        order = [k % (2 * n - 2) if n > 1 else 0 for k in range(frames)]
        order = [i if i < n else 2 * n - 2 - i for i in order]
        msgs = [conv.numpy_to_image(images[i], 'bgr8') for i in range(n)]
        period = 1.0 / rate_hz
        published: dict[float, float] = {}
        cpu0, start = _cpu_seconds(proc.pid), time.monotonic()
        for k, i in enumerate(order):
            time.sleep(max(0.0, start + k * period - time.monotonic()))
            stamp = conv.seconds_to_stamp(1.0 + k * period)
            info_pub.publish(conv.intrinsics_to_camera_info(intrinsics, stamp=stamp))
            msg = msgs[i]
            msg.header.stamp = stamp
            published[round(1.0 + k * period, 6)] = time.monotonic()
            image_pub.publish(msg)
        run = result.run
        run.published = len(order)
        run.seconds = time.monotonic() - start
        run.publish_rate_hz = (len(order) - 1) / run.seconds if run.seconds > 0 else 0.0
        last = round(1.0 + (len(order) - 1) * period, 6)
        while time.monotonic() < start + run.seconds + 10.0:
            with lock:
                if any(round(st.stamp, 6) == last for st, _ in statuses[-5:]):
                    run.newest_processed = True
                    break
            time.sleep(0.01)
        end = time.monotonic()
        result.cpu_seconds = _cpu_seconds(proc.pid) - cpu0
        result.cpu_share = result.cpu_seconds / (end - start)
        with lock:
            seen = list(statuses)
        timed = [
            (arrival - published[round(st.stamp, 6)], st)
            for st, arrival in seen
            if round(st.stamp, 6) in published
        ]
        run.latency = percentiles([t for t, _ in timed])
        run.slowest = [
            (t * 1e3, st.reason.value) for t, st in sorted(timed, key=lambda x: -x[0])[:3]
        ]
        summarize(run, [st for st, _ in seen])
        result.initializations = run.reasons.get('initialized', 0)
    finally:
        stop_process(proc)
        rclpy.try_shutdown(context=context)
        if thread is not None:
            thread.join(timeout=5.0)
        os.sched_setaffinity(0, affinity)
    return result


__all__ = ['CoreRun', 'flood', 'flood_publisher', 'node_in_own_process']
