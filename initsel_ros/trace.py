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
from initsel_ros.errors import ImageConversionError, InitselError
from initsel_ros.image import downscaled, tracking_factor
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
    max_tracking_width: int = 0,
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
        max_tracking_width: the node's parameter of that name: wider frames are shrunk by
            the smallest whole factor that brings them within it, and the calibration
            with them (0: full size).

    Yields:
        One :class:`FrameStatus` per frame. A frame the reader cannot load (a corrupt or
        missing file, another size) or the selector cannot use has reason ``image
        skipped`` and the error; an error inside the selector, ``internal error``: the trace
        goes on, as the node does.
    """
    factor = tracking_factor(sequence.intrinsics.width, max_tracking_width)
    camera = sequence.intrinsics.binned(factor)
    intrinsics = camera.to_dict()  # (the camera stays: the records share one calibration)
    selector = Selector(models, camera, config)
    stamps = sequence.stamps_ns
    stop = len(sequence) if stop is None else min(stop, len(sequence))
    initializations = processed = skipped = 0
    for received, i in enumerate(range(start, stop), start=1):
        stamp_ns = int(stamps[i])
        result, reason, detail = None, None, None
        try:
            image = downscaled(sequence.native_image(i), factor)
        except InitselError as exc:  # the reader's: corrupt, missing, another size
            reason, detail = Reason.SKIPPED_IMAGE, f'frame {i}: {exc}'
        else:
            try:
                result = selector.process(image, stamp_ns)
            except ImageConversionError as exc:  # the selector's, as the node's
                reason, detail = Reason.SKIPPED_IMAGE, f'frame {i}: {exc}'
            except Exception as exc:  # as the node: said in the record, on to the next frame
                reason, detail = Reason.INTERNAL_ERROR, f'frame {i}: {exc!r}'
        if result is None:
            skipped += 1
        else:
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
