"""The ROS 2 boundary: the ``selector`` node, message conversions and the replay tool.

Only this subpackage imports rclpy and message packages. Submodules are not imported here, so
``initsel --help`` (which imports :mod:`initsel_ros.ros.replay`) works without ROS installed.
"""

from __future__ import annotations
