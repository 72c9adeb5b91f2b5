"""``initsel demo``: render a sequence, run the selector on it live, and check it against truth.

With ROS 2 available (the default), the ``selector`` node runs in this process and a player
plays the frames to it at the recorded rate (:mod:`initsel_ros.ros.demo_live`); frames and
initializations are matched by their exact stamps. ``--offline`` runs the same
:class:`~initsel_ros.selector.Selector` directly, without ROS. This module imports no ROS.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from initsel_ros.names import MODEL_NAMES

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


def prepare_sequence(
    work: Path,
    source: Path | None = None,
    *,
    scene: str = 'structure_texture',
    trajectory: str = 'near',
    seed: int = 0,
    frames: int = 240,
):
    """The sequence ``source``, or a rendered one in ``work`` (reused when it already holds
    ``frames`` frames)."""
    from initsel_ros.datasets import open_sequence

    if source is not None:
        return open_sequence(source)
    folder = work / f'{scene}_{trajectory}_{seed}'
    if (folder / 'rgb.txt').is_file():
        seq = open_sequence(folder)
        if len(seq) >= frames:
            print(f'reusing {folder} ({len(seq)} frames)')
            return seq
    from initsel_ros.synth import render_sequence

    print(f'rendering {frames} frames ({scene} scene, {trajectory} trajectory) into {folder}')
    render_sequence(folder, scene=scene, trajectory=trajectory, frames=frames, seed=seed)
    return open_sequence(folder)


def judge(
    seq,
    frame_index: int,
    reference_index: int,
    method: str,
    t_est: np.ndarray,
    probabilities: dict[str, float],
    n_points: int,
) -> InitRecord:
    """Compare an initialization's translation direction with the sequence's ground truth."""
    from initsel_ros.metrics import relative_pose, translation_chordal_error

    ref, cur = seq.frames[reference_index].pose, seq.frames[frame_index].pose
    error, baseline = float('nan'), float('nan')
    if ref is not None and cur is not None:
        _, t_gt = relative_pose(ref, cur)
        error = translation_chordal_error(t_gt, t_est)
        baseline = float(np.linalg.norm(t_gt))
    return InitRecord(
        frame_index, reference_index, method, dict(probabilities), n_points, error, baseline
    )


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
            records.append(
                judge(seq, i, ref, init.method.value, init.t, init.probabilities, len(init.points))
            )
    return records, reasons


def print_report(records: list[InitRecord], reasons: dict[str, int], frames: int) -> None:
    print(f'\nwhat the selector said over {frames} frames:')
    for reason, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
        print(f'  {count:5d}  {reason}')
    if not records:
        print('\nno initialization.')
        return
    print(
        '\ninitializations (E_t: translation direction error against ground truth, '
        'good below 0.8):'
    )
    print('  frame  ref  method   p_F   p_E   p_H   p_R  points  baseline_m   E_t  verdict')
    for r in records:
        p = r.probabilities
        points = str(r.n_points)
        print(
            f'  {r.frame_index:5d} {r.reference_index:4d}  {r.method:>6}  '
            + '  '.join(f'{p.get(m, float("nan")):.2f}' for m in MODEL_NAMES)
            + f'  {points:>6}  {r.gt_baseline_m:10.3f}  {r.translation_error:.3f}  '
            f'{"good" if r.good else "BAD"}'
        )
    first = records[0]
    good = sum(r.good for r in records)
    print(
        f'\nfirst initialization at frame {first.frame_index} with {first.method} '
        f'({first.frame_index - first.reference_index} frames after its reference), '
        f'{"good" if first.good else "bad"}; {good}/{len(records)} initializations good.'
    )
