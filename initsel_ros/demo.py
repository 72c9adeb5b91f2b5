"""``initsel demo``: render a sequence, run the selector on it live, and check it against truth.

With ROS 2 available (the default), the ``selector`` node runs in this process and a player
plays the frames to it at the recorded rate (:mod:`initsel_ros.ros.demo_live`); frames and
initializations are matched by their exact stamps. ``--offline`` runs the same
:class:`~initsel_ros.selector.Selector` directly, without ROS. This module imports no ROS.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.errors import InitselError
from initsel_ros.names import MODEL_NAMES, Mode

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
    parser.add_argument('--mode', choices=tuple(m.value for m in Mode), default=Mode.ONCE.value,
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
              + '  '.join(f'{p.get(m, float("nan")):.2f}' for m in MODEL_NAMES)
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
            from initsel_ros.ros import ros_available

            if not ros_available():
                print('rclpy is not importable: running offline (pip install -e ".[ros]")')
                live = False
        print(f'model file: {model_path}')
        transport = ', compressed (JPEG)' if live and args.compressed else ''
        print(f'running the selector {"live (ROS 2 node)" if live else "offline"} on '
              f'{seq.name}: {frames} frames, mode {args.mode}{transport}')
        if live:
            from initsel_ros.ros.demo_live import run_live

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
