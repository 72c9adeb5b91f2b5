"""The planar-arc table (issue 20): planes from sideways arcs, against an oracle frame.

Each sequence of ``scripts/planar_arc.sh`` is one batch from its first frame (the seed-map
machinery of :mod:`initsel_ros.learn.seedmap`: the live selector in mode 'once'). For each:

- the selector's first published initialization: the frame it was published on, its E_t and
  rotation error (as in the seed-map table);
- the oracle frame: the first frame whose homography estimate from the same tracks (the
  selector's tracker from the first frame, its points measured against the reference as the
  fire path reads them; the core's H estimate; where its decompositions are ambiguous, the
  one nearest the ground truth) has E_t < :data:`ORACLE_E_T`;
- optionally the real ORB-SLAM3 on the same frames (``orbslam3``: the seed map's
  ``ORB-SLAM3 (real)`` row, :func:`initsel_ros.learn.seedmap.run_orbslam3_batch`), judged at
  its first initialization by the same bar (it publishes when it initializes).

Sequences named ``rotation*`` or ``static*`` have no baseline: nothing may initialize there.
Run it as ``initsel planar_arc SEQUENCE... --out-dir DIR`` (``scripts/planar_arc.sh``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from initsel_ros.geometry import (
    Method,
    estimate_pose,
)
from initsel_ros.learn.seedmap import (
    INITSEL,
    NO_BASELINE_MARKERS,
    _Batch,
    _run_selector,
    run_orbslam3_batch,
)
from initsel_ros.markdown import number
from initsel_ros.metrics import finite_median, relative_pose, translation_chordal_error
from initsel_ros.models import ModelSet
from initsel_ros.selector import SelectorConfig
from initsel_ros.tracking import KltTracker

if TYPE_CHECKING:
    from initsel_ros.learn.real_baselines.orbslam3_runner import Orbslam3Setup

#: E_t below which the homography estimate counts as usable (the oracle frame's bar).
ORACLE_E_T = 0.1
#: A published initialization must be within this many frames of the oracle frame.
FRAMES_AFTER_ORACLE = 10


@dataclass(frozen=True)
class ArcOutcome:
    """One system's outcome on one sequence of the family.

    Attributes:
        sequence: its name.
        no_baseline: a pan or a camera standing still (nothing may initialize).
        initialized: the selector published an initialization.
        method: its method ('' when none).
        frame: the frame it was published on (NaN when none).
        e_t: its translation direction error (NaN when none).
        rotation_deg: its rotation error, degrees (NaN when none).
        oracle_frame: the first frame with a homography estimate of E_t < 0.1 (NaN when none).
        system: ``'initsel'`` or ``'ORB-SLAM3 (real)'``.
        failed: the system crashed or timed out on this sequence (ORB-SLAM3 only).
        detail: why it failed.
    """

    sequence: str
    no_baseline: bool
    initialized: bool
    method: str = ''
    frame: float = math.nan
    e_t: float = math.nan
    rotation_deg: float = math.nan
    oracle_frame: float = math.nan
    system: str = INITSEL
    failed: bool = False
    detail: str = ''

    @property
    def verdict(self) -> str:
        """'ok' when the outcome meets issue 20's bar for its kind, else why not."""
        if self.failed:
            return 'failed'
        if self.no_baseline:
            return 'initialized on a pan' if self.initialized else 'ok'
        if not math.isfinite(self.oracle_frame):
            return 'E_t > 0.3 without an oracle frame' if self.e_t > 0.3 else 'ok'
        if not self.initialized:
            return 'not initialized'
        if not (self.e_t < ORACLE_E_T and self.rotation_deg < 1.0):
            return 'inaccurate'
        if self.frame > self.oracle_frame + FRAMES_AFTER_ORACLE:
            return 'late'
        return 'ok'


def _homography_e_t(p0: np.ndarray, p1: np.ndarray, K: np.ndarray, t_gt: np.ndarray) -> float:
    """E_t of the core's H estimate on these tracks (NaN without a usable one).

    The estimate is the fire path's own (``geometry.estimate_pose`` with its defaults: points
    in front of both cameras, within 2.5 px, with 0.36 degrees of parallax, at least 8); where
    the core finds the decomposition ambiguous it keeps the runner-up for the verification
    (``keep_ambiguous``), and the oracle takes whichever of the two usable ones is nearer the
    ground truth.
    """
    estimate = estimate_pose(Method.H, p0, p1, K, keep_ambiguous=True)
    usable = [e for e in (estimate, estimate.alternative) if e is not None and e.ok]
    return min((translation_chordal_error(t_gt, e.t) for e in usable), default=math.nan)


def oracle_frame(batch: _Batch, config: SelectorConfig) -> float:
    """The first frame of ``batch`` whose homography estimate has E_t < 0.1 (NaN: none)."""
    tracker = KltTracker(config.tracker, batch.intrinsics.field_mask())
    tracker.reset(batch.gray(0))
    K = batch.intrinsics.K
    for k in range(1, len(batch.images)):
        tracker.track(batch.gray(k))
        tracks = tracker.anchored()  # the tracks the selector estimates geometry from
        if len(tracks) < config.policy.min_tracks:
            break
        _, t_gt = relative_pose(batch.poses[batch.start], batch.poses[batch.start + k])
        if np.linalg.norm(t_gt) < 1e-9:
            continue
        p0, p1 = batch.undistort(tracks.ref), batch.undistort(tracks.cur)
        if _homography_e_t(p0, p1, K, t_gt) < ORACLE_E_T:
            return float(k)
    return math.nan


def evaluate_arc(
    path: str,
    model_path: str,
    config: SelectorConfig,
    orbslam3: Orbslam3Setup | None = None,
) -> list[ArcOutcome]:
    """One sequence's outcomes: the selector's, then the real ORB-SLAM3's when ``orbslam3``
    is given (a process-pool task: arguments are picklable)."""
    from initsel_ros.datasets import open_sequence

    cv2.setNumThreads(1)
    sequence = open_sequence(path)
    batch = _Batch(sequence, 0, len(sequence))
    no_baseline = any(m in batch.name.lower() for m in NO_BASELINE_MARKERS)
    oracle = math.nan if no_baseline else oracle_frame(batch, config)
    runs = [_run_selector(batch, ModelSet.load(model_path), config, 0.05)]
    if orbslam3 is not None:
        runs.append(run_orbslam3_batch(batch, orbslam3))
    return [
        ArcOutcome(
            batch.name,
            no_baseline,
            run.initialized,
            run.method,
            run.frames_to_publish,
            run.e_t,
            run.rotation_deg,
            oracle,
            run.system,
            run.failed,
            run.detail,
        )
        for run in runs
    ]


def evaluate_arcs(
    paths: Sequence[Path | str],
    model_path: Path | str,
    config: SelectorConfig | None = None,
    jobs: int = 1,
    orbslam3: Orbslam3Setup | None = None,
) -> list[ArcOutcome]:
    """:func:`evaluate_arc` on every sequence (in a process pool when ``jobs`` > 1), the
    outcomes of each sequence one after the other."""
    config = config or SelectorConfig()
    args = [(str(p), str(model_path), config, orbslam3) for p in paths]
    if jobs <= 1:
        return [o for a in args for o in evaluate_arc(*a)]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context('spawn')) as pool:
        return [o for outs in pool.map(evaluate_arc, *zip(*args, strict=True)) for o in outs]


def _kind(name: str) -> str:
    """The sequence name without its noise and seed suffixes (``wall_arc_d3.5_e0.30``)."""
    parts = name.split('_')
    return '_'.join(p for p in parts if not (p[:1] in 'ns' and p[1:].isdigit()))


def _noise(name: str) -> str:
    return next((p[1:] for p in name.split('_') if p[:1] == 'n' and p[1:].isdigit()), '-')


def arc_markdown(outcomes: Sequence[ArcOutcome]) -> str:
    """The table: a summary per kind, noise level and system, then every sequence. The
    system column appears when another system than the selector was run."""
    systems = [INITSEL, *sorted({o.system for o in outcomes} - {INITSEL})]
    several = len(systems) > 1
    groups: dict[tuple[str, str, int], list[ArcOutcome]] = {}
    for o in outcomes:
        key = (_kind(o.sequence), _noise(o.sequence), systems.index(o.system))
        groups.setdefault(key, []).append(o)
    system_head, system_rule = ('system | ', '---|') if several else ('', '')
    lines = [
        f'| sequences | noise, grey levels | {system_head}runs | with an oracle frame | '
        'initialized | median E_t | median rotation error, deg | median frame published | '
        'median oracle frame | meet the bar |',
        f'|---|---|{system_rule}---|---|---|---|---|---|---|---|',
    ]
    for (kind, noise, system), sel in sorted(groups.items()):
        done = [o for o in sel if o.initialized]

        failed = sum(o.failed for o in sel)
        runs = f'{len(sel)} ({failed} failed)' if failed else f'{len(sel)}'
        system_cell = f'{systems[system]} | ' if several else ''
        lines.append(
            f'| {kind} | {noise} | {system_cell}{runs} | '
            f'{sum(math.isfinite(o.oracle_frame) for o in sel)} | {len(done)} | '
            f'{number(finite_median([o.e_t for o in done]))} | '
            f'{number(finite_median([o.rotation_deg for o in done]), 2)} | '
            f'{number(finite_median([o.frame for o in done]), 1)} | '
            f'{number(finite_median([o.oracle_frame for o in sel]), 1)} | '
            f'{sum(o.verdict == "ok" for o in sel)}/{len(sel)} |'
        )
    lines += [
        '',
        f'| sequence | {system_head}method | frame published | E_t | rotation error, deg | '
        'oracle frame | verdict |',
        f'|---|{system_rule}---|---|---|---|---|---|',
    ]
    for o in outcomes:
        system_cell = f'{o.system} | ' if several else ''
        method = o.method or ('H/F' if o.initialized else '-')  # ORB-SLAM3 reports no choice
        verdict = f'{o.verdict}: {o.detail}' if o.failed and o.detail else o.verdict
        lines.append(
            f'| {o.sequence} | {system_cell}{method} | {number(o.frame, 0)} | {number(o.e_t)} | '
            f'{number(o.rotation_deg, 2)} | {number(o.oracle_frame, 0)} | {verdict} |'
        )
    return '\n'.join(lines)


def write_outputs(outcomes: Sequence[ArcOutcome], out_dir: Path) -> str:
    """Write planar_arc.md and planar_arc.csv (one row per sequence) and return the table."""
    import csv

    table = arc_markdown(outcomes)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / 'planar_arc.md').write_text(table + '\n')
    with open(out_dir / 'planar_arc.csv', 'w', newline='') as f:
        fields = [*asdict(outcomes[0]).keys(), 'verdict'] if outcomes else ['sequence']
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        for o in outcomes:
            writer.writerow({**asdict(o), 'verdict': o.verdict})
    return table


__all__ = [
    'FRAMES_AFTER_ORACLE',
    'INITSEL',
    'ORACLE_E_T',
    'ArcOutcome',
    'arc_markdown',
    'evaluate_arc',
    'evaluate_arcs',
    'oracle_frame',
    'write_outputs',
]
