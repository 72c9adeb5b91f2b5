"""The ROS-free side of the node runs of ``initsel bench``: environment, records, frames.

The runs themselves (a timed replay at 30/60 Hz, a flood at 200 Hz of 1920x1080 frames) are in
:mod:`initsel_ros.ros.bench_live`; this module holds what they share without ROS: the DDS
environment, the :class:`NodeRun` record and its summary of the node's statuses, the textured
frames and the child-process handling.
"""

from __future__ import annotations

import atexit
import logging
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from initsel_ros.errors import InitselError
from initsel_ros.status import FrameStatus

log = logging.getLogger(__name__)


def configure_ros_environment() -> None:
    """Private DDS domain, localhost discovery, shared-memory profile, temporary log folder.

    Values already in the environment are kept (except the domain, kept when set).
    """
    os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 50 + 150))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if 'ROS_LOG_DIR' not in os.environ:  # a folder of this run's own, removed at its exit
        os.environ['ROS_LOG_DIR'] = tempfile.mkdtemp(prefix='initsel-bench-roslog-')
        atexit.register(shutil.rmtree, os.environ['ROS_LOG_DIR'], True)
    if 'FASTRTPS_DEFAULT_PROFILES_FILE' not in os.environ:
        from initsel_ros.config_files import find_config_file

        try:
            os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(find_config_file('fastdds_shm.xml'))
        except InitselError:
            log.warning('config/fastdds_shm.xml not found: default Fast DDS transports')


def percentiles(values: list[float]) -> dict[str, float]:
    """Median, p90, p99 and max of durations in seconds, as milliseconds (NaN when empty)."""
    if not values:
        return {
            'median_ms': float('nan'),
            'p90_ms': float('nan'),
            'p99_ms': float('nan'),
            'max_ms': float('nan'),
        }
    a = np.asarray(values) * 1e3
    return {
        'median_ms': float(np.median(a)),
        'p90_ms': float(np.percentile(a, 90)),
        'p99_ms': float(np.percentile(a, 99)),
        'max_ms': float(a.max()),
    }


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
        slowest: the three largest latencies, (milliseconds, the frame's status reason).
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
    slowest: list[tuple[float, str]] = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain data for --json."""
        return asdict(self)


def summarize(run: NodeRun, statuses: Sequence[FrameStatus]) -> None:
    """Fill ``run``'s node counts and reasons from the statuses it received."""
    run.processed = len(statuses)
    if statuses:
        run.received = max(s.received_frames for s in statuses)
        run.dropped = max(s.dropped_frames for s in statuses)
        run.skipped = max(s.skipped_frames for s in statuses)
    for s in statuses:
        run.reasons[s.reason.value] = run.reasons.get(s.reason.value, 0) + 1


def textured_frames(
    width: int, height: int, count: int, shift_px: int = 3, seed: int = 0
) -> list[np.ndarray]:
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
        gray = np.ascontiguousarray(base[:, k * shift_px : k * shift_px + width])
        frames.append(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
    return frames


def stop_process(proc: subprocess.Popen, grace: float = 5.0) -> tuple[str, str]:
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


__all__ = [
    'NodeRun',
    'configure_ros_environment',
    'percentiles',
    'stop_process',
    'summarize',
    'textured_frames',
]
