"""Checks on a stream's image stamps (integer nanoseconds): negative, zero, repeated, backwards,
and gaps where frames are missing.

Time going back by at most a tolerance (:data:`DEFAULT_RESTART_TOLERANCE_NS`, the node's
``restart_tolerance_s``) is jitter: the frame is *out of order* and skipped, and the stream's
latest stamp stays what it was. A jump back by more is a *restart* (a bag replayed from the
start, a clock reset). Negative, zero and repeated stamps never stop a frame: the selector
carries any stamp through unchanged. A zero stamp is a frame its publisher did not stamp: it is
neither compared with the latest stamp nor remembered as it, so one unstamped frame in a
stamped stream is not a restart. The node logs each kind the first time it appears and
counts them in ``~/status``.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass
from enum import Enum


class StampIssue(str, Enum):
    """Something unusual about a frame's stamp."""

    NEGATIVE = 'negative'  # before 1970 (sec < 0): allowed by builtin_interfaces/Time
    ZERO = 'zero'  # sec = nanosec = 0: the publisher does not stamp its images
    DUPLICATE = 'duplicate'  # the same stamp as the previous frame
    OUT_OF_ORDER = 'out_of_order'  # earlier than the latest frame, within the tolerance
    RESTART = 'restart'  # earlier than the latest frame by more than the tolerance
    GAP = 'gap'  # later than the latest frame by over GAP_PERIODS of the stream's period


#: What each issue means for the selector, for the log line.
CONSEQUENCES: dict[StampIssue, str] = {
    StampIssue.NEGATIVE: 'processed as usual; init/* carry the same negative stamps',
    StampIssue.ZERO: 'processed as usual, but init/* cannot tell frames apart by stamp',
    StampIssue.DUPLICATE: 'processed as usual, but init/* cannot tell these frames apart',
    StampIssue.OUT_OF_ORDER: (
        'jitter (within restart_tolerance_s): the frame is skipped (3 such frames in a row, '
        'each later than the one before, are a restart)'
    ),
    StampIssue.RESTART: (
        'a replay restart or clock reset (further back than restart_tolerance_s, or frames '
        'going on from a little back): a new reference is taken, but in mode once an '
        'initialization is kept until ~/reset'
    ),
    StampIssue.GAP: (
        'frames are missing before this one: lost on the way (a best-effort image QoS under '
        'load drops them before the node sees them) or a camera that paused; processed as '
        'usual'
    ),
}

#: A frame whose stamp follows the previous one by more than this many times the stream's
#: period (the median of its last :data:`PERIOD_WINDOW` intervals) has frames missing before
#: it; a stream of varying rate (15-30 Hz) stays under it.
GAP_PERIODS = 2.5
#: Intervals the period is the median of; at least a third of them are needed to judge. An
#: interval over frames the node dropped counts as their mean spacing (before, it did not
#: count, and a node that dropped every other frame never learnt a period). The median, not a
#: low quantile: with stamps jittered by 8-10 ms at 30 Hz, or stamped in pairs, a low quantile
#: saw gaps that were not there.
PERIOD_WINDOW = 30

#: Default largest jump back in time that is still jitter, nanoseconds (1 s).
DEFAULT_RESTART_TOLERANCE_NS = 1_000_000_000
#: Frames in a row behind the latest stamp, each later than the one before, that make a
#: restart though they are within the tolerance: a stream that started over a little back
#: (a bag looped every 0.67 s had every later frame skipped as out of order). Jitter delays
#: single frames.
RESTART_AFTER_LATE_FRAMES = 3


@dataclass(frozen=True)
class StampCheck:
    """The issues of one stamp.

    Attributes:
        issues: every issue of this stamp.
        new: those seen for the first time on this stream (to be logged).
        back_ns: how far time went back, nanoseconds (0 unless OUT_OF_ORDER or RESTART).
        late_restart: a RESTART within the tolerance: the
            :data:`RESTART_AFTER_LATE_FRAMES`-th frame in a row from a little back (else a
            restart is a jump back beyond the tolerance).
    """

    issues: tuple[StampIssue, ...] = ()
    new: tuple[StampIssue, ...] = ()
    back_ns: int = 0
    late_restart: bool = False

    @property
    def out_of_order(self) -> bool:
        """The frame is a little older than the latest one: skip it."""
        return StampIssue.OUT_OF_ORDER in self.issues

    @property
    def restart(self) -> bool:
        """Time jumped back further than the tolerance: the stream started over."""
        return StampIssue.RESTART in self.issues


class StampMonitor:
    """Classifies each frame's stamp against the latest frame's and counts the issues.

    Args:
        restart_tolerance_ns: largest jump back that is jitter (out of order), nanoseconds.
    """

    def __init__(self, restart_tolerance_ns: int = DEFAULT_RESTART_TOLERANCE_NS) -> None:
        self.counts: dict[str, int] = {issue.value: 0 for issue in StampIssue}
        #: Frames missing from the stream, estimated from the gaps' lengths in periods.
        self.missing = 0
        self.restart_tolerance_ns = int(restart_tolerance_ns)
        self._last_ns: int | None = None
        self._intervals: deque[int] = deque(maxlen=PERIOD_WINDOW)
        self._late: list[int] = []  # the frames in a row behind the latest stamp, rising

    def check(self, stamp_ns: int, unchecked: int = 0) -> StampCheck:
        """Classify ``stamp_ns`` (the next frame's stamp) and remember it (unless out of order).

        ``unchecked``: frames received since the last check but not checked (the node dropped
        them for want of time): the interval spans them too, so its share of the period is
        interval / (unchecked + 1), and a gap lies only beyond them (:meth:`_missing`).
        """
        issues = []
        if stamp_ns < 0:
            issues.append(StampIssue.NEGATIVE)
        back_ns = 0
        late_restart = False
        if stamp_ns == 0:  # not stamped: no time to compare, and none to remember
            issues.append(StampIssue.ZERO)
        else:
            if self._last_ns is not None:
                if stamp_ns == self._last_ns:
                    issues.append(StampIssue.DUPLICATE)
                elif stamp_ns < self._last_ns:
                    back_ns = self._last_ns - stamp_ns
                    within = back_ns <= self.restart_tolerance_ns
                    late = within and not self._started_over(stamp_ns)
                    late_restart = within and not late
                    issues.append(StampIssue.OUT_OF_ORDER if late else StampIssue.RESTART)
                    if not late:
                        self._intervals.clear()  # (another stream, maybe another rate)
                        self._late.clear()
                else:
                    interval = stamp_ns - self._last_ns
                    missing = self._missing(interval, unchecked)
                    if missing:
                        issues.append(StampIssue.GAP)
                        self.missing += missing
                    # over frames the node dropped: their mean spacing, a period too
                    self._intervals.append(interval // (unchecked + 1))
            if StampIssue.OUT_OF_ORDER not in issues:
                self._last_ns = stamp_ns
                self._late.clear()
        new = tuple(issue for issue in issues if self.counts[issue.value] == 0)
        for issue in issues:
            self.counts[issue.value] += 1
        return StampCheck(tuple(issues), new, back_ns, late_restart)

    def _started_over(self, stamp_ns: int) -> bool:
        """Is ``stamp_ns``, behind the latest stamp, the :data:`RESTART_AFTER_LATE_FRAMES`-th
        such frame in a row, each later than the one before?"""
        if self._late and stamp_ns <= self._late[-1]:
            self._late.clear()
        self._late.append(stamp_ns)
        return len(self._late) >= RESTART_AFTER_LATE_FRAMES

    def _missing(self, interval_ns: int, unchecked: int) -> int:
        """Frames missing within ``interval_ns``, which also spans ``unchecked`` frames: 0
        unless it exceeds :data:`GAP_PERIODS` of the stream's period (the median of the last
        :data:`PERIOD_WINDOW` intervals, once a third of them are there) beyond those frames'
        periods; then the periods it spans, less one and less those frames (at least 1)."""
        if len(self._intervals) < PERIOD_WINDOW // 3:
            return 0
        period = statistics.median(self._intervals)
        if interval_ns <= (GAP_PERIODS + unchecked) * period:
            return 0
        return max(1, round(interval_ns / period) - 1 - unchecked)

    def forget_last(self) -> None:
        """Forget the previous stamp (after a reset, any next stamp is fine)."""
        self._last_ns = None
        self._intervals.clear()
        self._late.clear()


__all__ = [
    'CONSEQUENCES',
    'DEFAULT_RESTART_TOLERANCE_NS',
    'GAP_PERIODS',
    'PERIOD_WINDOW',
    'RESTART_AFTER_LATE_FRAMES',
    'StampCheck',
    'StampIssue',
    'StampMonitor',
]
