"""The per-frame status record: the schema of ``~/status`` and of ``/diagnostics``' values.

The node builds one :class:`FrameStatus` per received frame from the selector's
:class:`~initsel_ros.selector.FrameResult` (None for a frame that never reached the selector)
and its own counters (:class:`NodeCounters`), publishes :meth:`FrameStatus.to_json` on
``~/status`` and :meth:`FrameStatus.diagnostic_values` on ``/diagnostics``; readers turn the
JSON back into the record with :meth:`FrameStatus.from_json`. docs/node.md documents every
field (a test holds the table there to the fields here). Imports nothing from ROS.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

from initsel_ros import timestamps
from initsel_ros.errors import StatusError
from initsel_ros.names import MODEL_NAMES
from initsel_ros.policy import Reason

if TYPE_CHECKING:  # the selector pulls in OpenCV; readers of the status need none of it
    from initsel_ros.selector import FrameResult
    from initsel_ros.verify import VerifyStep

#: Reasons reported with level WARN (every other reason is OK): the node lost something
#: (its tracks, a frame) or failed. 'pose estimation failed' is OK: the fire path refusing
#: a pair whose baseline is too short, or ambiguous, is the ordinary wait before a good
#: initialization (25 WARNs of it before one in a probe's run flooded /diagnostics).
WARN_REASONS = frozenset({Reason.TOO_FEW_TRACKS, Reason.SKIPPED_IMAGE, Reason.INTERNAL_ERROR})


def _split_ns(ns: int | None) -> tuple[int | None, int | None]:
    """:func:`initsel_ros.timestamps.split_ns`, None for None."""
    return (None, None) if ns is None else timestamps.split_ns(ns)


@dataclass(frozen=True)
class VerificationStatus:
    """One frame's PnP check of a held-back candidate (see :mod:`initsel_ros.verify`).

    Attributes:
        ok: the frame confirms the candidate.
        tracked: map points still tracked in this frame.
        inliers: of those, PnP inliers.
        fraction: inliers / map points, rounded to 3 decimals.
        rms_px: RMS reprojection error of the inliers, pixels, 3 decimals (None when there
            was no pose).
        detail: the check in words.
    """

    ok: bool
    tracked: int
    inliers: int
    fraction: float
    rms_px: float | None
    detail: str

    @classmethod
    def from_step(cls, step: VerifyStep) -> VerificationStatus:
        """The status view of a :class:`~initsel_ros.verify.VerifyStep`."""
        return cls(
            ok=bool(step.ok),
            tracked=int(step.tracked),
            inliers=int(step.inliers),
            fraction=round(float(step.fraction), 3),
            rms_px=round(float(step.rms_px), 3) if math.isfinite(step.rms_px) else None,
            detail=step.detail,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class NodeCounters:
    """What the node knows about its stream beyond one frame's result.

    Attributes:
        initialized: the selector is done (mode once) until a reset.
        initializations: initializations published so far.
        received_frames: images received; once the node is idle, processed + dropped +
            skipped.
        processed_frames: images the selector decided on.
        dropped_frames: images overwritten before they were processed, or dropped by
            ``~/reset``.
        skipped_frames: images that could not be used (conversion errors, out-of-order
            stamps, internal errors).
        missing_frames: images that never reached the node, estimated from the gaps in the
            stamps (lost on the way, or a camera that paused).
        intrinsics_source: 'parameters' (camera.*) or 'camera_info'.
        intrinsics: the intrinsics in use (fx, fy, cx, cy, width, height), or None.
        intrinsics_guessed: the pose uses guessed intrinsics, or the last camera_info was
            refused.
        intrinsics_warning: why the intrinsics in use are doubtful: guessed, the last
            camera_info refused, or scaled from another image size ('' when they are not).
        bit_depth: significant bits used to scale 16-bit images (None until one arrives).
        stamp_issues: stamp issue ('negative', 'zero', 'duplicate', 'out_of_order',
            'restart') -> frames.
        source_warning: why the frames look like more than one camera on the image topic
            ('' when they do not).
    """

    initialized: bool = False
    initializations: int = 0
    received_frames: int = 0
    processed_frames: int = 0
    dropped_frames: int = 0
    skipped_frames: int = 0
    missing_frames: int = 0
    intrinsics_source: str = 'parameters'
    intrinsics: Mapping[str, Any] | None = None
    intrinsics_guessed: bool = False
    intrinsics_warning: str = ''
    bit_depth: int | None = None
    stamp_issues: Mapping[str, int] = field(default_factory=dict)
    source_warning: str = ''


@dataclass(frozen=True)
class FrameStatus:
    """What the node says about one received frame (``~/status``, one JSON object).

    Stamps are integer seconds and nanoseconds, exactly as the image header carried them.
    docs/node.md describes every field.
    """

    stamp: float
    stamp_sec: int
    stamp_nanosec: int
    reference_stamp_sec: int | None
    reference_stamp_nanosec: int | None
    frame_index: int | None
    reason: Reason
    detail: str
    level: str
    probabilities: Mapping[str, float | None]
    fired: tuple[str, ...]
    vetoed: tuple[str, ...]
    referred: tuple[str, ...]
    tracks: int
    mean_disparity_px: float
    frames_since_reference: int
    new_reference: bool
    method: str | None
    initializing_stamp_sec: int | None
    initializing_stamp_nanosec: int | None
    initialized: bool
    initializations: int
    received_frames: int
    processed_frames: int
    dropped_frames: int
    skipped_frames: int
    missing_frames: int
    intrinsics_source: str
    intrinsics: Mapping[str, Any] | None
    intrinsics_guessed: bool
    intrinsics_warning: str
    bit_depth: int | None
    stamp_issues: Mapping[str, int]
    source_warning: str
    selection: Mapping[str, Any] | None
    verification: VerificationStatus | None
    rotation_test: Mapping[str, float | None] | None = None
    background_test: Mapping[str, float | None] | None = None
    fire_path_due_in: int | None = None

    # ------------------------------------------------------------------------------ building
    @classmethod
    def from_result(
        cls,
        result: FrameResult | None,
        *,
        stamp_sec: int,
        stamp_nanosec: int,
        counters: NodeCounters,
        reason: Reason | None = None,
        detail: str | None = None,
    ) -> FrameStatus:
        """The status of one frame.

        Args:
            result: what the selector did with the frame; None when it never got there
                (then ``reason`` is required).
            stamp_sec: the image header's ``stamp.sec``, as received.
            stamp_nanosec: the image header's ``stamp.nanosec``, as received.
            counters: the node's counters after this frame.
            reason: overrides the decision's reason (e.g. ``INTERNAL_ERROR``).
            detail: overrides the decision's detail.

        Raises:
            StatusError: no result and no reason.
        """
        decision = result.decision if result is not None else None
        if reason is None:
            if decision is None:
                raise StatusError('a status without a selector result needs a reason')
            reason = decision.reason
        if detail is None:
            detail = decision.detail if decision is not None else ''
        reason = Reason(reason)
        probabilities = dict(decision.probabilities) if decision is not None else {}
        init = result.initialization if result is not None else None
        reference_sec, reference_nanosec = _split_ns(
            result.reference_stamp_ns if result is not None else None
        )
        init_sec, init_nanosec = _split_ns(init.stamp_ns if init is not None else None)
        selection = (
            init.selection
            if init is not None
            else (result.selection if result is not None else None)
        )
        step = result.verification if result is not None else None
        return cls(
            stamp=stamp_sec + stamp_nanosec * 1e-9,  # for humans; exact: stamp_sec/_nanosec
            stamp_sec=int(stamp_sec),
            stamp_nanosec=int(stamp_nanosec),
            reference_stamp_sec=reference_sec,
            reference_stamp_nanosec=reference_nanosec,
            frame_index=result.frame_index if result is not None else None,
            reason=reason,
            detail=detail,
            level='WARN' if reason in WARN_REASONS else 'OK',
            probabilities={m: _float_or_none(probabilities.get(m)) for m in MODEL_NAMES},
            fired=tuple(decision.fired) if decision is not None else (),
            vetoed=tuple(decision.vetoed) if decision is not None else (),
            referred=tuple(decision.referred) if decision is not None else (),
            tracks=int(decision.n_tracks) if decision is not None else 0,
            mean_disparity_px=float(decision.mean_disparity) if decision is not None else 0.0,
            frames_since_reference=result.frames_since_reference if result is not None else 0,
            new_reference=bool(result.new_reference) if result is not None else False,
            method=init.method.value if init is not None else None,
            initializing_stamp_sec=init_sec,
            initializing_stamp_nanosec=init_nanosec,
            initialized=bool(counters.initialized),
            initializations=int(counters.initializations),
            received_frames=int(counters.received_frames),
            processed_frames=int(counters.processed_frames),
            dropped_frames=int(counters.dropped_frames),
            skipped_frames=int(counters.skipped_frames),
            missing_frames=int(counters.missing_frames),
            intrinsics_source=counters.intrinsics_source,
            intrinsics=None if counters.intrinsics is None else dict(counters.intrinsics),
            intrinsics_guessed=bool(counters.intrinsics_guessed),
            intrinsics_warning=counters.intrinsics_warning,
            bit_depth=counters.bit_depth,
            stamp_issues=dict(counters.stamp_issues),
            source_warning=counters.source_warning,
            selection=None if selection is None else selection.to_dict(),
            verification=None if step is None else VerificationStatus.from_step(step),
            rotation_test=(
                result.rotation.to_dict()
                if result is not None and result.rotation is not None
                else None
            ),
            background_test=(
                result.background.to_dict()
                if result is not None and result.background is not None
                else None
            ),
            fire_path_due_in=result.fire_path_due_in if result is not None else None,
        )

    # --------------------------------------------------------------------------------- reading
    @property
    def stamp_ns(self) -> int:
        """The frame's stamp, integer nanoseconds (exact)."""
        return timestamps.stamp_ns(self.stamp_sec, self.stamp_nanosec)

    @property
    def initializing_stamp_ns(self) -> int | None:
        """The stamp of the frame the published initialization belongs to, nanoseconds."""
        if self.initializing_stamp_sec is None or self.initializing_stamp_nanosec is None:
            return None
        return timestamps.stamp_ns(self.initializing_stamp_sec, self.initializing_stamp_nanosec)

    @property
    def diagnostic_level(self) -> str:
        """'WARN' for a WARN reason, doubtful intrinsics (guessed, refused or scaled from
        another size) or frames from more than one camera, else 'OK' (``/diagnostics``)."""
        doubtful = self.intrinsics_guessed or bool(self.intrinsics_warning)
        warn = self.level == 'WARN' or doubtful or bool(self.source_warning)
        return 'WARN' if warn else 'OK'

    def diagnostic_values(self) -> dict[str, str]:
        """The ``/diagnostics`` key-values of this frame, in order."""
        values = {
            **{f'p_{m}': _fmt(self.probabilities.get(m)) for m in MODEL_NAMES},
            'tracks': str(self.tracks),
            'mean_disparity_px': _fmt(self.mean_disparity_px),
            'frames_since_reference': str(self.frames_since_reference),
            'dropped_frames': str(self.dropped_frames),
            'reason': self.reason.value
            if not self.detail
            else f'{self.reason.value}: {self.detail}',
            'intrinsics': (
                f'guessed: {self.intrinsics_warning}'
                if self.intrinsics_guessed
                else f'{self.intrinsics_source}: {self.intrinsics_warning}'
                if self.intrinsics_warning
                else self.intrinsics_source
            ),
        }
        if self.source_warning:
            values['source'] = self.source_warning
        if self.selection is not None:
            values['selection'] = str(self.selection['why'])
        return values

    # ----------------------------------------------------------------------------------- JSON
    def to_dict(self) -> dict[str, Any]:
        """Plain data, the fields in order (what :meth:`to_json` writes)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out['reason'] = self.reason.value
        out['probabilities'] = dict(self.probabilities)
        out['fired'], out['vetoed'] = list(self.fired), list(self.vetoed)
        out['referred'] = list(self.referred)
        out['stamp_issues'] = dict(self.stamp_issues)
        out['intrinsics'] = None if self.intrinsics is None else dict(self.intrinsics)
        out['selection'] = None if self.selection is None else dict(self.selection)
        out['verification'] = None if self.verification is None else self.verification.to_dict()
        out['rotation_test'] = None if self.rotation_test is None else dict(self.rotation_test)
        out['background_test'] = (
            None if self.background_test is None else dict(self.background_test)
        )
        return out

    def to_json(self) -> str:
        """The ``~/status`` message text: one JSON object."""
        return json.dumps(self.to_dict())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FrameStatus:
        """The record of :meth:`to_dict`'s output.

        Raises:
            StatusError: missing or unknown keys, an unknown reason or a malformed
                verification.
        """
        names = [f.name for f in fields(cls)]
        # (records of earlier versions have no 'referred', 'fire_path_due_in' or
        # 'source_warning')
        data = {'referred': [], 'fire_path_due_in': None, 'source_warning': '', **data}
        missing = [n for n in names if n not in data]
        unknown = sorted(set(data) - set(names))
        problems = ([f'missing {", ".join(missing)}'] if missing else []) + (
            [f'unknown {", ".join(unknown)}'] if unknown else []
        )
        if problems:
            raise StatusError('not a FrameStatus: ' + '; '.join(problems))
        values = dict(data)
        try:
            values['reason'] = Reason(values['reason'])
        except ValueError as exc:
            raise StatusError(f'not a FrameStatus: unknown reason {data["reason"]!r}') from exc
        values['fired'] = tuple(values['fired'])
        values['vetoed'] = tuple(values['vetoed'])
        values['referred'] = tuple(values['referred'])
        verification = values['verification']
        if verification is not None:
            try:
                values['verification'] = VerificationStatus(**verification)
            except TypeError as exc:
                raise StatusError(f'not a FrameStatus: verification {verification!r}') from exc
        return cls(**values)

    @classmethod
    def from_json(cls, text: str | bytes) -> FrameStatus:
        """Parse a ``~/status`` message.

        Raises:
            StatusError: not JSON, or not a FrameStatus (see :meth:`from_dict`).
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise StatusError(f'not a FrameStatus: invalid JSON: {exc}') from exc
        if not isinstance(data, dict):
            raise StatusError(f'not a FrameStatus: a JSON {type(data).__name__}, not an object')
        return cls.from_dict(data)


def _float_or_none(value: float | None) -> float | None:
    return None if value is None else float(value)


def _fmt(value: float | None) -> str:
    return '' if value is None else f'{value:.4f}'


#: The fields of ``~/status``, in order.
STATUS_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(FrameStatus))

__all__ = ['STATUS_FIELDS', 'WARN_REASONS', 'FrameStatus', 'NodeCounters', 'VerificationStatus']
