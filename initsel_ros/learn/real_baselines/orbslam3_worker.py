"""Run the real ORB-SLAM3 monocular system on one batch and report its first initialization.

This file runs under the separate ORB-SLAM3 interpreter (``scripts/setup_orbslam3.sh``), which
has ``orbslam3`` (and its own OpenCV) but not initsel_ros: it imports only the standard library,
numpy and orbslam3. Usage: ``python orbslam3_worker.py BATCH.npz VOCAB SETTINGS.yaml OUT.json``.

Input ``BATCH.npz``: ``images`` (N, H, W) uint8 grey frames, ``stamps`` (N,) float64 seconds.
Output ``OUT.json``: ``{"initialized": false, "frames": N}`` when tracking never reached OK;
else also ``frame`` (the first frame tracked OK, the initializing one), ``keyframes`` (the map's
keyframes then, the two initializing ones: ``[stamp, T_wc as 16 numbers]``, the first being the
reference, which ORB-SLAM3 may have replaced after the batch's first frame) and ``points`` (the
map points tracked in that frame, world coordinates).
"""

from __future__ import annotations

import json
import sys

import numpy as np


def _pose(R, C) -> list[float]:
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=np.float64)
    T[:3, 3] = np.asarray(C, dtype=np.float64).reshape(3)
    return T.reshape(-1).tolist()


def run(batch_path: str, vocabulary: str, settings: str) -> dict:
    """Feed the frames with their stamps until the first initialization."""
    import orbslam3

    data = np.load(batch_path)
    images, stamps = data['images'], data['stamps']
    slam = orbslam3.System(vocabulary, settings, orbslam3.Sensor.MONOCULAR)
    slam.set_use_viewer(False)
    if not slam.initialize():
        raise RuntimeError('ORB-SLAM3 did not start (vocabulary or settings)')
    result: dict = {'initialized': False, 'frames': len(images)}
    try:
        for k in range(len(images)):
            slam.process_image_mono(np.ascontiguousarray(images[k]), float(stamps[k]))
            if slam.get_tracking_state() != orbslam3.TrackingState.OK:
                continue
            # keyframes: (stamp, R_wc, camera centre); points: world coordinates
            keyframes = [[float(s), _pose(R, C)] for s, R, C in slam.get_keyframe_points()]
            points = np.asarray(slam.get_tracked_mappoints(), dtype=np.float64).reshape(-1, 3)
            result.update(initialized=True, frame=k, keyframes=keyframes, points=points.tolist())
            break
    finally:
        slam.shutdown()
    return result


def main(argv: list[str]) -> int:
    """Command line: BATCH.npz VOCAB SETTINGS OUT.json."""
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    batch, vocabulary, settings, out = argv
    result = run(batch, vocabulary, settings)
    with open(out, 'w') as f:
        json.dump(result, f)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
