"""``initsel demo``: render a sequence, run the selector on it live, and check it against truth.

With ROS 2 available (the default), the ``selector`` node runs in this process on its own
executor, a publisher plays the rendered frames on ``image_raw`` + ``camera_info`` at the
recorded rate (``--compressed``: JPEG on ``image_raw/compressed``), and a listener collects
``init/*`` and the per-frame status; frames and initializations are matched by their exact
stamps. ``--offline`` runs the same :class:`~initsel_ros.selector.Selector` directly, without
ROS.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.errors import InitselError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InitRecord:
    """One initialization as seen by the demo, judged against the ground truth."""

    frame_index: int
    reference_index: int
    method: str
    probabilities: dict[str, float]
    n_points: int
    translation_error: float  # chordal, 0..2 (NaN without ground truth)
    gt_baseline_m: float

    @property
    def good(self) -> bool:
        """True when the translation direction is trustworthy (E_t < 0.8)."""
        return bool(self.translation_error < 0.8)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel demo``."""
    parser.add_argument('--work', type=Path, default=None,
                        help='folder for the rendered sequence (default: a temporary folder, '
                        'removed afterwards); reused when it already holds enough frames')
    parser.add_argument('--source', type=Path, default=None,
                        help='use this TUM folder or bag instead of rendering one')
    parser.add_argument('--frames', type=int, default=240, help='frames to render and play')
    parser.add_argument('--scene', default='structure_texture', help='scene to render')
    parser.add_argument('--trajectory', default='near', help='camera trajectory to render')
    parser.add_argument('--seed', type=int, default=0, help='rendering seed')
    parser.add_argument('--mode', choices=('once', 'continuous'), default='once',
                        help='stop after the first initialization (default), or re-anchor '
                        'after each and judge every one')
    parser.add_argument('--models', type=Path, default=None,
                        help='model file (default: the packaged config/models.json)')
    parser.add_argument('--rate', type=float, default=1.0,
                        help='playback speed factor for the live run (1 = 30 Hz)')
    parser.add_argument('--offline', action='store_true',
                        help='run the selector directly, without ROS 2')
    parser.add_argument('--compressed', action='store_true',
                        help='publish JPEG sensor_msgs/CompressedImage on image_raw/compressed '
                        '(node parameter image_transport:=compressed)')
    parser.add_argument('--jpeg-quality', type=int, default=95,
                        help='JPEG quality with --compressed (default 95)')


def _prepare_sequence(args: argparse.Namespace, work: Path):
    from initsel_ros.datasets import open_sequence

    if args.source is not None:
        return open_sequence(args.source)
    folder = work / f'{args.scene}_{args.trajectory}_{args.seed}'
    if (folder / 'rgb.txt').is_file():
        seq = open_sequence(folder)
        if len(seq) >= args.frames:
            print(f'reusing {folder} ({len(seq)} frames)')
            return seq
    from initsel_ros.synth import render_sequence

    print(f'rendering {args.frames} frames ({args.scene} scene, {args.trajectory} trajectory) '
          f'into {folder}')
    render_sequence(folder, scene=args.scene, trajectory=args.trajectory,
                    frames=args.frames, seed=args.seed)
    return open_sequence(folder)


def judge(seq, frame_index: int, reference_index: int, method: str, t_est: np.ndarray,
          probabilities: dict[str, float], n_points: int) -> InitRecord:
    """Compare an initialization's translation direction with the sequence's ground truth."""
    from initsel_ros.geometry import relative_pose, translation_chordal_error

    ref, cur = seq.frames[reference_index].pose, seq.frames[frame_index].pose
    error, baseline = float('nan'), float('nan')
    if ref is not None and cur is not None:
        _, t_gt = relative_pose(ref, cur)
        error = translation_chordal_error(t_gt, t_est)
        baseline = float(np.linalg.norm(t_gt))
    return InitRecord(frame_index, reference_index, method, dict(probabilities), n_points,
                      error, baseline)


def run_offline(seq, models, mode: str, frames: int) -> tuple[list[InitRecord], dict[str, int]]:
    """Run the Selector over the first ``frames`` frames; initializations and reason counts."""
    from initsel_ros.selector import Selector, SelectorConfig

    selector = Selector(models, seq.intrinsics, SelectorConfig(mode=mode))
    stamps = seq.stamps_ns
    records, reasons = [], {}
    for i in range(min(frames, len(seq))):
        result = selector.process(seq.image(i), int(stamps[i]))
        reasons[result.decision.reason.value] = reasons.get(result.decision.reason.value, 0) + 1
        init = result.initialization
        if init is not None:
            ref = int(np.argmin(np.abs(stamps - init.reference_stamp_ns)))
            records.append(judge(seq, i, ref, init.method.value, init.t, init.probabilities,
                                 len(init.points)))
    return records, reasons


def run_live(seq, model_path: Path | None, mode: str, frames: int, rate: float,
             compressed: bool = False, jpeg_quality: int = 95,
             ) -> tuple[list[InitRecord], dict[str, int]]:
    """Play the sequence to the in-process ``selector`` node and listen to what it says.

    Args:
        compressed: publish JPEG CompressedImages (the node takes ``image_transport``
            ``compressed``) instead of raw rgb8 Images.
    """
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
    from std_msgs.msg import String

    from initsel_ros.ros import conversions as conv
    from initsel_ros.ros.node import SelectorNode
    from initsel_ros.ros.transport import oversize_warning

    context = rclpy.Context()
    rclpy.init(context=context)
    overrides = [Parameter('mode', value=mode)]
    if compressed:
        overrides.append(Parameter('image_transport', value='compressed'))
    if model_path is not None:
        overrides.append(Parameter('model_file', value=str(model_path)))
    stamps_ns = [int(ns) for ns in seq.stamps_ns]
    index_of_ns = {ns: i for i, ns in enumerate(stamps_ns)}
    statuses: list[dict] = []
    methods: list[str] = []
    poses: list[PoseStamped] = []
    clouds: list[PointCloud2] = []
    lock = threading.Lock()
    executor = SingleThreadedExecutor(context=context)
    node = SelectorNode(parameter_overrides=overrides, context=context)
    player = rclpy.create_node('initsel_demo_player', context=context)
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

    def on_status(msg: String) -> None:
        with lock:
            statuses.append(json.loads(msg.data))

    def on_method(msg: String) -> None:
        with lock:
            methods.append(msg.data)

    def on_pose(msg: PoseStamped) -> None:
        with lock:
            poses.append(msg)

    def on_points(msg: PointCloud2) -> None:
        with lock:
            clouds.append(msg)

    player.create_subscription(String, '/selector/status', on_status, reliable)
    player.create_subscription(String, 'init/method', on_method, latched)
    player.create_subscription(PoseStamped, 'init/pose', on_pose, latched)
    player.create_subscription(PointCloud2, 'init/points', on_points, latched)
    image_pub = (player.create_publisher(CompressedImage, 'image_raw/compressed', reliable)
                 if compressed else player.create_publisher(Image, 'image_raw', reliable))
    info_pub = player.create_publisher(CameraInfo, 'camera_info', reliable)
    executor.add_node(node)
    executor.add_node(player)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    n = min(frames, len(seq))
    try:
        deadline = time.monotonic() + 10.0
        while image_pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        start = time.monotonic()
        for i in range(n):
            due = start + (stamps_ns[i] - stamps_ns[0]) * 1e-9 / max(rate, 1e-6)
            time.sleep(max(0.0, due - time.monotonic()))
            header_stamp = conv.ns_to_stamp(stamps_ns[i])
            frame_id = 'camera_rgb_optical_frame'
            if compressed:
                msg = conv.numpy_to_compressed(seq.image(i), 'jpeg', quality=jpeg_quality,
                                               stamp=header_stamp, frame_id=frame_id)
            else:
                image = seq.image(i)[:, :, ::-1]  # BGR -> RGB
                msg = conv.numpy_to_image(image, 'rgb8', stamp=header_stamp, frame_id=frame_id)
            if i == 0:
                warning = oversize_warning(len(msg.data))
                if warning:
                    print(f'note: this demo runs the node in its own process, but {warning}')
            info = conv.intrinsics_to_camera_info(seq.intrinsics, stamp=header_stamp,
                                                  frame_id=frame_id)
            info_pub.publish(info)
            image_pub.publish(msg)
        last_ns = stamps_ns[n - 1]
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            with lock:
                if statuses and _status_ns(statuses[-1]) >= last_ns:
                    break
            time.sleep(0.05)
        time.sleep(0.3)
    finally:
        executor.shutdown()
        node.destroy_node()
        player.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(timeout=5.0)

    reasons: dict[str, int] = {}
    by_stamp = {}
    for s in statuses:
        reasons[s['reason']] = reasons.get(s['reason'], 0) + 1
        by_stamp[_status_ns(s)] = s
    dropped = max((s['dropped_frames'] for s in statuses), default=0)
    reasons['(frames received)'] = len(statuses)
    reasons['(frames dropped)'] = dropped
    records = []
    for method, pose, cloud in zip(methods, poses, clouds, strict=False):
        # Exact stamps: the pose carries the initializing frame's, the cloud the reference's.
        stamp_ns = conv.stamp_to_ns(pose.header.stamp)
        i = index_of_ns[stamp_ns]
        status = by_stamp.get(stamp_ns, {})
        ref = index_of_ns[conv.stamp_to_ns(cloud.header.stamp)]
        position = np.array([pose.pose.position.x, pose.pose.position.y, pose.pose.position.z])
        q = pose.pose.orientation
        R_ref_cur = conv.quaternion_to_rotation([q.x, q.y, q.z, q.w])
        t_est = -R_ref_cur.T @ position  # back to OpenCV's x_cur = R x_ref + t
        probabilities = {k: v for k, v in status.get('probabilities', {}).items() if v is not None}
        n_points = int(cloud.width) * int(cloud.height)
        records.append(judge(seq, i, ref, method, t_est, probabilities, n_points))
    return records, reasons


def _status_ns(status: dict) -> int:
    """A ``~/status`` entry's exact stamp, integer nanoseconds."""
    return int(status['stamp_sec']) * 1_000_000_000 + int(status['stamp_nanosec'])


def _report(records: list[InitRecord], reasons: dict[str, int], frames: int) -> None:
    print(f'\nwhat the selector said over {frames} frames:')
    for reason, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
        print(f'  {count:5d}  {reason}')
    if not records:
        print('\nno initialization.')
        return
    print('\ninitializations (E_t: translation direction error against ground truth, '
          'good below 0.8):')
    print('  frame  ref  method   p_F   p_E   p_H   p_R  points  baseline_m   E_t  verdict')
    for r in records:
        p = r.probabilities
        points = str(r.n_points)
        print(f'  {r.frame_index:5d} {r.reference_index:4d}  {r.method:>6}  '
              + '  '.join(f'{p.get(m, float("nan")):.2f}' for m in 'FEHR')
              + f'  {points:>6}  {r.gt_baseline_m:10.3f}  {r.translation_error:.3f}  '
              f'{"good" if r.good else "BAD"}')
    first = records[0]
    good = sum(r.good for r in records)
    print(f'\nfirst initialization at frame {first.frame_index} with {first.method} '
          f'({first.frame_index - first.reference_index} frames after its reference), '
          f'{"good" if first.good else "bad"}; {good}/{len(records)} initializations good.')


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 when the first initialization (the one a SLAM system keeps) is good."""
    from initsel_ros.models import ModelSet, default_model_path

    model_path = args.models or default_model_path()
    models = ModelSet.load(model_path)
    work = args.work
    temporary = work is None
    if temporary:
        work = Path(tempfile.mkdtemp(prefix='initsel-demo-'))
    try:
        seq = _prepare_sequence(args, Path(work))
        frames = min(args.frames, len(seq))
        live = not args.offline
        if live:
            try:
                import rclpy  # noqa: F401
            except ImportError:
                print('rclpy is not importable: running offline (pip install -e ".[ros]")')
                live = False
        print(f'model file: {model_path}')
        transport = ', compressed (JPEG)' if live and args.compressed else ''
        print(f'running the selector {"live (ROS 2 node)" if live else "offline"} on '
              f'{seq.name}: {frames} frames, mode {args.mode}{transport}')
        if live:
            records, reasons = run_live(seq, args.models, args.mode, frames, args.rate,
                                        args.compressed, args.jpeg_quality)
        else:
            records, reasons = run_offline(seq, models, args.mode, frames)
        _report(records, reasons, frames)
        if not records:
            raise InitselError('the selector never initialized on this sequence')
        return 0 if records[0].good else 1
    finally:
        if temporary:
            shutil.rmtree(work, ignore_errors=True)
