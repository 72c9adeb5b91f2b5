"""Checks on a stream's image stamps (integer nanoseconds): negative, zero, repeated, backwards.

None of them stops a frame: the selector carries any stamp through unchanged. The node logs
each kind the first time it appears, counts them in ``~/status`` and, when time goes
backwards (a bag replayed from the start, a clock reset), takes a new reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class StampIssue(str, Enum):
    """Something unusual about a frame's stamp."""

    NEGATIVE = 'negative'  # before 1970 (sec < 0): allowed by builtin_interfaces/Time
    ZERO = 'zero'  # sec = nanosec = 0: the publisher does not stamp its images
    DUPLICATE = 'duplicate'  # the same stamp as the previous frame
    BACKWARDS = 'backwards'  # earlier than the previous frame


#: What each issue means for the selector, for the log line.
CONSEQUENCES: dict[StampIssue, str] = {
    StampIssue.NEGATIVE: 'processed as usual; init/* carry the same negative stamps',
    StampIssue.ZERO: 'processed as usual, but init/* cannot tell frames apart by stamp',
    StampIssue.DUPLICATE: 'processed as usual, but init/* cannot tell these frames apart',
    StampIssue.BACKWARDS: 'a replay restart or clock reset: a new reference is taken',
}


@dataclass(frozen=True)
class StampCheck:
    """The issues of one stamp.

    Attributes:
        issues: every issue of this stamp.
        new: those seen for the first time on this stream (to be logged).
        back_ns: how far time went back, nanoseconds (0 unless BACKWARDS).
    """

    issues: tuple[StampIssue, ...] = ()
    new: tuple[StampIssue, ...] = ()
    back_ns: int = 0


class StampMonitor:
    """Classifies each frame's stamp against the previous frame's and counts the issues."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {issue.value: 0 for issue in StampIssue}
        self._last_ns: int | None = None

    def check(self, stamp_ns: int) -> StampCheck:
        """Classify ``stamp_ns`` (the next frame's stamp) and remember it."""
        issues = []
        if stamp_ns < 0:
            issues.append(StampIssue.NEGATIVE)
        if stamp_ns == 0:
            issues.append(StampIssue.ZERO)
        back_ns = 0
        if self._last_ns is not None:
            if stamp_ns == self._last_ns and stamp_ns != 0:
                issues.append(StampIssue.DUPLICATE)
            elif stamp_ns < self._last_ns:
                issues.append(StampIssue.BACKWARDS)
                back_ns = self._last_ns - stamp_ns
        self._last_ns = stamp_ns
        new = tuple(issue for issue in issues if self.counts[issue.value] == 0)
        for issue in issues:
            self.counts[issue.value] += 1
        return StampCheck(tuple(issues), new, back_ns)

    def forget_last(self) -> None:
        """Forget the previous stamp (after a reset, any next stamp is fine)."""
        self._last_ns = None


__all__ = ['CONSEQUENCES', 'StampCheck', 'StampIssue', 'StampMonitor']
