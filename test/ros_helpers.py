"""Shared helpers of the ROS integration tests: a private DDS domain, subprocess handling."""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: One DDS domain per test process, so parallel runs on one machine never see each other.
DOMAIN_ID = os.getpid() % 100 + 100

_log_dir: str | None = None


def _private_log_dir() -> str:
    """One ROS log folder per test process, removed when the process exits."""
    global _log_dir
    if _log_dir is None:
        _log_dir = tempfile.mkdtemp(prefix='initsel-roslog-')
        atexit.register(shutil.rmtree, _log_dir, True)
    return _log_dir


def ros_environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for ROS processes of this test run: private domain, localhost only."""
    env = dict(os.environ if base is None else base)
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(ROOT / 'config' / 'fastdds_shm.xml'))
    if 'ROS_LOG_DIR' not in env:
        env['ROS_LOG_DIR'] = _private_log_dir()
    env['PYTHONUNBUFFERED'] = '1'
    return env


def configure_this_process() -> None:
    """Apply :func:`ros_environment` to ``os.environ`` (before any rclpy.init)."""
    os.environ.update(ros_environment())


def stop_process(proc: subprocess.Popen, timeout: float = 5.0) -> int:
    """SIGINT, then SIGTERM, then SIGKILL, waiting ``timeout`` s after each; the exit code."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            break
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            continue
    return proc.wait(timeout=timeout)
