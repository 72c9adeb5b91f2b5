"""Offline pictures: the debug overlay as a video or PNG frames, and probabilities over time.

Run the ROS-free :class:`~initsel_ros.selector.Selector` over a
:class:`~initsel_ros.datasets.Sequence` and write what it saw::

    initsel pictures --source SEQ --video out.mp4 --plot out.png
    initsel pictures --out docs/images      # regenerate the README pictures

matplotlib (the optional ``plot`` extra) is imported only by :func:`plot_probabilities`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator, Mapping
from collections.abc import Sequence as SequenceABC
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from initsel_ros.errors import ConfigError, InitselError
from initsel_ros.models import ModelSet
from initsel_ros.names import MODEL_NAMES
from initsel_ros.overlay import draw_frame_overlay
from initsel_ros.policy import Reason
from initsel_ros.selector import FrameResult, Selector, SelectorConfig

log = logging.getLogger(__name__)

#: Where :func:`make_readme_pictures` writes by default: relative to the working directory
#: (run from the repository root, that is the README's folder), never to the installed package.
README_IMAGES = Path('docs') / 'images'
#: Largest PNG :func:`write_png` leaves on disk when asked to keep files small, bytes.
MAX_PNG_BYTES = 300_000
VIDEO_SUFFIXES = ('.mp4', '.avi', '.mov', '.mkv')
#: Frames kept in the README figure after the initialization.
AFTER_INIT_FRAMES = 12

_MODEL_COLOURS = {'F': 'tab:blue', 'E': 'tab:green', 'H': 'tab:orange', 'R': 'tab:red'}


@dataclass(frozen=True)
class OverlayRun:
    """What :func:`write_overlay_video` did.

    Attributes:
        results: one :class:`FrameResult` per processed frame.
        indices: (N,) int sequence index of each result.
        thresholds: model name -> threshold the selector used.
        output: the video file or PNG folder written.
        frames_written: frames in ``output``.
    """

    results: list[FrameResult]
    indices: np.ndarray
    thresholds: dict[str, float]
    output: Path
    frames_written: int


def iter_overlays(
    sequence: Any,
    models: ModelSet,
    config: SelectorConfig | None = None,
    start: int = 0,
    stop: int | None = None,
) -> Iterator[tuple[int, FrameResult, np.ndarray, Selector]]:
    """Run a :class:`Selector` over ``sequence[start:stop]`` and draw each frame's overlay.

    Args:
        sequence: a :class:`~initsel_ros.datasets.Sequence` (``image(i)``, ``stamps``,
            ``intrinsics``).
        models: the four models.
        config: selector settings (default :class:`SelectorConfig`).
        start: first frame index.
        stop: one past the last frame index (default: the end).

    Yields:
        ``(index, result, overlay (H, W, 3) uint8 BGR, selector)`` per frame.
    """
    selector = Selector(models, sequence.intrinsics, config)
    stamps = sequence.stamps_ns
    stop = len(sequence) if stop is None else min(stop, len(sequence))
    for i in range(start, stop):
        image = sequence.image(i)
        result = selector.process(image, int(stamps[i]))
        overlay = draw_frame_overlay(image, result)
        yield i, result, overlay, selector


def write_png(path: Path | str, image: np.ndarray, max_bytes: int | None = None) -> Path:
    """Write a PNG; with ``max_bytes``, posterize colours (then halve the size) until it fits.

    Returns:
        The path written.

    Raises:
        ConfigError: OpenCV cannot write the file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    candidates = [image]
    if max_bytes is not None:
        candidates += [image & np.uint8(mask) for mask in (0xF8, 0xF0, 0xE0)]
        small = cv2.resize(image, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        candidates.append(small & np.uint8(0xF0))
    for img in candidates:
        ok, buf = cv2.imencode('.png', img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        if not ok:
            raise ConfigError(f'{path}: cannot encode PNG')
        if max_bytes is None or buf.size <= max_bytes:
            break
    try:
        path.write_bytes(buf.tobytes())
    except OSError as exc:
        raise ConfigError(f'{path}: cannot write: {exc}') from exc
    return path


def write_overlay_video(
    sequence: Any,
    models: ModelSet,
    out_path: Path | str,
    config: SelectorConfig | None = None,
    start: int = 0,
    stop: int | None = None,
    fps: float | None = None,
) -> OverlayRun:
    """Write the debug overlay of every frame as an MP4 or as numbered PNG frames.

    Args:
        sequence: the frames (see :func:`iter_overlays`).
        models: the four models.
        out_path: a ``.mp4`` (also ``.avi``/``.mov``/``.mkv``) file, written with OpenCV's
            'mp4v' codec; any other path is a folder that receives ``frame_000000.png``, ...
            named by sequence index.
        config: selector settings.
        start: first frame index.
        stop: one past the last frame index (default: the end).
        fps: video frame rate (default: from the sequence's timestamps, else 30).

    Returns:
        An :class:`OverlayRun` with every frame's result.

    Raises:
        ConfigError: the output cannot be opened for writing.
    """
    out_path = Path(out_path)
    as_video = out_path.suffix.lower() in VIDEO_SUFFIXES
    if fps is None:
        fps = _frame_rate(sequence.stamps)
    writer = None
    if not as_video:
        out_path.mkdir(parents=True, exist_ok=True)
    results, indices = [], []
    thresholds: dict[str, float] = {}
    try:
        for i, result, overlay, selector in iter_overlays(sequence, models, config, start, stop):
            thresholds = dict(selector.thresholds)
            if as_video:
                if writer is None:
                    writer = _open_video(out_path, fps, overlay.shape[1], overlay.shape[0])
                writer.write(overlay)
            else:
                write_png(out_path / f'frame_{i:06d}.png', overlay)
            results.append(result)
            indices.append(i)
    finally:
        if writer is not None:
            writer.release()
    log.info('wrote %d overlay frames to %s', len(results), out_path)
    return OverlayRun(results, np.asarray(indices, np.int64), thresholds, out_path, len(results))


def _frame_rate(stamps: np.ndarray) -> float:
    if len(stamps) < 2:
        return 30.0
    dt = float(np.median(np.diff(stamps)))
    return 1.0 / dt if dt > 1e-4 and math.isfinite(dt) else 30.0


def _open_video(path: Path, fps: float, width: int, height: int) -> cv2.VideoWriter:
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*'mp4v'), fps, (width, height))
    if not writer.isOpened():
        raise ConfigError(f'{path}: OpenCV cannot open a video writer (mp4v codec)')
    return writer


def groundtruth_baselines(
    sequence: Any, results: SequenceABC[FrameResult], indices: SequenceABC[int]
) -> np.ndarray:
    """Ground-truth baseline of each processed frame: camera-centre distance to its reference.

    Args:
        sequence: the frames with ground-truth poses (``poses()``, ``stamps``).
        results: the selector's results.
        indices: sequence index of each result.

    Returns:
        (N,) float64 metres; NaN where a pose or the reference is unknown.
    """
    stamps = sequence.stamps_ns
    centres = sequence.poses()[:, :3, 3]
    out = np.full(len(results), np.nan)
    for k, (result, i) in enumerate(zip(results, indices, strict=True)):
        if result.reference_stamp_ns is None:
            continue
        ref = int(np.argmin(np.abs(stamps - result.reference_stamp_ns)))
        out[k] = float(np.linalg.norm(centres[i] - centres[ref]))
    return out


def plot_probabilities(
    results: SequenceABC[FrameResult],
    groundtruth_baselines: np.ndarray | None,
    out_png: Path | str,
    thresholds: Mapping[str, float] | None = None,
    indices: SequenceABC[int] | None = None,
    title: str | None = None,
    r_baseline_m: float | None = 0.05,
) -> Path:
    """Plot the four probabilities over time, with thresholds, firings and the true baseline.

    Args:
        results: the selector's results, in order.
        groundtruth_baselines: (N,) metres per result (NaN = unknown), or None.
        out_png: the PNG to write.
        thresholds: model name -> threshold, drawn as dashed lines (default 0.5 each).
        indices: x value (sequence frame index) per result (default ``result.frame_index``).
        title: figure title.
        r_baseline_m: baseline below which model R's training label says rotation, metres;
            drawn on the baseline axis (None: not drawn).

    Returns:
        The path written (about 800x400 pixels).

    Raises:
        ConfigError: matplotlib is not installed (``pip install initsel_ros[plot]``).
    """
    try:
        import matplotlib

        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise ConfigError(
            'plotting needs matplotlib: pip install "initsel_ros[plot]" (or matplotlib)'
        ) from exc
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    x = np.asarray([r.frame_index for r in results] if indices is None else indices, np.float64)
    thresholds = dict(thresholds or {})
    fig, ax = plt.subplots(figsize=(8, 4.4), dpi=100)
    try:
        for name in MODEL_NAMES:
            p = np.array([r.decision.probabilities.get(name, np.nan) for r in results], float)
            colour = _MODEL_COLOURS[name]
            ax.plot(x, p, color=colour, lw=1.4, label=f'P({name})')
            ax.axhline(thresholds.get(name, 0.5), color=colour, lw=0.8, ls='--', alpha=0.8)
        for reason, colour, alpha, label in (
            (Reason.ROTATION, 'tab:red', 0.08, 'reason: rotation (R fired)'),
            (Reason.DONE, '0.5', 0.15, "initialized (mode 'once')"),
        ):
            where = np.array([r.decision.reason is reason for r in results])
            if where.any():
                ax.fill_between(
                    x, 0, 1, where=where, step='mid', color=colour, alpha=alpha, lw=0, label=label
                )
        new_ref = [xi for xi, r in zip(x, results, strict=True) if r.new_reference]
        for xi in new_ref:
            ax.axvline(xi, color='0.6', lw=0.6, ls=':')
        for xi, r in zip(x, results, strict=True):
            if r.initialization is not None:
                ax.axvline(xi, color='k', lw=1.6)
                ax.annotate(
                    f'init {r.initialization.method.value}',
                    (xi, 1.02),
                    xycoords=('data', 'axes fraction'),
                    ha='center',
                    fontsize=8,
                )
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel('frame')
        ax.set_ylabel('probability (dashed: threshold)')
        if len(x):
            ax.set_xlim(x[0], x[-1])
        handles, labels = ax.get_legend_handles_labels()
        if groundtruth_baselines is not None and np.isfinite(groundtruth_baselines).any():
            ax2 = ax.twinx()
            (line,) = ax2.plot(x, groundtruth_baselines, color='k', lw=1.0, alpha=0.7)
            handles.append(line)
            labels.append('true baseline to reference (m)')
            if r_baseline_m is not None:
                handles.append(ax2.axhline(r_baseline_m, color='k', lw=0.8, ls=':', alpha=0.7))
                labels.append(f'R label limit ({r_baseline_m:g} m)')
            ax2.set_ylabel('baseline, metres')
            ax2.set_ylim(0, max(float(np.nanmax(groundtruth_baselines)) * 1.1, 0.1))
        ax.legend(
            handles,
            labels,
            loc='upper center',
            bbox_to_anchor=(0.5, -0.16),
            fontsize=7,
            ncol=5,
            frameon=False,
        )
        if title:
            ax.set_title(title, fontsize=10, pad=14)
        fig.tight_layout()
        fig.savefig(out_png)
    finally:
        plt.close(fig)
    return out_png


# --- README pictures -----------------------------------------------------------------------


def _rendered(
    work_dir: Path, trajectory: str, frames: int, seed: int = 0, scene: str = 'structure_texture'
) -> Any:
    """A rendered sequence in ``work_dir`` (reused when it already has enough frames)."""
    from initsel_ros.datasets import open_sequence

    folder = work_dir / f'{scene}_{trajectory}_{seed}'
    if (folder / 'rgb.txt').is_file():
        seq = open_sequence(folder)
        if len(seq) >= frames:
            return seq
    from initsel_ros.synth import render_sequence

    log.info('rendering %d frames (%s, %s) into %s', frames, scene, trajectory, folder)
    render_sequence(folder, scene=scene, trajectory=trajectory, frames=frames, seed=seed)
    return open_sequence(folder)


def _rotation_frame(seq: Any, models: ModelSet, frames: int) -> tuple[np.ndarray, FrameResult]:
    """The overlay that best shows the R veto: ROTATION with vetoed models, highest P(R)."""
    best: tuple[tuple, np.ndarray, FrameResult] | None = None
    for _, result, overlay, _sel in iter_overlays(seq, models, stop=frames):
        d = result.decision
        key = (d.reason is Reason.ROTATION, len(d.vetoed), d.probabilities.get('R', -1.0))
        if best is None or key > best[0]:
            best = (key, overlay, result)
    if best is None:
        raise InitselError('the rotation sequence has no frames')
    return best[1], best[2]


def make_readme_pictures(
    out_dir: Path | str = README_IMAGES,
    work_dir: Path | str | None = None,
    models: ModelSet | None = None,
    frames: int = 240,
    max_bytes: int = MAX_PNG_BYTES,
    rotation_frames: int = 90,
) -> list[Path]:
    """Regenerate the README pictures from rendered sequences.

    Writes ``rotation_veto.png`` (a frame under pure rotation, models vetoed by R),
    ``initialization.png`` (the frame that initialized on the ``near`` trajectory, inliers
    shown) and ``probabilities.png`` (the four probabilities over that run with the true
    baseline).

    Args:
        out_dir: where the PNGs go.
        work_dir: where sequences are rendered (reused across calls; default: a temporary
            folder removed afterwards).
        models: the models (default: the packaged ``config/models.json``).
        frames: frames of the ``near`` run.
        max_bytes: largest PNG size, bytes (colours are posterized until it fits).
        rotation_frames: frames of the ``rotation`` run the veto frame is chosen from.

    Returns:
        The paths written.
    """
    import shutil
    import tempfile

    out_dir = Path(out_dir)
    if models is None:
        from initsel_ros.models import default_model_path

        models = ModelSet.load(default_model_path())
    tmp = None
    if work_dir is None:
        tmp = Path(tempfile.mkdtemp(prefix='initsel_pictures_'))
        work_dir = tmp
    work_dir = Path(work_dir)
    try:
        written = []
        rot = _rendered(work_dir, 'rotation', rotation_frames)
        overlay, result = _rotation_frame(rot, models, rotation_frames)
        log.info('rotation frame %d: %s', result.frame_index, result.decision.reason.value)
        written.append(write_png(out_dir / 'rotation_veto.png', overlay, max_bytes))

        near = _rendered(work_dir, 'near', frames)
        results, indices, init_overlay, init_at = [], [], None, None
        thresholds: dict[str, float] = {}
        for i, res, ov, sel in iter_overlays(
            near, models, SelectorConfig(mode='once'), stop=frames
        ):
            results.append(res)
            indices.append(i)
            thresholds = dict(sel.thresholds)
            if res.initialization is not None and init_overlay is None:
                init_overlay, init_at = ov, len(results)
            if init_at is not None and len(results) >= init_at + AFTER_INIT_FRAMES:
                break  # mode 'once': nothing more to see
        if init_overlay is None:
            log.warning('no initialization in %d frames of the near trajectory', len(results))
        else:
            written.append(write_png(out_dir / 'initialization.png', init_overlay, max_bytes))
        baselines = groundtruth_baselines(near, results, indices)
        written.append(
            plot_probabilities(
                results,
                baselines,
                out_dir / 'probabilities.png',
                thresholds,
                indices,
                title='Rendered near trajectory: model probabilities and true baseline',
            )
        )
        return written
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
