"""Helpers of ``initsel bench`` that need no ROS: timings, memory, the records of node runs.

Nothing here is imported by the library itself, and nothing here imports ROS: the runs that
need the node (the per-frame path from an Image, the replay, the flood, the fuzzers) are in
:mod:`initsel_ros.ros` (``bench_frame``, ``bench_live``, ``fuzz``). scikit-learn and
hypothesis are imported inside the functions that need them.
"""
