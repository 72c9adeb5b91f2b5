"""The ROS 2 boundary: the ``selector`` node, message conversions, the harness and the tools.

Only this subpackage imports rclpy and message packages (a test scans every other module).
Submodules are not imported here, so this package imports without ROS installed.
"""

from __future__ import annotations


def ros_available() -> bool:
    """True when rclpy imports, so the live tools (node, demo, bench) can run."""
    try:
        import rclpy  # noqa: F401
    except ImportError:
        return False
    return True


__all__ = ['ros_available']
