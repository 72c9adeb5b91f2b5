"""Synthetic TUM-format sequences: textured planar scenes rendered along camera trajectories.

``render_sequence(out_dir, scene='structure_texture', trajectory='near', frames=None, seed=0)``
writes ``rgb/``, ``depth/``, ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``,
``intrinsics.yaml`` and ``effects.yaml`` (and optionally ROS 1/ROS 2 bags). Camera effects
(motion blur, rolling shutter, auto-exposure, vignetting, shot noise, JPEG, distortion, moving
objects) are :class:`Effects`; ``realism=True`` draws them from the seed.
"""

from __future__ import annotations

from initsel_ros.synth.effects import Effects
from initsel_ros.synth.render import render_frame
from initsel_ros.synth.scene import Scene, SceneName, build_scene
from initsel_ros.synth.trajectories import TrajectoryName, look_at, make_trajectory
from initsel_ros.synth.write import SynthResult, render, render_sequence

__all__ = [
    'Effects',
    'Scene',
    'SceneName',
    'SynthResult',
    'TrajectoryName',
    'build_scene',
    'look_at',
    'make_trajectory',
    'render',
    'render_frame',
    'render_sequence',
]
