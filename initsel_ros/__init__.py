"""initsel_ros: decide when and how a monocular SLAM system initializes its map.

The core (everything outside ``initsel_ros.ros``) imports without rclpy.
"""

from __future__ import annotations

import logging

__version__ = '0.1.0'

logging.getLogger(__name__).addHandler(logging.NullHandler())
