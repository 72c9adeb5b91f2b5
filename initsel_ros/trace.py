"""What the selector did on a recorded sequence, frame by frame, without ROS.

:func:`trace_sequence` runs a :class:`~initsel_ros.selector.Selector` over a sequence (any
:func:`~initsel_ros.datasets.open_sequence` source) and yields, per frame, the record the node
publishes on ``~/status`` (:class:`~initsel_ros.status.FrameStatus`, the same schema and the
same builder): reason, detail, the four probabilities, the rotation and background tests, the
candidates' scores, the verification. A frame that cannot be read is a skipped frame, said
and counted, as the node counts a frame it cannot convert. :func:`summary_line` is one line
of text per record, for the frames where something happened (:func:`eventful`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from initsel_ros import timestamps
from initsel_ros.errors import InitselError
from initsel_ros.models import ModelSet
from initsel_ros.names import MODEL_NAMES
from initsel_ros.policy import Reason
from initsel_ros.selector import Selector, SelectorConfig
from initsel_ros.status import FrameStatus, NodeCounters


def trace_sequence(
    sequence: Any,
    models: ModelSet,
    config: SelectorConfig | None = None,
    start: int = 0,
    stop: int | None = None,
) -> Iterator[FrameStatus]:
    """The ``~/status`` record of each frame ``start..stop - 1`` of ``sequence`` run through a
    selector with ``config`` (default :class:`SelectorConfig`), as the node would publish it
    for the same frames arriving one by one, none dropped.

    Args:
        sequence: a :class:`~initsel_ros.datasets.Sequence` (``native_image(i)``,
            ``stamps_ns``, ``intrinsics``).
        models: the four models.
        config: the selector's settings.
        start: first frame index.
        stop: one past the last frame index (default: the end).

    Yields:
        One :class:`FrameStatus` per frame; a frame the reader cannot load (a corrupt or
        missing file, another size) has reason ``skipped image`` and the reader's message.
    """
    selector = Selector(models, sequence.intrinsics, config)
    stamps = sequence.stamps_ns
    stop = len(sequence) if stop is None else min(stop, len(sequence))
    intrinsics = sequence.intrinsics.to_dict()
    initializations = processed = skipped = 0
    for received, i in enumerate(range(start, stop), start=1):
        stamp_ns = int(stamps[i])
        result, reason, detail = None, None, None
        try:
            image = sequence.native_image(i)
        except InitselError as exc:  # the reader's own errors: corrupt, missing, resized
            skipped += 1
            reason, detail = Reason.SKIPPED_IMAGE, f'frame {i}: {exc}'
        else:
            result = selector.process(image, stamp_ns)
            processed += 1
            initializations += result.initialization is not None
        counters = NodeCounters(
            initialized=bool(selector.initialized),
            initializations=initializations,
            received_frames=received,
            processed_frames=processed,
            skipped_frames=skipped,
            intrinsics_source='camera_info',  # the source's calibration, as `initsel replay`
            intrinsics=intrinsics,
            bit_depth=selector.bit_depth.bits or None,
        )
        sec, nanosec = timestamps.split_ns(stamp_ns)
        yield FrameStatus.from_result(
            result,
            stamp_sec=sec,
            stamp_nanosec=nanosec,
            counters=counters,
            reason=reason,
            detail=detail,
        )


def eventful(status: FrameStatus) -> bool:
    """Did something happen on this frame beyond "no model fired": a new reference, a model's
    yes, a fire-path run (its rotation test), a verification step, an initialization or a
    warning?"""
    return bool(
        status.new_reference
        or status.fired
        or status.rotation_test is not None
        or status.verification is not None
        or status.method is not None
        or status.level != 'OK'
    )


def summary_line(status: FrameStatus, index: int | None = None) -> str:
    """One line of text for one record: the frame (``index``, else the selector's count),
    frames since the reference, the reason, the probabilities, the rotation test (statistic
    and noise) where it ran, and the detail."""
    frame = index if index is not None else status.frame_index
    parts = [f'{frame if frame is not None else "-":>5} +{status.frames_since_reference:<3}']
    parts.append(f'{status.reason.value:<24}')
    probabilities = ' '.join(
        f'{m} {p:.2f}' if p is not None else f'{m} -'
        for m, p in ((m, status.probabilities.get(m)) for m in MODEL_NAMES)
    )
    parts.append(probabilities)
    rotation = status.rotation_test
    if rotation is not None and rotation.get('statistic') is not None:
        parts.append(f'rotation {rotation["statistic"]:.1f}x noise {rotation["noise_px"]:.2f}px')
    if status.method is not None:
        parts.append(f'-> {status.method}')
    if status.detail:
        parts.append(status.detail)
    return '  '.join(parts)


__all__ = ['eventful', 'summary_line', 'trace_sequence']
