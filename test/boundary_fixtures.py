"""What counts as ROS, and a fresh interpreter that cannot import it (boundary tests)."""

from __future__ import annotations

import os

#: ROS packages by name; any ``*_msgs``, ``*_srvs``, ``*_interfaces`` or ``*_action(s)``
#: package counts as a message package too.
ROS_PACKAGES = frozenset(
    {
        'rclpy',
        'rcl',
        'rcl_interfaces',
        'rcl_logging',
        'rmw',
        'rosidl_runtime_py',
        'rosidl_parser',
        'rosidl_generator_py',
        'builtin_interfaces',
        'std_msgs',
        'sensor_msgs',
        'geometry_msgs',
        'diagnostic_msgs',
        'std_srvs',
        'tf2_msgs',
        'tf2_ros',
        'cv_bridge',
        'sensor_msgs_py',
        'launch',
        'launch_ros',
        'rosbag2_py',
        'unique_identifier_msgs',
    }
)
ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces', '_action', '_actions')


def is_ros_package(module: str) -> bool:
    """True for rclpy, a message package or another ROS client package (by top-level name)."""
    top = module.split('.')[0]
    return top in ROS_PACKAGES or top.endswith(ROS_SUFFIXES)


_BLOCKER = """
import importlib.abc, sys
class _BlockRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        top = name.split('.')[0]
        if top in {blocked!r} or top.endswith({suffixes!r}):
            raise ImportError('blocked for this test: ' + name)
sys.meta_path.insert(0, _BlockRos())
try:
    import rclpy
    raise SystemExit('the blocker did not block rclpy')
except ImportError:
    pass
"""


def ros_blocker() -> str:
    """Python source that makes rclpy and every message package unimportable (run it first)."""
    return _BLOCKER.format(blocked=sorted(ROS_PACKAGES), suffixes=ROS_SUFFIXES)


def without_ros_environment() -> dict[str, str]:
    """The environment of a fresh interpreter that must not see ROS."""
    return {
        k: v
        for k, v in os.environ.items()
        if k not in ('PYTHONPATH', '_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH')
    }
