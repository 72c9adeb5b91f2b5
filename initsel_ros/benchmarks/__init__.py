"""Helpers of ``initsel bench``: timings, the live node runs, the flood and the fuzzers.

Nothing here is imported by the library itself. rclpy, scikit-learn and hypothesis are
imported inside the functions that need them, so this package imports without ROS.
"""
