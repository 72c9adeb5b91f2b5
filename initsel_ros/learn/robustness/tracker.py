"""The tracker under brightness changes: photometric modes against the rendered truth.

For each brightness condition (clean, auto-exposure ramps) and each
:class:`~initsel_ros.tracking.Photometric` mode, KLT tracks over 30-frame batches are compared
with the rendered ground truth (track error: the reference pixel moved with its depth and the
true relative pose), and the seed map of an E 5-point pose (the fire path's estimator,
:func:`initsel_ros.initialize.initialize_pair`) with the true pose (E_t, rotation error,
median depth error) on every pair with a baseline of at least 5 cm
(``initsel robustness tracker``).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.initialize import ESTIMATES_ONLY, initialize_pair
from initsel_ros.learn.labels import ground_truth_points
from initsel_ros.learn.robustness.models import slug
from initsel_ros.metrics import relative_pose, rotation_error_deg, translation_chordal_error
from initsel_ros.tracking import KltTracker, Photometric, TrackerConfig

LOG = logging.getLogger(__name__)


#: Brightness conditions of the tracker comparison: name -> gain_ramp (() = clean).
RAMPS: dict[str, tuple[float, ...]] = {
    'clean': (),
    'ramp 0.6->1.4 / 2 s': (0.6, 1.4, 2.0),
    'ramp 1.4->0.6 / 1 s': (1.4, 0.6, 1.0, 0.3),
    'ramp 0.4->1.8 / 1 s': (0.4, 1.8, 1.0, 0.3),
    'all effects (default), ramp 0.6->1.4 / 2 s': (),
    'clean, seed 100': (),
}


def _all_effects() -> tuple[Any, tuple[float, ...]]:
    from initsel_ros.synth.realism import effect_level

    effects, distortion, _ = effect_level('all', 'default')
    return effects, distortion


#: Further conditions: name -> () -> (Effects, distortion)
EXTRA_CONDITIONS = {'all effects (default), ramp 0.6->1.4 / 2 s': _all_effects}


#: Conditions rendered with another seed (noise and textures): the spread between
#: 'clean' and 'clean, seed 100' is the noise level of the figures
NOISE_SEEDS = {'clean, seed 100': 100}


#: Sequences of the tracker comparison: name -> render() arguments.
TRACKER_SEQUENCES: dict[str, dict[str, Any]] = {
    'near': {'trajectory': 'near', 'start': 80},
    'far': {'trajectory': 'far', 'start': 80},
    'random': {'trajectory': 'random', 'seed': 3},
    'forward': {'trajectory': 'forward'},
}


MIN_BASELINE_M = 0.05


# ----------------------------------------------------------------------------- ground truth
def true_positions(
    p0: np.ndarray, depth: np.ndarray, camera: Intrinsics, T_ref: np.ndarray, T_cur: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where reference pixels truly are in the current frame (with the camera's distortion).

    Returns:
        ``(pixels (N, 2), points (N, 3) in the reference camera frame, valid (N,) bool)``;
        invalid where the reference depth is missing.
    """
    und = camera.undistort_pixels(p0).astype(np.float64)
    X, known = ground_truth_points(und, camera.K, depth, depth_pixels=p0)  # NaN where unknown
    R, t = relative_pose(T_ref, T_cur)
    Xc = X @ R.T + t
    in_front = known & (np.nan_to_num(Xc[:, 2]) > 0.05)
    pixels = np.full((len(Xc), 2), np.nan)
    pixels[in_front] = camera.project(Xc[in_front])
    return pixels, X, in_front


@dataclass(frozen=True)
class PairResult:
    """One reference/current pair of a tracker run."""

    frames: int
    tracks: int
    track_err_px: float  # median over the pair's tracks
    far_share: float  # tracks more than 2 px off
    baseline_m: float
    et: float
    rot_deg: float
    depth_err: float  # median relative depth error of the seed map (median scale)
    points: int


def _seed_map(
    p0: np.ndarray,
    p1: np.ndarray,
    X_gt: np.ndarray,
    valid: np.ndarray,
    camera: Intrinsics,
    T_ref: np.ndarray,
    T_cur: np.ndarray,
) -> tuple[float, float, float, int]:
    """E 5-point pose of a pair against the truth: (E_t, rotation error deg, depth error,
    points); NaN when the estimate fails."""
    u0, u1 = camera.undistort_pixels(p0), camera.undistort_pixels(p1)
    est = initialize_pair(u0, u1, camera.K, ('E',), ESTIMATES_ONLY).estimates[0]
    if not est.ok:
        return math.nan, math.nan, math.nan, 0
    R_gt, t_gt = relative_pose(T_ref, T_cur)
    et = translation_chordal_error(t_gt, est.t)
    rot = rotation_error_deg(R_gt, est.R)
    idx = est.indices[valid[est.indices]]
    if len(idx) < 2:
        return et, rot, math.nan, est.n_points
    z_gt, z_est = X_gt[idx, 2], est.points[valid[est.indices], 2]
    scale = float(
        np.median(
            np.linalg.norm(X_gt[idx], axis=1)
            / np.linalg.norm(est.points[valid[est.indices]], axis=1)
        )
    )
    depth_err = float(np.median(np.abs(scale * z_est - z_gt) / z_gt))
    return et, rot, depth_err, est.n_points


def track_sequence(
    sequence: Any, config: TrackerConfig, batch: int = 30, min_frames: int = 1
) -> tuple[list[PairResult], int]:
    """Track every 30-frame batch and measure every pair against the ground truth.

    Returns:
        The pairs, and the number of frames the tracker's photometric mapping changed.
    """
    camera = sequence.intrinsics
    out = []
    remaps = 0
    for b0 in range(0, len(sequence) - batch + 1, batch):
        tracker = KltTracker(config, camera.field_mask())
        tracker.reset(sequence.gray(b0))
        depth = sequence.depth(b0)
        T_ref = sequence.frames[b0].pose
        for j in range(b0 + 1, b0 + batch):
            tracks = tracker.track(sequence.gray(j))
            if j - b0 < min_frames or len(tracks) < 8:
                continue
            T_cur = sequence.frames[j].pose
            truth, X_gt, valid = true_positions(tracks.ref, depth, camera, T_ref, T_cur)
            err = np.linalg.norm(tracks.cur - truth, axis=1)[valid]
            baseline = float(np.linalg.norm(relative_pose(T_ref, T_cur)[1]))
            seed = (math.nan, math.nan, math.nan, 0)
            if baseline >= MIN_BASELINE_M:
                seed = _seed_map(tracks.ref, tracks.cur, X_gt, valid, camera, T_ref, T_cur)
            out.append(
                PairResult(
                    j - b0,
                    len(tracks),
                    float(np.median(err)),
                    float(np.mean(err > 2.0)),
                    baseline,
                    *seed,
                )
            )
        remaps += tracker.photometric_remaps
    return out, remaps


def _summary(results: Sequence[PairResult]) -> dict[str, float]:
    last = [r for r in results if r.frames == max(p.frames for p in results)]
    seed = [r for r in results if r.baseline_m >= MIN_BASELINE_M]
    et = np.array([r.et for r in seed])
    rot = np.array([r.rot_deg for r in seed])
    dep = np.array([r.depth_err for r in seed])
    ok = np.isfinite(et)
    return {
        'tracks_end': float(np.mean([r.tracks for r in last])),
        'track_err_px': float(np.median([r.track_err_px for r in results])),
        'lost_pairs': float(np.mean([r.track_err_px > 2.0 for r in results])),
        'far_share': float(np.mean([r.far_share for r in results])),
        'pairs': float(len(seed)),
        'et_median': float(np.median(et[ok])) if ok.any() else math.nan,
        'et_p90': float(np.percentile(et[ok], 90)) if ok.any() else math.nan,
        'rot_median': float(np.median(rot[ok])) if ok.any() else math.nan,
        'rot_p90': float(np.percentile(rot[ok], 90)) if ok.any() else math.nan,
        'depth_err_median': float(np.nanmedian(dep[ok])) if ok.any() else math.nan,
        'bad_share': float(np.mean(~ok | (et >= 0.2) | (rot >= 1.0))) if len(et) else math.nan,
    }


def compare_trackers(
    out_dir: Path,
    frames: int = 120,
    modes: Iterable[Photometric] = tuple(Photometric),
    sequences: dict[str, dict[str, Any]] | None = None,
    ramps: dict[str, tuple[float, ...]] | None = None,
) -> list[dict[str, Any]]:
    """Render the sequences under each brightness condition and compare the tracker modes.

    Returns:
        One row per (condition, mode): the :func:`_summary` figures pooled over sequences,
        plus the tracking time per frame (ms, images decoded beforehand).
    """
    from initsel_ros.datasets import open_sequence
    from initsel_ros.synth import Effects, render

    sequences = TRACKER_SEQUENCES if sequences is None else sequences
    ramps = RAMPS if ramps is None else ramps
    rows = []
    for cond, ramp in ramps.items():
        pooled: dict[Photometric, list[PairResult]] = {m: [] for m in modes}
        seconds = dict.fromkeys(modes, 0.0)
        remaps = dict.fromkeys(modes, 0)
        n_frames = 0
        for name, kwargs in sequences.items():
            path = out_dir / f'{name}_{slug(cond)}'
            if not (path / 'rgb.txt').is_file():
                effects, distortion = Effects(gain_ramp=ramp), ()
                if cond in EXTRA_CONDITIONS:
                    effects, distortion = EXTRA_CONDITIONS[cond]()
                render(
                    path,
                    frames=frames,
                    effects=effects,
                    distortion=distortion,
                    **{**kwargs, 'seed': kwargs.get('seed', 0) + NOISE_SEEDS.get(cond, 0)},
                )
            seq = _Cached(open_sequence(path))
            for i in range(len(seq)):  # decode before timing
                seq.gray(i)
                seq.depth(i)
            n_frames += len(seq)
            for mode in modes:
                start = time.perf_counter()
                results, n_remaps = track_sequence(
                    seq, dataclasses.replace(TrackerConfig(), photometric=mode)
                )
                seconds[mode] += time.perf_counter() - start
                pooled[mode] += results
                remaps[mode] += n_remaps
        for mode in modes:
            rows.append(
                {
                    'condition': cond,
                    'mode': mode.value,
                    **_summary(pooled[mode]),
                    'seconds_per_frame': seconds[mode] / max(n_frames, 1),
                    'remaps': remaps[mode] / max(n_frames, 1),
                }
            )
            LOG.info('%s %s: %s', cond, mode.value, rows[-1])
    return rows


class _Cached:
    """A sequence whose grey frames and depth maps are decoded once (for fair timings)."""

    def __init__(self, sequence: Any) -> None:
        self._seq = sequence
        self.intrinsics = sequence.intrinsics
        self.frames = sequence.frames
        self.name = sequence.name
        self._gray: dict[int, np.ndarray] = {}
        self._depth: dict[int, np.ndarray | None] = {}

    def __len__(self) -> int:
        return len(self._seq)

    def gray(self, i: int) -> np.ndarray:
        if i not in self._gray:
            self._gray[i] = self._seq.gray(i)
        return self._gray[i]

    def depth(self, i: int) -> np.ndarray | None:
        if i not in self._depth:
            self._depth[i] = self._seq.depth(i)
        return self._depth[i]

    def image(self, i: int) -> np.ndarray:
        return self._seq.image(i)


def tracker_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The tracker comparison as a Markdown table."""
    head = (
        '| condition | photometric | tracks at frame 29 | track error px (median) | '
        'tracks > 2 px | pairs with median error > 2 px | E_t median | E_t p90 | '
        'rotation median deg | rotation p90 deg | '
        'depth error median | bad seeds (E_t >= 0.2 or rot >= 1 deg) | tracking ms/frame | '
        'frames remapped |'
    )
    lines = [head, '|' + '---|' * 14]
    for r in rows:
        lines.append(
            f'| {r["condition"]} | {r["mode"]} | {r["tracks_end"]:.0f} | '
            f'{r["track_err_px"]:.2f} | {100 * r["far_share"]:.1f} % | '
            f'{100 * r["lost_pairs"]:.1f} % | {r["et_median"]:.3f} | '
            f'{r["et_p90"]:.3f} | {r["rot_median"]:.2f} | {r["rot_p90"]:.2f} | '
            f'{100 * r["depth_err_median"]:.1f} % | {100 * r["bad_share"]:.1f} % | '
            f'{1e3 * r["seconds_per_frame"]:.1f} | {100 * r["remaps"]:.0f} % |'
        )
    return '\n'.join(lines) + '\n'


__all__ = [
    'ESTIMATES_ONLY',
    'EXTRA_CONDITIONS',
    'MIN_BASELINE_M',
    'NOISE_SEEDS',
    'RAMPS',
    'TRACKER_SEQUENCES',
    'PairResult',
    'compare_trackers',
    'track_sequence',
    'tracker_markdown',
    'true_positions',
]
