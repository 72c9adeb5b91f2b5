"""Names shared by the core, the node and the tools: the models, the pose methods, the modes.

Each is defined here once, and imports nothing, so any module (the ``--help`` path included)
can use it.
"""

from __future__ import annotations

from enum import Enum


class Method(str, Enum):
    """Structure-from-motion method that initializes the map."""

    F = 'F'  # fundamental matrix, 8-point (normalized), then E = K^T F K
    E = 'E'  # essential matrix, Nister 5-point
    H = 'H'  # homography, 4-point DLT, Faugeras-Lustman decomposition


#: The pose methods' names, in declaration order ('F', 'E', 'H').
POSE_METHODS: tuple[str, ...] = tuple(m.value for m in Method)
#: The model that says "pure rotation" (it vetoes methods; it has no pose).
ROTATION_MODEL = 'R'
#: The four models, one per pose method plus the rotation model ('F', 'E', 'H', 'R').
MODEL_NAMES: tuple[str, ...] = (*POSE_METHODS, ROTATION_MODEL)


class Mode(str, Enum):
    """What the selector does after a successful initialization."""

    ONCE = 'once'  # publish once, then report 'already initialized' until a reset
    CONTINUOUS = 'continuous'  # re-anchor on the initializing frame and initialize again


__all__ = ['MODEL_NAMES', 'POSE_METHODS', 'ROTATION_MODEL', 'Method', 'Mode']
