"""The live part of ``initsel demo``: play a sequence to the in-process node and listen.

The ``selector`` node and a player run in this process (:class:`NodeHarness`, spinning in the
background); frames go out on ``image_raw`` + ``camera_info`` at the recorded rate (JPEG on
``image_raw/compressed`` with ``compressed``); frames and initializations are matched by their
exact stamps, and each initialization is judged by :func:`initsel_ros.demo.judge`.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.demo import InitRecord, judge
from initsel_ros.ros import conversions as conv
from initsel_ros.ros.harness import NodeHarness
from initsel_ros.ros.transport import oversize_warning

#: Frame id of the played images.
FRAME_ID = 'camera_rgb_optical_frame'
#: How long to wait for discovery and for the last frame's status, seconds.
WAIT_S = 10.0


def run_live(
    seq: Any,
    model_path: Path | None,
    mode: str,
    frames: int,
    rate: float,
    compressed: bool = False,
    jpeg_quality: int = 95,
) -> tuple[list[InitRecord], dict[str, int]]:
    """Play the sequence to the in-process ``selector`` node and listen to what it says.

    Args:
        seq: the sequence (TUM folder or bag reader).
        model_path: model file for the node (None: the packaged one).
        mode: the node's ``mode`` parameter.
        frames: frames to play (at most the sequence's length).
        rate: playback speed factor (1 = the recorded rate).
        compressed: publish JPEG CompressedImages (the node takes ``image_transport``
            ``compressed``) instead of raw rgb8 Images.
        jpeg_quality: JPEG quality with ``compressed``.

    Returns:
        The judged initializations, and reason -> frames (plus '(frames received)' and
        '(frames dropped)').

    Raises:
        HarnessTimeoutError: the node and the player never discovered each other.
    """
    parameters: dict[str, Any] = {'mode': mode}
    if compressed:
        parameters['image_transport'] = 'compressed'
    if model_path is not None:
        parameters['model_file'] = str(model_path)
    stamps_ns = [int(ns) for ns in seq.stamps_ns]
    index_of_ns = {ns: i for i, ns in enumerate(stamps_ns)}
    n = min(frames, len(seq))
    with NodeHarness(parameters, client_name='initsel_demo_player', timeout=WAIT_S) as h:
        h.start()
        start = time.monotonic()
        for i in range(n):
            due = start + (stamps_ns[i] - stamps_ns[0]) * 1e-9 / max(rate, 1e-6)
            time.sleep(max(0.0, due - time.monotonic()))
            header_stamp = conv.ns_to_stamp(stamps_ns[i])
            if compressed:
                msg = conv.numpy_to_compressed(
                    seq.image(i),
                    'jpeg',
                    quality=jpeg_quality,
                    stamp=header_stamp,
                    frame_id=FRAME_ID,
                )
            else:
                image = seq.image(i)[:, :, ::-1]  # BGR -> RGB
                msg = conv.numpy_to_image(image, 'rgb8', stamp=header_stamp, frame_id=FRAME_ID)
            if i == 0:
                warning = oversize_warning(len(msg.data))
                if warning:
                    print(f'note: this demo runs the node in its own process, but {warning}')
            h.publish_camera_info(seq.intrinsics, stamp=header_stamp, frame_id=FRAME_ID)
            h.publish(msg)
        last_ns = stamps_ns[n - 1]
        h.wait_for(lambda: bool(h.statuses) and h.statuses[-1].stamp_ns >= last_ns, WAIT_S)
        time.sleep(0.3)
        with h.lock:
            statuses, methods = list(h.statuses), list(h.methods)
            poses, clouds = list(h.poses), list(h.clouds)

    reasons: dict[str, int] = {}
    by_stamp = {}
    for s in statuses:
        reasons[s.reason.value] = reasons.get(s.reason.value, 0) + 1
        by_stamp[s.stamp_ns] = s
    # the node's own count (a frame overwritten before it was processed has no status)
    reasons['(frames received)'] = max((s.received_frames for s in statuses), default=0)
    reasons['(frames dropped)'] = max((s.dropped_frames for s in statuses), default=0)
    records = []
    for method, pose, cloud in zip(methods, poses, clouds, strict=False):
        # Exact stamps: the pose carries the initializing frame's, the cloud the reference's.
        stamp_ns = conv.stamp_to_ns(pose.header.stamp)
        i = index_of_ns[stamp_ns]
        status = by_stamp.get(stamp_ns)
        ref = index_of_ns[conv.stamp_to_ns(cloud.header.stamp)]
        position = np.array([pose.pose.position.x, pose.pose.position.y, pose.pose.position.z])
        q = pose.pose.orientation
        R_ref_cur = conv.quaternion_to_rotation([q.x, q.y, q.z, q.w])
        t_est = -R_ref_cur.T @ position  # back to OpenCV's x_cur = R x_ref + t
        probabilities = (
            {}
            if status is None
            else {k: v for k, v in status.probabilities.items() if v is not None}
        )
        n_points = int(cloud.width) * int(cloud.height)
        records.append(judge(seq, i, ref, method, t_est, probabilities, n_points))
    return records, reasons


__all__ = ['run_live']
